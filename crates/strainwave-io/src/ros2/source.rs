//! Messages of a log, in file order: an MCAP file, a rosbag2 SQLite file (`.db3`, with the
//! `sqlite` feature) or a rosbag2 folder (its `.mcap` or `.db3` files in the order its
//! `metadata.yaml` lists them); each may be compressed whole (`.mcap.zstd`, see
//! `unpacked`). One message is held at a time (MCAP: one decompressed
//! chunk; SQLite: a page of [`DB3_PAGE_ROWS`] rows).

use std::borrow::Cow;
use std::collections::HashMap;
use std::fs::File;
use std::io::{BufReader, Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};

use super::unpacked;
use crate::error::IoError;

/// Largest MCAP record (or decompressed chunk) read, bytes.
pub const MAX_RECORD_BYTES: usize = 1 << 28;
/// Rows fetched per SQLite query.
pub const DB3_PAGE_ROWS: i64 = 2048;

/// What a channel carries (the same topic and type in several files is one channel).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ChannelInfo {
    /// Topic name.
    pub topic: String,
    /// Message type (`sensor_msgs/msg/JointState`), empty without a schema.
    pub type_name: String,
    /// Schema encoding (`ros2msg`, `ros2idl`, `jsonschema`, `protobuf`, …).
    pub schema_encoding: String,
    /// Schema text.
    pub schema: Vec<u8>,
    /// Message encoding (`cdr`, `json`, …).
    pub message_encoding: String,
}

/// Channels by index, shared by the passes over a log.
#[derive(Debug, Default)]
pub struct Registry {
    /// Every channel seen.
    pub channels: Vec<ChannelInfo>,
    index: HashMap<(String, String, String), usize>,
}

impl Registry {
    pub(crate) fn intern(&mut self, info: ChannelInfo) -> usize {
        let key = (info.topic.clone(), info.type_name.clone(), info.message_encoding.clone());
        *self.index.entry(key).or_insert_with(|| {
            self.channels.push(info);
            self.channels.len() - 1
        })
    }
}

/// One message.
pub struct RawMessage {
    /// Index into [`Registry::channels`].
    pub channel: usize,
    /// Log (receive) time, ns.
    pub log_time_ns: u64,
    /// Serialized message.
    pub data: Cow<'static, [u8]>,
}

/// The first bytes of a zstd frame (a CDR message starts with its encapsulation `00 0x`,
/// a JSON one with text).
const ZSTD_MAGIC: [u8; 4] = [0x28, 0xb5, 0x2f, 0xfd];

/// A message compressed on its own, decompressed (at most [`MAX_RECORD_BYTES`]).
fn unzstd(path: &Path, data: &[u8]) -> Result<Vec<u8>, IoError> {
    let bad = |why: String| IoError::Csv { path: path.to_path_buf(), msg: format!("a zstd-compressed message: {why}") };
    let mut out = Vec::new();
    let decoder = zstd::stream::read::Decoder::with_buffer(data).map_err(|e| bad(e.to_string()))?;
    decoder.take(MAX_RECORD_BYTES as u64 + 1).read_to_end(&mut out).map_err(|e| bad(e.to_string()))?;
    if out.len() > MAX_RECORD_BYTES {
        return Err(bad(format!("it decompresses to more than {MAX_RECORD_BYTES} bytes")));
    }
    Ok(out)
}

