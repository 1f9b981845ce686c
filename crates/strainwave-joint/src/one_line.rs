//! Errors as the user sees them: the error and its causes joined on one line. The
//! command line prints this after `error: `; the Python package raises it.

/// The error and its causes on one line, each cause once (a cause whose text is already
/// in the line, as when an error prints its source itself, is not repeated).
pub fn one_line(e: &anyhow::Error) -> String {
    let mut line = String::new();
    for cause in e.chain() {
        let text = cause.to_string();
        if line.contains(&text) {
            continue;
        }
        if !line.is_empty() {
            line.push_str(": ");
        }
        line.push_str(&text);
    }
    line
}

#[cfg(test)]
mod tests {
    use super::one_line;
    use anyhow::Context;

    #[test]
    fn causes_joined_once_each() {
        let inner: anyhow::Result<()> = Err(anyhow::anyhow!("no column `torque`"));
        let e = inner.context("run.csv").context("run.csv").unwrap_err();
        assert_eq!(one_line(&e), "run.csv: no column `torque`");
        let io = std::io::Error::new(std::io::ErrorKind::NotFound, "not found");
        let e = anyhow::Error::new(io).context("joint.toml");
        assert_eq!(one_line(&e), "joint.toml: not found");
    }
}
