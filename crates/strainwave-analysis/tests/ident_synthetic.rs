//! Identification on synthetic runs with known parameters: recovery of the paper's
//! polynomial and of compliance parameters (linear least squares and Levenberg–Marquardt),
//! and the errors for bad or unexciting data.

use strainwave_analysis::ident::{
    fit_compliance, fit_kinematic_error, select_kinematic_basis, ComplianceFitOptions, ComplianceForm,
    ComplianceParams, FittedHysteresis, HysteresisForm, JointAngles, KinematicBasis, KinematicFitOptions,
};
use strainwave_analysis::AnalysisError;
use strainwave_core::compliance::{
    Compliance, CubicStiffness, FlexsplineStiffening, HdaArmCompliance, PlayHysteresis, ThreeSlopeStiffness,
    WaveGeneratorSoftening,
};
use strainwave_core::gear::{FixedElement, Gear};
use strainwave_core::torsion::{GearAngles, KinematicError, KinematicPolynomial, MeshAngle, NoKinematicError};

const N: f64 = 100.0;
const FS_HZ: f64 = 1000.0;

fn gear() -> Gear<f64> {
    Gear::new(N, FixedElement::CircularSpline).unwrap()
}

/// A loaded run at a held motor: `(motor, link, torque)` with the link twisted by `twist(τ)`.
fn held_run(n: usize, twist: impl Fn(f64, usize) -> f64) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
    let torque: Vec<f64> = (0..n)
        .map(|k| {
            let t = k as f64 / FS_HZ;
            50.0 * (0.5 * t).sin() + 12.0 * (3.3 * t).sin()
        })
        .collect();
    let motor = vec![0.0; n];
    let link: Vec<f64> = torque.iter().enumerate().map(|(k, tau)| -twist(*tau, k)).collect();
    (motor, link, torque)
}

#[test]
fn hda_arm_polynomial_is_recovered_over_one_motor_revolution() {
    // HDA arm, Table II: the polynomial over one motor revolution (2π/N of output).
    let truth = KinematicPolynomial::<f64, 6>::hda_arm();
    let g = gear();
    let n = 4000;
    let (mut motor, mut link) = (Vec::new(), Vec::new());
    for k in 0..n {
        // The link angle the encoder reads; the motor sits where θ_h = θ − θ_m/n_s = θ_k(θ).
        let out = std::f64::consts::TAU / N * k as f64 / n as f64;
        link.push(out);
        motor.push((out - truth.eval(out)) * g.signed_ratio());
    }
    let a = JointAngles { motor_angle_rad: &motor, link_angle_rad: &link, sample_rate_hz: FS_HZ };
    let opts = KinematicFitOptions { direction_offset: false, ..Default::default() };
    let fit = fit_kinematic_error(&g, &a, KinematicBasis::Polynomial { order: 5 }, &opts).unwrap();
    for (got, want) in fit.coefficients.iter().zip(truth.coefficients()) {
        assert!((got - want).abs() < 1e-6 * (1.0 + want.abs()), "{:?}", fit.coefficients);
    }
    let core = fit.to_polynomial::<6>().unwrap();
    assert!((core.eval(0.05) - truth.eval(0.05)).abs() < 1e-12);
    println!("the paper's polynomial refitted: {:?}", fit.coefficients);
    // A run that does not move cannot be fitted.
    let still = vec![0.0; 100];
    let a = JointAngles { motor_angle_rad: &still, link_angle_rad: &still, sample_rate_hz: FS_HZ };
    assert!(matches!(
        fit_kinematic_error(&g, &a, KinematicBasis::Polynomial { order: 5 }, &opts),
        Err(AnalysisError::Invalid { what: "link_angle_rad", .. })
    ));
}

#[test]
fn cross_validation_prefers_the_true_order() {
    let g = gear();
    let n = 20_000;
    let (mut motor, mut link) = (Vec::new(), Vec::new());
    let mut noise = 0x2545F4914F6CDD1D_u64;
    for k in 0..n {
        let out = 1.2 * std::f64::consts::TAU * k as f64 / n as f64;
        let m = out * g.signed_ratio();
        let phi = m - out;
        noise ^= noise << 13;
        noise ^= noise >> 7;
        noise ^= noise << 17;
        let e = 1e-6 * ((noise >> 11) as f64 / (1u64 << 53) as f64 - 0.5);
        link.push(out + 5e-5 * out.sin() + 2e-5 * (2.0 * phi + 0.3).sin() + e);
        motor.push(m);
    }
    let a = JointAngles { motor_angle_rad: &motor, link_angle_rad: &link, sample_rate_hz: FS_HZ };
    let cands: Vec<KinematicBasis> = (0..=3)
        .map(|hr| KinematicBasis::Fourier { output_harmonics: 1, mesh_harmonics: hr, mesh_angle: MeshAngle::Relative })
        .collect();
    let (best, cv) = select_kinematic_basis(&g, &a, &cands, 4, &KinematicFitOptions::default()).unwrap();
    println!("cv {cv:?} → {:?}", best.basis);
    assert!(matches!(best.basis, KinematicBasis::Fourier { mesh_harmonics: 2 | 3, .. }));
    assert!(cv[2] < 0.1 * cv[1]);
}