/// The files of a log, by the path the user gave.
pub fn log_files(path: &Path) -> Result<Vec<PathBuf>, IoError> {
    if !path.is_dir() {
        return Ok(vec![path.to_path_buf()]);
    }
    let os = |source| IoError::Os { path: path.to_path_buf(), source };
    // rosbag2's metadata.yaml lists the files in order under `relative_file_paths:`.
    let mut files = Vec::new();
    if let Ok(text) = std::fs::read_to_string(path.join("metadata.yaml")) {
        let mut inside = false;
        for line in text.lines() {
            let t = line.trim();
            if t.starts_with("relative_file_paths:") {
                inside = true;
                continue;
            }
            match t.strip_prefix("- ") {
                // Older rosbag2 versions write the folder's name in front (`bag/bag_0.db3`).
                Some(name) if inside => {
                    let name = Path::new(name.trim().trim_matches(|c| c == '"' || c == '\''));
                    files.push(path.join(name.file_name().unwrap_or(name.as_os_str())));
                }
                _ if inside => inside = false,
                _ => {}
            }
        }
    }
    // A part listed but missing would leave a silent jump in time. (None there: the
    // metadata is stale, a renamed bag; its files are taken as the folder has them.)
    let present = files.iter().filter(|f| f.is_file()).count();
    if let Some(missing) = files.iter().find(|f| present > 0 && !f.is_file()) {
        let name = missing.file_name().unwrap_or_default().to_string_lossy();
        return Err(IoError::Csv {
            path: path.to_path_buf(),
            msg: format!(
                "metadata.yaml lists `{name}`, which is not in the folder (a part of the bag is missing; \
                 give each part that is there with --in to read it alone)"
            ),
        });
    }
    files.retain(|f| f.is_file());
    if files.is_empty() {
        for e in std::fs::read_dir(path).map_err(os)? {
            let p = e.map_err(os)?.path();
            if matches!(unpacked::inner(&p).extension().and_then(|e| e.to_str()), Some("mcap" | "db3")) {
                files.push(p);
            }
        }
        // bag_2 before bag_10.
        files.sort_by(|a, b| (a.as_os_str().len(), a).cmp(&(b.as_os_str().len(), b)));
    }
    if files.is_empty() {
        return Err(IoError::Csv {
            path: path.to_path_buf(),
            msg: "a folder without .mcap or .db3 files (expected a rosbag2 folder)".into(),
        });
    }
    Ok(files)
}

fn mcap_error(path: &Path, e: mcap::McapError) -> IoError {
    match e {
        mcap::McapError::Io(source) => IoError::Os { path: path.to_path_buf(), source },
        mcap::McapError::BadMagic => {
            IoError::Csv { path: path.to_path_buf(), msg: "not an MCAP file (bad magic)".into() }
        }
        e => IoError::Csv { path: path.to_path_buf(), msg: format!("MCAP: {e}") },
    }
}

/// Opens `file` (named `path` in errors: the log's own file, where `file` is its
/// decompressed copy) after checking its records.
fn open_mcap(file: &Path, path: &Path) -> Result<mcap::io::MessageReader<BufReader<File>>, IoError> {
    let os = |source| IoError::Os { path: path.to_path_buf(), source };
    let mut file_handle = File::open(file).map_err(os)?;
    let mut magic = Vec::with_capacity(mcap::MAGIC.len());
    (&mut file_handle).take(mcap::MAGIC.len() as u64).read_to_end(&mut magic).map_err(os)?;
    if magic != mcap::MAGIC {
        return Err(IoError::Csv {
            path: path.to_path_buf(),
            msg: "not an MCAP file (no MCAP magic at the start)".into(),
        });
    }
    file_handle.seek(SeekFrom::Start(0)).map_err(os)?;
    super::record_check::check_records(file, path)?;
    let options = mcap::sans_io::LinearReaderOptions::default().with_record_length_limit(MAX_RECORD_BYTES);
    Ok(mcap::io::MessageReader::new_with_options(BufReader::with_capacity(1 << 16, file_handle), options))
}

enum FileStream {
    Mcap {
        path: PathBuf,
        reader: Box<mcap::io::MessageReader<BufReader<File>>>,
        ids: HashMap<u16, usize>,
    },
    #[cfg(feature = "sqlite")]
    Db3(super::db3::Db3Stream),
}

/// Every message of a log's files, in file order. An MCAP file that ends before its
/// footer (a recorder stopped before closing it, or a copy cut short) gives the messages
/// before the cut, and is listed in [`MessageStream::cut_short`].
pub struct MessageStream {
    files: Vec<PathBuf>,
    next_file: usize,
    current: Option<FileStream>,
    /// The current file's decompressed copy, if compressed whole.
    unpacked: Option<unpacked::Unpacked>,
    /// The log time of the last message given from the current file, ns.
    last_log_ns: Option<u64>,
    cut_short: Vec<(PathBuf, Option<u64>)>,
}

impl MessageStream {
    /// Opens the log at `path` (a file or a rosbag2 folder).
    pub fn open(path: &Path) -> Result<Self, IoError> {
        Ok(Self {
            files: log_files(path)?,
            next_file: 0,
            current: None,
            unpacked: None,
            last_log_ns: None,
            cut_short: Vec::new(),
        })
    }

