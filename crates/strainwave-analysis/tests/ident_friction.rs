//! Friction and rotor inertia identified with the compliance against a synthetic
//! motor-current torque (known parameters), and the blocked holdout on it.

use strainwave_analysis::ident::{
    blocked_holdout, fit_compliance, motion_rates, training_rows, ComplianceFitOptions, ComplianceForm,
    ComplianceParams, FrictionFitOptions, FrictionParams, JointAngles,
};
use strainwave_core::compliance::{Compliance, ThreeSlopeStiffness};
use strainwave_core::gear::{FixedElement, Gear};
use strainwave_core::torsion::NoKinematicError;

const FS_HZ: f64 = 500.0;
const RATIO: f64 = 100.0;

fn gear() -> Gear<f64> {
    Gear::new(RATIO, FixedElement::CircularSpline).unwrap()
}

/// A swinging joint: link torque `τ(t)`, the spring's twist on the link side, and the
/// current torque with the given friction. Returns (motor, link, link torque, current torque).
fn swing(spring: &impl Compliance<f64>, friction: &FrictionParams) -> (Vec<f64>, Vec<f64>, Vec<f64>, Vec<f64>) {
    let n = 6000;
    let g = gear();
    let mut motor = Vec::with_capacity(n);
    let mut link = Vec::with_capacity(n);
    let mut torque = Vec::with_capacity(n);
    for k in 0..n {
        let t = k as f64 / FS_HZ;
        // The motor sweeps back and forth; the load follows the angle (gravity) plus a wobble.
        let theta_m_link = 0.8 * (0.7 * t).sin() + 0.1 * (2.3 * t).sin();
        let tau = 40.0 * theta_m_link.cos() + 15.0 * (1.9 * t).sin();
        // w = θ_k − θ_h with θ_k = 0: the torsion θ_h = θ − θ_m/n_s is −twist(τ).
        let twist = spring.twist_rad(tau);
        motor.push(theta_m_link * g.signed_ratio());
        link.push(theta_m_link - twist);
        torque.push(tau);
    }
    let (v, a) =
        motion_rates(&motor.iter().map(|m| m / g.signed_ratio()).collect::<Vec<_>>(), FS_HZ, friction.rate_span)
            .unwrap();
    let current = torque.iter().zip(v.iter().zip(&a)).map(|(t, (v, a))| t + friction.torque_nm(*t, *v, *a)).collect();
    (motor, link, torque, current)
}

fn truth() -> FrictionParams {
    FrictionParams {
        coulomb_nm: 6.0,
        viscous_nm_s_per_rad: 20.0,
        stribeck_nm: 0.0,
        stribeck_speed_rad_s: 0.0,
        inertia_kg_m2: 2.5,
        load_coefficient: 0.05,
        smoothing_speed_rad_s: 0.01,
        rate_span: 4,
    }
}

#[test]
fn linear_spring_and_friction_in_one_solve() {
    let spring = ThreeSlopeStiffness::linear(30e3).unwrap();
    let f = truth();
    let (m, l, link_torque, current) = swing(&spring, &f);
    let a = JointAngles { motor_angle_rad: &m, link_angle_rad: &l, sample_rate_hz: FS_HZ };
    let mut o = ComplianceFitOptions::new(ComplianceForm::Linear, 100.0);
    o.friction = Some(FrictionFitOptions { load_dependent: true, ..Default::default() });
    let fit = fit_compliance(&gear(), &NoKinematicError, &a, &current, &o).unwrap();
    let got = fit.friction.unwrap();
    println!("{:?}\n{:?}", fit.params, got);
    let ComplianceParams::Linear { k_nm_per_rad } = fit.params else { panic!("{:?}", fit.params) };
    assert!((k_nm_per_rad / 30e3 - 1.0).abs() < 1e-6, "{k_nm_per_rad}");
    assert!((got.coulomb_nm - 6.0).abs() < 1e-4 && (got.viscous_nm_s_per_rad - 20.0).abs() < 1e-4, "{got:?}");
    assert!((got.inertia_kg_m2 - 2.5).abs() < 1e-4 && (got.load_coefficient - 0.05).abs() < 1e-6, "{got:?}");
    assert!(fit.converged() && fit.termination.is_none() && fit.metrics.r_squared > 1.0 - 1e-9);
    assert_eq!(fit.parameters.len(), 5);
    // The link torque alone is recovered from the torsion, the friction kept apart.
    let link = fit.predict(&gear(), NoKinematicError, &a).unwrap();
    let err = link.iter().zip(&link_torque).map(|(p, t)| (p - t).abs()).fold(0.0, f64::max);
    assert!(err < 1e-6, "{err}");
    // Without friction the same spring fit against the current torque is biased.
    let plain = fit_compliance(
        &gear(),
        &NoKinematicError,
        &a,
        &current,
        &ComplianceFitOptions::new(ComplianceForm::Linear, 100.0),
    )
    .unwrap();
    assert!(plain.metrics.r_squared < fit.metrics.r_squared - 0.01, "{:?}", plain.metrics);
}