#[test]
fn linear_and_cubic_stiffness_by_least_squares() {
    let g = gear();
    let cubic = CubicStiffness::new(1.1e4, 3.0e8).unwrap();
    let (m, l, tau) = held_run(5000, |t, _| cubic.twist_rad(t));
    let a = JointAngles { motor_angle_rad: &m, link_angle_rad: &l, sample_rate_hz: FS_HZ };
    let fit = fit_compliance(&g, &NoKinematicError, &a, &tau, &ComplianceFitOptions::new(ComplianceForm::Cubic, 40.0))
        .unwrap();
    match fit.params {
        ComplianceParams::Cubic { k1_nm_per_rad, k3_nm_per_rad3 } => {
            assert!((k1_nm_per_rad / 1.1e4 - 1.0).abs() < 1e-6, "{k1_nm_per_rad}");
            assert!((k3_nm_per_rad3 / 3.0e8 - 1.0).abs() < 1e-5, "{k3_nm_per_rad3}");
        }
        p => panic!("{p:?}"),
    }
    assert_eq!(fit.iterations, 0);
    assert!(fit.metrics.max_abs < 1e-6 && fit.metrics.r_squared > 0.999_999_9);
    let lin = fit_compliance(&g, &NoKinematicError, &a, &tau, &ComplianceFitOptions::new(ComplianceForm::Linear, 40.0))
        .unwrap();
    assert!(lin.metrics.rms > 100.0 * fit.metrics.rms);
}

#[test]
fn three_slope_and_hda_arm_springs_by_levenberg_marquardt() {
    let g = gear();
    let k = ThreeSlopeStiffness::new(1.3e4, 1.8e4, 2.3e4, 7.0, 25.0).unwrap();
    let (m, l, tau) = held_run(6000, |t, _| Compliance::twist_rad(&k, t));
    let a = JointAngles { motor_angle_rad: &m, link_angle_rad: &l, sample_rate_hz: FS_HZ };
    let mut o = ComplianceFitOptions::new(ComplianceForm::ThreeSlope { t1_nm: 7.0, t2_nm: 25.0 }, 40.0);
    o.decimation = 4;
    let fit = fit_compliance(&g, &NoKinematicError, &a, &tau, &o).unwrap();
    match fit.params {
        ComplianceParams::ThreeSlope { k1_nm_per_rad, k2_nm_per_rad, k3_nm_per_rad, .. } => {
            for (got, want) in [(k1_nm_per_rad, 1.3e4), (k2_nm_per_rad, 1.8e4), (k3_nm_per_rad, 2.3e4)] {
                assert!((got / want - 1.0).abs() < 1e-4, "{got} vs {want}");
            }
        }
        p => panic!("{p:?}"),
    }
    let springs = HdaArmCompliance::new(
        FlexsplineStiffening::new(2.0e4, 0.015).unwrap(),
        WaveGeneratorSoftening::new(2.5, 1.5).unwrap(),
        N,
    )
    .unwrap();
    let (m, l, tau) = held_run(6000, |t, _| springs.twist_rad(t));
    let a = JointAngles { motor_angle_rad: &m, link_angle_rad: &l, sample_rate_hz: FS_HZ };
    let mut o = ComplianceFitOptions::new(ComplianceForm::Seed { ratio: N }, 40.0);
    o.decimation = 4;
    o.max_iterations = 80;
    let fit = fit_compliance(&g, &NoKinematicError, &a, &tau, &o).unwrap();
    println!("HDA-arm springs: {:?} {:?}", fit.params, fit.metrics);
    // Two hardening springs in series are nearly interchangeable: check the curve, not each parameter.
    assert!(fit.metrics.max_abs < 0.02, "{:?}", fit.metrics);
}

