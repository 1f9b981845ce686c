//! The structured filter equals the textbook dense prediction-type Kalman filter
//! (Taghirad and Bélanger, 1999) run with the same Φ sequence, Q, R, x0 and P0.

mod ripple_common;

use ripple_common::{block_phi, DenseKf, Joint, Sample};
use strainwave_core::ripple::{step, Limits, Order, Reference, ReferenceValues, RippleInput, RippleModel, RippleState};

/// Agreement of predictions, posteriors and covariances in f64 (relative to max(1, |x|)).
const TOL_F64: f64 = 1e-9;
/// f32 clean torque against f64, N·m (noise 0.05 N·m, ripple O(1) N·m).
const TOL_F32_NM: f64 = 0.02;
/// f32 and f64 clean-torque RMS errors agree within this fraction.
const F32_RMS_REL: f64 = 0.02;

/// The textbook filter has neither the standstill hold nor the load-step detector.
fn no_hold<const M: usize>(m: RippleModel<f64, M>) -> RippleModel<f64, M> {
    m.with_limits(Limits { hold_below_hz: 0.0, load_step_nis: 0.0, ..Limits::default() }).unwrap()
}

/// Speed with a reversal: 40 rad/s mean, ±94 rad/s swing at 0.5 Hz; a load step.
fn samples(n: usize) -> Vec<Sample> {
    let joint = Joint::default();
    joint.run(
        n,
        7,
        |t| 40.0 * t + 30.0 * (std::f64::consts::TAU * 0.5 * t).sin(),
        |t| if t < 1.0 { 5.0 } else { -12.0 },
    )
}

fn angle_of(s: &Sample, r: Reference) -> f64 {
    match r {
        Reference::Relative => s.relative,
        Reference::Output => s.output,
        Reference::Motor => s.motor,
    }
}

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() <= TOL_F64 * b.abs().max(1.0)
}

#[allow(clippy::needless_range_loop)] // P[i][j] against the reference, index by index
fn equivalence<const M: usize>(model: RippleModel<f64, M>, n: usize) {
    let data = samples(n);
    let bias = model.bias_q_nm2().is_some();
    let dim = model.state_len();
    let (p0, p0b) = model.initial_variance_nm2();
    let mut p_init = vec![vec![0.0; dim]; dim];
    for (i, row) in p_init.iter_mut().enumerate() {
        row[i] = if bias && i == dim - 1 { p0b } else { p0 };
    }
    let c: Vec<f64> = (0..dim).map(|i| if i % 2 == 0 || (bias && i == dim - 1) { 1.0 } else { 0.0 }).collect();
    let mut dense = DenseKf::new(vec![0.0; dim], p_init, c, model.noise_nm() * model.noise_nm());
    let mut state = RippleState::new(&model);
    for k in 0..n {
        let s = &data[k];
        let input = RippleInput::new(s.measured, ReferenceValues::new(s.relative, s.output, s.motor));
        let out = step(&model, &mut state, &input).unwrap();
        let (_, s_dense) = dense.pc();
        let y_hat = s.measured - out.innovation_nm;
        assert!(close(y_hat, dense.predict_y()), "k {k}: ŷ {y_hat} vs {}", dense.predict_y());
        assert!(close(out.innovation_variance_nm2, s_dense), "k {k}: S");
        if !bias {
            assert!(close(out.ripple_nm + out.misalignment_nm, dense.predict_y()), "k {k}");
        }
        let (x_post, p_post) = dense.posterior(s.measured);
        for i in 0..dim {
            let xi = state.estimate(&model, i).unwrap();
            assert!(close(xi, x_post[i]), "k {k}: x[{i}] {xi} vs {}", x_post[i]);
            for j in 0..dim {
                let pij = state.covariance(&model, i, j).unwrap();
                assert!(close(pij, p_post[i][j]), "k {k}: P[{i}][{j}] {pij} vs {}", p_post[i][j]);
            }
        }
        if k + 1 < n {
            let next = &data[k + 1];
            let inc: Vec<f64> = model
                .orders()
                .iter()
                .map(|o| o.multiple() * (angle_of(next, o.reference()) - angle_of(s, o.reference())))
                .collect();
            let phi = block_phi(&inc, bias);
            // Q(k), including the covariance inflation ρ of `Limits` (isotropic per block).
            let rho = model.limits().covariance_inflation;
            let mut q = vec![vec![0.0; dim]; dim];
            for (i, o) in model.orders().iter().enumerate() {
                let grow = rho * 0.5 * (p_post[2 * i][2 * i] + p_post[2 * i + 1][2 * i + 1]);
                let qi = o.q_per_sample_nm2() + o.q_per_rad_nm2() * inc[i].abs() + grow;
                q[2 * i][2 * i] = qi;
                q[2 * i + 1][2 * i + 1] = qi;
            }
            if let Some(qb) = model.bias_q_nm2() {
                q[dim - 1][dim - 1] = qb + rho * p_post[dim - 1][dim - 1];
            }
            dense.step(s.measured, &phi, &q);
        }
    }
}

