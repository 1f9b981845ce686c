//! MCAP input: ROS 2 `sensor_msgs/msg/JointState` (CDR) and JSON messages as recording columns.
//!
//! What becomes a column:
//!
//! - `time`: the message's MCAP log time in seconds (f64). At Unix-epoch magnitudes
//!   (about 1.7e9 s) an f64 resolves about 240 ns; times below 2^53 ns (104 days) are the
//!   correctly rounded quotient `log_time_ns / 1e9`.
//! - JointState (schema `sensor_msgs/msg/JointState`, message encoding `cdr`), any topic:
//!   `<joint>.position`, `<joint>.velocity`, `<joint>.effort` for each name; an empty
//!   array gives no column. Two topics with the same joint names share the columns.
//! - JSON (message encoding `json`), topic `T`: every numeric field as `T.<path>`, nested
//!   objects by dotted path and arrays by index (`T.accel.x`, `T.q.0`); strings, booleans
//!   and nulls are left out.
//! - Any other channel (protobuf, flatbuffer, other ROS messages, …) is skipped, with one
//!   warning that names its topic and schema.
//!
//! The table: one row per message that yields at least one value, in log-time order (ties
//! in file order). Columns are `time` then the union over all messages in first-seen
//! order; a row holds NaN in every column its message does not have (a JointState row has
//! NaN in the JSON columns, and so on).
//!
//! Memory: [`McapReader`] streams the file twice with `mcap::io::MessageReader`, which holds
//! one record or one decompressed chunk at a time. The first pass finds the columns,
//! the warnings and whether log times are in order; the second emits rows. Memory is
//! therefore the largest chunk plus the column names, whatever the file size, when the
//! messages are in log-time order (what recorders write). Otherwise the rows are sorted
//! in memory: rows × columns × 8 bytes.

use std::collections::HashMap;
use std::fmt;
use std::fs::File;
use std::io::{BufReader, Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};

use serde::de::{DeserializeSeed, Deserializer, MapAccess, SeqAccess, Visitor};

use crate::error::IoError;
use crate::Table;

mod bounds;
mod cdr;
pub use cdr::{decode_joint_state, CdrError, JointState, JOINT_STATE_SCHEMAS};

/// Appends `(column, value)` for every numeric field of one JSON document, in document
/// order: `prefix.a.b` for nested objects, `prefix.a.0` for array items (`prefix` alone
/// for a bare number). Strings, booleans and nulls are left out.
///
/// ```
/// let mut out = Vec::new();
/// strainwave_io::mcap_in::flatten_json(br#"{"q": [1, 2.5], "id": "x"}"#, "/arm", &mut out).unwrap();
/// assert_eq!(out, vec![("/arm.q.0".to_string(), 1.0), ("/arm.q.1".to_string(), 2.5)]);
/// ```
pub fn flatten_json(data: &[u8], prefix: &str, out: &mut Vec<(String, f64)>) -> Result<(), serde_json::Error> {
    let mut path = prefix.to_string();
    let mut de = serde_json::Deserializer::from_slice(data);
    Flatten { path: &mut path, out }.deserialize(&mut de)?;
    de.end()
}

/// Walks a JSON document without building a tree, keeping key order.
struct Flatten<'p> {
    path: &'p mut String,
    out: &'p mut Vec<(String, f64)>,
}

impl Flatten<'_> {
    fn child(&mut self, segment: &str) -> Flatten<'_> {
        if !self.path.is_empty() {
            self.path.push('.');
        }
        self.path.push_str(segment);
        Flatten { path: self.path, out: self.out }
    }
}

impl<'de> DeserializeSeed<'de> for Flatten<'_> {
    type Value = ();
    fn deserialize<D: Deserializer<'de>>(self, d: D) -> Result<(), D::Error> {
        d.deserialize_any(self)
    }
}

impl<'de> Visitor<'de> for Flatten<'_> {
    type Value = ();
    fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
        f.write_str("a JSON value")
    }
    fn visit_f64<E: serde::de::Error>(self, v: f64) -> Result<(), E> {
        self.out.push((self.path.clone(), v));
        Ok(())
    }
    fn visit_i64<E: serde::de::Error>(self, v: i64) -> Result<(), E> {
        self.visit_f64(v as f64)
    }
    fn visit_u64<E: serde::de::Error>(self, v: u64) -> Result<(), E> {
        self.visit_f64(v as f64)
    }
    fn visit_bool<E: serde::de::Error>(self, _: bool) -> Result<(), E> {
        Ok(())
    }
    fn visit_str<E: serde::de::Error>(self, _: &str) -> Result<(), E> {
        Ok(())
    }
    fn visit_unit<E: serde::de::Error>(self) -> Result<(), E> {
        Ok(())
    }
    fn visit_seq<A: SeqAccess<'de>>(mut self, mut seq: A) -> Result<(), A::Error> {
        let base = self.path.len();
        for i in 0usize.. {
            let more = seq.next_element_seed(self.child(&i.to_string()))?;
            self.path.truncate(base);
            if more.is_none() {
                break;
            }
        }
        Ok(())
    }
    fn visit_map<A: MapAccess<'de>>(mut self, mut map: A) -> Result<(), A::Error> {
        let base = self.path.len();
        while let Some(key) = map.next_key::<String>()? {
            map.next_value_seed(self.child(&key))?;
            self.path.truncate(base);
        }
        Ok(())
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Kind {
    JointState,
    Json,
    Skip,
}

