//! The simulation loop: scenario in, one recording row per sample out, with the truth.

use crate::error::SimError;
use crate::joint::{JointModel, JointState, SpeedController};
use crate::profile::{external_torque_nm, Command, MotionProfile};
use crate::rng::Rng;
use crate::scenario::{ExternalTorque, LineReference, Scenario};
use crate::sensors::TorqueSensor;

/// Measured columns, in order. `measured_torque` is the bridge voltage times the
/// sensor's true gain (a perfectly calibrated sensor).
pub const MEASURED_COLUMNS: &[&str] =
    &["time", "motor_angle", "output_angle", "motor_velocity", "motor_current", "bridge_voltage", "measured_torque"];

/// Truth columns, in order.
pub const TRUE_COLUMNS: &[&str] = &[
    "true_torque",
    "true_ripple",
    "true_misalignment",
    "true_relative_angle",
    "true_motor_angle",
    "true_output_angle",
    "true_motor_velocity",
    "true_output_velocity",
    "true_motor_current",
    "true_external_torque",
];

/// Largest `|ω h|` of the stiffest mode per RK4 sub-step. RK4's phase error is
/// about `(ωh)⁵/120` per step (7e-3 rad per period at 0.6) and its stability limit 2.8;
/// the test `integrator_converges_against_a_finer_step` holds the result to a 4× finer step.
pub const MAX_OMEGA_H: f64 = 0.6;

/// Most RK4 sub-steps per sample. Beyond the count [`MAX_OMEGA_H`] asks for, the run is
/// less accurate but still stable up to [`STABLE_OMEGA_H`].
pub const MAX_SUBSTEPS: u32 = 10_000;

/// Largest `|ω h|` RK4 is run at: below its stability limit on the real axis (2.785), so
/// that a damped mode decays instead of growing into NaN. A scenario whose stiffest mode
/// needs more at [`MAX_SUBSTEPS`] is refused.
pub const STABLE_OMEGA_H: f64 = 2.5;

/// A running simulation.
pub struct Simulator {
    scenario: Scenario,
    model: JointModel,
    sensor: TorqueSensor,
    profile: MotionProfile,
    controller: SpeedController,
    rng: Rng,
    state: JointState,
    k: u64,
    n_samples: u64,
    dt_s: f64,
    n_sub: u32,
    open_loop: bool,
    motor_step_rad: f64,
    output_step_rad: f64,
    clipped: u64,
    diverged_at_s: Option<f64>,
}

/// Encoder reading: whole counts, rad.
fn encoder(angle_rad: f64, step_rad: f64) -> f64 {
    (angle_rad / step_rad).floor() * step_rad
}

impl Simulator {
    /// Prepares a run of a validated scenario; the RK4 sub-step count follows from the
    /// stiffest mode (`|ω h| ≤ MAX_OMEGA_H`).
    pub fn new(scenario: &Scenario) -> Result<Self, SimError> {
        scenario.validate()?;
        let w = JointModel::max_natural_frequency_rad_s(scenario);
        let omega_h = w / scenario.sample_rate_hz / f64::from(MAX_SUBSTEPS);
        if omega_h.is_nan() || omega_h > STABLE_OMEGA_H {
            let (key, value) = JointModel::stiffest_mode_key(scenario);
            let inertias = format!(
                "`motor.inertia_kg_m2` = {:e}, `load.inertia_kg_m2` = {:e}",
                scenario.motor.inertia_kg_m2, scenario.load.inertia_kg_m2
            );
            return Err(SimError::invalid(
                key,
                format!(
                    "= {value:e} with {inertias}: the joint's fastest mode ({w:.3e} rad/s) makes RK4 unstable even at \
                     {MAX_SUBSTEPS} sub-steps per sample (ω h = {omega_h:.3e}, at most {STABLE_OMEGA_H}); lower it, \
                     raise an inertia or raise `sample_rate_hz`"
                ),
            ));
        }
        Self::with_substeps(scenario, Self::auto_substeps(scenario))
    }

    /// Sub-steps per sample that keep `|ω h| ≤ MAX_OMEGA_H` for the stiffest mode.
    pub fn auto_substeps(scenario: &Scenario) -> u32 {
        let w = JointModel::max_natural_frequency_rad_s(scenario);
        ((w / scenario.sample_rate_hz / MAX_OMEGA_H).ceil() as u32).clamp(1, MAX_SUBSTEPS)
    }

