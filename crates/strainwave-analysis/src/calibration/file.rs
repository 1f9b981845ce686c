//! The calibration file (TOML, units in key names) that carries a fitted model to the
//! controller, rejecting NaN/∞ on write and on read.

use std::path::Path;

use serde::{Deserialize, Serialize};
use strainwave_core::calibration::Calibration;

use super::{check_columns, invalid, CalibrationError, ErrorMetrics, Extrapolation, MAX_TABLE_LEN};

/// The model form stored in a calibration file (`model = "…"`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum ModelKind {
    /// `T = g V`: key `gain_nm_per_v`.
    Gain,
    /// `T = α x + β` from quasi-static ramps: keys `alpha`, `beta_nm` (numbers).
    Static,
    /// `T = α x + β` from sinusoidal-load data, speed-independent: same keys.
    Dynamic,
    /// Table: `speed_rad_s`, `alpha`, `beta_nm` (arrays of equal length), `extrapolation`.
    #[serde(alias = "speed_table")]
    SpeedTable,
    /// Polynomials: `alpha`, `beta_nm` (coefficients lowest order first, per (rad/s)^k),
    /// `speed_range_rad_s = [min, max]`, `extrapolation`.
    #[serde(alias = "speed_poly")]
    SpeedPoly,
}

impl std::str::FromStr for ModelKind {
    type Err = String;

    /// `gain`, `static`, `dynamic`, `speed-table` or `speed-poly` (the snake spellings are
    /// accepted); the error lists them.
    fn from_str(name: &str) -> Result<Self, String> {
        use ModelKind::*;
        let table = [
            ("gain", Gain),
            ("static", Static),
            ("dynamic", Dynamic),
            ("speed-table", SpeedTable),
            ("speed-poly", SpeedPoly),
            ("speed_table", SpeedTable),
            ("speed_poly", SpeedPoly),
        ];
        crate::choice::parse(name, &table, 5)
    }
}

impl ModelKind {
    fn name(self) -> &'static str {
        match self {
            ModelKind::Gain => "gain",
            ModelKind::Static => "static",
            ModelKind::Dynamic => "dynamic",
            ModelKind::SpeedTable => "speed-table",
            ModelKind::SpeedPoly => "speed-poly",
        }
    }
}

/// A coefficient: one number (static/dynamic) or an array (table values, polynomial).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum Coefficients {
    /// One number.
    Scalar(f64),
    /// An array.
    List(Vec<f64>),
}

/// A calibration file (TOML). Units are in the key names; keys that do not belong to
/// the model are refused. Example:
///
/// ```toml
/// model = "speed-table"          # gain | static | dynamic | speed-table | speed-poly
/// extrapolation = "clamp"        # clamp | linear | reject (speed models only, required)
/// speed_rad_s = [0.5, 2.0, 4.0]  # breakpoints, strictly increasing
/// alpha = [1.55, 1.57, 1.60]
/// beta_nm = [-0.090, -0.093, -0.100]
///
/// [metrics]
/// rows = 1200
/// max_abs_error_nm = 0.64
/// rms_error_nm = 0.265
/// mean_error_nm = 0.0
/// full_scale_nm = 20.87
/// rms_percent_fs = 1.27
/// ```
///
/// ```
/// use strainwave_analysis::calibration::CalibrationFile;
/// let f = CalibrationFile::from_toml_str("model = \"static\"\nalpha = 1.284\nbeta_nm = -0.0812\n").unwrap();
/// let cal = f.to_core::<f64, 1>().unwrap();
/// assert!((cal.apply(10.0, 0.0).unwrap() - 12.7588).abs() < 1e-12);
/// assert!(CalibrationFile::from_toml_str("model = \"static\"\nalpha = nan\nbeta_nm = 0.0\n").is_err());
/// ```
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CalibrationFile {
    /// The model form.
    pub model: ModelKind,
    /// Free text: sensor, date, test conditions.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub description: Option<String>,
    /// Policy outside the speed range (speed models, required there).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub extrapolation: Option<Extrapolation>,
    /// Gain, N·m/V (model `gain`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gain_nm_per_v: Option<f64>,
    /// Table breakpoints, rad/s (model `speed-table`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub speed_rad_s: Option<Vec<f64>>,
    /// `[min, max]` fitted speed range, rad/s (model `speed-poly`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub speed_range_rad_s: Option<Vec<f64>>,
    /// α: a number (static, dynamic), table values or polynomial coefficients.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub alpha: Option<Coefficients>,
    /// β, N·m: as `alpha`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub beta_nm: Option<Coefficients>,
    /// Fit metrics.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub metrics: Option<ErrorMetrics>,
}

