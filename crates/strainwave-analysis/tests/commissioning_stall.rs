//! Commissioning that the canceller's own load-step test stalls (random joint 18 of the
//! twin): learned without the watch of `step_lock`, the 2× ripple comes out tens of times
//! too large and the test fires on almost every sample; `commission`, which restarts the
//! learning when the test fires on 40 % of the samples, learns a canceller at the noise
//! floor.

mod twin;

use strainwave_analysis::canceller_eval::{commission, evaluate, Method};
use strainwave_analysis::step_lock::StepLock;
use strainwave_core::ripple::{step, ReferenceValues, RippleInput, RippleModel, RippleState, StepFlags};
use twin::{random_joint, run, signals};

#[test]
fn a_stalled_commissioning_starts_again() {
    let (comm, test) = random_joint(18);
    let c = run(&comm);
    let s = signals(&c);

    // The plain loop: the stall.
    let m = RippleModel::<f64, 5>::full_commissioning(s.sample_rate_hz, c.noise_nm).unwrap();
    let mut state = RippleState::new(&m);
    let mut fired = 0usize;
    for k in 0..s.measured_nm.len() {
        let refs = ReferenceValues::from_gear(&c.gear, s.motor_angle_rad[k], s.output_angle_rad[k]);
        let out = step(&m, &mut state, &RippleInput::new(s.measured_nm[k], refs)).unwrap();
        fired += usize::from(out.flags.contains(StepFlags::LOAD_STEP));
    }
    let ([a, b], _) = state.learned(0).unwrap();
    let stalled_2x_nm = a.hypot(b);
    eprintln!(
        "plain: load steps on {fired} of {} samples, 2× ripple learned {stalled_2x_nm:.3} N·m",
        s.measured_nm.len()
    );
    assert!(fired > s.measured_nm.len() / 2, "the stall is no longer reproduced: {fired} load steps");
    assert!(stalled_2x_nm > 1.0, "{stalled_2x_nm}");

    // The watch, as `commission` runs it: where it restarts the learning.
    let mut state = RippleState::new(&m);
    let mut lock = StepLock::new(s.sample_rate_hz);
    let mut restarts = Vec::new();
    for k in 0..s.measured_nm.len() {
        let refs = ReferenceValues::from_gear(&c.gear, s.motor_angle_rad[k], s.output_angle_rad[k]);
        let out = step(&m, &mut state, &RippleInput::new(s.measured_nm[k], refs)).unwrap();
        if lock.locked(out.flags.contains(StepFlags::LOAD_STEP)) {
            state.reset(&m);
            restarts.push(k);
        }
    }
    eprintln!("watched: restarts at samples {restarts:?}");
    assert!(!restarts.is_empty() && restarts.len() <= 3, "{restarts:?}");
    assert_eq!(state.learned_all(), commission(&s, &c.gear, c.noise_nm).unwrap());

    // With the watch.
    let learned = commission(&s, &c.gear, c.noise_nm).unwrap();
    let [a, b] = learned[0].0;
    let r = run(&test);
    let full = evaluate(&signals(&r), &r.gear, r.noise_nm, &[Method::Full], 0.3, Some(&learned)).unwrap();
    eprintln!(
        "commission: 2× ripple {:.3} N·m, causal full {:.4} N·m ({:.2}× the floor)",
        a.hypot(b),
        full[0].rms_error_nm,
        full[0].rms_error_nm / r.noise_nm
    );
    assert!(a.hypot(b) < 0.5, "{}", a.hypot(b));
    assert!(full[0].rms_error_nm < 1.5 * r.noise_nm, "{} vs floor {}", full[0].rms_error_nm, r.noise_nm);
}
