//! The twin runs the accuracy tests share: a scenario simulated with its truth columns,
//! its signals as the canceller evaluation takes them, commissioning on a run of the same
//! joint, and joints with random parameters and load profiles.

#![allow(dead_code)] // each test file uses its own part

use strainwave_analysis::canceller_eval::{commission, Learned, RunSignals};
use strainwave_sim::scenario::ExternalTorque;
use strainwave_sim::{presets, simulate, Recording, Scenario};

/// A simulated run: the recording (with `true_*` columns), its gear, the sensor's
/// white-noise floor and the sample rate.
pub struct Run {
    pub rec: Recording,
    pub gear: strainwave_core::gear::Gear<f64>,
    pub noise_nm: f64,
    pub fs: f64,
}

/// Simulates `scenario`.
pub fn run(scenario: &Scenario) -> Run {
    let (rec, sim) = simulate(scenario).unwrap();
    Run { gear: sim.model().gear, noise_nm: sim.sensor().noise_floor_nm(), fs: scenario.sample_rate_hz, rec }
}

/// Simulates the preset `name`.
pub fn run_preset(name: &str) -> Run {
    run(&presets::preset(name).unwrap())
}

/// The run's signals for [`strainwave_analysis::canceller_eval`].
pub fn signals(r: &Run) -> RunSignals<'_> {
    let c = |n: &str| r.rec.column(n).unwrap();
    RunSignals {
        sample_rate_hz: r.fs,
        measured_nm: c("measured_torque"),
        motor_angle_rad: c("motor_angle"),
        output_angle_rad: c("output_angle"),
        motor_velocity_rad_s: c("motor_velocity"),
        true_torque_nm: c("true_torque"),
        true_ripple_nm: c("true_ripple"),
        true_misalignment_nm: c("true_misalignment"),
    }
}

/// What the full configuration learns on the commissioning run `scenario`.
pub fn commissioned(scenario: &Scenario) -> Learned {
    let comm = run(scenario);
    commission(&signals(&comm), &comm.gear, comm.noise_nm).unwrap()
}

/// Uniform in `[lo, hi)` from a small deterministic generator.
fn uniform(seed: &mut u64, lo: f64, hi: f64) -> f64 {
    *seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
    lo + (hi - lo) * ((*seed >> 11) as f64 / (1u64 << 53) as f64)
}

/// The taghirad joint with its ripple, misalignment, stiffness and load drawn at random
/// from `seed`: its commissioning run, and a run under a random sinusoidal load and four
/// random steps (named "random joint {seed}").
pub fn random_joint(seed: u64) -> (Scenario, Scenario) {
    let mut g = seed;
    let mut comm = presets::preset("taghirad-commissioning").unwrap();
    let scale = |g: &mut u64| uniform(g, 0.5, 1.5);
    comm.seed = seed;
    comm.ripple.amplitude_2x_nm *= scale(&mut g);
    comm.ripple.amplitude_4x_nm *= scale(&mut g);
    comm.ripple.amplitude_2x_per_nm *= scale(&mut g);
    comm.ripple.phase_2x_rad = uniform(&mut g, -3.0, 3.0);
    comm.ripple.phase_4x_rad = uniform(&mut g, -3.0, 3.0);
    comm.misalignment.amplitude_nm *= scale(&mut g);
    comm.misalignment.phase_rad = uniform(&mut g, -3.0, 3.0);
    let k = scale(&mut g);
    comm.gear.k1_nm_per_rad *= k;
    comm.gear.k2_nm_per_rad *= k;
    comm.gear.k3_nm_per_rad *= k;
    comm.load.inertia_kg_m2 *= scale(&mut g);
    let keep = presets::preset("taghirad-loaded").unwrap();
    let mut test = Scenario {
        name: format!("random joint {seed}"),
        noise_seed: Some(seed + 1000),
        motion: keep.motion,
        duration_s: keep.duration_s,
        external_torque: Vec::new(),
        ..comm.clone()
    };
    test.external_torque.push(ExternalTorque::Sine {
        amplitude_nm: uniform(&mut g, 0.0, 8.0),
        frequency_hz: uniform(&mut g, 0.1, 2.0),
        phase_rad: 0.0,
        start_s: uniform(&mut g, 0.5, 1.5),
    });
    for _ in 0..4 {
        test.external_torque.push(ExternalTorque::Step {
            at_s: uniform(&mut g, 1.0, test.duration_s - 0.5),
            torque_nm: uniform(&mut g, -6.0, 6.0),
        });
    }
    (comm, test)
}
