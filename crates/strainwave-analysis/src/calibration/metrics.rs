//! Error metrics of a calibrated sensor against a reference (see the module doc of
//! [`crate::calibration`] for the definitions).

use serde::{Deserialize, Serialize};

use super::{check_columns, invalid, CalibrationError};

/// Error figures of a calibrated sensor against a reference (see the module doc).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ErrorMetrics {
    /// Rows `n` the figures are taken over.
    pub rows: usize,
    /// `max_i |e_i|`, N·m.
    pub max_abs_error_nm: f64,
    /// Row (0-based) of the largest `|e_i|`.
    #[serde(default)]
    pub max_abs_row: usize,
    /// `√(Σ e_i² / n)`, N·m.
    pub rms_error_nm: f64,
    /// `Σ e_i / n`, N·m (positive: the calibrated sensor reads high).
    pub mean_error_nm: f64,
    /// Full-scale torque the percentages refer to, N·m.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub full_scale_nm: Option<f64>,
    /// `100 · RMS / FS`, %.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rms_percent_fs: Option<f64>,
    /// `100 · max|e| / FS`, %.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_abs_percent_fs: Option<f64>,
}

/// Error metrics of calibrated torques against reference torques (both N·m), with
/// `e_i = calibrated_i − reference_i`; `full_scale_nm` (> 0) enables the %FS figures.
///
/// ```
/// use strainwave_analysis::calibration::error_metrics;
/// let m = error_metrics(&[1.0, 2.3, 2.9], &[1.0, 2.0, 3.0], Some(20.0)).unwrap();
/// assert!((m.max_abs_error_nm - 0.3).abs() < 1e-12);
/// assert!((m.rms_error_nm - (0.1f64 / 3.0).sqrt()).abs() < 1e-12);
/// assert!((m.rms_percent_fs.unwrap() - 100.0 * m.rms_error_nm / 20.0).abs() < 1e-12);
/// ```
pub fn error_metrics(
    calibrated_nm: &[f64],
    reference_nm: &[f64],
    full_scale_nm: Option<f64>,
) -> Result<ErrorMetrics, CalibrationError> {
    let n = check_columns("error metrics", &[("calibrated_nm", calibrated_nm), ("reference_nm", reference_nm)])?;
    if n == 0 {
        return Err(CalibrationError::TooFewRows { what: "error metrics".into(), needed: 1, got: 0 });
    }
    if let Some(fs) = full_scale_nm {
        if !(fs.is_finite() && fs > 0.0) {
            return Err(invalid("full_scale_nm", format!("must be a positive finite torque, got {fs}")));
        }
    }
    let (mut max_abs, mut max_row, mut sum, mut sum2) = (0.0f64, 0usize, 0.0, 0.0);
    for (i, (c, r)) in calibrated_nm.iter().zip(reference_nm).enumerate() {
        let e = c - r;
        if e.abs() > max_abs {
            max_abs = e.abs();
            max_row = i;
        }
        sum += e;
        sum2 += e * e;
    }
    let rms = (sum2 / n as f64).sqrt();
    Ok(ErrorMetrics {
        rows: n,
        max_abs_error_nm: max_abs,
        max_abs_row: max_row,
        rms_error_nm: rms,
        mean_error_nm: sum / n as f64,
        full_scale_nm,
        rms_percent_fs: full_scale_nm.map(|fs| 100.0 * rms / fs),
        max_abs_percent_fs: full_scale_nm.map(|fs| 100.0 * max_abs / fs),
    })
}

/// All-zero metrics, overwritten once a fit is evaluated.
pub(super) fn placeholder_metrics() -> ErrorMetrics {
    ErrorMetrics {
        rows: 0,
        max_abs_error_nm: 0.0,
        max_abs_row: 0,
        rms_error_nm: 0.0,
        mean_error_nm: 0.0,
        full_scale_nm: None,
        rms_percent_fs: None,
        max_abs_percent_fs: None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const TIGHT: f64 = 1e-12;

    #[test]
    fn metrics_by_hand() {
        // e = (+0.3, −0.1, 0, −0.2): max 0.3, mean 0, RMS √(0.14/4).
        let m = error_metrics(&[1.3, 1.9, 3.0, 3.8], &[1.0, 2.0, 3.0, 4.0], Some(10.0)).unwrap();
        assert!((m.max_abs_error_nm - 0.3).abs() < TIGHT && m.max_abs_row == 0);
        assert!(m.mean_error_nm.abs() < TIGHT);
        assert!((m.rms_error_nm - 0.035f64.sqrt()).abs() < TIGHT);
        assert!((m.max_abs_percent_fs.unwrap() - 3.0).abs() < 1e-10);
        assert!(error_metrics(&[1.0], &[1.0], Some(0.0)).is_err());
        assert!(matches!(error_metrics(&[], &[], None), Err(CalibrationError::TooFewRows { .. })));
        assert!(matches!(
            error_metrics(&[1.0, f64::NAN], &[1.0, 2.0], None),
            Err(CalibrationError::NonFiniteRow { row: 1, column: "calibrated_nm", .. })
        ));
    }
}
