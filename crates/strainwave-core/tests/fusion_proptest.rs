//! Property tests of the fusion, filters and flux maps, for f32 and f64: complementarity
//! for any inputs, stable designs over the whole allowed range, no panic on any input.

use proptest::prelude::*;
use strainwave_core::fusion::{
    AccelerometerPair, ComplementaryFusion, CrossoverOrder, FusionState, HybridTorqueSensor,
};
use strainwave_core::iir::{Biquad, BiquadState, Complex};
use strainwave_core::pmsm::FluxMap;
use strainwave_core::{Error, Real};

fn complementary_for_equal_inputs<T: Real>(fc: f64, fs: f64, xs: &[f64], tol: f64) {
    for order in [CrossoverOrder::First, CrossoverOrder::Second] {
        let f = ComplementaryFusion::<T>::new(T::from_f64(fc), T::from_f64(fs), order).unwrap();
        assert!(f.lowpass().is_stable(), "{order:?} {fc} {fs}");
        let mut st = FusionState::default();
        for &x in xs {
            let y = f.step(&mut st, T::from_f64(x), T::from_f64(x)).to_f64();
            assert!((y - x).abs() <= tol * (1.0 + x.abs()), "{order:?}: {y} vs {x}");
        }
        for k in 0..8 {
            let fr = T::from_f64(fs * 0.5 * k as f64 / 8.0);
            let (lp, hp) = f.responses(fr);
            let sum = lp + hp - Complex::real(T::ONE);
            assert!(sum.norm().to_f64() < 100.0 * tol);
        }
    }
}

proptest! {
    #[test]
    fn fusion_is_complementary(
        fs in 100.0f64..1e5,
        ratio in 1e-3f64..0.49,
        xs in proptest::collection::vec(-1e3f64..1e3, 1..200),
    ) {
        let fc = ratio * fs;
        complementary_for_equal_inputs::<f64>(fc, fs, &xs, 1e-12);
        complementary_for_equal_inputs::<f32>(fc, fs, &xs, 1e-5);
    }

    #[test]
    fn crossover_above_nyquist_is_an_error(fs in 1.0f64..1e6, over in 0.5f64..10.0) {
        for order in [CrossoverOrder::First, CrossoverOrder::Second] {
            prop_assert_eq!(
                ComplementaryFusion::<f64>::new(over * fs, fs, order),
                Err(Error::OutOfRange("crossover_hz"))
            );
        }
    }

    #[test]
    fn designs_are_stable(fs in 10.0f64..1e6, ratio in 1e-4f64..0.499, q in 0.1f64..20.0) {
        let fc = ratio * fs;
        for f in [
            Biquad::lowpass(fc, q, fs).unwrap(),
            Biquad::highpass(fc, q, fs).unwrap(),
            Biquad::first_order_lowpass(fc, fs).unwrap(),
            Biquad::first_order_highpass(fc, fs).unwrap(),
        ] {
            prop_assert!(f.is_stable(), "{:?}", f);
            let mut st = BiquadState::default();
            let mut y = 0.0;
            for _ in 0..100 {
                y = f.step(&mut st, 1.0);
            }
            prop_assert!(y.is_finite());
        }
    }

    #[test]
    fn vibration_cancels(t in -100.0f64..100.0, v in -100.0f64..100.0, r in 0.01f64..1.0) {
        let p = AccelerometerPair::new(r, 1.305e-3).unwrap();
        prop_assert!((p.angular_accel_rad_s2(t + v, t - v) - t / r).abs() < 1e-9 * (1.0 + (t / r).abs() + (v / r).abs()));
    }

    #[test]
    fn nothing_panics(a in any::<f64>(), b in any::<f64>(), c in any::<f64>()) {
        let map = FluxMap::<f64, 8, 2, 2>::from_fn(1.0, [-1.0, 1.0], [-1.0, 1.0], |g, d, q| (g.sin() + d, q)).unwrap();
        let _ = map.evaluate(a, b, c);
        let _ = map.torque_nm(3.0, a, b, c);
        let _ = map.mean_flux_vs(b, c);
        let s = HybridTorqueSensor::new(AccelerometerPair::<f32>::kit(), ComplementaryFusion::kit(20_000.0).unwrap());
        let mut st = FusionState::default();
        let r = s.step(&mut st, a as f32, b as f32, c as f32);
        if a.is_finite() && b.is_finite() && c.is_finite() && (a as f32).is_finite() && (b as f32).is_finite() && (c as f32).is_finite() {
            prop_assert!(r.is_ok());
        } else {
            prop_assert!(r.is_err());
        }
        let _ = ComplementaryFusion::<f64>::new(a, b, CrossoverOrder::Second);
        let _ = Biquad::<f64>::lowpass(a, b, c);
    }
}