/// The torques of a calibration applied to a recording.
#[derive(Debug, Clone, PartialEq)]
pub struct Evaluation {
    /// Calibrated torque per row, N·m.
    pub torque_nm: Vec<f64>,
    /// Rows whose speed was outside the range and extrapolated by the policy.
    pub extrapolated_rows: Vec<usize>,
}

impl CalibrationFile {
    /// A `gain` file.
    ///
    /// ```
    /// use strainwave_analysis::calibration::CalibrationFile;
    /// let f = CalibrationFile::gain(6.60);
    /// assert!(f.to_toml_string().unwrap().contains("gain_nm_per_v = 6.6"));
    /// ```
    pub fn gain(gain_nm_per_v: f64) -> Self {
        Self {
            model: ModelKind::Gain,
            description: None,
            gain_nm_per_v: Some(gain_nm_per_v),
            alpha: None,
            beta_nm: None,
            speed_rad_s: None,
            speed_range_rad_s: None,
            extrapolation: None,
            metrics: None,
        }
    }

    /// A `static` or `dynamic` file (`model` must be one of those; other kinds give a
    /// file that [`Self::validate`] refuses).
    ///
    /// ```
    /// use strainwave_analysis::calibration::{CalibrationFile, ModelKind};
    /// let f = CalibrationFile::affine(ModelKind::Dynamic, 1.572, -0.0928);
    /// assert!(f.validate().is_ok());
    /// ```
    pub fn affine(model: ModelKind, alpha: f64, beta_nm: f64) -> Self {
        Self {
            model,
            alpha: Some(Coefficients::Scalar(alpha)),
            beta_nm: Some(Coefficients::Scalar(beta_nm)),
            gain_nm_per_v: None,
            ..Self::gain(0.0)
        }
    }

    /// Parses and validates TOML text (NaN/∞ refused with the key named).
    pub fn from_toml_str(text: &str) -> Result<Self, CalibrationError> {
        let f: Self = toml::from_str(text).map_err(|e| CalibrationError::Toml(toml_error_line(text, &e)))?;
        f.validate()?;
        Ok(f)
    }

    /// Validates, then writes TOML text.
    pub fn to_toml_string(&self) -> Result<String, CalibrationError> {
        self.validate()?;
        toml::to_string(self).map_err(|e| CalibrationError::Toml(e.to_string()))
    }

    /// Reads a file.
    pub fn load(path: &Path) -> Result<Self, CalibrationError> {
        let text = std::fs::read_to_string(path)
            .map_err(|e| CalibrationError::Io { path: path.display().to_string(), message: e.to_string() })?;
        // The file named in front of what is wrong in it.
        Self::from_toml_str(&text)
            .map_err(|e| CalibrationError::Io { path: path.display().to_string(), message: e.to_string() })
    }

    /// Writes a file.
    pub fn save(&self, path: &Path) -> Result<(), CalibrationError> {
        let text = self.to_toml_string()?;
        std::fs::write(path, text)
            .map_err(|e| CalibrationError::Io { path: path.display().to_string(), message: e.to_string() })
    }

