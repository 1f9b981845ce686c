//! The streaming estimator on synthetic encoder counts with known truth: single-turn
//! counters that wrap, jumps, reversed encoders with offsets, kinematic error removal,
//! hysteresis, f32 against f64, and bad input.

use strainwave_core::compliance::{
    Compliance, FlexsplineStiffening, HdaArmCompliance, Hysteresis, WaveGeneratorSoftening,
};
use strainwave_core::gear::{FixedElement, Gear};
use strainwave_core::torsion::{
    EncoderConfig, EstimatorState, GearAngles, KinematicError, KinematicFourier, MeshAngle, NoKinematicError,
    TorqueSolver, TorsionEstimator,
};
use strainwave_core::{Error, Real};

const TAU: f64 = std::f64::consts::TAU;
/// Motor and link encoder resolution of the synthetic joint.
const MOTOR_CPR: u64 = 1 << 17;
const LINK_CPR: u64 = 1 << 20;

fn hda_arm_model<T: Real>() -> HdaArmCompliance<T> {
    HdaArmCompliance::new(
        FlexsplineStiffening::new(T::from_f64(2.0e4), T::from_f64(0.015)).unwrap(),
        WaveGeneratorSoftening::new(T::from_f64(2.5), T::from_f64(1.5)).unwrap(),
        T::from_f64(100.0),
    )
    .unwrap()
}

fn kinematic() -> KinematicFourier<f64, 2, 4> {
    KinematicFourier::new(
        3e-5,
        [[8e-5, -2e-5], [1e-5, 3e-5]],
        [[0.0, 0.0], [1.5e-5, -1e-5], [0.0, 0.0], [4e-6, 2e-6]],
        MeshAngle::Relative,
    )
    .unwrap()
}

/// Synthetic run: `(motor_angle, link_angle, true_torque)` in the gear convention.
fn run(n: usize, gear: &Gear<f64>, kin: &dyn Fn(&GearAngles<f64>) -> f64) -> Vec<(f64, f64, f64)> {
    let model = hda_arm_model::<f64>();
    (0..n)
        .map(|k| {
            let t = k as f64 * 1e-3;
            let motor = 40.0 * t + 3.0 * (0.7 * t).sin(); // several motor turns, with reversals of speed
            let torque = 60.0 * (0.9 * t).sin() + 10.0 * (7.0 * t).sin();
            let w = model.twist_rad(torque);
            let rigid = gear.output_angle(motor);
            // θ = rigid + θ_h with θ_h = θ_k − w; θ_k depends on θ itself: two fixed-point passes.
            let mut link = rigid;
            for _ in 0..3 {
                let a = GearAngles::from_f64(gear, motor, link);
                link = rigid + kin(&a) - w;
            }
            (motor, link, torque)
        })
        .collect()
}

/// A centred quantizer (the count nearest the angle).
fn counts(angle: f64, cpr: u64) -> i64 {
    (angle / (TAU / cpr as f64)).round() as i64
}

/// Quantization of the torsion, rad: half a motor count at the output plus half a link count.
fn quantization_rad(n: f64) -> f64 {
    0.5 * TAU / MOTOR_CPR as f64 / n + 0.5 * TAU / LINK_CPR as f64
}

#[test]
fn single_turn_counters_wrap_without_losing_torque() {
    let gear = Gear::new(100.0, FixedElement::CircularSpline).unwrap();
    let kin = kinematic();
    let data = run(20_000, &gear, &|a| kin.kinematic_error_rad(a));
    let est = TorsionEstimator::new(
        gear,
        EncoderConfig::single_turn(MOTOR_CPR).unwrap(),
        EncoderConfig::single_turn(LINK_CPR).unwrap(),
        kin,
        hda_arm_model::<f64>(),
        TorqueSolver::for_rated_torque(40.0).unwrap(),
    );
    let mut st = EstimatorState::new();
    let (mut wraps, mut worst, mut max_iter) = (0, 0.0_f64, 0);
    // Worst torque error from quantization: stiffest tangent (≈ 3e4 N·m/rad at 70 N·m) × quantization.
    let bound = 3.5e4 * quantization_rad(100.0);
    for &(m, l, tau) in &data {
        let mc = counts(m, MOTOR_CPR).rem_euclid(MOTOR_CPR as i64);
        let lc = counts(l, LINK_CPR).rem_euclid(LINK_CPR as i64);
        let e = est.step_counts(&mut st, mc, lc).unwrap();
        assert!(!e.flags.any_jump());
        wraps += usize::from(e.flags.motor_wrapped) + usize::from(e.flags.link_wrapped);
        worst = worst.max((e.link_torque_nm - tau).abs());
        max_iter = max_iter.max(e.iterations);
    }
    println!("wraps {wraps}, worst |error| {worst:.4} N·m (bound {bound:.4}), max iterations {max_iter}");
    assert!(wraps >= 100, "{wraps}");
    assert!(worst < bound, "{worst}");
    assert!(max_iter <= 6);
}

