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

/// A field of a record, as far as its length matters.
#[derive(Clone, Copy)]
enum F {
    Fixed(u64),
    /// u32 length, then that many bytes.
    Str,
    /// u64 length, then that many bytes.
    Bytes64,
    /// u32 byte length, then string → string entries.
    StrMap,
}

/// The fields with lengths in them of the records the `mcap` crate parses with strings,
/// maps or byte arrays (it allocates what each length field claims before reading).
fn fields(op: u8) -> &'static [F] {
    use F::*;
    match op {
        0x01 => &[Str, Str],                                 // header
        0x03 => &[Fixed(2), Str, Str, Str],                  // schema
        0x04 => &[Fixed(4), Str, Str, StrMap],               // channel
        0x07 => &[Fixed(2), Str],                            // message index
        0x08 => &[Fixed(32), Str, Fixed(8), Str, Fixed(16)], // chunk index
        0x09 => &[Fixed(16), Str, Str, Bytes64],             // attachment
        0x0A => &[Fixed(40), Str, Str],                      // attachment index
        0x0B => &[Fixed(42), Str],                           // statistics
        0x0C => &[Str, StrMap],                              // metadata
        0x0D => &[Fixed(16), Str],                           // metadata index
        _ => &[],
    }
}

/// Reads the length fields of a record body of `len` bytes and leaves the reader after it.
fn check_body(path: &Path, r: &mut BufReader<std::fs::File>, op: u8, len: u64, at: u64) -> Result<(), IoError> {
    let os = |source| IoError::Os { path: path.to_path_buf(), source };
    let mut left = len;
    let bad = |what: String| corrupt(path, at, what);
    let take_len = |r: &mut BufReader<std::fs::File>, left: &mut u64, wide: bool| -> Result<u64, IoError> {
        let n = if wide { 8 } else { 4 };
        if *left < n {
            return Err(bad(format!("a length field runs past the record's {len} bytes")));
        }
        let mut b = [0u8; 8];
        r.read_exact(&mut b[..n as usize]).map_err(os)?;
        *left -= n;
        let v = u64::from_le_bytes(b);
        if v > *left {
            return Err(bad(format!("a field claims {v} bytes, {} are left in the record", *left)));
        }
        Ok(v)
    };
    for f in fields(op) {
        match *f {
            F::Fixed(n) => {
                if n > left {
                    return Err(bad(format!("a record of {len} bytes is too short")));
                }
                r.seek_relative(n as i64).map_err(os)?;
                left -= n;
            }
            F::Str | F::Bytes64 => {
                let n = take_len(r, &mut left, matches!(f, F::Bytes64))?;
                r.seek_relative(n as i64).map_err(os)?;
                left -= n;
            }
            F::StrMap => {
                let mut map = take_len(r, &mut left, false)?;
                left -= map;
                while map > 0 {
                    let k = take_len(r, &mut map, false)?;
                    r.seek_relative(k as i64).map_err(os)?;
                    map -= k;
                    let v = take_len(r, &mut map, false)?;
                    r.seek_relative(v as i64).map_err(os)?;
                    map -= v;
                }
            }
        }
    }
    r.seek_relative(left as i64).map_err(os)?;
    Ok(())
}

/// Walks the records inside an uncompressed chunk of `bytes` bytes, from the reader's
/// position; leaves the reader after them.
fn check_inner(path: &Path, r: &mut BufReader<std::fs::File>, chunk_at: u64, bytes: u64) -> Result<(), IoError> {
    let os = |source| IoError::Os { path: path.to_path_buf(), source };
    let mut done = 0u64;
    let mut header = [0u8; RECORD_HEADER_BYTES as usize];
    while done + RECORD_HEADER_BYTES <= bytes {
        r.read_exact(&mut header).map_err(os)?;
        let len = u64_le(&header[1..]);
        let left = bytes - done - RECORD_HEADER_BYTES;
        if len > left {
            return Err(corrupt(path, chunk_at, format!("a record in the chunk claims {len} bytes, {left} are left")));
        }
        check_body(path, r, header[0], len, chunk_at)?;
        done += RECORD_HEADER_BYTES + len;
    }
    r.seek_relative((bytes - done) as i64).map_err(os)?;
    Ok(())
}

/// Walks the top-level records of the file at `path` (after its 8-byte magic).
pub(crate) fn check_record_lengths(path: &Path) -> Result<(), IoError> {
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
        let mut skip = 0;
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
            if name.is_empty() {
                // Read straight from the file: the records inside must fit in the chunk.
                check_inner(path, &mut r, pos, records_len)?;
                skip -= records_len;
            }
        }
        if op == OP_CHUNK {
            r.seek_relative(skip as i64).map_err(os)?;
        } else {
            check_body(path, &mut r, op, len, pos)?;
        }
        pos += RECORD_HEADER_BYTES + len;
    }
    Ok(())
}
