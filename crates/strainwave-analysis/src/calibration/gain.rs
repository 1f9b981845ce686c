//! Gain per experiment and the consistency across experiments (Taghirad and Bélanger (1999) §IV).

use super::{
    check_columns, error_metrics, invalid, require_two_values, CalibrationError, CalibrationFile, ErrorMetrics,
    ModelKind,
};
use crate::lstsq;

/// One calibration experiment: rows of (reference torque, sensor voltage).
#[derive(Debug, Clone, PartialEq)]
pub struct Experiment {
    /// Name used in reports and errors (e.g. `"FS at 90°, full range, 25 °C"`).
    pub label: String,
    /// Applied reference torque per row, N·m.
    pub reference_torque_nm: Vec<f64>,
    /// Sensor (bridge amplifier) voltage per row, V.
    pub sensor_v: Vec<f64>,
}

impl Experiment {
    /// An experiment from its columns.
    ///
    /// ```
    /// use strainwave_analysis::calibration::Experiment;
    /// let e = Experiment::new("loading, 0°", &[0.0, 6.6], &[0.0, 1.0]);
    /// assert_eq!(e.sensor_v.len(), 2);
    /// ```
    pub fn new(label: &str, reference_torque_nm: &[f64], sensor_v: &[f64]) -> Self {
        Self {
            label: label.to_string(),
            reference_torque_nm: reference_torque_nm.to_vec(),
            sensor_v: sensor_v.to_vec(),
        }
    }
}

/// The model fitted to each experiment.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum GainFit {
    /// `T = g V` (Taghirad and Bélanger (1999)).
    #[default]
    ThroughOrigin,
    /// `T = g V + c`, the offset absorbing a bridge zero error.
    WithOffset,
}

/// The fit of one experiment.
#[derive(Debug, Clone, PartialEq)]
pub struct ExperimentGain {
    /// The experiment's label.
    pub label: String,
    /// Gain `g`, N·m/V.
    pub gain_nm_per_v: f64,
    /// Offset `c`, N·m (0 through the origin).
    pub offset_nm: f64,
    /// Standard error of `g` from the residuals (`None` with no redundant row).
    pub gain_std_error_nm_per_v: Option<f64>,
    /// Error metrics of this experiment's own fit.
    pub metrics: ErrorMetrics,
}

/// Gains of several experiments and their consistency (Taghirad and Bélanger (1999) §IV).
#[derive(Debug, Clone, PartialEq)]
pub struct GainCalibration {
    /// The model fitted per experiment.
    pub fit: GainFit,
    /// One entry per experiment, in input order.
    pub experiments: Vec<ExperimentGain>,
    /// Final gain: the mean of the experiments' gains, N·m/V.
    pub gain_nm_per_v: f64,
    /// Final offset: mean of the offsets (0 through the origin), N·m.
    pub offset_nm: f64,
    /// Sample standard deviation of the gains (`n − 1`), N·m/V; `None` for one experiment.
    pub gain_std_nm_per_v: Option<f64>,
    /// Consistency `s_g / |ḡ|` as a fraction (0.02 = 2 %); `None` for one experiment.
    pub consistency: Option<f64>,
    /// Metrics of the final gain (and offset) over all rows of all experiments.
    pub metrics: ErrorMetrics,
}

impl GainCalibration {
    /// Consistency in percent.
    pub fn consistency_percent(&self) -> Option<f64> {
        self.consistency.map(|c| 100.0 * c)
    }

    /// The calibration file: model `gain`, or `static` (α = g, β = c) with an offset.
    pub fn to_file(&self) -> CalibrationFile {
        let mut f = match self.fit {
            GainFit::ThroughOrigin => CalibrationFile::gain(self.gain_nm_per_v),
            GainFit::WithOffset => CalibrationFile::affine(ModelKind::Static, self.gain_nm_per_v, self.offset_nm),
        };
        f.metrics = Some(self.metrics);
        f
    }
}

