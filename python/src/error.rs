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

/// `e` as a `StrainwaveError`.
pub fn to_py(e: anyhow::Error) -> PyErr {
    StrainwaveError::new_err(strainwave_joint::one_line(&e))
}
