//! Calibration fixtures shared by the calibration tests and the `calib_golden` example
//! (included there with `#[path]`); as a test target it checks the fixtures themselves.
//!
//! **Series-elastic joint, dead-weight static calibration** (made up for this project,
//! documented here so it can be recomputed by hand): masses hung on a lever of
//! 0.300 m, g = 9.80665 m/s², torque `T = m g L`; the spring deflection is read from the
//! motor- and link-side encoders. The readings were generated from a 420 N·m/rad
//! spring, a 4.0e-4 rad encoder zero, 4e-5 rad of hysteresis on unloading and a few
//! 1e-5 rad of reading scatter, rounded to 1e-7 rad, then frozen here:
//!
//! | step | mass kg | deflection rad |
//! |---|---|---|
//! | load 0–5 | 0, 1, 2, 3, 4, 5 | 0.000403, 0.0073998, 0.0144175, 0.0214123, 0.028425, 0.0354197 |
//! | unload 4–0 | 4, 3, 2, 1, 0 | 0.02846, 0.0214472, 0.0144545, 0.0074417, 0.000442 |
//!
//! numpy.polyfit(deflection, torque, 1) gives slope 420.1365949023933 N·m/rad and
//! intercept −0.17801892769676325 N·m (numpy 2.4).
//!
//! **the embedded-sensor article error patterns**: residual vectors with exactly the embedded-sensor article's max |e| and RMS
//! that are orthogonal to `[1, x]`, so the least-squares line through
//! `T_ref = α x + β + e` is exactly `α x + β`:
//! - static, `x = 0, 2, …, 14` N·m: `e = (−0.09, 0.39, −0.09, −0.09, −0.39, 0.09, 0.09, 0.09)`:
//!   max |e| = 0.39, Σe² = 2·0.39² + 6·0.09² = 0.3528 = 8·0.21² → RMS 0.21;
//! - dynamic, `x = −7.5, −6.5, …, 7.5` N·m: two ±0.64, ten ±0.16, four ±0.11:
//!   Σe² = 2·0.4096 + 10·0.0256 + 4·0.0121 = 1.1236 = 16·0.265² → RMS 0.265.
#![allow(dead_code)]

/// Standard gravity, m/s².
pub const GRAVITY_M_S2: f64 = 9.80665;
/// Lever arm of the dead-weight rig, m.
pub const LEVER_ARM_M: f64 = 0.300;
/// Masses in the order hung, kg (loading then unloading).
pub const SEA_MASSES_KG: [f64; 11] = [0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 4.0, 3.0, 2.0, 1.0, 0.0];
/// Spring deflection read at each step, rad.
pub const SEA_DEFLECTION_RAD: [f64; 11] = [
    0.000403, 0.0073998, 0.0144175, 0.0214123, 0.028425, 0.0354197, 0.02846, 0.0214472, 0.0144545, 0.0074417, 0.000442,
];
/// numpy.polyfit(deflection, torque, 1)[0], N·m/rad.
pub const SEA_NUMPY_SLOPE: f64 = 420.1365949023933;
/// numpy.polyfit(deflection, torque, 1)[1], N·m.
pub const SEA_NUMPY_INTERCEPT: f64 = -0.17801892769676325;

/// Reference torque at each step, `m g L`, N·m.
pub fn sea_torque_nm() -> Vec<f64> {
    SEA_MASSES_KG.iter().map(|m| m * GRAVITY_M_S2 * LEVER_ARM_M).collect()
}

/// the embedded-sensor article static model.
pub const STATIC_ALPHA: f64 = 1.284;
/// the embedded-sensor article static model, N·m.
pub const STATIC_BETA_NM: f64 = -0.0812;
/// Reference minus model on the static fixture, N·m.
pub const STATIC_ERRORS_NM: [f64; 8] = [-0.09, 0.39, -0.09, -0.09, -0.39, 0.09, 0.09, 0.09];
/// the embedded-sensor article dynamic model.
pub const DYNAMIC_ALPHA: f64 = 1.572;
/// the embedded-sensor article dynamic model, N·m.
pub const DYNAMIC_BETA_NM: f64 = -0.0928;
/// Reference minus model on the dynamic fixture, N·m.
pub const DYNAMIC_ERRORS_NM: [f64; 16] =
    [0.16, -0.16, 0.16, -0.16, -0.11, -0.16, 0.11, 0.16, -0.16, -0.16, 0.16, 0.11, 0.64, -0.11, -0.64, 0.16];

/// `(T_sens, T_ref)` of the static fixture.
pub fn embedded_sensor_static() -> (Vec<f64>, Vec<f64>) {
    let x: Vec<f64> = (0..8).map(|k| 2.0 * k as f64).collect();
    let t = x.iter().zip(STATIC_ERRORS_NM).map(|(x, e)| STATIC_ALPHA * x + STATIC_BETA_NM + e).collect();
    (x, t)
}

/// `(T_sens, T_ref)` of the dynamic fixture.
pub fn embedded_sensor_dynamic() -> (Vec<f64>, Vec<f64>) {
    let x: Vec<f64> = (0..16).map(|k| k as f64 - 7.5).collect();
    let t = x.iter().zip(DYNAMIC_ERRORS_NM).map(|(x, e)| DYNAMIC_ALPHA * x + DYNAMIC_BETA_NM + e).collect();
    (x, t)
}

#[test]
fn error_patterns_are_orthogonal_to_the_regressors() {
    let (xs, _) = embedded_sensor_static();
    let (xd, _) = embedded_sensor_dynamic();
    for (x, e) in [(&xs, &STATIC_ERRORS_NM[..]), (&xd, &DYNAMIC_ERRORS_NM[..])] {
        let sum: f64 = e.iter().sum();
        let dot: f64 = x.iter().zip(e).map(|(a, b)| a * b).sum();
        assert!(sum.abs() < 1e-12 && dot.abs() < 1e-12, "sum {sum}, dot {dot}");
    }
    let ss: f64 = STATIC_ERRORS_NM.iter().map(|e| e * e).sum();
    assert!((ss - 8.0 * 0.21 * 0.21).abs() < 1e-12);
    let sd: f64 = DYNAMIC_ERRORS_NM.iter().map(|e| e * e).sum();
    assert!((sd - 16.0 * 0.265 * 0.265).abs() < 1e-12);
}

#[test]
fn sea_fixture_is_consistent() {
    let t = sea_torque_nm();
    assert_eq!(t.len(), SEA_DEFLECTION_RAD.len());
    assert!((t[5] - 14.709975).abs() < 1e-9);
}
