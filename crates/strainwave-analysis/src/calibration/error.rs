//! The error type of calibration fitting, evaluation and files.

use crate::lstsq::LstsqError;
use crate::AnalysisError;

/// Why a calibration could not be fitted, evaluated, read or written.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CalibrationError {
    /// The least-squares solver refused the problem (singular, too few rows, …).
    #[error(transparent)]
    Lstsq(#[from] LstsqError),
    /// Fewer rows than the fit needs.
    #[error("{what}: {got} rows, needs at least {needed}")]
    TooFewRows {
        /// Which input.
        what: String,
        /// Rows needed.
        needed: usize,
        /// Rows given.
        got: usize,
    },
    /// A NaN or infinite value in a row.
    #[error("{what}: row {} has a non-finite `{column}`", .row + 1)]
    NonFiniteRow {
        /// Which input.
        what: String,
        /// Row index (0-based; shown 1-based, as users count).
        row: usize,
        /// Column name.
        column: &'static str,
    },
    /// Every row has the same value where the fit needs at least two (singular).
    #[error("{what}: all {rows} rows have {column} = {value}; the fit is singular (needs two distinct values)")]
    SingleValue {
        /// Which input.
        what: String,
        /// Column name.
        column: &'static str,
        /// Rows.
        rows: usize,
        /// The common value.
        value: f64,
    },
    /// Columns of different lengths.
    #[error("{what}: `{column}` has {got} rows, expected {expected}")]
    LengthMismatch {
        /// Which input.
        what: String,
        /// Column name.
        column: &'static str,
        /// Rows expected.
        expected: usize,
        /// Rows given.
        got: usize,
    },
    /// A speed outside the calibrated range under `extrapolation = "reject"`.
    #[error(
        "row {}: speed {speed_rad_s} rad/s is outside the calibrated range [{min_rad_s}, {max_rad_s}] rad/s \
         and extrapolation is `reject`", .row + 1
    )]
    SpeedOutsideTable {
        /// Row index (0-based; shown 1-based, as users count).
        row: usize,
        /// The speed.
        speed_rad_s: f64,
        /// Range start.
        min_rad_s: f64,
        /// Range end.
        max_rad_s: f64,
    },
    /// An error inside one speed bin.
    #[error("speed bin {index} [{lo_rad_s}, {hi_rad_s}] rad/s: {source}")]
    Bin {
        /// Bin index.
        index: usize,
        /// Bin start.
        lo_rad_s: f64,
        /// Bin end.
        hi_rad_s: f64,
        /// What went wrong.
        source: Box<CalibrationError>,
    },
    /// A problem found at one row of the input.
    #[error("{what}: row {}: {why}", .row + 1)]
    AtRow {
        /// Which input.
        what: String,
        /// Row index (0-based; shown 1-based, as users count).
        row: usize,
        /// What is wrong there.
        why: String,
    },
    /// An invalid option or input structure.
    #[error("{what}: {why}")]
    Invalid {
        /// Which parameter.
        what: String,
        /// Why.
        why: String,
    },
    /// A NaN or infinite number in a calibration file.
    #[error("calibration file: `{key}` is not finite")]
    NonFiniteKey {
        /// The key, with an index for arrays (`alpha[2]`, `metrics.rms_error_nm`).
        key: String,
    },
    /// A key missing, misplaced or of the wrong shape for the model.
    #[error("calibration file: `{key}`: {why}")]
    FileKey {
        /// The key.
        key: &'static str,
        /// Why.
        why: String,
    },
    /// TOML syntax or type error (the message carries line and column).
    #[error("calibration file: {0}")]
    Toml(String),
    /// Reading or writing a file.
    #[error("{path}: {message}")]
    Io {
        /// The file.
        path: String,
        /// The OS error.
        message: String,
    },
    /// The core rejected the coefficients.
    #[error("calibration: {0}")]
    Core(strainwave_core::Error),
}

impl From<CalibrationError> for AnalysisError {
    fn from(e: CalibrationError) -> Self {
        match e {
            CalibrationError::Lstsq(l) => l.into(),
            other => AnalysisError::Invalid { what: "calibration", why: other.to_string() },
        }
    }
}

impl From<strainwave_core::Error> for CalibrationError {
    fn from(e: strainwave_core::Error) -> Self {
        CalibrationError::Core(e)
    }
}