    /// Prepares a run with a given number of RK4 sub-steps per sample (≥ 1).
    pub fn with_substeps(scenario: &Scenario, n_sub: u32) -> Result<Self, SimError> {
        scenario.validate()?;
        let s = scenario.clone();
        let dt_s = 1.0 / s.sample_rate_hz;
        let n_sub = n_sub.max(1);
        // Friction regularization follows the automatic step, so that the model is the
        // same whatever step integrates it.
        let model = JointModel::new(&s, dt_s / Self::auto_substeps(&s) as f64)?;
        let mut rng = Rng::new(s.seed);
        let fs_per_out = model.gear.flexspline_torque_from_output(1.0);
        let sensor = TorqueSensor::new(&s, fs_per_out, &mut rng)?;
        if let Some(noise_seed) = s.noise_seed {
            // Same sensor (placement drawn above), other noise.
            rng = Rng::new(noise_seed);
        }
        let controller = SpeedController::new(&model, s.motor.speed_loop_bandwidth_hz, s.motor.current_limit_a);
        let n_samples = (s.duration_s * s.sample_rate_hz).round() as u64;
        let tau = std::f64::consts::TAU;
        Ok(Self {
            profile: MotionProfile::new(&s.motion),
            motor_step_rad: tau / s.encoders.motor_counts_per_rev as f64,
            output_step_rad: tau / s.encoders.output_counts_per_rev as f64,
            scenario: s,
            model,
            sensor,
            controller,
            rng,
            state: JointState::default(),
            k: 0,
            n_samples,
            dt_s,
            n_sub,
            open_loop: false,
            clipped: 0,
            diverged_at_s: None,
        })
    }

    /// Column names of the rows, in order.
    pub fn columns(&self) -> Vec<&'static str> {
        let mut c: Vec<&'static str> = MEASURED_COLUMNS.to_vec();
        if self.scenario.encoders.reference_torque_noise_nm.is_some() {
            c.push("reference_torque");
        }
        c.extend_from_slice(TRUE_COLUMNS);
        c
    }

    /// Number of rows the run will produce.
    pub fn len(&self) -> u64 {
        self.n_samples
    }

    /// Whether the run produces no rows.
    pub fn is_empty(&self) -> bool {
        self.n_samples == 0
    }

    /// RK4 sub-steps per sample.
    pub fn substeps(&self) -> u32 {
        self.n_sub
    }

    /// The scenario.
    pub fn scenario(&self) -> &Scenario {
        &self.scenario
    }

    /// The joint model.
    pub fn model(&self) -> &JointModel {
        &self.model
    }

    /// The torque sensor.
    pub fn sensor(&self) -> &TorqueSensor {
        &self.sensor
    }

    /// Samples the ADC clipped so far.
    pub fn clipped_samples(&self) -> u64 {
        self.clipped
    }

    /// The time at which the run stopped because its true values were no longer finite.
    pub fn diverged_at_s(&self) -> Option<f64> {
        self.diverged_at_s
    }

    /// Writes the next row into `row` (length = `columns().len()`); `false` when done, or
    /// when the dynamics diverged ([`Simulator::diverged_at_s`]).
    pub fn next_row(&mut self, row: &mut Vec<f64>) -> bool {
        if self.k >= self.n_samples {
            return false;
        }
        let t = self.k as f64 * self.dt_s;
        let x = self.state;
        let s = &self.scenario;

        // Controller (digital, one update per sample, current held over the sample).
        let current_a = match self.profile.command(t) {
            Command::Speed { speed_rad_s, accel_rad_s2 } => {
                if self.open_loop {
                    self.controller.reset();
                    self.open_loop = false;
                }
                self.controller.current_a(speed_rad_s, accel_rad_s2, x.motor_speed_rad_s, self.dt_s)
            }
            Command::Current(i) => {
                self.open_loop = true;
                i.clamp(-s.motor.current_limit_a, s.motor.current_limit_a)
            }
        };

        // Truth at this instant.
        let tau = self.model.transmitted_torque_nm(&x);
        let ext = external_torque_nm(&s.external_torque, t);
        let phi = self.model.gear.relative_angle(x.motor_angle_rad, x.output_angle_rad);
        let r = &s.ripple;
        let mesh = (r.amplitude_2x_nm + r.amplitude_2x_per_nm * tau.abs()) * (2.0 * phi + r.phase_2x_rad).sin()
            + (r.amplitude_4x_nm + r.amplitude_4x_per_nm * tau.abs()) * (4.0 * phi + r.phase_4x_rad).sin();
        let mut mis = s.misalignment.amplitude_nm * (x.output_angle_rad + s.misalignment.phase_rad).sin();
        let mut mesh = mesh;
        for l in &s.extra_lines {
            let theta = match l.reference {
                LineReference::Relative => phi,
                LineReference::Output => x.output_angle_rad,
                LineReference::Motor => x.motor_angle_rad,
            };
            let v = l.amplitude_nm * (l.multiple * theta + l.phase_rad).sin();
            match l.reference {
                LineReference::Output => mis += v,
                _ => mesh += v,
            }
        }

        // Measurements.
        let reading = self.sensor.read(tau + mesh + mis, phi, &mut self.rng);
        self.clipped += u64::from(reading.clipped);
        let tacho = x.motor_speed_rad_s + s.encoders.tacho_noise_rad_s * self.rng.normal();
        let current_meas = current_a + s.encoders.current_noise_a * self.rng.normal();

        row.clear();
        row.extend_from_slice(&[
            t,
            encoder(x.motor_angle_rad, self.motor_step_rad),
            encoder(x.output_angle_rad, self.output_step_rad),
            tacho,
            current_meas,
            reading.voltage_v,
            reading.voltage_v * self.sensor.gain_nm_per_v(),
        ]);
        if let Some(noise) = s.encoders.reference_torque_noise_nm {
            row.push(tau + noise * self.rng.normal());
        }
        let truth_from = row.len();
        row.extend_from_slice(&[
            tau,
            mesh + reading.interference_nm,
            mis,
            phi,
            x.motor_angle_rad,
            x.output_angle_rad,
            x.motor_speed_rad_s,
            x.output_speed_rad_s,
            current_a,
            ext,
        ]);
        if !row[truth_from..].iter().all(|v| v.is_finite()) {
            // The dynamics left the numbers: stop rather than write NaN as truth.
            self.diverged_at_s = Some(t);
            self.k = self.n_samples;
            row.clear();
            return false;
        }

        // Advance the dynamics over the sample.
        let h = self.dt_s / self.n_sub as f64;
        let torques: &[ExternalTorque] = &s.external_torque;
        let ext_fn = |time: f64| external_torque_nm(torques, time);
        let mut state = self.state;
        for j in 0..self.n_sub {
            self.model.rk4_step(&mut state, t + j as f64 * h, h, current_a, &ext_fn);
        }
        self.state = state;
        self.k += 1;
        true
    }
}

