//! Rust errors as Python exceptions, with the command line's one-line message.

use pyo3::create_exception;
use pyo3::exceptions::PyValueError;
use pyo3::PyErr;

create_exception!(
    strainwave,
    StrainwaveError,
    PyValueError,
    "A strainwave error: bad file, bad config value, bad row. The message is the command line's."
);

/// The error and its causes on one line, each cause once (as `strainwave` prints them
/// after `error: `).
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

/// `e` as a `StrainwaveError`.
pub fn to_py(e: anyhow::Error) -> PyErr {
    StrainwaveError::new_err(one_line(&e))
}