    /// Every number finite, the keys those of the model, the coefficients acceptable
    /// to the core (increasing breakpoints, lengths, non-zero gain …).
    pub fn validate(&self) -> Result<(), CalibrationError> {
        self.check_finite()?;
        self.to_core::<f64, MAX_TABLE_LEN>().map(|_| ())
    }

    fn check_finite(&self) -> Result<(), CalibrationError> {
        let bad = |key: String| Err(CalibrationError::NonFiniteKey { key });
        let check_list = |key: &str, v: &[f64]| -> Result<(), CalibrationError> {
            match v.iter().position(|x| !x.is_finite()) {
                Some(i) => bad(format!("{key}[{i}]")),
                None => Ok(()),
            }
        };
        let check_coeffs = |key: &str, c: &Option<Coefficients>| -> Result<(), CalibrationError> {
            match c {
                Some(Coefficients::Scalar(x)) if !x.is_finite() => bad(key.to_string()),
                Some(Coefficients::List(v)) => check_list(key, v),
                _ => Ok(()),
            }
        };
        if let Some(g) = self.gain_nm_per_v {
            if !g.is_finite() {
                return bad("gain_nm_per_v".into());
            }
        }
        check_coeffs("alpha", &self.alpha)?;
        check_coeffs("beta_nm", &self.beta_nm)?;
        if let Some(v) = &self.speed_rad_s {
            check_list("speed_rad_s", v)?;
        }
        if let Some(v) = &self.speed_range_rad_s {
            check_list("speed_range_rad_s", v)?;
        }
        if let Some(m) = &self.metrics {
            let fields = [
                ("max_abs_error_nm", Some(m.max_abs_error_nm)),
                ("rms_error_nm", Some(m.rms_error_nm)),
                ("mean_error_nm", Some(m.mean_error_nm)),
                ("full_scale_nm", m.full_scale_nm),
                ("rms_percent_fs", m.rms_percent_fs),
                ("max_abs_percent_fs", m.max_abs_percent_fs),
            ];
            for (k, v) in fields {
                if let Some(x) = v {
                    if !x.is_finite() {
                        return bad(format!("metrics.{k}"));
                    }
                }
            }
        }
        Ok(())
    }

    fn absent<T>(&self, key: &'static str, v: &Option<T>) -> Result<(), CalibrationError> {
        match v {
            Some(_) => {
                Err(CalibrationError::FileKey { key, why: format!("does not belong to model `{}`", self.model.name()) })
            }
            None => Ok(()),
        }
    }

    fn required<'a, T>(&self, key: &'static str, v: &'a Option<T>) -> Result<&'a T, CalibrationError> {
        v.as_ref()
            .ok_or_else(|| CalibrationError::FileKey { key, why: format!("required by model `{}`", self.model.name()) })
    }

    fn scalar(&self, key: &'static str, c: &Option<Coefficients>) -> Result<f64, CalibrationError> {
        match self.required(key, c)? {
            Coefficients::Scalar(x) => Ok(*x),
            Coefficients::List(_) => Err(CalibrationError::FileKey {
                key,
                why: format!("must be a number for model `{}`", self.model.name()),
            }),
        }
    }

    fn list<'a>(&self, key: &'static str, c: &'a Option<Coefficients>) -> Result<&'a [f64], CalibrationError> {
        match self.required(key, c)? {
            Coefficients::List(v) => Ok(v),
            Coefficients::Scalar(_) => Err(CalibrationError::FileKey {
                key,
                why: format!("must be an array for model `{}`", self.model.name()),
            }),
        }
    }

