//! Tests of the guard on synthetic signals: each rule on its own.

use super::order::{chi2, octant};
use super::*;
use crate::ripple::{ReferenceValues, RippleInput, RippleModel};

/// Sample `k`: load, 2× ripple of `amp` on the relative angle at `w` rad per sample,
/// a little deterministic noise; output angle `φ / 100`.
fn sample<T: Real>(k: usize, w: f64, amp: f64, load: f64) -> RippleInput<T> {
    let phi = w * k as f64;
    let noise = 0.01 * ((k as f64 * 12.9898).sin() * 43_758.545).fract();
    let y = load + amp * (2.0 * phi + 0.3).cos() + noise;
    RippleInput::new(T::from_f64(y), ReferenceValues::new(T::from_f64(phi), T::from_f64(phi / 100.0), T::from_f64(phi)))
}

#[test]
fn chi2_and_octants() {
    let p = [[0.01, 0.0], [0.0, 0.04]];
    assert!((chi2(&p, [0.1, 0.2]) - (1.0 + 1.0)).abs() < 1e-12);
    assert_eq!(chi2(&[[0.0, 0.0], [0.0, 0.0]], [1.0, 1.0]), 0.0);
    assert_eq!(chi2(&[[f64::NAN, 0.0], [0.0, 1.0]], [1.0, 1.0]), 0.0);
    // The eight octants in turn around the circle.
    for o in 0..8u8 {
        let a = (f64::from(o) + 0.5) * core::f64::consts::FRAC_PI_4;
        assert_eq!(octant([a.cos(), a.sin()]), Some(o), "octant {o}");
        assert_eq!(octant([3.0 * a.cos(), 3.0 * a.sin()]), Some(o), "scaled, octant {o}");
    }
    assert_eq!(octant([0.0f64, 0.0]), None);
    assert_eq!(octant([f64::NAN, 1.0]), None);
}

/// A 2× ripple the model knows is applied once learned (f64 and f32); the 4× order
/// (no such line in the data) and the misalignment (not one output turn yet) are not,
/// and the output then is the load.
fn learns_and_applies<T: Real>() {
    let model = RippleModel::<T, 3>::product(T::from_f64(1000.0), T::from_f64(0.01)).unwrap();
    let mut guard = Guard::new(&model, GuardSettings::default());
    let mut first_applied = None;
    let mut last = None;
    for k in 0..6000 {
        let o = guard.step(&model, &sample::<T>(k, 0.05, 0.5, 2.0)).unwrap();
        if o.applied[0] && first_applied.is_none() {
            first_applied = Some(k);
        }
        last = Some(o);
    }
    let o = last.unwrap();
    // 2× applied; the 4× line is not in the data (no evidence), the misalignment has not turned.
    assert_eq!(o.applied, [true, false, false]);
    assert!((o.output.torque_nm.to_f64() - 2.0).abs() < 0.05, "{}", o.output.torque_nm.to_f64());
    // Not at once: it waits for evidence and three cycles of the line.
    assert!(first_applied.unwrap() > 10, "{first_applied:?}");
    let stats = guard.stats();
    assert_eq!(stats.samples, 6000);
    assert!(stats.applied_share(0) > 0.8 && stats.applied_share(2) == 0.0, "{stats:?}");
    assert!(stats.mean_nis() < 3.0, "{}", stats.mean_nis());
}

#[test]
fn learns_and_applies_f64_and_f32() {
    learns_and_applies::<f64>();
    learns_and_applies::<f32>();
}

/// A model whose noise is 100× too small for the data: its NIS is far above 1, the
/// whole model steps back, and the output is the raw torque, bit for bit.
#[test]
fn misfit_model_passes_the_raw_torque_through() {
    let model = RippleModel::<f64, 3>::product(1000.0, 1e-4).unwrap();
    let mut guard = Guard::new(&model, GuardSettings::default());
    let mut passed = 0;
    for k in 0..4000 {
        let input = sample::<f64>(k, 0.05, 0.5, 2.0);
        let o = guard.step(&model, &input).unwrap();
        if k > 2000 {
            assert!(o.flags.contains(GuardFlags::PASS_THROUGH), "k {k}: mean NIS {}", o.mean_nis);
            assert_eq!(o.output.torque_nm.to_bits(), input.torque_nm.to_bits(), "k {k}");
            assert_eq!(o.withheld_mask(), 0b111);
            passed += 1;
        }
    }
    assert!(guard.stats().pass_through >= passed && guard.stats().pass_through_share() > 0.4);
}

/// Cold, an order that has never moved removes nothing at a standstill, however its
/// estimate looks: the bound of what was learned while moving is zero.
#[test]
fn nothing_removed_at_a_standstill_before_any_motion() {
    let model = RippleModel::<f64, 3>::product(1000.0, 0.01).unwrap();
    let mut guard = Guard::new(&model, GuardSettings::default());
    for k in 0..3000 {
        // Standing at φ = 0.7 with a load that changes: the orders are held throughout.
        let load = if k < 1500 { 1.0 } else { 3.0 };
        let input = RippleInput::new(load, ReferenceValues::new(0.7, 0.007, 0.7));
        let o = guard.step(&model, &input).unwrap();
        assert_eq!(o.output.torque_nm, load, "k {k}");
        assert_eq!(o.applied, [false; 3]);
    }
}

