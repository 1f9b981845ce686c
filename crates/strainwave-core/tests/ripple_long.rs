//! Long runs in f32: the covariance stays symmetric, finite and positive and the clean
//! torque stays at the noise floor over 10⁷ samples (10⁸ with `--ignored`).

mod ripple_common;

use ripple_common::{is_psd, Rng};
use std::f64::consts::TAU;
use strainwave_core::ripple::{step, ReferenceValues, RippleInput, RippleModel, RippleState};

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