    /// The core calibration for the controller, in `f32` or `f64`, with room for `K`
    /// breakpoints/coefficients (`K` ≥ the table length).
    ///
    /// ```
    /// use strainwave_analysis::calibration::CalibrationFile;
    /// let cal = CalibrationFile::gain(6.6).to_core::<f32, 1>().unwrap();
    /// assert!((cal.apply(1.0, 0.0).unwrap() - 6.6).abs() < 1e-6);
    /// ```
    pub fn to_core<T: strainwave_core::Real, const K: usize>(&self) -> Result<Calibration<T, K>, CalibrationError> {
        self.check_finite()?;
        let f = T::from_f64;
        let conv = |v: &[f64]| -> Vec<T> { v.iter().map(|&x| f(x)).collect() };
        match self.model {
            ModelKind::Gain => {
                self.absent("alpha", &self.alpha)?;
                self.absent("beta_nm", &self.beta_nm)?;
                self.absent("speed_rad_s", &self.speed_rad_s)?;
                self.absent("speed_range_rad_s", &self.speed_range_rad_s)?;
                self.absent("extrapolation", &self.extrapolation)?;
                let g = *self.required("gain_nm_per_v", &self.gain_nm_per_v)?;
                Ok(Calibration::gain(f(g))?)
            }
            ModelKind::Static | ModelKind::Dynamic => {
                self.absent("gain_nm_per_v", &self.gain_nm_per_v)?;
                self.absent("speed_rad_s", &self.speed_rad_s)?;
                self.absent("speed_range_rad_s", &self.speed_range_rad_s)?;
                self.absent("extrapolation", &self.extrapolation)?;
                let a = self.scalar("alpha", &self.alpha)?;
                let b = self.scalar("beta_nm", &self.beta_nm)?;
                Ok(Calibration::affine(f(a), f(b))?)
            }
            ModelKind::SpeedTable => {
                self.absent("gain_nm_per_v", &self.gain_nm_per_v)?;
                self.absent("speed_range_rad_s", &self.speed_range_rad_s)?;
                let e = *self.required("extrapolation", &self.extrapolation)?;
                let s = self.required("speed_rad_s", &self.speed_rad_s)?;
                let a = self.list("alpha", &self.alpha)?;
                let b = self.list("beta_nm", &self.beta_nm)?;
                if a.len() != s.len() || b.len() != s.len() {
                    return Err(CalibrationError::FileKey {
                        key: if a.len() != s.len() { "alpha" } else { "beta_nm" },
                        why: format!("must have one value per breakpoint ({})", s.len()),
                    });
                }
                if s.len() > K {
                    return Err(CalibrationError::FileKey {
                        key: "speed_rad_s",
                        why: format!("{} breakpoints exceed the capacity {K}", s.len()),
                    });
                }
                Ok(Calibration::speed_table(&conv(s), &conv(a), &conv(b), e.into())?)
            }
            ModelKind::SpeedPoly => {
                self.absent("gain_nm_per_v", &self.gain_nm_per_v)?;
                self.absent("speed_rad_s", &self.speed_rad_s)?;
                let e = *self.required("extrapolation", &self.extrapolation)?;
                let r = self.required("speed_range_rad_s", &self.speed_range_rad_s)?;
                if r.len() != 2 {
                    return Err(CalibrationError::FileKey {
                        key: "speed_range_rad_s",
                        why: "must be [min, max]".into(),
                    });
                }
                let a = self.list("alpha", &self.alpha)?;
                let b = self.list("beta_nm", &self.beta_nm)?;
                Ok(Calibration::speed_polynomial(&conv(a), &conv(b), f(r[0]), f(r[1]), e.into())?)
            }
        }
    }

