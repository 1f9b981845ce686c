//! Long runs in f32: the covariance stays symmetric, finite and positive and the clean
//! torque stays at the noise floor over 10⁷ samples (10⁸ with `--ignored`); a held
//! order's variance stays bounded however long it is held.

mod ripple_common;

use ripple_common::{is_psd, Rng};
use std::f64::consts::TAU;
use strainwave_core::ripple::{step, Limits, OrderStatus, ReferenceValues, RippleInput, RippleModel, RippleState};

const FS: f64 = 1000.0;
const NOISE_NM: f64 = 0.05;
/// PSD tolerance relative to the trace, f32.
const PSD_TOL: f64 = 1e-4;

/// Runs `n` samples of a joint whose motor speed sweeps 100 ± 50 rad/s every 10 min,
/// with load sinusoid and steps; checks `P` every `check_every` samples.
fn long_run<const M: usize>(model: RippleModel<f32, M>, n: u64, check_every: u64) {
    let mut state = RippleState::new(&model);
    let mut rng = Rng::new(77);
    let (mut motor, mut sq_err, mut count) = (0.0f64, 0.0f64, 0u64);
    let dim = model.state_len();
    let has_bias = model.bias_q_nm2().is_some();
    for k in 0..n {
        let t = k as f64 / FS;
        motor += (100.0 + 50.0 * (TAU * t / 600.0).sin()) / FS;
        let out_angle = -motor / 100.0;
        let rel = motor - out_angle;
        let load = if has_bias {
            10.0 + 5.0 * (TAU * 0.02 * t).sin() + if (k / 3_000_000) % 2 == 0 { 4.0 } else { -4.0 }
        } else {
            0.0
        };
        let ripple = 0.5 * (2.0 * rel + 0.3).cos() + 0.2 * (4.0 * rel - 1.1).cos();
        let mis = 1.0 * (out_angle + 0.7).cos();
        // Uniform noise with the right variance (cheaper than Box–Muller over 10⁸ samples).
        let noise = NOISE_NM * 3f64.sqrt() * (2.0 * rng.uniform() - 1.0);
        let y = load + ripple + mis + noise;
        let w = |a: f64| a.rem_euclid(TAU) as f32;
        let inp = RippleInput::new(y as f32, ReferenceValues::new(w(rel), w(out_angle), w(motor)));
        let o = step(&model, &mut state, &inp).unwrap_or_else(|e| panic!("k {k}: {e}"));
        if k >= n - 100_000 {
            sq_err += (o.torque_nm as f64 - load).powi(2);
            count += 1;
        }
        if (k + 1) % check_every == 0 {
            let p: Vec<Vec<f64>> =
                (0..dim).map(|i| (0..dim).map(|j| state.covariance(&model, i, j).unwrap() as f64).collect()).collect();
            for i in 0..dim {
                for j in 0..dim {
                    assert!(p[i][j].is_finite(), "k {k}: P[{i}][{j}]");
                    let scale = (p[i][i] * p[j][j]).sqrt();
                    assert!((p[i][j] - p[j][i]).abs() <= 1e-5 * scale, "k {k}: asymmetric");
                }
            }
            assert!(is_psd(&p, PSD_TOL), "k {k}: P not PSD {p:?}");
        }
    }
    let rms = (sq_err / count as f64).sqrt();
    assert!(rms < 1.3 * NOISE_NM, "clean RMS after {n} samples: {rms}");
}

#[test]
fn f32_product_1e7_samples() {
    long_run(RippleModel::<f32, 3>::product(FS as f32, NOISE_NM as f32).unwrap(), 10_000_000, 1_000_000);
}

#[test]
fn f32_taghirad_6th_order_1e7_samples() {
    long_run(RippleModel::<f32, 3>::taghirad_6th_order(FS as f32).unwrap(), 10_000_000, 1_000_000);
}

#[test]
#[ignore = "10⁸ samples, about a minute of CPU (3 min wall on a loaded machine); run with --ignored"]
fn f32_product_1e8_samples() {
    long_run(RippleModel::<f32, 3>::product(FS as f32, NOISE_NM as f32).unwrap(), 100_000_000, 5_000_000);
}

/// A joint whose output turns below the hold speed for hours (or stands still): its
/// held orders are not updated, and the inflation alone would grow their variances as
/// `(1 + ρ)^k` until f32 overflows (a joint at a steady slow speed lost its
/// cancellation after 1.7 h, its covariance after 15 h). Here `ρ` is 100 times the
/// default, so 2·10⁵ samples are 2·10⁷ at the default: the variances stay at most
/// the initial ones, and the ripple of the relative angle is still cancelled.
#[test]
fn f32_held_orders_variances_stay_bounded() {
    let limits = Limits { covariance_inflation: 1600.0 * f32::EPSILON, ..Limits::default() };
    let model = RippleModel::<f32, 3>::product(FS as f32, NOISE_NM as f32).unwrap().with_limits(limits).unwrap();
    let mut state = RippleState::new(&model);
    let mut rng = Rng::new(5);
    let (mut sq_err, mut count) = (0.0f64, 0u64);
    for k in 0..200_000u64 {
        // Motor at 30 rad/s, output 100 times slower: 3·10⁻⁴ rad per sample, below the hold.
        let motor = 30.0 * k as f64 / FS;
        let out_angle = -motor / 100.0;
        let rel = motor - out_angle;
        let y = 10.0 + 0.5 * (2.0 * rel + 0.3).cos() + 0.3 * (out_angle + 0.7).cos() + NOISE_NM * rng.normal();
        let w = |a: f64| a.rem_euclid(TAU) as f32;
        let inp = RippleInput::new(y as f32, ReferenceValues::new(w(rel), w(out_angle), w(motor)));
        let o = step(&model, &mut state, &inp).unwrap_or_else(|e| panic!("k {k}: {e}"));
        if k >= 100_000 {
            sq_err += (f64::from(o.torque_nm) - 10.0 - 0.3 * (out_angle + 0.7).cos()).powi(2);
            count += 1;
        }
    }
    assert_eq!(state.order_status(2), Some(OrderStatus::Held));
    for i in 0..3 {
        let (_, var) = state.learned(i).unwrap();
        assert!(var.is_finite() && var <= 1.01, "order {i}: variance {var}");
    }
    let rms = (sq_err / count as f64).sqrt();
    assert!(rms < 1.5 * NOISE_NM, "clean RMS of the 2× line: {rms}");
}
