//! Calibration behaviour against the papers: Taghirad and Bélanger's gain consistency, the embedded-sensor article's
//! error table, and the series-elastic dead-weight fixture against numpy's polyfit.

#[path = "calibration_fixture.rs"]
mod fixture;

use fixture::*;
use strainwave_analysis::calibration::{
    calibrate_gain, fit_affine, CalibrationError, CalibrationFile, Experiment, GainFit, ModelKind,
};
use strainwave_analysis::lstsq::{fit_line, polyfit};

/// Coefficients recovered from exact data, relative.
const COEFF_TOL: f64 = 1e-12;
/// Agreement with numpy's polyfit, relative (what the Python test checks too).
const NUMPY_TOL: f64 = 1e-9;

fn round2(x: f64) -> f64 {
    (x * 100.0).round() / 100.0
}

/// Eight experiments (Taghirad and Bélanger (1999) used eight), loading and unloading at five steps, with
/// zero-mean hysteresis-like scatter orthogonal to the voltages so each gain is exact:
/// gains alternate 6.468 / 6.732 N·m/V → mean 6.6, deviations ±0.132.
fn taghirad_experiments() -> Vec<Experiment> {
    let v = [0.5, 1.0, 1.5, 1.0, 0.5];
    let scatter = [0.02, -0.01, 0.0, 0.01, -0.02]; // Σ v·scatter = 0
    (0..8)
        .map(|i| {
            let g = if i % 2 == 0 { 6.468 } else { 6.732 };
            let t: Vec<f64> = v.iter().zip(scatter).map(|(v, e)| g * v + e).collect();
            Experiment::new(&format!("position {}", 45 * i), &t, &v)
        })
        .collect()
}

#[test]
fn taghirad_consistency_uses_sample_std() {
    let g = calibrate_gain(&taghirad_experiments(), GainFit::ThroughOrigin, Some(10.0)).unwrap();
    for (i, e) in g.experiments.iter().enumerate() {
        let want = if i % 2 == 0 { 6.468 } else { 6.732 };
        assert!((e.gain_nm_per_v - want).abs() < COEFF_TOL * want, "{}: {}", e.label, e.gain_nm_per_v);
        assert!((e.metrics.max_abs_error_nm - 0.02).abs() < 1e-12);
    }
    assert!((g.gain_nm_per_v - 6.6).abs() < COEFF_TOL * 6.6);
    // Sample std: √(8 · 0.132² / 7); the population std would give exactly 2.000 %.
    let s = 0.132 * (8.0f64 / 7.0).sqrt();
    assert!((g.gain_std_nm_per_v.unwrap() - s).abs() < 1e-12);
    assert!((g.consistency.unwrap() - s / 6.6).abs() < 1e-12);
    assert!((g.consistency_percent().unwrap() - 2.138).abs() < 0.001);
    // The final gain as a file, and back.
    let f = g.to_file();
    assert_eq!(f.model, ModelKind::Gain);
    let back = CalibrationFile::from_toml_str(&f.to_toml_string().unwrap()).unwrap();
    let core = back.to_core::<f32, 1>().unwrap();
    assert!((core.apply(1.0, 0.0).unwrap() - 6.6).abs() < 1e-5);
}

#[test]
fn embedded_sensor_static_row_reproduced() {
    let (x, t) = embedded_sensor_static();
    let f = fit_affine(&x, &t, Some(20.19)).unwrap();
    assert!((f.alpha - STATIC_ALPHA).abs() < COEFF_TOL * STATIC_ALPHA);
    assert!((f.beta_nm - STATIC_BETA_NM).abs() < 1e-12);
    let m = f.metrics;
    assert!((m.max_abs_error_nm - 0.39).abs() < 1e-12);
    assert!((m.rms_error_nm - 0.21).abs() < 1e-12);
    assert!(m.mean_error_nm.abs() < 1e-12);
    // the embedded-sensor article prints 1.04 % FS: 0.21 / 20.19 = 1.0401 %. (With FS = 20 exactly it would be 1.05 %.)
    assert_eq!(round2(m.rms_percent_fs.unwrap()), 1.04);
    assert_eq!(m.rows, 8);
    assert_eq!(m.max_abs_row, 1);
}

#[test]
fn embedded_sensor_dynamic_row_reproduced() {
    let (x, t) = embedded_sensor_dynamic();
    let f = fit_affine(&x, &t, Some(20.87)).unwrap();
    assert!((f.alpha - DYNAMIC_ALPHA).abs() < COEFF_TOL * DYNAMIC_ALPHA);
    assert!((f.beta_nm - DYNAMIC_BETA_NM).abs() < 1e-12);
    let m = f.metrics;
    assert!((m.max_abs_error_nm - 0.64).abs() < 1e-12);
    assert!((m.rms_error_nm - 0.265).abs() < 1e-12);
    // the embedded-sensor article prints 1.27 % FS: 0.265 / 20.87 = 1.2698 %.
    assert_eq!(round2(m.rms_percent_fs.unwrap()), 1.27);
    let file = f.to_dynamic_file();
    let text = file.to_toml_string().unwrap();
    assert!(text.contains("model = \"dynamic\"") && text.contains("alpha = 1.572"), "{text}");
    let back = CalibrationFile::from_toml_str(&text).unwrap();
    assert!((back.metrics.unwrap().rms_error_nm - 0.265).abs() < 1e-12);
}

#[test]
fn series_elastic_dead_weight_matches_numpy() {
    let t = sea_torque_nm();
    let (slope, intercept) = fit_line(&SEA_DEFLECTION_RAD, &t).unwrap();
    assert!(((slope - SEA_NUMPY_SLOPE) / SEA_NUMPY_SLOPE).abs() < NUMPY_TOL, "slope {slope}");
    assert!(((intercept - SEA_NUMPY_INTERCEPT) / SEA_NUMPY_INTERCEPT).abs() < NUMPY_TOL, "intercept {intercept}");
    // The calibration fit gives the same line and sensible standard errors.
    let f = fit_affine(&SEA_DEFLECTION_RAD, &t, Some(15.0)).unwrap();
    assert!((f.alpha - slope).abs() < 1e-12 * slope);
    assert!(f.alpha_std_error.unwrap() > 0.0 && f.alpha_std_error.unwrap() < 1.0);
    // Hysteresis shows as max |e| above the RMS.
    assert!(f.metrics.max_abs_error_nm > f.metrics.rms_error_nm);
    let p = polyfit(&SEA_DEFLECTION_RAD, &t, 1).unwrap();
    assert!((p.eval(0.02) - (slope * 0.02 + intercept)).abs() < 1e-12);
}

#[test]
fn nan_rows_and_single_load_are_named() {
    let (mut x, t) = embedded_sensor_static();
    x[3] = f64::NAN;
    let err = fit_affine(&x, &t, None).unwrap_err();
    assert_eq!(err, CalibrationError::NonFiniteRow { what: "affine fit".into(), row: 3, column: "sensor" });
    // Rows are 0-based in the value and 1-based in the message, as the user counts.
    assert!(err.to_string().contains("row 4"), "{err}");
    let err = fit_affine(&[5.0; 6], &[1.0, 2.0, 3.0, 4.0, 5.0, 6.0], None).unwrap_err();
    assert!(err.to_string().contains("singular"), "{err}");
}
