//! Calibration fitting and the figures torque-transducer standards use (DIN 51309 / EURAMET cg-14).
//!
//! docs/physics.md §3. Four jobs, one file each, plus the error type and the file format:
//!
//! 1. **Gain per experiment** (Taghirad and Bélanger (1999) §IV): each experiment is a set of rows
//!    (reference torque `T_i`, bridge voltage `V_i`); the gain `g` minimises
//!    `Σ (T_i − g V_i)²` (through the origin, the default) or `Σ (T_i − g V_i − c)²`
//!    (with an offset). Across experiments:
//!    `consistency = s_g / |ḡ|`, with `ḡ` the mean gain (the final gain) and `s_g` the
//!    **sample** standard deviation (divisor `n − 1`); the paper only says "standard
//!    deviation" and reports 6.60 N·m/V at 2 %.
//! 2. **Static, dynamic and speed-dependent affine models** (the embedded-sensor article):
//!    `T_ref = α T_sens + β`, fitted on quasi-static ramps ("static") or sinusoidal-load
//!    data ("dynamic": same form, other data), and `T_ref = α(ω) T_sens + β(ω)` with
//!    `α`, `β` a polynomial in speed (one joint least-squares problem) or a lookup table
//!    (one affine fit per speed bin, breakpoint at the bin's mean speed). Results build a
//!    [`strainwave_core::calibration::Calibration`] for the controller.
//! 3. **Error metrics** for any fit, with `e_i = T_cal,i − T_ref,i` (calibrated sensor
//!    minus reference, N·m) over the `n` rows:
//!    ```text
//!    max |e| = max_i |e_i|
//!    RMS     = √( Σ e_i² / n )          divisor n (not n − p): the error a user sees
//!    mean e  = Σ e_i / n                bias
//!    RMS %FS = 100 · RMS / FS           FS = rated full-scale torque, given (not the data range)
//!    ```
//!    the embedded-sensor article's table (static 0.39 / 0.21 N·m / 1.04 %, dynamic 0.64 / 0.265 N·m /
//!    1.27 %) uses these definitions; its two %FS figures imply FS ≈ 20.2 and ≈ 20.9 N·m.
//! 4. **DIN 51309 / EURAMET cg-14 figures** from repeated loading series: see
//!    [`din51309_figures`] for the formulas.
//!
//! And the **calibration file** ([`CalibrationFile`], TOML, units in key names) that
//! carries a fitted model to the controller, rejecting NaN/∞ on write and on read.
//!
//! | file | holds |
//! |---|---|
//! | `error.rs` | [`CalibrationError`] |
//! | `metrics.rs` | [`ErrorMetrics`], [`error_metrics`] |
//! | `gain.rs` | [`Experiment`], [`calibrate_gain`] (Taghirad and Bélanger (1999)) |
//! | `affine.rs` | [`AffineFit`], [`fit_affine`] (the embedded-sensor article static / dynamic) |
//! | `speed.rs` | [`SpeedDependence`], [`fit_speed_dependent`] (table, polynomial) |
//! | `din.rs` | [`LoadSeries`], [`din51309_figures`] |
//! | `held.rs` | [`held_rows`]: the quasi-static rows of a step-loading recording |
//! | `series.rs` | [`split_load_series`]: readings of a recording → loading series |
//! | `file.rs` | [`CalibrationFile`] (TOML) |

mod affine;
mod din;
mod error;
mod file;
mod gain;
mod held;
mod metrics;
mod series;
mod speed;

pub use affine::{fit_affine, AffineFit};
pub use din::{din51309_figures, DinOptions, DinReport, DinStep, LoadSeries, SeriesStep};
pub use error::CalibrationError;
pub use file::{toml_error_line, toml_key_at, CalibrationFile, Coefficients, Evaluation, ModelKind};
pub use gain::{calibrate_gain, Experiment, ExperimentGain, GainCalibration, GainFit};
pub use held::held_rows;
pub use metrics::{error_metrics, ErrorMetrics};
pub use series::{group_by_levels, quantization_step, split_load_series};
pub use speed::{fit_speed_dependent, Extrapolation, SpeedBinFit, SpeedBins, SpeedDependence, SpeedFit};

/// Largest table length / polynomial coefficient count handled here (the core's `K`
/// used when this crate evaluates a calibration).
pub const MAX_TABLE_LEN: usize = 64;

fn invalid(what: &str, why: impl Into<String>) -> CalibrationError {
    CalibrationError::Invalid { what: what.to_string(), why: why.into() }
}

/// Checks equal lengths and finiteness of named columns; returns the row count.
fn check_columns(what: &str, cols: &[(&'static str, &[f64])]) -> Result<usize, CalibrationError> {
    let n = cols.first().map_or(0, |c| c.1.len());
    for &(column, c) in cols {
        if c.len() != n {
            return Err(CalibrationError::LengthMismatch { what: what.to_string(), column, expected: n, got: c.len() });
        }
    }
    for row in 0..n {
        for &(column, c) in cols {
            if !c[row].is_finite() {
                return Err(CalibrationError::NonFiniteRow { what: what.to_string(), row, column });
            }
        }
    }
    Ok(n)
}

fn require_two_values(what: &str, column: &'static str, x: &[f64]) -> Result<(), CalibrationError> {
    match x.first() {
        Some(&v) if x.iter().all(|&t| t == v) => {
            Err(CalibrationError::SingleValue { what: what.to_string(), column, rows: x.len(), value: v })
        }
        _ => Ok(()),
    }
}
