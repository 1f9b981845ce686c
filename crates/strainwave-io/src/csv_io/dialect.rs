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
    let mut head = Vec::with_capacity(SNIFF_BYTES);
    (&mut input)
        .take(SNIFF_BYTES as u64)
        .read_to_end(&mut head)
        .map_err(|source| IoError::Os { path: path.to_path_buf(), source })?;
    let text = head.strip_prefix(b"\xef\xbb\xbf").unwrap_or(&head);
    let header = text
        .split(|&b| b == b'\n')
        .map(|l| l.strip_suffix(b"\r").unwrap_or(l))
        .find(|l| !l.iter().all(u8::is_ascii_whitespace) && l.first() != Some(&b'#'))
        .unwrap_or(b"");
    let d = detect_delimiter(header);
    Ok((Box::new(Cursor::new(head).chain(input)), d))
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