#[test]
fn play_hysteresis_and_offset_are_fitted() {
    let g = gear();
    let k = ThreeSlopeStiffness::linear(1.2e4).unwrap();
    let widths = [2e-5, 6e-5, 1.8e-4];
    let truth = PlayHysteresis::new(&widths, &[3e-5, 5e-5, 4e-5]).unwrap();
    // Drive the wind-up, then compute the torque the plays give (elastic = w + Σβζ).
    let n = 8000;
    let mut plays = truth.initial_state(0.0);
    let w0 = 3e-5; // a zero offset the fit must find
    let mut link = Vec::new();
    let mut tau = Vec::new();
    for i in 0..n {
        let t = i as f64 / FS_HZ;
        let w = 3e-3 * (0.4 * t).sin() + 6e-4 * (2.9 * t).sin();
        truth.advance(&mut plays, w);
        tau.push(k.torque_nm(w + truth.offset_rad(&plays, w)));
        link.push(-(w - w0));
    }
    let motor = vec![0.0; n];
    let a = JointAngles { motor_angle_rad: &motor, link_angle_rad: &link, sample_rate_hz: FS_HZ };
    let mut o = ComplianceFitOptions::new(ComplianceForm::Linear, 40.0);
    o.hysteresis = HysteresisForm::Plays { half_widths_rad: widths.to_vec() };
    o.windup_offset = true;
    o.decimation = 2;
    let fit = fit_compliance(&g, &NoKinematicError, &a, &tau, &o).unwrap();
    println!("{fit:?}");
    assert!((fit.windup_offset_rad - w0).abs() < 1e-7, "{}", fit.windup_offset_rad);
    match &fit.hysteresis {
        FittedHysteresis::Plays { weights_rad, .. } => {
            for (got, want) in weights_rad.iter().zip([3e-5, 5e-5, 4e-5]) {
                assert!((got - want).abs() < 1e-7, "{weights_rad:?}");
            }
        }
        h => panic!("{h:?}"),
    }
    assert!(fit.metrics.max_abs < 1e-3);
    // Without hysteresis the same data fit ~1 N·m worse.
    let mut o2 = ComplianceFitOptions::new(ComplianceForm::Linear, 40.0);
    o2.windup_offset = true;
    let plain = fit_compliance(&g, &NoKinematicError, &a, &tau, &o2).unwrap();
    assert!(plain.metrics.rms > 0.3, "{:?}", plain.metrics);
}

#[test]
fn bad_data_is_an_error() {
    let g = gear();
    let (m, l, tau) = held_run(500, |t, _| t / 1e4);
    let a = JointAngles { motor_angle_rad: &m, link_angle_rad: &l, sample_rate_hz: FS_HZ };
    let o = ComplianceFitOptions::new(ComplianceForm::Linear, 40.0);
    let mut bad = tau.clone();
    bad[17] = f64::NAN;
    assert_eq!(
        fit_compliance(&g, &NoKinematicError, &a, &bad, &o).unwrap_err(),
        AnalysisError::NonFinite { what: "reference_torque_nm", index: 17 }
    );
    // No load: the reference does not move.
    let flat = vec![0.2; tau.len()];
    assert!(matches!(
        fit_compliance(&g, &NoKinematicError, &a, &flat, &o),
        Err(AnalysisError::Invalid { what: "reference_torque_nm", .. })
    ));
    // The joint never twists.
    let still = vec![0.0; tau.len()];
    let a0 = JointAngles { motor_angle_rad: &m, link_angle_rad: &still, sample_rate_hz: FS_HZ };
    assert!(matches!(
        fit_compliance(&g, &NoKinematicError, &a0, &tau, &o),
        Err(AnalysisError::Invalid { what: "windup_rad", .. })
    ));
    // Lengths, shortness, NaN angles.
    assert!(fit_compliance(&g, &NoKinematicError, &a, &tau[..100], &o).is_err());
    let short = JointAngles { motor_angle_rad: &m[..5], link_angle_rad: &l[..5], sample_rate_hz: FS_HZ };
    assert!(matches!(
        fit_compliance(&g, &NoKinematicError, &short, &tau[..5], &o),
        Err(AnalysisError::TooShort { .. })
    ));
    let mut ln = l.clone();
    ln[3] = f64::INFINITY;
    let an = JointAngles { motor_angle_rad: &m, link_angle_rad: &ln, sample_rate_hz: FS_HZ };
    assert_eq!(
        fit_compliance(&g, &NoKinematicError, &an, &tau, &o).unwrap_err(),
        AnalysisError::NonFinite { what: "link_angle_rad", index: 3 }
    );
    let mut o_bad = o.clone();
    o_bad.hysteresis = HysteresisForm::Plays { half_widths_rad: vec![0.0] };
    assert!(fit_compliance(&g, &NoKinematicError, &a, &tau, &o_bad).is_err());
    struct Zero;
    impl KinematicError<f64> for Zero {
        fn kinematic_error_rad(&self, _: &GearAngles<f64>) -> f64 {
            0.0
        }
    }
    let _ = Zero.kinematic_error_rad(&GearAngles::default());
}
