//! Property tests: no input (any f32/f64, NaN and ±∞ included) panics, and the
//! covariance stays finite, symmetric and positive semi-definite.

mod ripple_common;

use proptest::prelude::*;
use ripple_common::is_psd;
use strainwave_core::ripple::{
    step, Limits, PhaseSource, ReferenceValues, RippleInput, RippleModel, RippleState, StepFlags,
};
use strainwave_core::{Error, Real};

/// Relative PSD tolerance (of the trace) and symmetry tolerance, per scalar.
fn tolerances<T: Real>() -> (f64, f64) {
    if T::EPSILON.to_f64() > 1e-10 {
        (1e-4, 1e-5)
    } else {
        (1e-10, 1e-12)
    }
}

fn check_covariance<T: Real, const M: usize>(model: &RippleModel<T, M>, state: &RippleState<T, M>) {
    let n = model.state_len();
    let (psd_tol, sym_tol) = tolerances::<T>();
    let p: Vec<Vec<f64>> =
        (0..n).map(|i| (0..n).map(|j| state.covariance(model, i, j).unwrap().to_f64()).collect()).collect();
    for i in 0..n {
        assert!(state.estimate(model, i).unwrap().is_finite());
        for j in 0..n {
            assert!(p[i][j].is_finite(), "P[{i}][{j}] = {}", p[i][j]);
            let scale = (p[i][i] * p[j][j]).sqrt().max(f64::MIN_POSITIVE);
            assert!((p[i][j] - p[j][i]).abs() <= sym_tol * scale, "asymmetric P[{i}][{j}]");
        }
    }
    assert!(is_psd(&p, psd_tol), "P not PSD: {p:?}");
    assert!(state.covariance(model, n, 0).is_none() && state.estimate(model, n).is_none());
}

fn feed<T: Real, const M: usize>(model: &RippleModel<T, M>, inputs: &[RippleInput<T>]) {
    let mut state = RippleState::new(model);
    for inp in inputs {
        match step(model, &mut state, inp) {
            Ok(out) => {
                if !out.flags.contains(StepFlags::ANGLE_SKIPPED) {
                    assert!(out.innovation_variance_nm2.to_f64() > 0.0 || out.innovation_variance_nm2.is_finite());
                }
            }
            Err(e) => assert_eq!(e, Error::NotPositiveDefinite("ripple covariance")),
        }
        check_covariance(model, &state);
    }
}

fn models<T: Real>() -> (RippleModel<T, 3>, RippleModel<T, 2>, RippleModel<T, 3>) {
    let c = T::from_f64;
    let product = RippleModel::product(c(1000.0), c(0.05)).unwrap();
    let classic = RippleModel::taghirad_4th_order(c(1000.0)).unwrap();
    let velocity = RippleModel::product(c(500.0), c(0.1))
        .unwrap()
        .with_phase_source(PhaseSource::Velocity)
        .with_limits(Limits { max_gap_periods: c(f64::INFINITY), ..Limits::default() })
        .unwrap();
    (product, classic, velocity)
}

fn special_f64() -> impl Strategy<Value = f64> {
    prop_oneof![
        4 => -10.0..10.0f64,
        1 => Just(f64::NAN),
        1 => Just(f64::INFINITY),
        1 => Just(f64::NEG_INFINITY),
        1 => Just(0.0f64),
        2 => any::<f64>(),
    ]
}

fn special_f32() -> impl Strategy<Value = f32> {
    prop_oneof![
        4 => -10.0..10.0f32,
        1 => Just(f32::NAN),
        1 => Just(f32::INFINITY),
        1 => Just(f32::NEG_INFINITY),
        2 => any::<f32>(),
    ]
}

/// (torque, expected torque, relative, output, motor, dt).
type RawSample<T> = (T, T, T, T, T, Option<T>);

fn arbitrary_inputs<T: Real>(v: &[RawSample<T>]) -> Vec<RippleInput<T>> {
    v.iter()
        .map(|&(y, e, a, b, c, dt)| {
            let mut i = RippleInput::new(y, ReferenceValues::new(a, b, c)).with_expected_torque(e);
            i.dt_s = dt;
            i
        })
        .collect()
}

/// Realistic motion (speed `w` rad/sample) with occasional special values spliced in.
fn motion<T: Real>(w: f64, glitches: &[(usize, u8, f64)], n: usize) -> Vec<RippleInput<T>> {
    let mut v: Vec<RippleInput<T>> = (0..n)
        .map(|k| {
            let phi = w * k as f64;
            let y = 3.0 + 0.5 * (2.0 * phi).cos() + 0.2 * (4.0 * phi).sin();
            RippleInput::new(
                T::from_f64(y),
                ReferenceValues::new(T::from_f64(phi), T::from_f64(-phi / 101.0), T::from_f64(phi / 1.01)),
            )
        })
        .collect();
    for &(at, which, value) in glitches {
        if let Some(inp) = v.get_mut(at % n) {
            let x = T::from_f64(value);
            match which % 5 {
                0 => inp.torque_nm = x,
                1 => inp.references.relative = x,
                2 => inp.references.output = x,
                3 => inp.dt_s = Some(x),
                _ => inp.expected_torque_nm = x,
            }
        }
    }
    v
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 128, failure_persistence: None, ..ProptestConfig::default() })]

    #[test]
    fn any_f64_input_is_safe(v in prop::collection::vec(
        (special_f64(), special_f64(), special_f64(), special_f64(), special_f64(), prop::option::of(special_f64())),
        1..40,
    )) {
        let (a, b, c) = models::<f64>();
        let inputs = arbitrary_inputs(&v);
        feed(&a, &inputs);
        feed(&b, &inputs);
        feed(&c, &inputs);
    }

    #[test]
    fn any_f32_input_is_safe(v in prop::collection::vec(
        (special_f32(), special_f32(), special_f32(), special_f32(), special_f32(), prop::option::of(special_f32())),
        1..40,
    )) {
        let (a, b, c) = models::<f32>();
        let inputs = arbitrary_inputs(&v);
        feed(&a, &inputs);
        feed(&b, &inputs);
        feed(&c, &inputs);
    }

    #[test]
    fn motion_with_glitches_keeps_p_psd(
        w in -1.2..1.2f64,
        glitches in prop::collection::vec((0usize..400, 0u8..5, special_f64()), 0..12),
    ) {
        let (a, b, _) = models::<f64>();
        feed(&a, &motion::<f64>(w, &glitches, 400));
        feed(&b, &motion::<f64>(w, &glitches, 400));
        let (a32, b32, _) = models::<f32>();
        feed(&a32, &motion::<f32>(w, &glitches, 400));
        feed(&b32, &motion::<f32>(w, &glitches, 400));
    }
}