/// Fits a gain to each experiment and combines them (Taghirad and Bélanger (1999) §IV).
///
/// Errors name the experiment: too few rows, a non-finite row, all voltages equal or
/// (with an offset) all torques equal, all voltages zero through the origin (singular),
/// or fewer than one experiment.
///
/// ```
/// use strainwave_analysis::calibration::{calibrate_gain, Experiment, GainFit};
/// let v = [0.5, 1.0, 1.5];
/// let e1 = Experiment::new("a", &[3.234, 6.468, 9.702], &v); // g = 6.468
/// let e2 = Experiment::new("b", &[3.366, 6.732, 10.098], &v); // g = 6.732
/// let g = calibrate_gain(&[e1, e2], GainFit::ThroughOrigin, None).unwrap();
/// assert!((g.gain_nm_per_v - 6.6).abs() < 1e-12);
/// // Sample std of {6.468, 6.732} is 0.132·√2; consistency = that / 6.6.
/// assert!((g.consistency.unwrap() - 0.132 * 2f64.sqrt() / 6.6).abs() < 1e-12);
/// ```
pub fn calibrate_gain(
    experiments: &[Experiment],
    fit: GainFit,
    full_scale_nm: Option<f64>,
) -> Result<GainCalibration, CalibrationError> {
    if experiments.is_empty() {
        return Err(CalibrationError::TooFewRows { what: "experiments".into(), needed: 1, got: 0 });
    }
    let mut out = Vec::with_capacity(experiments.len());
    for e in experiments {
        let what = format!("experiment `{}`", e.label);
        let n = check_columns(&what, &[("reference_torque_nm", &e.reference_torque_nm), ("sensor_v", &e.sensor_v)])?;
        let needed = match fit {
            GainFit::ThroughOrigin => 1,
            GainFit::WithOffset => 2,
        };
        if n < needed {
            return Err(CalibrationError::TooFewRows { what, needed, got: n });
        }
        let (gain, offset, se) = match fit {
            GainFit::ThroughOrigin => {
                if e.sensor_v.iter().all(|&v| v == 0.0) {
                    return Err(CalibrationError::SingleValue { what, column: "sensor_v", rows: n, value: 0.0 });
                }
                let s = lstsq::lstsq(&e.sensor_v, 1, &e.reference_torque_nm)?;
                (s.x[0], 0.0, s.std_errors().map(|v| v[0]))
            }
            GainFit::WithOffset => {
                require_two_values(&what, "sensor_v", &e.sensor_v)?;
                require_two_values(&what, "reference_torque_nm", &e.reference_torque_nm)?;
                let p = lstsq::polyfit(&e.sensor_v, &e.reference_torque_nm, 1)?;
                (p.coeffs[1], p.coeffs[0], p.std_errors().map(|v| v[1]))
            }
        };
        let cal: Vec<f64> = e.sensor_v.iter().map(|v| gain * v + offset).collect();
        let metrics = error_metrics(&cal, &e.reference_torque_nm, full_scale_nm)?;
        out.push(ExperimentGain {
            label: e.label.clone(),
            gain_nm_per_v: gain,
            offset_nm: offset,
            gain_std_error_nm_per_v: se,
            metrics,
        });
    }
    let k = out.len() as f64;
    let mean = out.iter().map(|g| g.gain_nm_per_v).sum::<f64>() / k;
    let offset = out.iter().map(|g| g.offset_nm).sum::<f64>() / k;
    let std =
        (out.len() > 1).then(|| (out.iter().map(|g| (g.gain_nm_per_v - mean).powi(2)).sum::<f64>() / (k - 1.0)).sqrt());
    if mean == 0.0 {
        return Err(invalid("gain", "the mean gain is zero; consistency std/mean is undefined"));
    }
    let (mut cal, mut refs) = (Vec::new(), Vec::new());
    for e in experiments {
        cal.extend(e.sensor_v.iter().map(|v| mean * v + offset));
        refs.extend_from_slice(&e.reference_torque_nm);
    }
    let metrics = error_metrics(&cal, &refs, full_scale_nm)?;
    Ok(GainCalibration {
        fit,
        experiments: out,
        gain_nm_per_v: mean,
        offset_nm: offset,
        gain_std_nm_per_v: std,
        consistency: std.map(|s| s / mean.abs()),
        metrics,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    const TIGHT: f64 = 1e-12;

    #[test]
    fn gain_errors_name_the_experiment() {
        let e = Experiment::new("cold", &[1.0, 2.0], &[0.0, 0.0]);
        let err = calibrate_gain(&[e], GainFit::ThroughOrigin, None).unwrap_err();
        assert!(err.to_string().contains("`cold`") && err.to_string().contains("singular"), "{err}");
        let e = Experiment::new("hot", &[1.0, 2.0], &[0.1, f64::NAN]);
        let err = calibrate_gain(&[e], GainFit::WithOffset, None).unwrap_err();
        assert_eq!(err, CalibrationError::NonFiniteRow { what: "experiment `hot`".into(), row: 1, column: "sensor_v" });
        let e = Experiment::new("one", &[1.0], &[0.1]);
        assert!(matches!(
            calibrate_gain(&[e], GainFit::WithOffset, None),
            Err(CalibrationError::TooFewRows { needed: 2, got: 1, .. })
        ));
        assert!(calibrate_gain(&[], GainFit::ThroughOrigin, None).is_err());
    }

    #[test]
    fn gain_with_offset_and_single_experiment() {
        let v = [0.0, 1.0, 2.0];
        let e = Experiment::new("x", &[0.5, 7.1, 13.7], &v);
        let g = calibrate_gain(&[e], GainFit::WithOffset, Some(20.0)).unwrap();
        assert!((g.gain_nm_per_v - 6.6).abs() < TIGHT && (g.offset_nm - 0.5).abs() < TIGHT);
        assert!(g.consistency.is_none() && g.gain_std_nm_per_v.is_none());
        let f = g.to_file();
        assert_eq!(f.model, ModelKind::Static);
        assert!(f.validate().is_ok());
    }
}