    /// Applies the calibration to a recording: `sensor` per row and, for speed models,
    /// `speed_rad_s` per row. Rows beyond the speed range are listed; under
    /// `extrapolation = "reject"` the first such row is an error that names it.
    pub fn apply(&self, sensor: &[f64], speed_rad_s: Option<&[f64]>) -> Result<Evaluation, CalibrationError> {
        let cal = self.to_core::<f64, MAX_TABLE_LEN>()?;
        let range = cal.speed_range_rad_s();
        let speed = match (range, speed_rad_s) {
            (Some(_), None) => {
                return Err(invalid("speed_rad_s", format!("model `{}` needs a speed per row", self.model.name())))
            }
            (_, Some(w)) => {
                check_columns("apply calibration", &[("sensor", sensor), ("speed_rad_s", w)])?;
                Some(w)
            }
            (None, None) => {
                check_columns("apply calibration", &[("sensor", sensor)])?;
                None
            }
        };
        let mut out = Evaluation { torque_nm: Vec::with_capacity(sensor.len()), extrapolated_rows: Vec::new() };
        for (row, &x) in sensor.iter().enumerate() {
            let w = speed.map_or(0.0, |w| w[row]);
            match cal.apply_flagged(x, w) {
                Ok(a) => {
                    if a.extrapolated {
                        out.extrapolated_rows.push(row);
                    }
                    out.torque_nm.push(a.torque_nm);
                }
                Err(strainwave_core::Error::OutOfRange("speed_rad_s")) => {
                    let (min_rad_s, max_rad_s) = range.unwrap_or((0.0, 0.0));
                    return Err(CalibrationError::SpeedOutsideTable { row, speed_rad_s: w, min_rad_s, max_rad_s });
                }
                Err(e) => return Err(e.into()),
            }
        }
        Ok(out)
    }
}

/// A TOML error on one line: `line L, column C: key `K`: message`, the key as the user
/// wrote it when the error is a value's (the `toml` crate's own text draws the offending
/// line over several).
pub fn toml_error_line(text: &str, e: &toml::de::Error) -> String {
    let at = e.span().map_or(String::new(), |s| {
        let before = text.get(..s.start).unwrap_or(text);
        let line = before.matches('\n').count() + 1;
        let column = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
        let key = toml_key_at(before).map_or(String::new(), |k| format!("{k}: "));
        format!("line {line}, column {column}: {key}")
    });
    format!("{at}{}", e.message().trim().replace('\n', "; "))
}

