//! Number text: std's shortest round-trip text, fast, and cell parsing.

/// Formats an `f64` with the shortest text that parses back to the same bits.
///
/// Plain decimal for `1e-5 <= |x| < 1e16` (and zero), exponent form (`1e-7`, `6.02e23`)
/// otherwise, no `.0` on integers, `NaN`, `inf` and `-inf`: the text of Rust's `{}`/`{:e}`.
pub fn format_f64(x: f64, out: &mut String) {
    let mut bytes = Vec::with_capacity(24);
    push_f64(x, &mut bytes);
    out.extend(bytes.iter().map(|&b| char::from(b)));
}

/// Appends the text of [`format_f64`] to a byte buffer.
#[inline]
pub(super) fn push_f64(x: f64, out: &mut Vec<u8>) {
    let mut zmij = zmij::Buffer::new();
    let text = zmij.format(x).as_bytes();
    let start = out.len();
    // zmij chooses the notation as std does (plain for 1e-5 <= |x| < 1e16) and the same
    // digits, but writes `1.0` for `1`, `1e+30` for `1e30`, and breaks ties otherwise.
    if (1e-5..1e16).contains(&x.abs()) {
        out.extend_from_slice(text.strip_suffix(b".0").unwrap_or(text));
    } else {
        push_other(text, out);
    }
    if may_tie(x) {
        round_tie_away(x, start, out);
    }
}

/// Appends one CSV line: the cells as [`format_f64`] writes them, then `\n`.
#[inline]
pub fn format_row(row: &[f64], out: &mut Vec<u8>) {
    format_row_with(row, b',', out);
}

/// [`format_row`] with the cells apart by `delimiter` (a tab for `.tsv`).
#[inline]
pub(super) fn format_row_with(row: &[f64], delimiter: u8, out: &mut Vec<u8>) {
    for (i, v) in row.iter().enumerate() {
        if i > 0 {
            out.push(delimiter);
        }
        push_f64(*v, out);
    }
    out.push(b'\n');
}

/// Zero, `NaN`, infinities and the exponent form, from zmij's text to std's.
#[cold]
pub(super) fn push_other(text: &[u8], out: &mut Vec<u8>) {
    let text = text.strip_suffix(b".0").unwrap_or(text);
    match text.iter().position(|&c| c == b'e') {
        Some(e) if text.get(e + 1) == Some(&b'+') => {
            out.extend_from_slice(&text[..=e]);
            out.extend_from_slice(&text[e + 2..]);
        }
        _ => out.extend_from_slice(text),
    }
}

/// `|x| = m 2^p` with `m` odd (for finite non-zero `x`).
#[inline]
pub(super) fn odd_mantissa(x: f64) -> (u64, i32) {
    let bits = x.to_bits();
    let biased = ((bits >> 52) & 0x7ff) as i32;
    let fraction = bits & ((1u64 << 52) - 1);
    let (m, p) = if biased == 0 { (fraction, -1074) } else { (fraction | (1u64 << 52), biased - 1075) };
    let zeros = m.trailing_zeros().min(63);
    (m >> zeros, p + zeros as i32)
}

/// Whether the shortest text of `x` can be an exact tie between two candidates. A tie is
/// `2|x| = m 2^(p+1) = (2d+1) 10^e`, `d` the digits (< 10^17): both sides are odd numbers
/// times powers of two, so `p + 1 = e`, and `5^|e|` times an odd number stays below 2^58.
/// Zero, infinities and `NaN` fall outside too.
#[inline]
pub(super) fn may_tie(x: f64) -> bool {
    (-26..=22).contains(&odd_mantissa(x).1)
}

/// Where the digits `out[start..]` of `x` lie exactly half a unit of their last digit
/// below `|x|` (zmij took the even digit of a tie), moves the last digit away from zero, as
/// std does, so the text is std's byte for byte. The digit is even: no carry.
#[cold]
pub(super) fn round_tie_away(x: f64, start: usize, out: &mut [u8]) {
    let (m, p) = odd_mantissa(x);
    let text = &out[start..];
    let (mut d, mut e) = (0u64, 0i32);
    let mut in_fraction = false;
    let mut bytes = text.iter();
    for &c in bytes.by_ref() {
        match c {
            b'-' => {}
            b'.' => in_fraction = true,
            b'e' => break,
            c => {
                d = d * 10 + u64::from(c - b'0');
                e -= i32::from(in_fraction);
            }
        }
    }
    match bytes.as_slice() {
        [] => {}
        [b'-', digits @ ..] => e -= digits.iter().fold(0, |a, &c| a * 10 + i32::from(c - b'0')),
        digits => e += digits.iter().fold(0, |a, &c| a * 10 + i32::from(c - b'0')),
    }
    if p + 1 != e {
        return;
    }
    let (odd, pow5) = (2 * u128::from(d) + 1, 5u128.pow(e.unsigned_abs()));
    let tie = if e >= 0 { odd * pow5 == u128::from(m) } else { u128::from(m) * pow5 == odd };
    if tie {
        let digits = text.iter().position(|&c| c == b'e').unwrap_or(text.len());
        out[start + digits - 1] += 1;
    }
}

/// Parses one cell: ASCII whitespace around it is ignored.
#[inline]
pub(super) fn parse_cell(cell: &str) -> Option<f64> {
    cell.trim_ascii().parse().ok()
}

/// Parses a cell written with a decimal comma (`-1,25e3`): the comma read as a point.
#[cold]
pub(super) fn parse_decimal_comma(cell: &str) -> Option<f64> {
    let cell = cell.trim();
    let mut buf = [0u8; 64];
    let bytes = cell.as_bytes();
    if bytes.len() > buf.len() || bytes.iter().filter(|&&b| b == b',').count() > 1 {
        return None;
    }
    for (o, &b) in buf.iter_mut().zip(bytes) {
        *o = if b == b',' { b'.' } else { b };
    }
    std::str::from_utf8(&buf[..bytes.len()]).ok()?.parse().ok()
}
