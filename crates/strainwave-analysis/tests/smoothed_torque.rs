//! The smoothed torque (`filter --smooth`'s `torque_smoothed`) against the twin's truth on
//! every preset and on joints with random parameters and load profiles: within half the
//! white-noise floor, its 1σ band covering the truth about 68 % of the time, steps kept
//! sharp. Prints one table row per run (`scripts/smooth-check` collects them).

mod twin;

use strainwave_analysis::canceller_eval::{evaluate, smoothed_accuracy, Method, SmoothedAccuracy};
use strainwave_sim::{presets, Scenario};
use twin::{commissioned, random_joint, run, signals};

/// The target: RMS error against the truth at most this fraction of the white-noise floor.
const TARGET_X_FLOOR: f64 = 0.5;

/// The smoothed accuracy on `test` after commissioning on `commissioning`, the floor,
/// and the causal full configuration's RMS error on the same run.
fn measure(commissioning: &Scenario, test: &Scenario) -> (SmoothedAccuracy, f64, f64) {
    let learned = commissioned(commissioning);
    let r = run(test);
    let acc = smoothed_accuracy(&signals(&r), &r.gear, r.noise_nm, &learned, 0.3, None).unwrap();
    let full = evaluate(&signals(&r), &r.gear, r.noise_nm, &[Method::Full], 0.3, Some(&learned)).unwrap();
    (acc, r.noise_nm, full[0].rms_error_nm)
}

/// One markdown table row of what was measured (`--nocapture`).
fn show(name: &str, a: &SmoothedAccuracy, floor: f64, causal_nm: f64) {
    let at = a.step_offset_samples.map_or("never".to_string(), |k| k.to_string());
    eprintln!(
        "| {name} | {floor:.4} | {:.4} | {:.3} | {causal_nm:.4} | {:.2} % | {at} | {:.4} N·m | {:.3} N·m |",
        a.rms_error_nm,
        a.rms_error_nm / floor,
        100.0 * a.coverage_1sd,
        a.step_smear_before_nm,
        a.step_level_after_nm
    );
}

/// Below half the floor, an honest band, a 1 N·m step added to the run within 2 samples
/// and not smeared backwards.
fn check(name: &str, a: &SmoothedAccuracy, floor: f64) {
    assert!(a.rms_error_nm <= TARGET_X_FLOOR * floor, "{name}: {:.4} vs floor {floor:.4}", a.rms_error_nm);
    // The target: 68 % ± 5 %.
    assert!((0.63..=0.73).contains(&a.coverage_1sd), "{name}: coverage {:.4}", a.coverage_1sd);
    let at = a.step_offset_samples.unwrap_or(i64::MAX);
    assert!((0..=2).contains(&at), "{name}: step crosses 0.5 N·m at {at} samples");
    assert!(a.step_smear_before_nm < 0.05, "{name}: smeared {:.4} N·m before the step", a.step_smear_before_nm);
    assert!(a.step_level_after_nm > 0.9, "{name}: only {:.3} N·m from 2 samples after", a.step_level_after_nm);
}

#[test]
fn smoothed_torque_on_the_taghirad_presets() {
    let comm = presets::preset("taghirad-commissioning").unwrap();
    for name in ["taghirad", "taghirad-loaded", "taghirad-standstill"] {
        let (a, floor, causal) = measure(&comm, &presets::preset(name).unwrap());
        show(name, &a, floor, causal);
        check(name, &a, floor);
    }
}

#[test]
fn smoothed_torque_on_the_flexspline_fixed_preset() {
    let comm = presets::preset("flexspline-fixed-commissioning").unwrap();
    let (a, floor, causal) = measure(&comm, &presets::preset("flexspline-fixed").unwrap());
    show("flexspline-fixed", &a, floor, causal);
    check("flexspline-fixed", &a, floor);
}

#[test]
fn smoothed_torque_on_random_joints_and_load_profiles() {
    for seed in [11, 12, 13] {
        let (comm, test) = random_joint(seed);
        let (a, floor, causal) = measure(&comm, &test);
        show(&test.name, &a, floor, causal);
        check(&test.name, &a, floor);
    }
}

/// Seven more random joints, against the same targets (random joint 18 is the one whose
/// commissioning locked before `step_lock`, random joint 15 the one whose misalignment came
/// out 0.008 N·m off). Run by `scripts/smooth-check`.
#[test]
#[ignore = "slow: seven more simulated joints; scripts/smooth-check runs it"]
fn smoothed_torque_on_more_random_joints() {
    for seed in 14..=20 {
        let (comm, test) = random_joint(seed);
        let (a, floor, causal) = measure(&comm, &test);
        show(&test.name, &a, floor, causal);
        assert!(a.rms_error_nm < causal, "{}: smoothed {:.4} vs causal {causal:.4}", test.name, a.rms_error_nm);
        check(&test.name, &a, floor);
    }
}
