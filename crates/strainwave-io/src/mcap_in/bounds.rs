//! The record framing of an MCAP file checked before the `mcap` crate reads it: that
//! crate sizes a buffer from each record's length field and each chunk's uncompressed
//! size, so a crafted 38-byte file could ask for exabytes. Every top-level record must
//! fit in the bytes the file has left, and a chunk may unpack to at most
//! [`MAX_CHUNK_BYTES`] (an uncompressed chunk: exactly its record bytes).

use std::io::{BufReader, Read, Seek};
use std::path::Path;

use crate::error::IoError;

/// Largest uncompressed chunk accepted. Writers use chunks of a few MiB (the `mcap`
/// libraries default to 768 KiB to 4 MiB); 256 MiB leaves room for odd ones.
pub const MAX_CHUNK_BYTES: u64 = 256 << 20;

const OP_FOOTER: u8 = 0x02;
const OP_CHUNK: u8 = 0x06;
/// Opcode and length field.
const RECORD_HEADER_BYTES: u64 = 9;

fn corrupt(path: &Path, offset: u64, what: String) -> IoError {
    IoError::Csv {
        path: path.to_path_buf(),
        msg: format!("MCAP: record at byte {offset}: {what} (corrupt or truncated file)"),
    }
}

fn u64_le(b: &[u8]) -> u64 {
    let mut a = [0; 8];
    a.copy_from_slice(&b[..8]);
    u64::from_le_bytes(a)
}

/// Walks the top-level records of the file at `path` (after its 8-byte magic).
pub(super) fn check_record_lengths(path: &Path) -> Result<(), IoError> {
    let os = |source| IoError::Os { path: path.to_path_buf(), source };
    let file = std::fs::File::open(path).map_err(os)?;
    let size = file.metadata().map_err(os)?.len();
    let mut r = BufReader::with_capacity(1 << 12, file);
    let mut pos = mcap::MAGIC.len() as u64;
    r.seek(std::io::SeekFrom::Start(pos)).map_err(os)?;
    let mut header = [0u8; RECORD_HEADER_BYTES as usize];
    while pos + RECORD_HEADER_BYTES <= size {
        r.read_exact(&mut header).map_err(os)?;
        let (op, len) = (header[0], u64_le(&header[1..]));
        let left = size - pos - RECORD_HEADER_BYTES;
        if len > left {
            return Err(corrupt(path, pos, format!("length {len} bytes, but {left} bytes follow")));
        }
        if op == OP_FOOTER {
            return Ok(());
        }
        let mut skip = len;
        if op == OP_CHUNK {
            // start, end, uncompressed size, crc, compression (u32 length + text).
            let mut fixed = [0u8; 32];
            if len < fixed.len() as u64 {
                return Err(corrupt(path, pos, format!("a chunk of {len} bytes is too short")));
            }
            r.read_exact(&mut fixed).map_err(os)?;
            let unpacked = u64_le(&fixed[16..]);
            let name_len = u64::from(u32::from_le_bytes([fixed[28], fixed[29], fixed[30], fixed[31]]));
            let records_at = 32 + name_len + 8;
            if records_at > len {
                return Err(corrupt(path, pos, format!("a chunk's compression name of {name_len} bytes overruns it")));
            }
            let mut name = vec![0u8; name_len as usize];
            r.read_exact(&mut name).map_err(os)?;
            let mut records_len = [0u8; 8];
            r.read_exact(&mut records_len).map_err(os)?;
            let records_len = u64_le(&records_len);
            if records_len > len - records_at {
                return Err(corrupt(path, pos, format!("chunk records of {records_len} bytes overrun the chunk")));
            }
            if unpacked > MAX_CHUNK_BYTES {
                return Err(corrupt(
                    path,
                    pos,
                    format!("a chunk unpacks to {unpacked} bytes, more than the {MAX_CHUNK_BYTES} accepted"),
                ));
            }
            if name.is_empty() && unpacked != records_len {
                return Err(corrupt(
                    path,
                    pos,
                    format!("an uncompressed chunk of {records_len} bytes claims {unpacked} bytes"),
                ));
            }
            skip = len - records_at;
        }
        r.seek_relative(skip as i64).map_err(os)?;
        pos += RECORD_HEADER_BYTES + len;
    }
    Ok(())
}
