//! The HDA-arm arm twin: columns, determinism, physics checks with known answers,
//! encoder counts, integrator convergence and scenario validation.

use strainwave_sim::arm::{simulate_arm, ArmExperiment, ArmRecording, ArmScenario, ArmSimulator, COLUMNS};
use strainwave_sim::SimError;

fn run(e: ArmExperiment) -> (ArmScenario, ArmRecording) {
    let s = ArmScenario::experiment(e).unwrap();
    let r = simulate_arm(&s).unwrap();
    (s, r)
}

fn at(r: &ArmRecording, name: &str, t: f64) -> f64 {
    let time = r.column("time").unwrap();
    let k = time.partition_point(|x| *x < t);
    r.column(name).unwrap()[k]
}

fn std_dev(x: &[f64]) -> f64 {
    let m = x.iter().sum::<f64>() / x.len() as f64;
    (x.iter().map(|v| (v - m).powi(2)).sum::<f64>() / x.len() as f64).sqrt()
}

#[test]
fn columns_and_determinism() {
    let s = ArmScenario::preset().unwrap();
    let a = simulate_arm(&s).unwrap();
    let b = simulate_arm(&s).unwrap();
    assert_eq!(a.columns, COLUMNS);
    assert_eq!(a.data, b.data);
    assert_eq!(a.data[0].len(), 6000);
    let mut other = s.clone();
    other.seed += 1;
    assert_ne!(simulate_arm(&other).unwrap().column("link_counts"), a.column("link_counts"));
}

#[test]
fn held_motor_carries_the_hand_torque() {
    // Static equilibrium J θ̈ = τ + τ_d = 0: the link torque is minus the hand's 15 N·m,
    // and the link is pushed forward of its rigid position (θ_h > 0).
    let (_, r) = run(ArmExperiment::StepHold);
    let tau = at(&r, "true_link_torque", 3.5);
    assert!((tau + 15.0).abs() < 0.05, "{tau}");
    assert!(at(&r, "true_torsion", 3.5) - at(&r, "true_kinematic_error", 3.5) > 1e-3);
    assert!(at(&r, "true_link_torque", 5.9).abs() < 0.05);
    // The PID holds the motor within a few milliradians of motor angle.
    let m = r.column("true_motor_angle").unwrap();
    assert!(m.iter().all(|v| v.abs() < 0.05), "{}", m.iter().fold(0.0_f64, |a, v| a.max(v.abs())));
}

#[test]
fn no_load_torque_is_the_link_drag() {
    // Turning at 0.2 rad/s the gear transmits only the link's viscous drag b_L ω = 0.4 N·m.
    let (s, r) = run(ArmExperiment::NoLoad);
    let drag = s.link.viscous_nm_s_per_rad * 0.2;
    assert!((at(&r, "true_link_torque", 15.0) - drag).abs() < 0.05);
    assert!((at(&r, "true_link_torque", 50.0) + drag).abs() < 0.05);
    let link = r.column("true_link_angle").unwrap();
    assert!(link.iter().cloned().fold(f64::NEG_INFINITY, f64::max) > std::f64::consts::TAU);
    // Single-turn counters: always in range, and the motor's wraps every revolution.
    let mc = r.column("motor_counts").unwrap();
    let cpr = s.encoders.motor_counts_per_rev as f64;
    assert!(mc.iter().all(|c| *c >= 0.0 && *c < cpr && c.fract() == 0.0));
    let wraps = mc.windows(2).filter(|w| (w[1] - w[0]).abs() > cpr / 2.0).count();
    // Forward and back: the motor turns 2 × (2π + ...) × 100 / 2π ≈ 230 revolutions.
    assert!(wraps > 200, "{wraps}");
    let lc = r.column("link_counts").unwrap();
    assert!(lc.iter().all(|c| *c >= 0.0 && *c < s.encoders.link_counts_per_rev as f64));
}

