//! What every scenario file shares: TOML parsing with the error's line and column, and
//! value checks whose errors name the key.

use serde::de::DeserializeOwned;

use crate::error::SimError;

/// Parses a scenario's TOML; unknown keys and wrong types are errors with a location.
pub(crate) fn parse_toml<T: DeserializeOwned>(text: &str) -> Result<T, SimError> {
    toml::from_str(text)
        // One line: the parser's message may run over several.
        .map_err(|e| {
            let message = e.message().trim().replace('\n', "; ");
            // The key as the user wrote it (`sensor.layout`), when the error is a value's.
            let key = e.span().and_then(|s| key_at(text.get(..s.start)?));
            if let Some(k) = key {
                return SimError::Parse { message: format!("{k}: {message}"), location: toml_location(text, e.span()) };
            }
            // An error inside a `[[name]]` entry is reported at its header: name the entry
            // and, where the message tells, the key and its line.
            if let Some((entry, key_offset)) = e.span().and_then(|s| array_entry(text, s.start, &message)) {
                let location = toml_location(text, key_offset.map(|o| o..o).or(e.span()));
                return SimError::Parse { message: format!("{entry}: {message}"), location };
            }
            SimError::Parse { message, location: toml_location(text, e.span()) }
        })
}

/// When `offset` is at an `[[name]]` header (where the parser reports errors inside any
/// entry of the array): the entry whose key the message names (`` unknown field `k` ``) or
/// whose value it shows (`` invalid type: string "x" ``), as "`[[name]]` entry N, `key`"
/// (counted from 1), with the offset of that key's line; else "`[[name]]`".
fn array_entry(text: &str, offset: usize, message: &str) -> Option<(String, Option<usize>)> {
    let name = header_name(text.get(offset..)?.lines().next()?)?;
    let (mut n, mut inside, mut at) = (0, false, 0);
    for line in text.split_inclusive('\n') {
        let trimmed = line.trim_start();
        if trimmed.starts_with('[') {
            inside = header_name(line) == Some(name);
            n += usize::from(inside);
        } else if let (true, Some((key, value))) = (inside, line.split_once('=')) {
            let (key, value) = (key.trim(), without_comment(value).trim());
            if unknown_field(message) == Some(key) || (key != "kind" && shows_value(message, value)) {
                return Some((format!("`[[{name}]]` entry {n}, `{key}`"), Some(at)));
            }
        }
        at += line.len();
    }
    Some((format!("`[[{name}]]`"), None))
}

/// `value` up to its comment: the first `#` outside a quoted string.
fn without_comment(value: &str) -> &str {
    let (mut quote, mut escaped) = (None, false);
    for (i, c) in value.char_indices() {
        match (quote, c) {
            (None, '#') => return &value[..i],
            (None, '"' | '\'') => quote = Some(c),
            // Only basic strings (`"…"`) have escapes.
            (Some('"'), '\\') if !escaped => {
                escaped = true;
                continue;
            }
            (Some(q), _) if c == q && !escaped => quote = None,
            _ => {}
        }
        escaped = false;
    }
    value
}

/// The name of an `[[name]]` header line.
fn header_name(line: &str) -> Option<&str> {
    line.trim().strip_prefix("[[")?.split("]]").next().map(str::trim)
}

/// The key whose value starts at the end of `before`, as the user wrote it, in backticks
/// (`` `sensor.layout` ``, or `` `[[motion]]` entry 2, `to_rad_s` `` in an array of tables),
/// when the line is a plain `key = value`; the configuration files of the joint crate
/// name keys the same way.
fn key_at(before: &str) -> Option<String> {
    let mut lines = before.rsplit('\n');
    let (key, _) = lines.next()?.split_once('=')?;
    let key = key.trim().trim_matches('"');
    if key.is_empty() || key.contains(['[', '{', ',']) {
        return None;
    }
    let header = lines.map(str::trim).find(|l| l.starts_with('['));
    let name = |h: &str| h.trim_start_matches('[').split(']').next().unwrap_or("").trim().to_string();
    Some(match header {
        Some(h) if h.starts_with("[[") => {
            let n = before.lines().filter(|l| l.trim().starts_with("[[") && name(l) == name(h)).count();
            format!("`[[{}]]` entry {n}, `{key}`", name(h))
        }
        Some(h) if !name(h).is_empty() => format!("`{}.{key}`", name(h)),
        _ => format!("`{key}`"),
    })
}

/// The key of an `` unknown field `key`, expected … `` message.
fn unknown_field(message: &str) -> Option<&str> {
    message.strip_prefix("unknown field `")?.split('`').next()
}

/// Whether `message` is an `invalid type` error showing the value written as `value`
/// (serde shows `string "x"`, `` boolean `true` ``, `` integer `5` ``, `sequence`, `map`).
fn shows_value(message: &str, value: &str) -> bool {
    let Some(found) = message.strip_prefix("invalid type: ") else {
        return false;
    };
    let shown = found.split(", expected").next().unwrap_or("");
    match shown.split_once(' ') {
        Some(("string", s)) => s == value || s.trim_matches('"') == value.trim_matches(['"', '\'']),
        Some((_, v)) => v.trim_matches('`') == value,
        None => (shown == "sequence" && value.starts_with('[')) || (shown == "map" && value.starts_with('{')),
    }
}

