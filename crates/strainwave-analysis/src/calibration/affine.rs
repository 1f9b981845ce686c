//! Static and dynamic affine models `T_ref = α x + β` (the embedded-sensor article).

use super::{
    check_columns, error_metrics, require_two_values, CalibrationError, CalibrationFile, ErrorMetrics, ModelKind,
};
use crate::lstsq;

/// An affine fit `T_ref = α x + β`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AffineFit {
    /// Slope α (N·m per sensor unit; dimensionless when the sensor reads N·m).
    pub alpha: f64,
    /// Intercept β, N·m.
    pub beta_nm: f64,
    /// Standard error of α (`None` with exactly two rows).
    pub alpha_std_error: Option<f64>,
    /// Standard error of β, N·m.
    pub beta_std_error_nm: Option<f64>,
    /// Metrics of `α x + β` against the reference.
    pub metrics: ErrorMetrics,
}

impl AffineFit {
    /// The calibration file of a static (quasi-static ramp) fit.
    pub fn to_static_file(&self) -> CalibrationFile {
        let mut f = CalibrationFile::affine(ModelKind::Static, self.alpha, self.beta_nm);
        f.metrics = Some(self.metrics);
        f
    }

    /// The calibration file of a dynamic (sinusoidal load) fit, speed-independent.
    pub fn to_dynamic_file(&self) -> CalibrationFile {
        let mut f = CalibrationFile::affine(ModelKind::Dynamic, self.alpha, self.beta_nm);
        f.metrics = Some(self.metrics);
        f
    }
}

/// Fits `T_ref = α · sensor + β` by least squares (QR); the embedded-sensor article's static and dynamic rows.
///
/// Errors: fewer than 2 rows, a non-finite row (named), all sensor values equal or all
/// reference torques equal (one load: singular).
///
/// ```
/// use strainwave_analysis::calibration::fit_affine;
/// let x = [0.0, 5.0, 10.0];
/// let t: Vec<f64> = x.iter().map(|v| 1.284 * v - 0.0812).collect();
/// let f = fit_affine(&x, &t, Some(20.0)).unwrap();
/// assert!((f.alpha - 1.284).abs() < 1e-12 && (f.beta_nm + 0.0812).abs() < 1e-12);
/// ```
pub fn fit_affine(
    sensor: &[f64],
    reference_nm: &[f64],
    full_scale_nm: Option<f64>,
) -> Result<AffineFit, CalibrationError> {
    let what = "affine fit";
    let n = check_columns(what, &[("sensor", sensor), ("reference_nm", reference_nm)])?;
    if n < 2 {
        return Err(CalibrationError::TooFewRows { what: what.into(), needed: 2, got: n });
    }
    require_two_values(what, "sensor", sensor)?;
    // One load only: the sensor's scatter would set the slope.
    require_two_values(what, "reference_nm", reference_nm)?;
    let p = lstsq::polyfit(sensor, reference_nm, 1)?;
    let (alpha, beta_nm) = (p.coeffs[1], p.coeffs[0]);
    let se = p.std_errors();
    let cal: Vec<f64> = sensor.iter().map(|x| alpha * x + beta_nm).collect();
    Ok(AffineFit {
        alpha,
        beta_nm,
        alpha_std_error: se.as_ref().map(|s| s[1]),
        beta_std_error_nm: se.as_ref().map(|s| s[0]),
        metrics: error_metrics(&cal, reference_nm, full_scale_nm)?,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn affine_single_load_is_singular() {
        let err = fit_affine(&[3.0; 4], &[1.0, 2.0, 3.0, 4.0], None).unwrap_err();
        assert!(matches!(err, CalibrationError::SingleValue { column: "sensor", rows: 4, .. }));
        assert!(err.to_string().contains("singular"));
        let err = fit_affine(&[0.74, 0.75, 0.76], &[5.0; 3], None).unwrap_err();
        assert!(matches!(err, CalibrationError::SingleValue { column: "reference_nm", rows: 3, .. }), "{err}");
        assert!(matches!(fit_affine(&[1.0], &[1.0], None), Err(CalibrationError::TooFewRows { .. })));
        assert!(matches!(
            fit_affine(&[1.0, 2.0], &[1.0], None),
            Err(CalibrationError::LengthMismatch { column: "reference_nm", .. })
        ));
    }
}