/// A whole run in memory: column names and one `Vec` per column.
#[derive(Debug, Clone)]
pub struct Recording {
    /// Column names.
    pub columns: Vec<&'static str>,
    /// Column data, `data[c][k]`.
    pub data: Vec<Vec<f64>>,
}

impl Recording {
    /// A column by name.
    pub fn column(&self, name: &str) -> Option<&[f64]> {
        self.columns.iter().position(|c| *c == name).map(|i| self.data[i].as_slice())
    }
}

/// Runs a scenario to the end in memory.
pub fn simulate(scenario: &Scenario) -> Result<(Recording, Simulator), SimError> {
    let mut sim = Simulator::new(scenario)?;
    let columns = sim.columns();
    let mut data = vec![Vec::with_capacity(sim.len() as usize); columns.len()];
    let mut row = Vec::with_capacity(columns.len());
    while sim.next_row(&mut row) {
        for (c, v) in data.iter_mut().zip(row.iter()) {
            c.push(*v);
        }
    }
    if let Some(t) = sim.diverged_at_s() {
        return Err(SimError::invalid("scenario", format!("the joint's dynamics diverged at t = {t:?} s")));
    }
    Ok((Recording { columns, data }, sim))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_run_that_diverges_stops_before_writing_nan() {
        let mut s = crate::presets::preset("taghirad").unwrap();
        s.gear.damping_nm_s_per_rad = 1e7;
        assert!(Simulator::new(&s).is_err(), "too stiff for the sub-step cap");
        assert!(simulate(&s).is_err());
        // Stiff enough to pass the sub-steps that accuracy asks for, not RK4's stability:
        // it runs (ω h about 1.5 at the cap), finite.
        let mut stiff = s.clone();
        stiff.gear.damping_nm_s_per_rad = 3.7e6;
        stiff.duration_s = 0.05;
        let (run, sim) = simulate(&stiff).unwrap();
        assert_eq!(sim.substeps(), MAX_SUBSTEPS);
        assert!(run.data.iter().flatten().all(|v| v.is_finite()));
        // Forced to one sub-step, RK4 runs past its stability limit.
        let mut sim = Simulator::with_substeps(&s, 1).unwrap();
        let mut row = Vec::new();
        let mut rows = 0;
        while sim.next_row(&mut row) {
            assert!(row.iter().all(|v| v.is_finite()), "row {rows}: {row:?}");
            rows += 1;
        }
        assert!(rows < sim.len() as usize, "{rows} rows");
        let stopped_s = sim.diverged_at_s().expect("the time it stopped");
        assert!((stopped_s * s.sample_rate_hz - rows as f64).abs() < 1e-6, "{stopped_s} s after {rows} rows");
        assert!(!sim.next_row(&mut row), "stays stopped");
    }
}