    /// The files read so far that end before their footer, each with the log time of
    /// its last message read (ns; `None`: none).
    pub fn cut_short(&self) -> &[(PathBuf, Option<u64>)] {
        &self.cut_short
    }

    fn open_next(&mut self, registry: &mut Registry) -> Result<bool, IoError> {
        // The last file's decompressed copy is removed first.
        (self.current, self.unpacked) = (None, None);
        let Some(path) = self.files.get(self.next_file).cloned() else { return Ok(false) };
        self.next_file += 1;
        self.last_log_ns = None;
        let file = if unpacked::is_compressed(&path) {
            self.unpacked.insert(unpacked::Unpacked::new(&path)?).path().to_path_buf()
        } else {
            path.clone()
        };
        let is_db3 = unpacked::inner(&path).extension().is_some_and(|e| e.eq_ignore_ascii_case("db3"));
        self.current = Some(if is_db3 {
            #[cfg(feature = "sqlite")]
            {
                FileStream::Db3(super::db3::Db3Stream::open(&file, &path, registry)?)
            }
            #[cfg(not(feature = "sqlite"))]
            {
                let _ = (registry, file);
                return Err(IoError::FeatureOff { path, feature: "sqlite" });
            }
        } else {
            FileStream::Mcap { reader: Box::new(open_mcap(&file, &path)?), path, ids: HashMap::new() }
        });
        Ok(true)
    }

    /// The next message; `Ok(None)` at the end of the last file. A message compressed on
    /// its own (rosbag2's `compression_mode: message`, zstd) is decompressed.
    pub fn next(&mut self, registry: &mut Registry) -> Result<Option<RawMessage>, IoError> {
        let Some(mut msg) = self.next_stored(registry)? else { return Ok(None) };
        // Only CDR and JSON are decoded, and neither starts like a zstd frame.
        let encoding = registry.channels.get(msg.channel).map_or("", |c| c.message_encoding.as_str());
        if msg.data.starts_with(&ZSTD_MAGIC) && ["cdr", "json"].contains(&encoding.to_ascii_lowercase().as_str()) {
            let path = self.files.get(self.next_file.saturating_sub(1)).map_or(Path::new(""), PathBuf::as_path);
            msg.data = Cow::Owned(unzstd(path, &msg.data)?);
        }
        Ok(Some(msg))
    }

    /// The next message as stored.
    fn next_stored(&mut self, registry: &mut Registry) -> Result<Option<RawMessage>, IoError> {
        loop {
            match self.current.as_mut() {
                None => {
                    if !self.open_next(registry)? {
                        return Ok(None);
                    }
                }
                Some(FileStream::Mcap { path, reader, ids }) => match reader.next() {
                    None => self.current = None,
                    Some(Err(mcap::McapError::UnexpectedEof)) => {
                        self.cut_short.push((path.clone(), self.last_log_ns));
                        self.current = None;
                    }
                    Some(Err(e)) => return Err(mcap_error(path, e)),
                    Some(Ok(m)) => {
                        let ch = &m.channel;
                        let channel = match ids.get(&ch.id) {
                            Some(&c) => c,
                            None => {
                                let (type_name, schema_encoding, schema) = match &ch.schema {
                                    Some(s) => (s.name.clone(), s.encoding.clone(), s.data.to_vec()),
                                    None => (String::new(), String::new(), Vec::new()),
                                };
                                let info = ChannelInfo {
                                    topic: ch.topic.clone(),
                                    type_name,
                                    schema_encoding,
                                    schema,
                                    message_encoding: ch.message_encoding.clone(),
                                };
                                let c = registry.intern(info);
                                ids.insert(ch.id, c);
                                c
                            }
                        };
                        self.last_log_ns = Some(m.log_time);
                        return Ok(Some(RawMessage { channel, log_time_ns: m.log_time, data: m.data }));
                    }
                },
                #[cfg(feature = "sqlite")]
                Some(FileStream::Db3(s)) => match s.next()? {
                    None => self.current = None,
                    Some(m) => return Ok(Some(m)),
                },
            }
        }
    }
}