fn kind_of(ch: &mcap::Channel) -> Kind {
    if ch.message_encoding.eq_ignore_ascii_case("json") {
        return Kind::Json;
    }
    match &ch.schema {
        Some(s) if ch.message_encoding == "cdr" && JOINT_STATE_SCHEMAS.contains(&s.name.as_str()) => Kind::JointState,
        _ => Kind::Skip,
    }
}

/// Per-channel counts of the first pass, for the warnings.
struct ChannelStat {
    kind: Kind,
    warning_head: String,
    messages: u64,
    without_values: u64,
}

/// Decodes messages into `(column, value)` pairs.
struct Decoder {
    path: PathBuf,
    kinds: HashMap<u16, Kind>,
    values: Vec<(String, f64)>,
}

impl Decoder {
    /// Fills `self.values` with the message's columns; `Ok(None)` for a skipped channel.
    fn decode(&mut self, msg: &mcap::Message) -> Result<Option<Kind>, IoError> {
        let ch = &msg.channel;
        let kind = *self.kinds.entry(ch.id).or_insert_with(|| kind_of(ch));
        self.values.clear();
        let bad = |what: &str, e: &dyn fmt::Display| IoError::Csv {
            path: self.path.clone(),
            msg: format!("topic `{}`, message at log time {} ns: bad {what}: {e}", ch.topic, msg.log_time),
        };
        match kind {
            Kind::Skip => return Ok(None),
            Kind::Json => flatten_json(&msg.data, &ch.topic, &mut self.values).map_err(|e| bad("JSON", &e))?,
            Kind::JointState => {
                let js = decode_joint_state(&msg.data).map_err(|e| bad("JointState CDR", &e))?;
                for (i, name) in js.name.iter().enumerate() {
                    for (field, v) in [("position", &js.position), ("velocity", &js.velocity), ("effort", &js.effort)] {
                        if let Some(x) = v.get(i) {
                            self.values.push((format!("{name}.{field}"), *x));
                        }
                    }
                }
            }
        }
        Ok(Some(kind))
    }
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

fn open_stream(path: &Path) -> Result<mcap::io::MessageReader<BufReader<File>>, IoError> {
    if path.is_dir() {
        return Err(IoError::IsDirectory(path.to_path_buf()));
    }
    let os = |source| IoError::Os { path: path.to_path_buf(), source };
    let mut file = File::open(path).map_err(os)?;
    let mut magic = Vec::with_capacity(mcap::MAGIC.len());
    (&mut file).take(mcap::MAGIC.len() as u64).read_to_end(&mut magic).map_err(os)?;
    if magic != mcap::MAGIC {
        return Err(IoError::Csv {
            path: path.to_path_buf(),
            msg: "not an MCAP file (no MCAP magic at the start)".into(),
        });
    }
    bounds::check_record_lengths(path)?;
    file.seek(SeekFrom::Start(0)).map_err(os)?;
    Ok(mcap::io::MessageReader::new(BufReader::with_capacity(1 << 16, file)))
}

fn log_time_s(ns: u64) -> f64 {
    ns as f64 / 1e9
}

enum Rows {
    Stream(Box<mcap::io::MessageReader<BufReader<File>>>),
    Sorted(std::vec::IntoIter<Vec<f64>>),
}

/// An MCAP log read as a recording, row by row (see the module doc for columns, order
/// and memory).
pub struct McapReader {
    path: PathBuf,
    columns: Vec<String>,
    index: HashMap<String, usize>,
    warnings: Vec<String>,
    rows: u64,
    rows_read: u64,
    decoder: Decoder,
    source: Rows,
}

impl McapReader {
    /// Opens a log and runs the first pass (columns, warnings, row count).
    pub fn open(path: &Path) -> Result<Self, IoError> {
        let mut decoder = Decoder { path: path.to_path_buf(), kinds: HashMap::new(), values: Vec::new() };
        let mut columns = vec!["time".to_string()];
        let mut index = HashMap::from([("time".to_string(), 0)]);
        let mut stats: Vec<(u16, ChannelStat)> = Vec::new();
        let (mut rows, mut last_ns, mut in_order) = (0u64, 0u64, true);
        for msg in open_stream(path)? {
            let msg = msg.map_err(|e| mcap_error(path, e))?;
            let kind = decoder.decode(&msg)?.unwrap_or(Kind::Skip);
            let at = match stats.iter().position(|(id, _)| *id == msg.channel.id) {
                Some(at) => at,
                None => {
                    stats.push((msg.channel.id, ChannelStat::new(&msg.channel, kind)));
                    stats.len() - 1
                }
            };
            let stat = &mut stats[at].1;
            stat.messages += 1;
            if kind == Kind::Skip {
                continue;
            }
            if decoder.values.is_empty() {
                stat.without_values += 1;
                continue;
            }
            for (name, _) in &decoder.values {
                if !index.contains_key(name) {
                    index.insert(name.clone(), columns.len());
                    columns.push(name.clone());
                }
            }
            in_order &= rows == 0 || msg.log_time >= last_ns;
            last_ns = msg.log_time;
            rows += 1;
        }
        let warnings = stats.iter().filter_map(|(_, s)| s.warning()).collect();
        let source = Rows::Stream(Box::new(open_stream(path)?));
        let path = path.to_path_buf();
        let mut reader = Self { path, columns, index, warnings, rows, rows_read: 0, decoder, source };
        if !in_order {
            let mut all = Vec::with_capacity(rows as usize);
            let mut row = Vec::new();
            while let Some(ns) = reader.next_streamed(&mut row)? {
                all.push((ns, row.clone()));
            }
            all.sort_by_key(|(ns, _)| *ns);
            reader.source = Rows::Sorted(all.into_iter().map(|(_, r)| r).collect::<Vec<_>>().into_iter());
        }
        Ok(reader)
    }