/// The key whose value starts at the end of `before` (the text up to an error's span),
/// as the user wrote it, in backticks: the table header above it joined with the key on
/// its own line (`` `filter.model` ``), or in an array of tables the entry, counted from 1,
/// and the key (`` `[[orders]]` entry 2, `multiple` ``). `None` unless the line is a plain
/// `key = value`.
pub fn toml_key_at(before: &str) -> Option<String> {
    let mut lines = before.rsplit('\n');
    let current = lines.next()?;
    let (key, _) = current.split_once('=')?;
    let key = key.trim().trim_matches('"');
    if key.is_empty() || key.contains(['[', '{', ',']) {
        return None;
    }
    let header = lines.map(str::trim).find(|l| l.starts_with('['));
    let name = |h: &str| h.trim_start_matches('[').split(']').next().unwrap_or("").trim().to_string();
    Some(match header {
        Some(h) if h.starts_with("[[") => {
            let n = before.lines().filter(|l| l.trim().starts_with("[[") && name(l) == name(h)).count();
            format!("`[[{}]]` entry {n}, `{key}`", name(h))
        }
        Some(h) if !name(h).is_empty() => format!("`{}.{key}`", name(h)),
        _ => format!("`{key}`"),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::calibration::metrics::placeholder_metrics;

    #[test]
    fn file_rejects_non_finite_and_misplaced_keys() {
        let err = CalibrationFile::from_toml_str(
            "model = \"speed_table\"\nextrapolation = \"clamp\"\nspeed_rad_s = [0.0, 1.0]\nalpha = [1.0, inf]\nbeta_nm = [0.0, 0.0]\n",
        )
        .unwrap_err();
        assert_eq!(err, CalibrationError::NonFiniteKey { key: "alpha[1]".into() });
        let mut f = CalibrationFile::gain(f64::NAN);
        assert_eq!(f.to_toml_string().unwrap_err(), CalibrationError::NonFiniteKey { key: "gain_nm_per_v".into() });
        f.gain_nm_per_v = Some(6.6);
        f.metrics = Some(ErrorMetrics { rms_error_nm: f64::NAN, ..placeholder_metrics() });
        assert_eq!(
            f.to_toml_string().unwrap_err(),
            CalibrationError::NonFiniteKey { key: "metrics.rms_error_nm".into() }
        );
        let err = CalibrationFile::from_toml_str("model = \"gain\"\ngain_nm_per_v = 6.6\nalpha = 1.0\n").unwrap_err();
        assert!(matches!(err, CalibrationError::FileKey { key: "alpha", .. }), "{err}");
        let err = CalibrationFile::from_toml_str(
            "model = \"speed_table\"\nspeed_rad_s = [0.0, 1.0]\nalpha = [1.0, 1.0]\nbeta_nm = [0.0, 0.0]\n",
        )
        .unwrap_err();
        assert!(matches!(err, CalibrationError::FileKey { key: "extrapolation", .. }), "{err}");
        let err = CalibrationFile::from_toml_str(
            "model = \"speed_table\"\nextrapolation = \"clamp\"\nspeed_rad_s = [1.0, 0.0]\nalpha = [1.0, 1.0]\nbeta_nm = [0.0, 0.0]\n",
        )
        .unwrap_err();
        assert_eq!(err, CalibrationError::Core(strainwave_core::Error::NotIncreasing("speed_rad_s")));
        let err = CalibrationFile::from_toml_str("model = \"static\"\nalpha = [1.0]\nbeta_nm = 0.0\n").unwrap_err();
        assert!(matches!(err, CalibrationError::FileKey { key: "alpha", .. }));
        let err = CalibrationFile::from_toml_str("model = \"gains\"\n").unwrap_err();
        assert!(matches!(err, CalibrationError::Toml(_)), "{err}");
        let err =
            CalibrationFile::from_toml_str("model = \"gain\"\ngain_nm_per_v = 1.0\nunknown_key = 1\n").unwrap_err();
        assert!(err.to_string().contains("unknown_key"), "{err}");
        // Capacity of the caller's K.
        let t = CalibrationFile::from_toml_str(
            "model = \"speed_table\"\nextrapolation = \"clamp\"\nspeed_rad_s = [0.0, 1.0, 2.0]\nalpha = [1.0, 1.0, 1.0]\nbeta_nm = [0.0, 0.0, 0.0]\n",
        )
        .unwrap();
        assert!(matches!(t.to_core::<f32, 2>(), Err(CalibrationError::FileKey { key: "speed_rad_s", .. })));
    }

    #[test]
    fn speed_poly_file_round_trip() {
        let text = "model = \"speed_poly\"\nextrapolation = \"linear\"\nspeed_range_rad_s = [-5.0, 5.0]\n\
                    alpha = [1.5, 0.01]\nbeta_nm = [-0.09]\n";
        let f = CalibrationFile::from_toml_str(text).unwrap();
        let c = f.to_core::<f32, 4>().unwrap();
        assert!((c.apply(2.0, 7.0).unwrap() - (2.0 * 1.57 - 0.09)).abs() < 1e-5);
        let again = CalibrationFile::from_toml_str(&f.to_toml_string().unwrap()).unwrap();
        assert_eq!(again, f);
        // Written kebab-case, as every value; the snake spelling (older files) still loads.
        assert!(f.to_toml_string().unwrap().contains("model = \"speed-poly\""));
        assert_eq!(CalibrationFile::from_toml_str(&text.replace("speed_poly", "speed-poly")).unwrap(), f);
        let e = CalibrationFile::from_toml_str(&text.replace("speed_poly", "speed_spline")).unwrap_err().to_string();
        assert!(e.contains("line 1, column 9: `model`: unknown variant `speed_spline`"), "{e}");
        assert!(e.contains("`speed-table`") && !e.contains('\n'), "{e}");
    }
}
