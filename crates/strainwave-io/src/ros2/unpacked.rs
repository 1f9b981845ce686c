//! A log file compressed whole (rosbag2's `compression_mode: file`: `bag_0.mcap.zstd`,
//! `bag_0.db3.zstd`), decompressed into a temporary file of the system's temporary
//! folder (`TMPDIR`) for as long as it is read. The temporary file is registered like an
//! output's (an interrupt removes it) and is removed when dropped.
//!
//! A file that would decompress to more than [`MAX_FILE_RATIO`] times its size (and
//! more than [`MIN_FILE_LIMIT_BYTES`]) is refused, so that a few crafted bytes cannot
//! fill the disk. A file cut short inside its compressed data gives what comes before
//! the cut, as a cut-short MCAP file does.

use std::fs::File;
use std::io::{ErrorKind, Read, Write};
use std::path::{Path, PathBuf};

use crate::error::IoError;
use crate::output::AtomicFile;

/// Largest ratio of decompressed to compressed size (logs of joint states compress 3–10×).
pub const MAX_FILE_RATIO: u64 = 200;
/// A small file may always decompress to this many bytes.
pub const MIN_FILE_LIMIT_BYTES: u64 = 64 << 20;

/// Whether `path` is a log file compressed whole (ends in `.zstd` or `.zst`).
pub fn is_compressed(path: &Path) -> bool {
    path.extension().is_some_and(|e| e.eq_ignore_ascii_case("zstd") || e.eq_ignore_ascii_case("zst"))
}

/// The name of the file inside: `bag_0.mcap` for `bag_0.mcap.zstd`, else `path` itself.
pub fn inner(path: &Path) -> PathBuf {
    if is_compressed(path) {
        path.with_extension("")
    } else {
        path.to_path_buf()
    }
}

/// The decompressed copy of a file compressed whole.
pub struct Unpacked {
    file: AtomicFile,
}

impl Unpacked {
    /// Decompresses `path` into a new temporary file.
    pub fn new(path: &Path) -> Result<Self, IoError> {
        let os = |source| IoError::Os { path: path.to_path_buf(), source };
        let bytes = std::fs::metadata(path).map_err(os)?.len();
        Self::with_limit(path, bytes.saturating_mul(MAX_FILE_RATIO).max(MIN_FILE_LIMIT_BYTES))
    }

    /// Decompresses `path`, refusing it past `limit` bytes.
    fn with_limit(path: &Path, limit: u64) -> Result<Self, IoError> {
        let os = |source| IoError::Os { path: path.to_path_buf(), source };
        let fail = |msg: String| IoError::Csv { path: path.to_path_buf(), msg };
        let compressed = File::open(path).map_err(os)?;
        let name = inner(path).file_name().map_or_else(|| "log".into(), |n| n.to_os_string());
        let dir = std::env::temp_dir();
        let in_temp = |e: std::io::Error| fail(format!("decompressing into {}: {e}", dir.display()));
        let mut file = match AtomicFile::create(&dir.join(name)) {
            Ok(f) => f,
            Err(IoError::Os { source, .. }) => return Err(in_temp(source)),
            Err(e) => return Err(e),
        };
        let zstd_error = |e: std::io::Error| fail(format!("zstd: {e}"));
        let mut decoder = zstd::stream::read::Decoder::new(compressed).map_err(zstd_error)?;
        let mut buf = vec![0u8; 1 << 16];
        let mut written = 0u64;
        loop {
            let n = match decoder.read(&mut buf) {
                Ok(0) => break,
                Ok(n) => n,
                Err(e) if e.kind() == ErrorKind::Interrupted => continue,
                // Cut short: the reader of the log takes what came before the cut.
                Err(e) if e.kind() == ErrorKind::UnexpectedEof => break,
                Err(e) => return Err(zstd_error(e)),
            };
            written += n as u64;
            if written > limit {
                return Err(fail(format!(
                    "decompresses to more than {MAX_FILE_RATIO} times its size; decompress it with `zstd -d` \
                     and read the file it gives"
                )));
            }
            file.write_all(&buf[..n]).map_err(in_temp)?;
        }
        file.flush().map_err(in_temp)?;
        Ok(Self { file })
    }

    /// The temporary file.
    pub fn path(&self) -> &Path {
        self.file.temp_path()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A zstd file of `data` in a folder of its own; the folder.
    fn compressed(name: &str, data: &[u8]) -> (PathBuf, PathBuf) {
        let dir = std::env::temp_dir().join(format!("sw-unpacked-{name}-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join(format!("{name}.mcap.zstd"));
        std::fs::write(&path, zstd::stream::encode_all(data, 3).unwrap()).unwrap();
        (dir, path)
    }

    /// Temporary files of the system's temporary folder made from `name`.
    fn temps_of(name: &str) -> usize {
        let prefix = format!(".{name}.mcap.{}-", std::process::id());
        std::fs::read_dir(std::env::temp_dir())
            .unwrap()
            .flatten()
            .filter(|e| e.file_name().to_string_lossy().starts_with(&prefix))
            .count()
    }

    #[test]
    fn a_file_decompresses_whole_and_its_copy_goes_when_dropped() {
        let data: Vec<u8> = (0..300_000u32).map(|k| (k % 251) as u8).collect();
        let (dir, path) = compressed("whole", &data);
        assert!(is_compressed(&path) && inner(&path).ends_with("whole.mcap"));
        let unpacked = Unpacked::new(&path).unwrap();
        assert_eq!(std::fs::read(unpacked.path()).unwrap(), data);
        assert_eq!(temps_of("whole"), 1);
        drop(unpacked);
        assert_eq!(temps_of("whole"), 0);
        std::fs::remove_dir_all(dir).unwrap();
    }

    #[test]
    fn a_file_past_the_limit_is_refused_and_leaves_nothing() {
        let data = vec![0u8; 1 << 20];
        let (dir, path) = compressed("bomb", &data);
        let err = Unpacked::with_limit(&path, 100_000).err().unwrap().to_string();
        assert!(err.contains("bomb.mcap.zstd: decompresses to more than 200 times its size"), "{err}");
        assert!(Unpacked::with_limit(&path, 1 << 20).is_ok());
        assert_eq!(temps_of("bomb"), 0);
        std::fs::remove_dir_all(dir).unwrap();
    }

    #[test]
    fn a_file_cut_short_gives_what_comes_before_the_cut() {
        let data: Vec<u8> = (0..1_000_000u32).map(|k| (k.wrapping_mul(2_654_435_761) >> 13) as u8).collect();
        let (dir, path) = compressed("cut", &data);
        let bytes = std::fs::read(&path).unwrap();
        std::fs::write(&path, &bytes[..bytes.len() / 2]).unwrap();
        let unpacked = Unpacked::new(&path).unwrap();
        let got = std::fs::read(unpacked.path()).unwrap();
        assert!(!got.is_empty() && got.len() < data.len() && data.starts_with(&got), "{} bytes", got.len());
        drop(unpacked);
        std::fs::remove_dir_all(dir).unwrap();
    }
}
