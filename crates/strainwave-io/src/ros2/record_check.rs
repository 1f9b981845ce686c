//! Checks of an MCAP file's length fields before the MCAP library reads them.
//!
//! The `mcap` crate trusts two kinds of length:
//! - a record inside an uncompressed chunk must end within the chunk: a crafted length
//!   makes its reader subtract past zero (a panic in debug builds, a wrapped count that
//!   reads on past the chunk in release);
//! - a string's length prefix: it reserves that many bytes (up to 4 GiB) before reading.
//!
//! So every record at the top level and in uncompressed chunks is walked once, and a
//! record or string that runs past its end is refused with a one-line error. Records
//! inside compressed chunks are seen only by the library (its decompressor checks the
//! chunk's sizes). A file cut short is not an error here: the reader yields the messages
//! before the cut. It also streams the records of an uncompressed chunk that the cut
//! runs through, so those that lie wholly before the cut are checked too.

use std::fs::File;
use std::io::{self, BufReader, Read, Seek, SeekFrom};
use std::path::Path;

use crate::IoError;

const OP_FOOTER: u8 = 0x02;
const OP_CHUNK: u8 = 0x06;
/// Opcode (1 byte) and length (u64).
const RECORD_HEADER_BYTES: u64 = 9;
/// A chunk's start time, end time, uncompressed size (u64 each) and CRC (u32).
const CHUNK_FIXED_BYTES: u64 = 28;

/// What is wrong with a record, or the bytes of it that were read.
type Verdict = Result<u64, &'static str>;

/// Refuses a file with a record or string that runs past the end of what holds it.
/// `path` names `file` in errors.
pub(super) fn check_records(file: &Path, path: &Path) -> Result<(), IoError> {
    let os = |source| IoError::Os { path: path.to_path_buf(), source };
    let file = File::open(file).map_err(os)?;
    let file_bytes = file.metadata().map_err(os)?.len();
    let mut r = BufReader::with_capacity(1 << 16, file);
    let mut pos = mcap::MAGIC.len() as u64;
    r.seek(SeekFrom::Start(pos)).map_err(os)?;
    while pos + RECORD_HEADER_BYTES <= file_bytes {
        let (opcode, len) = read_header(&mut r).map_err(os)?;
        let corrupt = |what: &str| IoError::Csv {
            path: path.to_path_buf(),
            msg: format!("MCAP: corrupt record at byte {pos}: {what}"),
        };
        let body = pos + RECORD_HEADER_BYTES;
        let end = body.saturating_add(len);
        if opcode == OP_FOOTER {
            return Ok(());
        }
        if end > file_bytes {
            // A cut-short file: the reader deals with the rest, but streams the records of
            // an uncompressed chunk up to the cut.
            if opcode == OP_CHUNK {
                check_chunk(&mut r, len, file_bytes - body).map_err(os)?.map_err(corrupt)?;
            }
            return Ok(());
        }
        let verdict =
            if opcode == OP_CHUNK { check_chunk(&mut r, len, len) } else { check_fields(&mut r, opcode, len) };
        match verdict.map_err(os)? {
            Ok(read) => skip(&mut r, len - read).map_err(os)?,
            Err(what) => return Err(corrupt(what)),
        }
        pos = end;
    }
    Ok(())
}

/// Walks one chunk's body of `len` bytes, and each record of it when uncompressed,
/// reading no further than `available` bytes (`len`, or less where the file is cut
/// short: the walk ends at the cut).
fn check_chunk(r: &mut BufReader<File>, len: u64, available: u64) -> io::Result<Verdict> {
    if len < CHUNK_FIXED_BYTES + 4 {
        return Ok(Err("a chunk's header runs past its end"));
    }
    // Bytes up to here are in the file (the cut is not reached).
    let present = |upto: u64| upto <= available;
    if !present(CHUNK_FIXED_BYTES + 4) {
        return Ok(Ok(0));
    }
    skip(r, CHUNK_FIXED_BYTES)?;
    let compression_bytes = u64::from(read_u32(r)?);
    let mut read = CHUNK_FIXED_BYTES + 4;
    if compression_bytes > len - read {
        return Ok(Err("a chunk's compression name runs past its end"));
    }
    if compression_bytes != 0 {
        // Compressed: the decompressor checks the sizes.
        return Ok(Ok(read));
    }
    if len - read < 8 {
        return Ok(Err("a chunk's header runs past its end"));
    }
    if !present(read + 8) {
        return Ok(Ok(read));
    }
    let records_bytes = read_u64(r)?;
    read += 8;
    if records_bytes > len - read {
        return Ok(Err("a chunk's records run past its end"));
    }
    let mut left = records_bytes;
    while left > 0 {
        if left < RECORD_HEADER_BYTES {
            return Ok(Err("a record in a chunk is cut off"));
        }
        let at = read + records_bytes - left;
        if !present(at + RECORD_HEADER_BYTES) {
            return Ok(Ok(at));
        }
        let (opcode, record_bytes) = read_header(r)?;
        left -= RECORD_HEADER_BYTES;
        if record_bytes > left {
            return Ok(Err("a record in a chunk runs past the chunk's end"));
        }
        if !present(at + RECORD_HEADER_BYTES + record_bytes) {
            return Ok(Ok(at + RECORD_HEADER_BYTES));
        }
        match check_fields(r, opcode, record_bytes)? {
            Ok(fields) => skip(r, record_bytes - fields)?,
            Err(what) => return Ok(Err(what)),
        }
        left -= record_bytes;
    }
    Ok(Ok(read + records_bytes))
}

