//! Text exports as DAQ systems write them: the delimiter (comma, semicolon or tab) found
//! from the header line, and units taken out of the column names (`Time [s]`,
//! `torque (N·m)`).

use std::io::{Cursor, Read};
use std::path::Path;

use crate::error::IoError;

/// Bytes looked at for the header line.
const SNIFF_BYTES: usize = 1 << 16;

/// How a delimiter is named in messages.
pub fn delimiter_name(d: u8) -> String {
    match d {
        b',' => "comma".into(),
        b';' => "semicolon".into(),
        b'\t' => "tab".into(),
        b' ' => "space".into(),
        d => format!("`{}`", char::from(d)),
    }
}

/// The delimiter of a header line: whichever of tab, semicolon and comma it holds most
/// of outside quotes (ties in that order); a comma when it holds none.
///
/// ```
/// use strainwave_io::csv_io::detect_delimiter;
/// assert_eq!(detect_delimiter(b"Time [s]\ttorque (N\xc2\xb7m)"), b'\t');
/// assert_eq!(detect_delimiter(b"time;torque_nm"), b';');
/// assert_eq!(detect_delimiter(b"time,\"a;b\""), b',');
/// assert_eq!(detect_delimiter(b"time"), b',');
/// ```
pub fn detect_delimiter(header: &[u8]) -> u8 {
    let (mut tab, mut semi, mut comma, mut quoted) = (0, 0, 0, false);
    for &b in header {
        match b {
            b'"' => quoted = !quoted,
            b'\t' if !quoted => tab += 1,
            b';' if !quoted => semi += 1,
            b',' if !quoted => comma += 1,
            _ => {}
        }
    }
    if tab > 0 && tab >= semi && tab >= comma {
        b'\t'
    } else if semi > 0 && semi >= comma {
        b';'
    } else {
        b','
    }
}

/// Reads the start of `input` to find the header line (after a byte-order mark, empty
/// and `#` lines) and its delimiter; returns the input whole again.
pub(super) fn sniff(path: &Path, mut input: Box<dyn Read + Send>) -> Result<(Box<dyn Read + Send>, u8), IoError> {
    // Reads only until the header line is whole: a live pipe sends no more yet.
    let mut head = Vec::with_capacity(4096);
    let mut chunk = [0u8; 4096];
    let header = loop {
        if let Some(line) = header_line(&head) {
            break line;
        }
        let n = match input.read(&mut chunk) {
            Ok(n) => n,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
            Err(source) => return Err(IoError::Os { path: path.to_path_buf(), source }),
        };
        head.extend_from_slice(&chunk[..n]);
        if n == 0 || head.len() >= SNIFF_BYTES {
            // The last line without its end, or a header longer than we look at.
            let text = head.strip_prefix(b"\xef\xbb\xbf").unwrap_or(&head);
            let last = text.split(|&b| b == b'\n' || b == b'\r').find(|l| is_header(l)).unwrap_or(b"");
            break last.to_vec();
        }
    };
    let d = detect_delimiter(&header);
    Ok((Box::new(Cursor::new(head).chain(input)), d))
}

fn is_header(line: &[u8]) -> bool {
    !line.iter().all(u8::is_ascii_whitespace) && line.first() != Some(&b'#')
}

/// The first complete line that is not empty or a comment.
fn header_line(head: &[u8]) -> Option<Vec<u8>> {
    let text = head.strip_prefix(b"\xef\xbb\xbf").unwrap_or(head);
    let mut lines = text.split(|&b| b == b'\n' || b == b'\r');
    let mut complete = text.iter().filter(|&&b| b == b'\n' || b == b'\r').count();
    for line in lines.by_ref() {
        if complete == 0 {
            return None;
        }
        complete -= 1;
        let line = line.strip_suffix(b"\r").unwrap_or(line);
        if is_header(line) {
            return Some(line.to_vec());
        }
    }
    None
}

/// A unit in parentheses: short, and no characters a unit does not have (so
/// `torq.(P:00A305h)` keeps its parenthesis).
fn looks_like_unit(u: &str) -> bool {
    !u.is_empty()
        && u.chars().count() <= 16
        && u.chars().all(|c| c.is_alphanumeric() || " ·*/^°%µΩ²³⁻¹.-".contains(c))
        && u.chars().any(|c| c.is_alphabetic() || "°%Ω".contains(c))
}

/// A header cell as `(name, unit)`: `Time [s]` → (`time`, `s`), `torque (N·m)` →
/// (`torque`, `N·m`). A unit is in square brackets, or in parentheses when it looks like
/// one; a column named `time` in any case is `time`. Other names are kept as written.
///
/// ```
/// use strainwave_io::csv_io::split_unit;
/// assert_eq!(split_unit("Time [s]"), ("time".to_string(), Some("s".to_string())));
/// assert_eq!(split_unit("torque (N·m)"), ("torque".to_string(), Some("N·m".to_string())));
/// assert_eq!(split_unit("ch1 torq.(P:00A305h)"), ("ch1 torq.(P:00A305h)".to_string(), None));
/// assert_eq!(split_unit("motor_position"), ("motor_position".to_string(), None));
/// ```
pub fn split_unit(cell: &str) -> (String, Option<String>) {
    let cell = cell.trim();
    let split = [('[', ']'), ('(', ')')].iter().find_map(|&(open, close)| {
        let body = cell.strip_suffix(close)?;
        let at = body.rfind(open)?;
        let (name, unit) = (body[..at].trim(), body[at + open.len_utf8()..].trim());
        (!name.is_empty() && (open == '[' || looks_like_unit(unit))).then(|| (name.to_string(), unit.to_string()))
    });
    let (name, unit) = match split {
        Some((n, u)) => (n, (!u.is_empty()).then_some(u)),
        None => (cell.to_string(), None),
    };
    if name.eq_ignore_ascii_case("time") {
        return ("time".to_string(), unit);
    }
    (name, unit)
}

/// A header cell as text: UTF-8, or else Windows-1252, as DAQ software on Windows writes
/// it (`Drehmoment [N·m]` with `·` the byte 0xB7).
pub(super) fn header_text(cell: &[u8]) -> String {
    match std::str::from_utf8(cell) {
        Ok(s) => s.to_string(),
        Err(_) => cell.iter().map(|&b| windows_1252(b)).collect(),
    }
}

/// One Windows-1252 byte as a character: Latin-1 but for 0x80–0x9F (the five bytes
/// that code page leaves undefined keep their C1 control).
fn windows_1252(b: u8) -> char {
    const HIGH: [char; 32] = [
        '\u{20ac}', '\u{81}', '\u{201a}', '\u{192}', '\u{201e}', '\u{2026}', '\u{2020}', '\u{2021}', '\u{2c6}',
        '\u{2030}', '\u{160}', '\u{2039}', '\u{152}', '\u{8d}', '\u{17d}', '\u{8f}', '\u{90}', '\u{2018}', '\u{2019}',
        '\u{201c}', '\u{201d}', '\u{2022}', '\u{2013}', '\u{2014}', '\u{2dc}', '\u{2122}', '\u{161}', '\u{203a}',
        '\u{153}', '\u{9d}', '\u{17e}', '\u{178}',
    ];
    match b {
        0x80..=0x9f => HIGH[usize::from(b - 0x80)],
        _ => char::from(b),
    }
}