#[test]
fn three_slope_spring_and_friction_alternately_with_holdout() {
    let spring = ThreeSlopeStiffness::new(25e3, 40e3, 50e3, 14.0, 48.0).unwrap();
    let f = truth();
    let (m, l, _, current) = swing(&spring, &f);
    let a = JointAngles { motor_angle_rad: &m, link_angle_rad: &l, sample_rate_hz: FS_HZ };
    let mut o = ComplianceFitOptions::new(ComplianceForm::ThreeSlope { t1_nm: 14.0, t2_nm: 48.0 }, 100.0);
    o.friction = Some(FrictionFitOptions { load_dependent: true, ..Default::default() });
    let fit = fit_compliance(&gear(), &NoKinematicError, &a, &current, &o).unwrap();
    let got = fit.friction.unwrap();
    println!("{:?}\n{:?}\n{:?}", fit.params, got, fit.termination);
    assert!(fit.converged(), "{:?}", fit.termination);
    let ComplianceParams::ThreeSlope { k1_nm_per_rad, k2_nm_per_rad, k3_nm_per_rad, .. } = fit.params else {
        panic!("{:?}", fit.params)
    };
    for (got, want) in [(k1_nm_per_rad, 25e3), (k2_nm_per_rad, 40e3), (k3_nm_per_rad, 50e3)] {
        assert!((got / want - 1.0).abs() < 0.02, "{got} vs {want}");
    }
    assert!((got.coulomb_nm - 6.0).abs() < 0.1 && (got.inertia_kg_m2 - 2.5).abs() < 0.1, "{got:?}");
    assert!((got.load_coefficient - 0.05).abs() < 0.005, "{got:?}");
    assert!(fit.parameters.iter().all(|p| p.std_error.is_finite()), "{:?}", fit.parameters);
    // Blocked holdout: each fifth predicted from the other four.
    let n = current.len();
    let score = blocked_holdout(&current, 5, |_, block| {
        let o = ComplianceFitOptions { train_rows: Some(training_rows(n, block)), ..o.clone() };
        let fit = fit_compliance(&gear(), &NoKinematicError, &a, &current, &o)?;
        Ok(fit.predict_reference(&gear(), NoKinematicError, &a)?[block.clone()].to_vec())
    })
    .unwrap();
    println!("holdout {score:?}");
    // Measured 0.9943: a block whose torque leaves the range the others span is extrapolated.
    assert!(score.r_squared > 0.99, "{score:?}");
}

#[test]
fn friction_on_a_still_joint_is_refused() {
    let n = 2000;
    let m = vec![0.0; n];
    let l: Vec<f64> = (0..n).map(|k| 1e-4 * (k as f64 * 0.01).sin()).collect();
    let q: Vec<f64> = l.iter().map(|l| 3e4 * l).collect();
    let a = JointAngles { motor_angle_rad: &m, link_angle_rad: &l, sample_rate_hz: FS_HZ };
    let mut o = ComplianceFitOptions::new(ComplianceForm::Linear, 100.0);
    o.friction = Some(FrictionFitOptions { load_dependent: true, ..Default::default() });
    let e = fit_compliance(&gear(), &NoKinematicError, &a, &q, &o).unwrap_err();
    assert!(e.to_string().contains("not identifiable"), "{e}");
}