    /// Column names: `time`, then the message columns in first-seen order.
    pub fn columns(&self) -> &[String] {
        &self.columns
    }

    /// One line per skipped channel (naming topic and schema) or per channel with
    /// messages that had no values.
    pub fn warnings(&self) -> &[String] {
        &self.warnings
    }

    /// Rows the log yields.
    pub fn rows(&self) -> u64 {
        self.rows
    }

    /// Rows read so far.
    pub fn rows_read(&self) -> u64 {
        self.rows_read
    }

    /// Reads the next row (NaN where the message has no value); `Ok(false)` at the end.
    pub fn read_row(&mut self, row: &mut Vec<f64>) -> Result<bool, IoError> {
        let more = match &mut self.source {
            Rows::Sorted(it) => match it.next() {
                Some(r) => {
                    *row = r;
                    true
                }
                None => false,
            },
            Rows::Stream(_) => self.next_streamed(row)?.is_some(),
        };
        self.rows_read += u64::from(more);
        Ok(more)
    }

    /// The next row from the stream and its log time in ns.
    fn next_streamed(&mut self, row: &mut Vec<f64>) -> Result<Option<u64>, IoError> {
        let Rows::Stream(stream) = &mut self.source else { return Ok(None) };
        let path = &self.path;
        for msg in stream.by_ref() {
            let msg = msg.map_err(|e| mcap_error(path, e))?;
            if self.decoder.decode(&msg)?.is_none() || self.decoder.values.is_empty() {
                continue;
            }
            row.clear();
            row.resize(self.columns.len(), f64::NAN);
            row[0] = log_time_s(msg.log_time);
            for (name, v) in &self.decoder.values {
                let Some(&c) = self.index.get(name) else {
                    return Err(IoError::Csv {
                        path: path.clone(),
                        msg: format!("column `{name}` appeared on the second read (file changed while reading?)"),
                    });
                };
                row[c] = *v;
            }
            return Ok(Some(msg.log_time));
        }
        Ok(None)
    }
}

impl ChannelStat {
    fn new(ch: &mcap::Channel, kind: Kind) -> Self {
        let schema = match &ch.schema {
            Some(s) => format!("schema `{}` (schema encoding `{}`)", s.name, s.encoding),
            None => "no schema".to_string(),
        };
        let warning_head = format!("topic `{}` with {schema}, message encoding `{}`", ch.topic, ch.message_encoding);
        Self { kind, warning_head, messages: 0, without_values: 0 }
    }

    fn warning(&self) -> Option<String> {
        if self.kind == Kind::Skip {
            Some(format!(
                "{}: unknown schema (reads sensor_msgs/msg/JointState in CDR and JSON); skipped {} message(s)",
                self.warning_head, self.messages
            ))
        } else if self.without_values > 0 {
            Some(format!(
                "{}: {} of {} message(s) had no numeric values and were left out",
                self.warning_head, self.without_values, self.messages
            ))
        } else {
            None
        }
    }
}

/// A whole MCAP log as a table, with the warnings of skipped channels.
#[derive(Debug, Clone, PartialEq)]
pub struct McapTable {
    /// `time` and the message columns (NaN where a message lacks a column).
    pub table: Table,
    /// One line per skipped channel, naming topic and schema.
    pub warnings: Vec<String>,
}

/// Reads a whole MCAP log into memory (see [`McapReader`] to stream it).
pub fn read_mcap(path: &Path) -> Result<McapTable, IoError> {
    let mut r = McapReader::open(path)?;
    let mut data = vec![Vec::with_capacity(r.rows() as usize); r.columns().len()];
    let mut row = Vec::new();
    while r.read_row(&mut row)? {
        for (col, v) in data.iter_mut().zip(&row) {
            col.push(*v);
        }
    }
    Ok(McapTable { table: Table { columns: r.columns.clone(), data }, warnings: r.warnings.clone() })
}
