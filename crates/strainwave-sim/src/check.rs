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
            SimError::Parse {
                message: key.map_or(message.clone(), |k| format!("`{k}`: {message}")),
                location: toml_location(text, e.span()),
            }
        })
}

/// The dotted key whose value starts at the end of `before`: the table header above it
/// joined with the key on its own line, when the line is a plain `key = value` (as the
/// joint crate's configuration errors name it).
fn key_at(before: &str) -> Option<String> {
    let mut lines = before.rsplit('\n');
    let (key, _) = lines.next()?.split_once('=')?;
    let key = key.trim().trim_matches('"');
    if key.is_empty() || key.contains(['[', '{', ',']) {
        return None;
    }
    let table = lines
        .map(str::trim)
        .find(|l| l.starts_with('['))
        .map(|l| l.trim_start_matches('[').split(']').next().unwrap_or("").trim().to_string());
    Some(match table {
        Some(t) if !t.is_empty() => format!("{t}.{key}"),
        _ => key.to_string(),
    })
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
}
