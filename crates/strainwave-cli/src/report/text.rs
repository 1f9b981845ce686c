//! Fixed-width text tables for the terminal, and numbers short enough for them.

use std::fmt::Write as _;

/// `v` with `decimals` decimals, or in scientific notation from a million up (an extreme
/// value would otherwise print hundreds of digits).
pub fn compact(v: f64, decimals: usize) -> String {
    if v.abs() >= 1e6 {
        format!("{v:.3e}")
    } else {
        format!("{v:.decimals$}")
    }
}

/// A table with a header rule; first column left-aligned, the others right-aligned.
pub fn text_table(header: &[&str], rows: &[Vec<String>]) -> String {
    let n = header.len();
    let mut w: Vec<usize> = header.iter().map(|h| h.chars().count()).collect();
    for r in rows {
        for (i, c) in r.iter().enumerate().take(n) {
            w[i] = w[i].max(c.chars().count());
        }
    }
    let line = |cells: Vec<&str>| {
        let mut s = String::from("  ");
        for (i, c) in cells.iter().enumerate().take(n) {
            let pad = w[i].saturating_sub(c.chars().count());
            if i == 0 {
                let _ = write!(s, "{c}{}", " ".repeat(pad));
            } else {
                let _ = write!(s, "  {}{c}", " ".repeat(pad));
            }
        }
        s.trim_end().to_string() + "\n"
    };
    let mut out = line(header.to_vec());
    let rules: Vec<String> = w.iter().map(|k| "-".repeat(*k)).collect();
    out += &line(rules.iter().map(String::as_str).collect());
    for r in rows {
        out += &line(r.iter().map(String::as_str).collect());
    }
    out
}