#[test]
fn kinematic_error_model_removes_the_bias() {
    let gear = Gear::new(100.0, FixedElement::CircularSpline).unwrap();
    let kin = kinematic();
    let data = run(20_000, &gear, &|a| kin.kinematic_error_rad(a));
    let make = |with_kin: bool| {
        let e1 = TorsionEstimator::new(
            gear,
            EncoderConfig::multi_turn(MOTOR_CPR).unwrap(),
            EncoderConfig::multi_turn(LINK_CPR).unwrap(),
            kin,
            hda_arm_model::<f64>(),
            TorqueSolver::for_rated_torque(40.0).unwrap(),
        );
        let e0 = TorsionEstimator::new(
            gear,
            EncoderConfig::multi_turn(MOTOR_CPR).unwrap(),
            EncoderConfig::multi_turn(LINK_CPR).unwrap(),
            NoKinematicError,
            hda_arm_model::<f64>(),
            TorqueSolver::for_rated_torque(40.0).unwrap(),
        );
        let (mut s0, mut s1) = (EstimatorState::new(), EstimatorState::new());
        let mut sum = 0.0;
        for &(m, l, tau) in &data {
            let (mc, lc) = (counts(m, MOTOR_CPR), counts(l, LINK_CPR));
            let est = if with_kin {
                e1.step_counts(&mut s1, mc, lc).unwrap().link_torque_nm
            } else {
                e0.step_counts(&mut s0, mc, lc).unwrap().link_torque_nm
            };
            sum += (est - tau).abs();
        }
        sum / data.len() as f64
    };
    let (with, without) = (make(true), make(false));
    println!("mean |error|: with kinematic model {with:.4} N·m, without {without:.4} N·m");
    assert!(with < 0.04, "{with}");
    assert!(without > 10.0 * with);
}

#[test]
fn reversed_motor_encoder_with_offsets_as_on_lara8() {
    // LARA8 joint 3: ratio 101, 2^24 counts per rev, the motor encoder counts against the WG.
    let gear = Gear::new(101.0, FixedElement::CircularSpline).unwrap();
    let cpr = 1u64 << 24;
    let (off_m, off_l) = (-462_313_317_i64, 1_144_971_i64);
    let est = TorsionEstimator::new(
        gear,
        EncoderConfig::multi_turn(cpr).unwrap().with_offset(off_m).reversed(),
        EncoderConfig::multi_turn(cpr).unwrap().with_offset(off_l),
        NoKinematicError,
        strainwave_core::compliance::ThreeSlopeStiffness::new(31e3, 50e3, 57e3, 14.0, 48.0).unwrap(),
        TorqueSolver::for_rated_torque(100.0).unwrap(),
    );
    let est32 = TorsionEstimator::new(
        Gear::new(101.0_f32, FixedElement::CircularSpline).unwrap(),
        EncoderConfig::multi_turn(cpr).unwrap().with_offset(off_m).reversed(),
        EncoderConfig::multi_turn(cpr).unwrap().with_offset(off_l),
        NoKinematicError,
        strainwave_core::compliance::ThreeSlopeStiffness::new(31e3_f32, 50e3, 57e3, 14.0, 48.0).unwrap(),
        TorqueSolver::for_rated_torque(100.0_f32).unwrap(),
    );
    let (mut st, mut st32) = (EstimatorState::new(), EstimatorState::new());
    for k in 0..2000 {
        let link = -2.6 + 5.2 * k as f64 / 2000.0; // the LARA8 sweep
        let torque = 80.0 * (link + 1.1).cos();
        let w = strainwave_core::compliance::ThreeSlopeStiffness::new(31e3, 50e3, 57e3, 14.0, 48.0)
            .unwrap()
            .twist_rad(torque);
        // Gear convention: θ_wg = −θ_enc; rigid output = θ_wg / (−101) = θ_enc / 101; link = rigid − w.
        let motor_enc = (link + w) * 101.0;
        let mc = off_m + (motor_enc / (TAU / cpr as f64)).round() as i64;
        let lc = off_l + (link / (TAU / cpr as f64)).round() as i64;
        let e = est.step_counts(&mut st, mc, lc).unwrap();
        let e32 = est32.step_counts(&mut st32, mc, lc).unwrap();
        assert!((e.link_torque_nm - torque).abs() < 0.02, "{k}: {} vs {torque}", e.link_torque_nm);
        assert!((e32.link_torque_nm as f64 - torque).abs() < 0.05, "{k}: f32 {} vs {torque}", e32.link_torque_nm);
    }
}

