//! Load-scaled orders (ripple that grows with load) and learned priors.

use strainwave_core::ripple::{step, Order, Reference, ReferenceValues, RippleInput, RippleModel, RippleState};

const FS: f64 = 1000.0;
const NOISE_NM: f64 = 0.02;

/// Deterministic noise in [-√3, √3]σ (uniform, unit variance scaled).
fn noise(k: usize) -> f64 {
    let x = (k as u64).wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
    let u = ((x >> 11) as f64) / ((1u64 << 53) as f64);
    (u - 0.5) * 2.0 * 3f64.sqrt() * NOISE_NM
}

fn load_nm(k: usize) -> f64 {
    [2.0, 12.0, -6.0, 18.0, 4.0, -14.0][(k / 4000) % 6]
}

fn ripple_nm(phi: f64, load: f64) -> f64 {
    (0.3 + 0.02 * load.abs()) * (2.0 * phi + 0.4).sin()
}

fn model(scaled: bool) -> RippleModel<f64, 2> {
    let o = Order::new(Reference::Relative, 2.0).unwrap().with_noise(0.0, 2e-6).unwrap();
    let second = if scaled {
        Order::new(Reference::Relative, 2.0).unwrap().with_noise(0.0, 1e-9).unwrap().scaled_by_load()
    } else {
        // Same state count, but a line that is not in the signal.
        Order::new(Reference::Relative, 6.0).unwrap().with_noise(0.0, 1e-9).unwrap()
    };
    let second = second.with_prior([0.0, 0.0], 0.05 * 0.05).unwrap();
    RippleModel::new([o, second], NOISE_NM, FS).unwrap().with_bias_state(0.05).unwrap()
}

/// RMS ripple error over the last `tail` samples of an `n`-sample run.
fn run(model: &RippleModel<f64, 2>, n: usize, tail: usize) -> (f64, RippleState<f64, 2>) {
    let mut st = RippleState::new(model);
    let (mut e2, mut count) = (0.0, 0.0);
    for k in 0..n {
        let phi = 0.31 * k as f64; // 49 Hz 2× line
        let load = load_nm(k);
        let y = load + ripple_nm(phi, load) + noise(k);
        let o = step(model, &mut st, &RippleInput::new(y, ReferenceValues::new(phi, 0.0, 0.0))).unwrap();
        if k >= n - tail {
            e2 += (o.ripple_nm - ripple_nm(phi, load)).powi(2);
            count += 1.0;
        }
    }
    ((e2 / count).sqrt(), st)
}

#[test]
fn load_scaled_order_learns_ripple_that_grows_with_load() {
    let n = 72_000;
    let (err_scaled, st) = run(&model(true), n, 24_000);
    let (err_plain, _) = run(&model(false), n, 24_000);
    // The scaled order's coefficients: 0.02 sin(2φ + 0.4) = 0.02 sin 0.4 cos 2φ + 0.02 cos 0.4 sin 2φ.
    let (z, _) = st.learned(1).unwrap();
    assert!((z[0] - 0.02 * 0.4f64.sin()).abs() < 2e-3, "{z:?}");
    assert!((z[1] - 0.02 * 0.4f64.cos()).abs() < 2e-3, "{z:?}");
    assert!(err_scaled < 0.01, "scaled model ripple error {err_scaled}");
    assert!(err_plain > 2.0 * err_scaled, "plain {err_plain} vs scaled {err_scaled}");
}

#[test]
fn learned_priors_carry_over_and_resets_return_to_them() {
    let m = model(true);
    let (_, st) = run(&m, 48_000, 1);
    let learned = st.learned_all();
    let warm = m.with_priors(learned).unwrap();
    let fresh = RippleState::new(&warm);
    assert_eq!(fresh.learned(0).unwrap().0, learned[0].0);
    assert_eq!(fresh.learned(1).unwrap().0, learned[1].0);

    // Warm start: the ripple is right from the first samples.
    let mut s = RippleState::new(&warm);
    let mut worst: f64 = 0.0;
    for k in 0..200 {
        let phi = 0.31 * k as f64;
        let y = 2.0 + ripple_nm(phi, 2.0) + noise(k + 7);
        let o = step(&warm, &mut s, &RippleInput::new(y, ReferenceValues::new(phi, 0.0, 0.0))).unwrap();
        if k > 2 {
            worst = worst.max((o.ripple_nm - ripple_nm(phi, 2.0)).abs());
        }
    }
    assert!(worst < 0.03, "warm start ripple error {worst}");

    // An encoder jump resets the orders to their prior, not to zero (no update: NaN torque).
    let o = step(&warm, &mut s, &RippleInput::new(f64::NAN, ReferenceValues::new(3.0, 0.0, 0.0))).unwrap();
    assert!(o.flags.contains(strainwave_core::ripple::StepFlags::JUMP_RESET));
    assert_eq!(s.learned(0).unwrap().0, learned[0].0);
}

#[test]
fn bad_priors_are_refused() {
    let o = Order::new(Reference::Relative, 2.0_f64).unwrap();
    assert!(o.with_prior([f64::INFINITY, 0.0], 1.0).is_err());
    assert!(o.with_prior([0.0, 0.0], 0.0).is_err());
    assert!(o.with_prior([0.0, 0.0], f64::NAN).is_err());
    let m = RippleModel::<f64, 2>::taghirad_4th_order(FS).unwrap();
    assert!(m.with_priors([([0.0, f64::NAN], 1.0), ([0.0, 0.0], 1.0)]).is_err());
}