#[test]
fn taghirad_4th_order_equals_dense() {
    equivalence(RippleModel::<f64, 2>::taghirad_4th_order(1000.0).unwrap(), 3000);
}

#[test]
fn taghirad_6th_order_equals_dense() {
    equivalence(RippleModel::<f64, 3>::taghirad_6th_order(1000.0).unwrap(), 3000);
}

#[test]
fn product_with_bias_and_per_radian_noise_equals_dense() {
    equivalence(no_hold(RippleModel::<f64, 3>::product(1000.0, 0.05).unwrap()), 3000);
}

#[test]
fn mixed_noise_motor_reference_and_fractional_multiple_equal_dense() {
    let orders = [
        Order::new(Reference::Relative, 2.0).unwrap().with_noise(1e-4, 1e-3).unwrap(),
        Order::new(Reference::Motor, 1.5).unwrap().with_noise(0.0, 2e-3).unwrap(),
        Order::new(Reference::Output, 1.0).unwrap().with_noise(1e-5, 0.0).unwrap(),
    ];
    let model = RippleModel::new(orders, 0.1, 1000.0)
        .unwrap()
        .with_bias_state(1e-3)
        .unwrap()
        .with_initial_variance(2.0, 50.0)
        .unwrap();
    equivalence(no_hold(model), 3000);
}

#[test]
fn f32_is_as_accurate_as_f64() {
    let joint = Joint::default();
    let data = joint.run(120_000, 11, |t| 150.0 * t, |t| if t < 30.0 { 5.0 } else { -12.0 });
    let m64 = RippleModel::<f64, 3>::product(1000.0, 0.05).unwrap();
    let m32 = RippleModel::<f32, 3>::product(1000.0, 0.05).unwrap();
    let (mut s64, mut s32) = (RippleState::new(&m64), RippleState::new(&m32));
    let (mut e64, mut e32, mut worst) = (Vec::new(), Vec::new(), 0.0_f64);
    for (k, s) in data.iter().enumerate() {
        let i64_ = RippleInput::new(s.measured, ReferenceValues::new(s.relative, s.output, s.motor));
        let o64 = step(&m64, &mut s64, &i64_).unwrap();
        // f32 users feed wrapped angles; the increments then keep their precision.
        let w = |a: f64| a.rem_euclid(std::f64::consts::TAU) as f32;
        let i32_ = RippleInput::new(s.measured as f32, ReferenceValues::new(w(s.relative), w(s.output), w(s.motor)));
        let o32 = step(&m32, &mut s32, &i32_).unwrap();
        if k > 80_000 {
            e64.push(o64.torque_nm - s.true_torque);
            e32.push(o32.torque_nm as f64 - s.true_torque);
            worst = worst.max((o64.torque_nm - o32.torque_nm as f64).abs());
        }
    }
    let (r64, r32) = (ripple_common::rms(e64), ripple_common::rms(e32));
    assert!((r32 / r64 - 1.0).abs() < F32_RMS_REL, "clean-torque RMS error f32 {r32} vs f64 {r64}");
    assert!(worst < TOL_F32_NM, "f32 and f64 clean torques differ by up to {worst} N·m");
}