/// After learning while moving, the angles stop. At a real standstill the torque stops
/// rippling: the held order is applied (its constant at that angle removed). With frozen
/// encoders the joint turns on and the torque ripples: within 0.1 s nothing is applied, and
/// the rest of the second is the raw torque (a constant taken off would be worse).
#[test]
fn held_orders_are_applied_at_a_standstill_not_under_frozen_encoders() {
    // The product model's 2× order alone, the one line of the data: the model is complete
    // once it is learned.
    let product = RippleModel::<f64, 3>::product(1000.0, 0.01).unwrap();
    let (p0, p0_bias) = product.initial_variance_nm2();
    let model = RippleModel::new([product.orders()[0]], 0.01, 1000.0)
        .and_then(|m| m.with_bias_state(product.bias_q_nm2().unwrap()))
        .and_then(|m| m.with_initial_variance(p0, p0_bias))
        .unwrap();
    let (w, amp, load, stop) = (0.05, 0.5, 2.0, 8000);
    for frozen in [false, true] {
        let mut guard = Guard::new(&model, GuardSettings::default());
        let (mut clean_e2, mut raw_e2, mut last_corrected) = (0.0, 0.0, 0);
        for k in 0..stop + 1000 {
            let input = match k {
                _ if k < stop => sample::<f64>(k, w, amp, load),
                _ if frozen => {
                    RippleInput { references: sample::<f64>(stop, w, amp, load).references, ..sample(k, w, amp, load) }
                }
                _ => sample::<f64>(stop, w, amp, load),
            };
            let o = guard.step(&model, &input).unwrap();
            if k == stop - 1 {
                assert!(o.applied[0], "frozen {frozen}: learned before the stop");
            }
            if k >= stop && o.output.torque_nm != input.torque_nm {
                last_corrected = k - stop;
            }
            if k >= stop + 100 && !frozen {
                assert!(o.applied[0], "standstill, sample {}", k - stop);
            }
            if k >= stop {
                clean_e2 += (o.output.torque_nm - load).powi(2);
                raw_e2 += (input.torque_nm - load).powi(2);
            }
        }
        let ratio = (clean_e2 / raw_e2).sqrt();
        eprintln!(
            "frozen {frozen}: the second after the stop, clean / raw {ratio:.3}; last corrected +{last_corrected}"
        );
        assert!(if frozen { ratio <= 1.0 } else { ratio < 0.1 }, "frozen {frozen}: clean / raw {ratio:.3}");
        if frozen {
            assert!(last_corrected < 100, "frozen encoders corrected until sample +{last_corrected}");
        }
    }
}

/// The settings' defaults are the documented ones.
#[test]
fn default_settings() {
    let s = GuardSettings::<f64>::default();
    assert_eq!((s.apply_chi2, s.release_chi2, s.min_cycles_output, s.window_s), (25.0, 9.0, 3.0, 0.25));
    assert_eq!((s.nis_pass_through, s.nis_recover, s.standstill_max_nis, s.complete_max_nis), (6.0, 3.0, 2.0, 3.0));
    assert!(!s.learned_prior);
}

/// One glitched sample in a warm run, of the torque (1000 or −10⁶ N·m) or of the expected torque
/// (10⁶ N·m): the canceller takes it for a load step and its bias jumps, and the load that
/// scales the load-scaled orders is far off on that sample and the next (which undoes
/// it). From the glitch on, no sample is worse (beyond the noise) than both the raw torque
/// and the run without the glitch (plus the glitch, on its sample): the load-scaled line is
/// withheld where its load jumped.
/// The glitch says nothing of the orders' fit: their running statistics are not swayed,
/// and 10 samples later they are applied as in the run without it.
#[test]
fn a_glitched_sample_makes_nothing_worse_than_raw() {
    let model = RippleModel::<f64, 5>::full(1000.0, 0.01).unwrap();
    let glitch_at = 20_000;
    for (glitch, of_expected) in [(1000.0, false), (-1e6, false), (1e6, true)] {
        let mut guard = Guard::new(&model, GuardSettings::default());
        let mut unglitched = Guard::new(&model, GuardSettings::default());
        let mut withheld = 0;
        for k in 0..glitch_at + 50 {
            let phi = 0.05 * k as f64;
            let load = 10.0 + 5.0 * (k as f64 * 1e-3).sin();
            let noise = 0.01 * (((k as f64 * 12.9898).sin() * 43_758.545).fract() - 0.5);
            // A load-scaled 2× ripple and a misalignment line.
            let y = load + (0.3 + 0.02 * load) * (2.0 * phi + 0.3).cos() + 0.2 * (phi / 50.0 + 0.7).cos() + noise;
            let refs = ReferenceValues::new(phi, phi / 50.0, phi);
            let at = if k == glitch_at { glitch } else { 0.0 };
            let input = if of_expected {
                RippleInput::new(y, refs).with_expected_torque(at)
            } else {
                RippleInput::new(y + at, refs)
            };
            let o = guard.step(&model, &input).unwrap();
            let reference = unglitched.step(&model, &RippleInput::new(y, refs)).unwrap();
            if k == glitch_at - 1 {
                assert!(o.applied[2], "the load-scaled order is applied before the glitch");
            }
            if k >= glitch_at {
                let error = |t: f64| (t - load).abs();
                let (cleaned, raw) = (error(o.output.torque_nm), error(input.torque_nm));
                // The run without the glitch, plus the glitch where it is in the torque.
                let bound = raw.max(error(reference.output.torque_nm + input.torque_nm - y)) + 0.05;
                let after = k - glitch_at;
                assert!(cleaned <= bound, "glitch {glitch}, sample +{after}: {cleaned} N·m against {bound}");
                withheld += usize::from(o.flags.contains(GuardFlags::LOAD_STEP_WITHHELD));
                if after >= 10 {
                    assert_eq!(o.applied, reference.applied, "glitch {glitch}, sample +{after}");
                }
                // Nor does it sway the running fit (which would freeze the verdicts).
                assert!(guard.mean_e2 < 2.0 * unglitched.mean_e2, "glitch {glitch}, sample +{after}");
            }
        }
        assert!(withheld >= 2, "glitch {glitch}: withheld on {withheld} samples");
    }
}
