//! What `calibrate --summary-json` writes: the fitted coefficients with their standard
//! errors, the fit statistics, and the rows read, used and left out.
//!
//! Standard errors come from the residuals of each least-squares fit
//! (`s² (AᵀA)⁻¹`, computed by `strainwave_analysis`); where a model has none (a speed
//! polynomial) the value is `null` and `std_error_source` says why.

use serde_json::{json, Value};
use strainwave_analysis::calibration::{fit_affine, AffineFit, ErrorMetrics, GainCalibration, SpeedFit};

fn finite(x: f64) -> Value {
    if x.is_finite() {
        json!(x)
    } else {
        Value::Null
    }
}

fn opt(x: Option<f64>) -> Value {
    x.map_or(Value::Null, finite)
}

/// One named coefficient.
fn coef(name: &str, value: f64, std_error: Option<f64>) -> Value {
    json!({ "name": name, "value": finite(value), "std_error": opt(std_error) })
}

/// Fit statistics of a calibration over the rows it was scored on; R² when the
/// reference of exactly those rows is known.
pub fn statistics(m: &ErrorMetrics, reference_nm: &[f64]) -> Value {
    let r_squared = if m.rows == reference_nm.len() && m.rows > 1 {
        let mean = reference_nm.iter().sum::<f64>() / m.rows as f64;
        let sst: f64 = reference_nm.iter().map(|t| (t - mean) * (t - mean)).sum();
        (sst > 0.0).then(|| 1.0 - m.rows as f64 * m.rms_error_nm * m.rms_error_nm / sst)
    } else {
        None
    };
    json!({
        "rows": m.rows,
        "r_squared": opt(r_squared),
        "rms_error_nm": finite(m.rms_error_nm),
        "mean_error_nm": finite(m.mean_error_nm),
        "max_abs_error_nm": finite(m.max_abs_error_nm),
        // 1-based among the rows used (after --held), in input order.
        "max_abs_used_row": m.max_abs_row + 1,
        "full_scale_nm": opt(m.full_scale_nm),
        "rms_percent_fs": opt(m.rms_percent_fs),
        "max_abs_percent_fs": opt(m.max_abs_percent_fs),
    })
}

/// Coefficients of a gain calibration: the final gain (the experiments' mean, its
/// standard error `s_g / √m` over `m` experiments, or the single experiment's own), the
/// offset, and each experiment's fit.
pub fn gain(g: &GainCalibration) -> (Value, &'static str, Vec<Value>) {
    let m = g.experiments.len();
    let gain_se = match (g.gain_std_nm_per_v, m) {
        (Some(s), m) if m > 1 => Some(s / (m as f64).sqrt()),
        _ => g.experiments.first().and_then(|e| e.gain_std_error_nm_per_v),
    };
    let mut c = vec![coef("gain_nm_per_v", g.gain_nm_per_v, gain_se)];
    if g.experiments.iter().any(|e| e.offset_nm != 0.0) || g.offset_nm != 0.0 {
        c.push(coef("offset_nm", g.offset_nm, None));
    }
    let per: Vec<Value> = g
        .experiments
        .iter()
        .map(|e| {
            json!({
                "label": e.label,
                "gain_nm_per_v": finite(e.gain_nm_per_v),
                "gain_std_error_nm_per_v": opt(e.gain_std_error_nm_per_v),
                "offset_nm": finite(e.offset_nm),
                "rms_error_nm": finite(e.metrics.rms_error_nm),
                "rows": e.metrics.rows,
            })
        })
        .collect();
    let source = if m > 1 {
        "gain: spread of the experiments' gains / sqrt(experiments); offset: none"
    } else {
        "gain: residuals of the single experiment's fit; offset: none"
    };
    (Value::Array(c), source, per)
}

/// Coefficients of an affine (static or dynamic) fit.
pub fn affine(f: &AffineFit) -> Value {
    json!([coef("alpha", f.alpha, f.alpha_std_error), coef("beta_nm", f.beta_nm, f.beta_std_error_nm)])
}

/// Coefficients of a speed fit. A table's per-bin α, β get the standard errors of the
/// same per-bin affine fit the library makes (rows `[lo, hi)`, the last bin closed),
/// kept only when that refit reproduces the table's values; a polynomial has none.
pub fn speed(f: &SpeedFit, sensor: &[f64], reference_nm: &[f64], speed_rad_s: &[f64]) -> (Value, &'static str) {
    if f.bins.is_empty() {
        let mut c = Vec::new();
        for (i, a) in f.alpha.iter().enumerate() {
            c.push(coef(&format!("alpha_{i}"), *a, None));
        }
        for (i, b) in f.beta_nm.iter().enumerate() {
            c.push(coef(&format!("beta_{i}_nm"), *b, None));
        }
        return (Value::Array(c), "none: the speed polynomial's fit does not report standard errors");
    }
    let last = f.bins.len() - 1;
    let bins: Vec<Value> = f
        .bins
        .iter()
        .enumerate()
        .map(|(b, bin)| {
            let inside = |w: f64| w >= bin.lo_rad_s && (w < bin.hi_rad_s || (b == last && w <= bin.hi_rad_s));
            let rows: Vec<usize> = (0..speed_rad_s.len()).filter(|&i| inside(speed_rad_s[i])).collect();
            let x: Vec<f64> = rows.iter().map(|&i| sensor[i]).collect();
            let t: Vec<f64> = rows.iter().map(|&i| reference_nm[i]).collect();
            let refit = fit_affine(&x, &t, None).ok().filter(|r| r.alpha == bin.alpha && r.beta_nm == bin.beta_nm);
            json!({
                "lo_rad_s": finite(bin.lo_rad_s),
                "hi_rad_s": finite(bin.hi_rad_s),
                "speed_rad_s": finite(bin.mean_speed_rad_s),
                "rows": bin.rows,
                "alpha": finite(bin.alpha),
                "alpha_std_error": opt(refit.and_then(|r| r.alpha_std_error)),
                "beta_nm": finite(bin.beta_nm),
                "beta_std_error_nm": opt(refit.and_then(|r| r.beta_std_error_nm)),
            })
        })
        .collect();
    (Value::Array(bins), "residuals of each bin's affine fit")
}

/// The JSON document, pretty-printed with a final newline.
pub fn document(v: Value) -> String {
    let mut s = serde_json::to_string_pretty(&v).unwrap_or_default();
    s.push('\n');
    s
}