/// The fields of a record up to its last string (MCAP format, version 0).
#[derive(Clone, Copy)]
enum Field {
    /// Fixed-size fields of this many bytes.
    Fixed(u64),
    /// A u32-length-prefixed run of fixed-size entries (read until its end).
    Entries,
    /// A u32-length-prefixed UTF-8 string.
    Str,
    /// A u32-byte-length-prefixed map of string to string.
    StrMap,
}

fn layout(opcode: u8) -> &'static [Field] {
    use Field::*;
    match opcode {
        0x01 => &[Str, Str],                          // header: profile, library
        0x03 => &[Fixed(2), Str, Str],                // schema: id, name, encoding
        0x04 => &[Fixed(4), Str, Str, StrMap],        // channel: ids, topic, encoding, metadata
        0x08 => &[Fixed(32), Entries, Fixed(8), Str], // chunk index: …, compression
        0x09 => &[Fixed(16), Str, Str],               // attachment: times, name, media type
        0x0A => &[Fixed(40), Str, Str],               // attachment index
        0x0C => &[Str, StrMap],                       // metadata: name, entries
        0x0D => &[Fixed(16), Str],                    // metadata index
        _ => &[],
    }
}

/// Checks each string of a record of `len` bytes against the record's end.
fn check_fields(r: &mut BufReader<File>, opcode: u8, len: u64) -> io::Result<Verdict> {
    const PAST_END: &str = "a string in a record runs past the record's end";
    let mut left = len;
    for field in layout(opcode) {
        match *field {
            Field::Fixed(bytes) => {
                if bytes > left {
                    break; // the library reports the short record
                }
                skip(r, bytes)?;
                left -= bytes;
            }
            Field::Entries | Field::Str => {
                if left < 4 {
                    break;
                }
                let bytes = u64::from(read_u32(r)?);
                left -= 4;
                if bytes > left {
                    if matches!(field, Field::Str) {
                        return Ok(Err(PAST_END));
                    }
                    break;
                }
                skip(r, bytes)?;
                left -= bytes;
            }
            Field::StrMap => {
                if left < 4 {
                    break;
                }
                let map_bytes = u64::from(read_u32(r)?);
                left -= 4;
                let start = left;
                // As the library reads it: key and value strings until the map's length is used.
                while start - left < map_bytes {
                    for _ in 0..2 {
                        if left < 4 {
                            return Ok(Ok(len - left));
                        }
                        let bytes = u64::from(read_u32(r)?);
                        left -= 4;
                        if bytes > left {
                            return Ok(Err(PAST_END));
                        }
                        skip(r, bytes)?;
                        left -= bytes;
                    }
                }
            }
        }
    }
    Ok(Ok(len - left))
}

fn read_header(r: &mut impl Read) -> io::Result<(u8, u64)> {
    let mut b = [0u8; RECORD_HEADER_BYTES as usize];
    r.read_exact(&mut b)?;
    let mut len = [0u8; 8];
    len.copy_from_slice(&b[1..]);
    Ok((b[0], u64::from_le_bytes(len)))
}

fn read_u32(r: &mut impl Read) -> io::Result<u32> {
    let mut b = [0u8; 4];
    r.read_exact(&mut b)?;
    Ok(u32::from_le_bytes(b))
}

fn read_u64(r: &mut impl Read) -> io::Result<u64> {
    let mut b = [0u8; 8];
    r.read_exact(&mut b)?;
    Ok(u64::from_le_bytes(b))
}