#[test]
fn hysteresis_is_tracked() {
    let gear = Gear::new(100.0, FixedElement::CircularSpline).unwrap();
    let model = hda_arm_model::<f64>();
    let hyst = Hysteresis::new(1.0e-4, 5.0e-5).unwrap();
    let solver = TorqueSolver::for_rated_torque(40.0).unwrap();
    let est = TorsionEstimator::new(
        gear,
        EncoderConfig::multi_turn(MOTOR_CPR).unwrap(),
        EncoderConfig::multi_turn(LINK_CPR).unwrap(),
        NoKinematicError,
        model,
        solver,
    )
    .with_hysteresis(hyst, 1.5 * TAU / LINK_CPR as f64)
    .unwrap();
    let plain = TorsionEstimator::new(
        gear,
        EncoderConfig::multi_turn(MOTOR_CPR).unwrap(),
        EncoderConfig::multi_turn(LINK_CPR).unwrap(),
        NoKinematicError,
        model,
        solver,
    );
    let (mut st, mut st0) = (EstimatorState::new(), EstimatorState::new());
    let (mut z, mut w_prev) = (0.0, 0.0);
    let (mut err, mut err0, mut sum, mut sum0, mut n) = (0.0_f64, 0.0_f64, 0.0, 0.0, 0.0);
    for k in 0..20_000 {
        let t = k as f64 * 1e-3;
        let w = 2e-3 * (0.8 * t).sin() + 4e-4 * (5.0 * t).sin(); // wind-up with minor loops
        z = hyst.update(z, if k == 0 { 0.0 } else { w - w_prev });
        w_prev = w;
        let torque = solver.solve(&model, hyst.elastic_twist_rad(w, z), 0.0).unwrap().torque_nm;
        let motor = 0.3 * t;
        let link = gear.output_angle(motor) - w;
        let (mc, lc) = (counts(motor, MOTOR_CPR), counts(link, LINK_CPR));
        let e = est.step_counts(&mut st, mc, lc).unwrap();
        let e0 = plain.step_counts(&mut st0, mc, lc).unwrap();
        if k > 100 {
            err = err.max((e.link_torque_nm - torque).abs());
            err0 = err0.max((e0.link_torque_nm - torque).abs());
            sum += (e.link_torque_nm - torque).abs();
            sum0 += (e0.link_torque_nm - torque).abs();
            n += 1.0;
        }
    }
    let (mean, mean0) = (sum / n, sum0 / n);
    println!("mean/max |error| with hysteresis model {mean:.3}/{err:.3} N·m, without {mean0:.3}/{err0:.3} N·m");
    // The play operator recognises a reversal 1.5 counts late: the max error sits there.
    assert!(err < 0.6, "{err}");
    assert!(mean < 0.1, "{mean}");
    assert!(mean0 > 5.0 * mean, "{mean0}");
}

#[test]
fn jumps_and_bad_input_are_reported() {
    let gear = Gear::new(100.0, FixedElement::CircularSpline).unwrap();
    let est = TorsionEstimator::new(
        gear,
        EncoderConfig::single_turn(MOTOR_CPR).unwrap(),
        EncoderConfig::multi_turn(LINK_CPR).unwrap().with_max_step(1000),
        NoKinematicError,
        hda_arm_model::<f64>(),
        TorqueSolver::for_rated_torque(40.0).unwrap(),
    );
    let mut st = EstimatorState::new();
    est.step_counts(&mut st, 10, 0).unwrap();
    // A link glitch of 5000 counts: flagged, and far out of the model's range.
    let r = est.step_counts(&mut st, 10, 5000);
    assert!(st.last_flags().link_jump);
    assert_eq!(r, Err(Error::OutOfRange("windup_rad")));
    assert_eq!(st.failures(), 1);
    // Raw counts outside a single-turn counter's range.
    assert_eq!(est.step_counts(&mut st, -1, 0), Err(Error::OutOfRange("motor_counts")));
    assert_eq!(est.step_counts(&mut st, MOTOR_CPR as i64, 0), Err(Error::OutOfRange("motor_counts")));
    // Non-finite angles.
    assert_eq!(est.step_angles(&mut st, f64::NAN, 0.0), Err(Error::NonFinite("motor_angle_rad")));
    assert_eq!(est.step_angles(&mut st, 0.0, f64::INFINITY), Err(Error::NonFinite("link_angle_rad")));
    // Back to good data: recovers.
    let e = est.step_angles(&mut st, 0.0, 0.0).unwrap();
    assert!(e.link_torque_nm.abs() < 1e-9);
    assert!(EncoderConfig::single_turn(0).is_err());
}

#[test]
fn single_turn_motor_turn_count_is_resolved_at_start() {
    // Start the joint at link angle 1.0 rad: the motor is 100 turns away, a single-turn
    // counter cannot tell; the estimator picks the turn that makes the torsion small.
    let gear = Gear::new(100.0, FixedElement::CircularSpline).unwrap();
    let est = TorsionEstimator::new(
        gear,
        EncoderConfig::single_turn(MOTOR_CPR).unwrap(),
        EncoderConfig::single_turn(LINK_CPR).unwrap(),
        NoKinematicError,
        hda_arm_model::<f64>(),
        TorqueSolver::for_rated_torque(40.0).unwrap(),
    );
    let mut st = EstimatorState::new();
    let w = hda_arm_model::<f64>().twist_rad(25.0);
    let link = 1.0;
    let motor = (link + w) * -100.0;
    let mc = counts(motor, MOTOR_CPR).rem_euclid(MOTOR_CPR as i64);
    let lc = counts(link, LINK_CPR).rem_euclid(LINK_CPR as i64);
    let e = est.step_counts(&mut st, mc, lc).unwrap();
    assert!((e.link_torque_nm - 25.0).abs() < 0.2, "{e:?}");
}