/// `line L, column C` of a byte offset (empty without one).
fn toml_location(text: &str, span: Option<std::ops::Range<usize>>) -> String {
    let Some(span) = span else {
        return String::new();
    };
    let upto = text.get(..span.start.min(text.len())).unwrap_or(text);
    let line = upto.matches('\n').count() + 1;
    let col = upto.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
    format!("line {line}, column {col}")
}

/// A run's length: `duration_s` and `sample_rate_hz` positive, at least one sample and at
/// most 10⁹.
pub(crate) fn run_length(duration_s: f64, sample_rate_hz: f64) -> Result<(), SimError> {
    positive(sample_rate_hz, "sample_rate_hz")?;
    positive(duration_s, "duration_s")?;
    let samples = duration_s * sample_rate_hz;
    if samples > 1e9 {
        return Err(SimError::invalid("duration_s", "more than 10⁹ samples at sample_rate_hz".into()));
    }
    if samples.round() < 1.0 {
        let msg = format!("= {duration_s:e} s: not one sample at sample_rate_hz = {sample_rate_hz} Hz");
        return Err(SimError::invalid("duration_s", msg));
    }
    Ok(())
}

/// A gear ratio within [`strainwave_core::gear::RATIO_RANGE`].
pub(crate) fn gear_ratio(ratio: f64) -> Result<(), SimError> {
    let ratios = strainwave_core::gear::RATIO_RANGE;
    if !ratios.contains(&ratio) {
        let (lo, hi) = (ratios.start(), ratios.end());
        return Err(SimError::invalid("gear.ratio", format!("must be between {lo} and {hi}, got {ratio:?}")));
    }
    Ok(())
}

/// `v` finite and `> 0`.
pub(crate) fn positive(v: f64, key: &'static str) -> Result<(), SimError> {
    if v.is_finite() && v > 0.0 {
        Ok(())
    } else {
        Err(SimError::invalid(key, format!("must be positive, got {v}")))
    }
}

/// `v` finite and `≥ 0`.
pub(crate) fn non_negative(v: f64, key: &'static str) -> Result<(), SimError> {
    if v.is_finite() && v >= 0.0 {
        Ok(())
    } else {
        Err(SimError::invalid(key, format!("must be ≥ 0, got {v}")))
    }
}

/// `v` finite.
pub(crate) fn finite(v: f64, key: &'static str) -> Result<(), SimError> {
    if v.is_finite() {
        Ok(())
    } else {
        Err(SimError::invalid(key, format!("must be finite, got {v}")))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn checks_name_the_key_and_parse_errors_the_line() {
        assert!(positive(0.0, "a.b").unwrap_err().to_string().contains("a.b"));
        assert!(non_negative(-1.0, "c").is_err() && non_negative(0.0, "c").is_ok());
        assert!(finite(f64::NAN, "d").is_err());
        #[derive(serde::Deserialize, Debug)]
        #[serde(deny_unknown_fields)]
        struct S {
            #[allow(dead_code)]
            x: f64,
        }
        let e = parse_toml::<S>("x = 1.0\ny = 2").unwrap_err().to_string();
        assert!(e.contains("line 2"), "{e}");
    }

    /// An error inside an array of tables is reported by the parser at the array's first
    /// header; the message names the entry and key, the location the key's line.
    #[test]
    fn an_error_in_an_array_of_tables_names_the_entry_and_key() {
        let preset = crate::presets::preset("taghirad").unwrap().to_toml();
        // `to_toml` writes each `[[motion]]` entry with its `kind` first.
        let nth = |n: usize| preset.match_indices("[[motion]]").nth(n).unwrap().0;
        let edit = |n: usize, from: &str, to: &str| {
            let (a, b) = (nth(n), nth(n + 1));
            format!("{}{}{}", &preset[..a], preset[a..b].replacen(from, to, 1), &preset[b..])
        };
        let line_of = |text: &str, what: &str| text[..text.find(what).unwrap()].matches('\n').count() + 1;
        let cases = [
            (
                edit(1, "duration_s = ", "duration_s = true #"),
                "`[[motion]]` entry 2, `duration_s`: invalid type",
                "= true",
            ),
            (
                edit(0, "duration_s = ", "durashun_s = "),
                "`[[motion]]` entry 1, `durashun_s`: unknown field",
                "durashun_s",
            ),
            (edit(2, "duration_s = ", "duration_s = \"long\" #"), "`[[motion]]` entry 3, `duration_s`", "\"long\""),
            // A `#` inside a string is the value's, not a comment.
            (edit(1, "duration_s = ", "duration_s = \"1 # s\" #"), "`[[motion]]` entry 2, `duration_s`", "\"1 # s\""),
            (edit(1, "duration_s = ", "duration_s = 'a#b' #"), "`[[motion]]` entry 2, `duration_s`", "'a#b'"),
        ];
        for (text, expect, at) in cases {
            let e = crate::Scenario::from_toml(&text).unwrap_err().to_string();
            assert!(e.contains(expect), "{e}");
            assert!(e.contains(&format!("(at line {}, column 1)", line_of(&text, at))), "{e}");
        }
        let e = crate::Scenario::from_toml(&edit(1, "duration_s = ", "duration_s = -")).unwrap_err().to_string();
        assert!(e.contains("`motion.duration_s` must be positive") && e.ends_with("(`[[motion]]` entry 2)"), "{e}");
    }
}
