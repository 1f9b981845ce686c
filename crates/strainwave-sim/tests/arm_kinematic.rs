//! Kinematic error on the twin: over a full output revolution the Fourier model (in the
//! output and the relative angle) beats the paper's 5th-order polynomial in the output
//! angle, both against the true kinematic error and in the torque estimated while the
//! arm turns; cross-validation finds the mesh harmonics; a held run cannot identify it.

use strainwave_analysis::ident::{
    cross_validate_kinematic, fit_kinematic_error, FitMetrics, JointAngles, KinematicBasis, KinematicFitOptions,
};
use strainwave_analysis::AnalysisError;
use strainwave_core::gear::{FixedElement, Gear};
use strainwave_core::torsion::MeshAngle;
use strainwave_sim::arm::{simulate_arm, ArmExperiment, ArmRecording, ArmScenario};

fn run(e: ArmExperiment) -> ArmRecording {
    simulate_arm(&ArmScenario::experiment(e).unwrap()).unwrap()
}

fn angles(r: &ArmRecording) -> JointAngles<'_> {
    JointAngles {
        motor_angle_rad: r.column("motor_angle").unwrap(),
        link_angle_rad: r.column("link_angle").unwrap(),
        sample_rate_hz: 1000.0,
    }
}

/// RMS of `a − b` after removing the mean (the quantization bias of the torsion, common
/// to every run and so cancelled in the wind-up).
fn rms_centred(a: &[f64], b: &[f64]) -> f64 {
    let d: Vec<f64> = a.iter().zip(b).map(|(x, y)| x - y).collect();
    let m = d.iter().sum::<f64>() / d.len() as f64;
    (d.iter().map(|v| (v - m).powi(2)).sum::<f64>() / d.len() as f64).sqrt()
}

const FOURIER: KinematicBasis =
    KinematicBasis::Fourier { output_harmonics: 2, mesh_harmonics: 4, mesh_angle: MeshAngle::Relative };
const PAPER_POLY: KinematicBasis = KinematicBasis::Polynomial { order: 5 };

#[test]
fn fourier_beats_the_fifth_order_polynomial_over_a_revolution() {
    let gear = Gear::new(100.0, FixedElement::CircularSpline).unwrap();
    let no_load = run(ArmExperiment::NoLoad);
    let opts = KinematicFitOptions::default();
    let fourier = fit_kinematic_error(&gear, &angles(&no_load), FOURIER, &opts).unwrap();
    let poly = fit_kinematic_error(&gear, &angles(&no_load), PAPER_POLY, &opts).unwrap();
    // On another run that turns the link a revolution (constant motor torque, load by hand).
    let turning = run(ArmExperiment::PeriodicConstantTorque);
    let truth = turning.column("true_kinematic_error").unwrap();
    let e_f = rms_centred(&fourier.eval_run(&gear, &angles(&turning)), truth);
    let e_p = rms_centred(&poly.eval_run(&gear, &angles(&turning)), truth);
    let on_fit_f =
        rms_centred(&fourier.eval_run(&gear, &angles(&no_load)), no_load.column("true_kinematic_error").unwrap());
    let on_fit_p =
        rms_centred(&poly.eval_run(&gear, &angles(&no_load)), no_load.column("true_kinematic_error").unwrap());
    println!("kinematic error rms vs truth, no-load run: Fourier {on_fit_f:.2e} rad, 5th-order polynomial {on_fit_p:.2e} rad");
    println!("kinematic error rms vs truth, turning run: Fourier {e_f:.2e} rad, 5th-order polynomial {e_p:.2e} rad");
    println!("torsion fit: Fourier {:?}\n             polynomial {:?}", fourier.metrics, poly.metrics);
    // The polynomial cannot follow the relative-angle harmonics (1.5e-5 rad at 2φ).
    assert!(e_f < 2.0e-6, "{e_f}");
    assert!(e_p > 5.0 * e_f, "{e_p} vs {e_f}");
    assert!(fourier.metrics.rms < poly.metrics.rms / 3.0);
    // The fit converts to the core's const-generic model and evaluates the same.
    let core = fourier.to_fourier::<2, 4>().unwrap();
    let a = strainwave_core::torsion::GearAngles::from_f64(&gear, 12.3, -0.4);
    use strainwave_core::torsion::KinematicError;
    assert!((core.kinematic_error_rad(&a) - fourier.eval(&a)).abs() < 1e-15);
    assert!(fourier.to_fourier::<1, 4>().is_err());
    assert!(poly.to_polynomial::<6>().is_ok());
    let _ = FitMetrics::of(&[0.0], &[0.0]);
}

#[test]
fn cross_validation_finds_the_mesh_harmonics() {
    let gear = Gear::new(100.0, FixedElement::CircularSpline).unwrap();
    let no_load = run(ArmExperiment::NoLoad);
    let candidates: Vec<KinematicBasis> = [0, 1, 2, 4, 8]
        .iter()
        .map(|&hr| KinematicBasis::Fourier { output_harmonics: 2, mesh_harmonics: hr, mesh_angle: MeshAngle::Relative })
        .chain([PAPER_POLY])
        .collect();
    let cv =
        cross_validate_kinematic(&gear, &angles(&no_load), &candidates, 5, &KinematicFitOptions::default()).unwrap();
    println!("5-fold CV rms (rad): {:?}", candidates.iter().zip(&cv).collect::<Vec<_>>());
    // The truth has relative harmonics 1, 2 and 4: four of them are needed, eight add nothing.
    assert!(cv[2] < 0.5 * cv[1], "{cv:?}");
    assert!(cv[3] < 0.8 * cv[2], "{cv:?}");
    assert!(cv[4] > 0.95 * cv[3], "{cv:?}");
    // Fitted on four folds, a polynomial extrapolates badly into the fifth.
    assert!(cv[5] > 10.0 * cv[3], "{cv:?}");
}

#[test]
fn a_held_run_cannot_identify_the_kinematic_error() {
    let gear = Gear::new(100.0, FixedElement::CircularSpline).unwrap();
    let held = run(ArmExperiment::StepHold);
    match fit_kinematic_error(&gear, &angles(&held), FOURIER, &KinematicFitOptions::default()) {
        Err(AnalysisError::Invalid { what, .. }) => assert_eq!(what, "link_angle_rad"),
        other => panic!("{other:?}"),
    }
    // Half a revolution is not enough for output harmonics either.
    let no_load = run(ArmExperiment::NoLoad);
    let n = no_load.column("time").unwrap().len() / 5;
    let part = JointAngles {
        motor_angle_rad: &no_load.column("motor_angle").unwrap()[..n],
        link_angle_rad: &no_load.column("link_angle").unwrap()[..n],
        sample_rate_hz: 1000.0,
    };
    assert!(fit_kinematic_error(&gear, &part, FOURIER, &KinematicFitOptions::default()).is_err());
    // Mesh harmonics alone only need the motor to turn.
    let mesh_only = KinematicBasis::Fourier { output_harmonics: 0, mesh_harmonics: 4, mesh_angle: MeshAngle::Relative };
    assert!(fit_kinematic_error(&gear, &part, mesh_only, &KinematicFitOptions::default()).is_ok());
}