#[test]
fn constant_motor_torque_turns_the_arm_about_once() {
    let (s, r) = run(ArmExperiment::PeriodicConstantTorque);
    let end = *r.column("true_link_angle").unwrap().last().unwrap();
    assert!((5.5..7.5).contains(&end), "{end}");
    // The motor torque is what the paper's 4.14 N·m at the link asks for.
    let tm = r.column("true_motor_torque").unwrap();
    assert!(tm.iter().all(|v| (v * s.gear.ratio + 4.14).abs() < 1e-12));
    // The current column is the torque over k_m plus 0.01 A of noise.
    let i = r.column("motor_current").unwrap();
    let dev: Vec<f64> = i.iter().zip(tm).map(|(i, t)| i - t / s.motor.torque_constant_nm_per_a).collect();
    assert!((std_dev(&dev) - s.sensors.current_noise_a).abs() < 0.002);
}

#[test]
fn reference_sensor_noise_and_quantized_angles() {
    let (s, r) = run(ArmExperiment::PeriodicHold);
    let d: Vec<f64> = r
        .column("reference_torque")
        .unwrap()
        .iter()
        .zip(r.column("true_link_torque").unwrap())
        .map(|(a, b)| a - b)
        .collect();
    assert!((std_dev(&d) - s.sensors.reference_torque_noise_nm).abs() < 0.01);
    let step = std::f64::consts::TAU / s.encoders.link_counts_per_rev as f64;
    for (q, t) in r.column("link_angle").unwrap().iter().zip(r.column("true_link_angle").unwrap()) {
        assert!((q / step - (q / step).round()).abs() < 1e-6);
        assert!((q - t).abs() < 3.0 * step);
    }
}

#[test]
fn integrator_converges_against_a_finer_step() {
    let s = ArmScenario::experiment(ArmExperiment::Fig4Step).unwrap();
    let mut coarse = ArmSimulator::new(&s).unwrap();
    let mut fine = ArmSimulator::with_substeps(&s, 4 * coarse.substeps()).unwrap();
    let (mut a, mut b) = (Vec::new(), Vec::new());
    let k = COLUMNS.iter().position(|c| *c == "true_link_torque").unwrap();
    let mut worst = 0.0_f64;
    while coarse.next_row(&mut a) && fine.next_row(&mut b) {
        worst = worst.max((a[k] - b[k]).abs());
    }
    // The plays' corners cost RK4 its order; still 0.3 % of the 10 N·m step, and far
    // below the encoder-limited estimation error (≈ 0.07 N·m).
    assert!(worst < 0.03, "{worst}");
}

#[test]
fn viscous_friction_from_the_motor_data() {
    // The HDA-arm paper's App. A: r_m = k_m I_0 / ω_0, ω_0 = 2π n_0 / 60.
    let s = ArmScenario::preset().unwrap();
    let expect = 0.06 * 0.15 / (std::f64::consts::TAU * 4000.0 / 60.0);
    assert!((s.motor.viscous_nm_s_per_rad() - expect).abs() < 1e-15);
}

#[test]
fn invalid_scenarios_name_the_key() {
    let mut s = ArmScenario::preset().unwrap();
    s.encoders.link_counts_per_rev = 0;
    match s.validate() {
        Err(SimError::Invalid { key, .. }) => assert_eq!(key, "encoders.link_counts_per_rev"),
        other => panic!("{other:?}"),
    }
    let mut s = ArmScenario::preset().unwrap();
    s.gear.flexspline_c_per_nm = -1.0;
    assert!(matches!(s.validate(), Err(SimError::Invalid { key: "gear.flexspline_c_per_nm", .. })));
    let mut s = ArmScenario::preset().unwrap();
    s.controller.bandwidth_hz = 500.0;
    assert!(matches!(s.validate(), Err(SimError::Invalid { key: "controller.bandwidth_hz", .. })));
    let mut s = ArmScenario::preset().unwrap();
    s.kinematic_error.polynomial = vec![f64::NAN];
    assert!(s.validate().is_err());
}
