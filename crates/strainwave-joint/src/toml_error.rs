//! A TOML error on one line: the file, the line and column, the key as the user wrote it
//! (`filter.model`), and the parser's message.

use std::path::Path;

/// `path: line L, column C: key `K`: message` for an error of `toml::from_str` over `text`.
pub fn one_line(path: &Path, text: &str, e: &toml::de::Error) -> anyhow::Error {
    let message = e.message().trim().replace('\n', "; ");
    let Some(span) = e.span() else {
        return anyhow::anyhow!("{}: {message}", path.display());
    };
    let before = text.get(..span.start).unwrap_or(text);
    let line = before.matches('\n').count() + 1;
    let column = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
    let key = strainwave_analysis::calibration::toml_key_at(before).map_or(String::new(), |k| format!("{k}: "));
    anyhow::anyhow!("{}: line {line}, column {column}: {key}{message}", path.display())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Debug, serde::Deserialize)]
    #[allow(dead_code)]
    struct F {
        filter: G,
    }
    #[derive(Debug, serde::Deserialize)]
    #[allow(dead_code)]
    struct G {
        model: u32,
    }

    #[test]
    fn names_file_line_and_key() {
        let text = "# c\n[filter]\nmodel = \"x\"\n";
        let e = toml::from_str::<F>(text).unwrap_err();
        let msg = one_line(Path::new("j.toml"), text, &e).to_string();
        assert!(msg.starts_with("j.toml: line 3, column 9: `filter.model`: "), "{msg}");
        assert!(!msg.contains('\n'));
    }

    #[test]
    fn no_key_for_a_table_error() {
        let text = "[filter]\n";
        let e = toml::from_str::<F>(text).unwrap_err();
        let msg = one_line(Path::new("j.toml"), text, &e).to_string();
        assert!(msg.starts_with("j.toml: "), "{msg}");
        assert!(msg.contains("model"), "{msg}");
    }

    #[derive(Debug, serde::Deserialize)]
    #[allow(dead_code)]
    struct Learned {
        joint: H,
        orders: Vec<H>,
    }
    #[derive(Debug, serde::Deserialize)]
    #[allow(dead_code)]
    struct H {
        multiple: f64,
    }

    /// In an array of tables the key is named with its entry, not the table above.
    #[test]
    fn names_the_entry_of_an_array_of_tables() {
        let text = "[joint]\nmultiple = 1.0\n[[orders]]\nmultiple = 2.0\n[[orders]]\nmultiple = \"four\"\n";
        let e = toml::from_str::<Learned>(text).unwrap_err();
        let msg = one_line(Path::new("l.toml"), text, &e).to_string();
        assert!(msg.starts_with("l.toml: line 6, column 12: `[[orders]]` entry 2, `multiple`: "), "{msg}");
    }
}