/// Moves forward `bytes` (within the file: the callers checked the record's end).
fn skip(r: &mut BufReader<File>, bytes: u64) -> io::Result<()> {
    match i64::try_from(bytes) {
        Ok(b) => r.seek_relative(b),
        Err(_) => Err(io::Error::new(io::ErrorKind::InvalidData, "record length beyond 2^63")),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn chunked(records: &[(u8, &[u8])], declared_records_bytes: Option<u64>) -> Vec<u8> {
        let mut inner = Vec::new();
        for (op, data) in records {
            inner.push(*op);
            inner.extend_from_slice(&(data.len() as u64).to_le_bytes());
            inner.extend_from_slice(data);
        }
        let mut body = vec![0u8; CHUNK_FIXED_BYTES as usize];
        body.extend_from_slice(&0u32.to_le_bytes());
        body.extend_from_slice(&declared_records_bytes.unwrap_or(inner.len() as u64).to_le_bytes());
        body.extend_from_slice(&inner);
        let mut file = mcap::MAGIC.to_vec();
        file.push(OP_CHUNK);
        file.extend_from_slice(&(body.len() as u64).to_le_bytes());
        file.extend_from_slice(&body);
        file
    }

    fn check(bytes: &[u8], name: &str) -> Result<(), IoError> {
        let p = std::env::temp_dir().join(format!("sw-chunk-check-{}-{name}.mcap", std::process::id()));
        std::fs::write(&p, bytes).unwrap();
        let r = check_records(&p, &p);
        std::fs::remove_file(&p).unwrap();
        r
    }

    #[test]
    fn records_within_their_chunk_pass() {
        assert!(check(&chunked(&[(0x05, b"abc"), (0x05, b"")], None), "ok").is_ok());
    }

    #[test]
    fn a_record_past_its_chunk_is_refused() {
        let mut bytes = chunked(&[(0x05, b"abcdef")], None);
        // The inner record's length (after magic, chunk header, fixed fields, compression
        // length, records length and the inner opcode) claims more than the chunk holds.
        let at = 8 + 9 + 28 + 4 + 8 + 1;
        bytes[at..at + 8].copy_from_slice(&100u64.to_le_bytes());
        let e = check(&bytes, "overrun").unwrap_err().to_string();
        assert!(e.contains("runs past the chunk's end") && e.contains("byte 8"), "{e}");
    }

    #[test]
    fn records_length_past_the_chunk_is_refused() {
        let e = check(&chunked(&[(0x05, b"abc")], Some(1 << 40)), "records").unwrap_err().to_string();
        assert!(e.contains("records run past"), "{e}");
    }

    #[test]
    fn a_cut_short_file_is_left_to_the_reader() {
        let bytes = chunked(&[(0x05, b"abcdef")], None);
        assert!(check(&bytes[..bytes.len() - 3], "cut").is_ok());
        // Cut anywhere: never an error (nor a read past the end) for a sound chunk.
        let bytes = chunked(&[(0x04, &channel(4)), (0x05, b"abcdef")], None);
        for cut in 8..bytes.len() {
            assert!(check(&bytes[..cut], "cut-anywhere").is_ok(), "cut at {cut}");
        }
    }

    /// A channel record (id, schema id, topic `/imu`, encoding `json`, no metadata)
    /// whose topic length claims `topic_bytes`.
    fn channel(topic_bytes: u32) -> Vec<u8> {
        let mut c = vec![1, 0, 0, 0];
        c.extend_from_slice(&topic_bytes.to_le_bytes());
        c.extend_from_slice(b"/imu");
        c.extend_from_slice(&4u32.to_le_bytes());
        c.extend_from_slice(b"json");
        c.extend_from_slice(&0u32.to_le_bytes());
        c
    }

    /// The long fuzz pass's case: the file ends inside an uncompressed chunk, and a
    /// channel record before the cut claims a topic of 4 GB; the library streamed it and
    /// reserved the 4 GB.
    #[test]
    fn a_string_past_its_record_in_a_cut_short_chunk_is_refused() {
        let bytes = chunked(&[(0x04, &channel(0xF800_0004)), (0x05, b"abcdef")], None);
        let e = check(&bytes[..bytes.len() - 10], "cut-string").unwrap_err().to_string();
        assert!(e.contains("a string in a record runs past") && e.contains("byte 8"), "{e}");
    }
}

#[cfg(test)]
mod string_tests {
    use super::*;

    /// A header record whose first string claims `claimed` bytes.
    fn header_with_string(claimed: u32) -> Vec<u8> {
        let mut body = claimed.to_le_bytes().to_vec();
        body.extend_from_slice(b"ros2");
        body.extend_from_slice(&0u32.to_le_bytes());
        let mut file = mcap::MAGIC.to_vec();
        file.push(0x01);
        file.extend_from_slice(&(body.len() as u64).to_le_bytes());
        file.extend_from_slice(&body);
        file
    }

    fn check(bytes: &[u8], name: &str) -> Result<(), IoError> {
        let p = std::env::temp_dir().join(format!("sw-record-check-{}-{name}.mcap", std::process::id()));
        std::fs::write(&p, bytes).unwrap();
        let r = check_records(&p, &p);
        std::fs::remove_file(&p).unwrap();
        r
    }

    #[test]
    fn a_string_within_its_record_passes() {
        assert!(check(&header_with_string(4), "ok").is_ok());
    }

    #[test]
    fn a_string_length_past_its_record_is_refused() {
        let e = check(&header_with_string(0xFF00_0000), "long").unwrap_err().to_string();
        assert!(e.contains("a string in a record runs past"), "{e}");
    }
}
