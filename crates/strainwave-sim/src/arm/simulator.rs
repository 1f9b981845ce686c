//! Stepping the arm twin and recording its columns with the truth.

use super::*;

/// Column names of a recording, in order.
pub const COLUMNS: &[&str] = &[
    "time",
    "motor_angle",
    "link_angle",
    "motor_counts",
    "link_counts",
    "motor_current",
    "reference_torque",
    "true_link_torque",
    "true_torsion",
    "true_kinematic_error",
    "true_external_torque",
    "true_windup",
    "true_motor_torque",
    "true_motor_angle",
    "true_link_angle",
    "true_link_velocity",
];

/// A running arm simulation: one row per sample.
pub struct ArmSimulator {
    scenario: ArmScenario,
    model: ArmModel,
    rng: Rng,
    state: ArmState,
    k: u64,
    n_samples: u64,
    dt_s: f64,
    n_sub: u32,
    kp: f64,
    kd: f64,
    ki: f64,
    integral_nm: f64,
    hold_angle_rad: f64,
    ramp_link_ref_rad: f64,
    torque_guess_nm: f64,
    motor_step_rad: f64,
    link_step_rad: f64,
}

impl ArmSimulator {
    /// Prepares a run; the RK4 sub-step count follows from the stiffest mode.
    ///
    /// ```
    /// use strainwave_sim::arm::{ArmScenario, ArmSimulator, COLUMNS};
    /// let mut sim = ArmSimulator::new(&ArmScenario::preset().unwrap()).unwrap();
    /// let mut row = Vec::new();
    /// assert!(sim.next_row(&mut row));
    /// assert_eq!(row.len(), COLUMNS.len());
    /// ```
    pub fn new(scenario: &ArmScenario) -> Result<Self, SimError> {
        let model = ArmModel::new(scenario)?;
        let dt_s = 1.0 / scenario.sample_rate_hz;
        let n_sub =
            ((model.max_rate_rad_s(scenario.gear.rated_torque_nm) * dt_s / MAX_OMEGA_H).ceil() as u32).clamp(1, 10_000);
        Self::with_substeps(scenario, n_sub)
    }

    /// Prepares a run with a given number of RK4 sub-steps per sample (≥ 1).
    pub fn with_substeps(scenario: &ArmScenario, n_sub: u32) -> Result<Self, SimError> {
        scenario.validate()?;
        let s = scenario.clone();
        let model = ArmModel::new(&s)?;
        let dt_s = 1.0 / s.sample_rate_hz;
        let n_sub = n_sub.max(1);
        // PID on the motor: motor plus reflected link inertia.
        let j = s.motor.inertia_kg_m2 + s.link.inertia_kg_m2 / (s.gear.ratio * s.gear.ratio);
        let wc = TAU * s.controller.bandwidth_hz;
        let kp = j * wc * wc;
        let kd = 2.0 * s.controller.damping_ratio * j * wc;
        let ki = kp / s.controller.integral_time_s;
        // Start with zero wind-up: the link sits at its kinematic-error position.
        let mut state = ArmState::default();
        for _ in 0..8 {
            state.link_angle_rad = model.kinematic_error_rad(&state);
        }
        let n_samples = (s.duration_s * s.sample_rate_hz).round() as u64;
        Ok(Self {
            rng: Rng::new(s.seed),
            motor_step_rad: TAU / s.encoders.motor_counts_per_rev as f64,
            link_step_rad: TAU / s.encoders.link_counts_per_rev as f64,
            scenario: s,
            model,
            state,
            k: 0,
            n_samples,
            dt_s,
            n_sub,
            kp,
            kd,
            ki,
            integral_nm: 0.0,
            hold_angle_rad: 0.0,
            ramp_link_ref_rad: 0.0,
            torque_guess_nm: 0.0,
        })
    }

    /// Column names, in order.
    pub fn columns(&self) -> Vec<&'static str> {
        COLUMNS.to_vec()
    }

    /// Number of rows of the run.
    pub fn len(&self) -> u64 {
        self.n_samples
    }

    /// Whether the run has no rows.
    pub fn is_empty(&self) -> bool {
        self.n_samples == 0
    }

    /// RK4 sub-steps per sample.
    pub fn substeps(&self) -> u32 {
        self.n_sub
    }

    /// The scenario.
    pub fn scenario(&self) -> &ArmScenario {
        &self.scenario
    }

    /// The physics.
    pub fn model(&self) -> &ArmModel {
        &self.model
    }

    /// The current mechanical state.
    pub fn state(&self) -> &ArmState {
        &self.state
    }

    fn motor_torque_nm(&mut self, t: f64) -> f64 {
        let s = &self.scenario;
        let limit = s.motor.torque_constant_nm_per_a * s.motor.current_limit_a;
        let x = self.state;
        let n_s = self.model.signed_ratio();
        let pid = |this: &mut Self, ref_rad: f64, ref_speed: f64| {
            let e = ref_rad - x.motor_angle_rad;
            let u = this.kp * e + this.kd * (ref_speed - x.motor_speed_rad_s) + this.integral_nm;
            let clipped = u.max(-limit).min(limit);
            if clipped == u {
                this.integral_nm += this.ki * e * this.dt_s;
            }
            clipped
        };
        let u = match s.command.clone() {
            MotorCommand::HoldPosition => {
                let r = self.hold_angle_rad;
                pid(self, r, 0.0)
            }
            MotorCommand::PositionRamp { link_speed_rad_s, reverse_at_s } => {
                let speed = link_speed_rad_s * (smooth_ramp(t, 0.0, 1.0) - 2.0 * smooth_ramp(t, reverse_at_s, 2.0));
                let link_ref = self.ramp_link_ref_rad;
                self.ramp_link_ref_rad += speed * self.dt_s;
                pid(self, link_ref * n_s, speed * n_s)
            }
            MotorCommand::ConstantTorque { motor_torque_nm } => motor_torque_nm,
            MotorCommand::TorqueStep { motor_torque_nm, at_s } => {
                if t >= at_s {
                    motor_torque_nm
                } else {
                    0.0
                }
            }
            MotorCommand::TorqueSine { amplitude_nm, frequency_hz } => amplitude_nm * (TAU * frequency_hz * t).sin(),
        };
        u.max(-limit).min(limit)
    }

    fn external_nm(&self, t: f64) -> f64 {
        self.scenario.external_torque.iter().map(|h| h.at(t)).sum()
    }

    /// Encoder reading `(counts as the counter shows them, quantized angle in rad)`.
    fn encoder(&mut self, angle_rad: f64, step_rad: f64, noise_counts: f64, offset: i64, cpr: u64) -> (f64, f64) {
        let c = (angle_rad / step_rad + noise_counts * self.rng.normal()).floor() as i64;
        let raw = if self.scenario.encoders.single_turn {
            (c.wrapping_add(offset)).rem_euclid(cpr as i64)
        } else {
            c.wrapping_add(offset)
        };
        (raw as f64, c as f64 * step_rad)
    }

    /// Writes the next row into `row` (length `COLUMNS.len()`); `false` when done.
    pub fn next_row(&mut self, row: &mut Vec<f64>) -> bool {
        if self.k >= self.n_samples {
            return false;
        }
        let t = self.k as f64 * self.dt_s;
        let tau_m = self.motor_torque_nm(t);
        let x = self.state;
        let tau = self.model.link_torque_nm(&x, self.torque_guess_nm);
        self.torque_guess_nm = tau;
        let ext = self.external_nm(t);
        let e = self.scenario.encoders.clone();
        let (motor_counts, motor_angle) = self.encoder(
            x.motor_angle_rad,
            self.motor_step_rad,
            e.motor_noise_counts,
            e.motor_offset_counts,
            e.motor_counts_per_rev,
        );
        let (link_counts, link_angle) = self.encoder(
            x.link_angle_rad,
            self.link_step_rad,
            e.link_noise_counts,
            e.link_offset_counts,
            e.link_counts_per_rev,
        );
        let kt = self.scenario.motor.torque_constant_nm_per_a;
        let current = tau_m / kt + self.scenario.sensors.current_noise_a * self.rng.normal();
        let reference = tau + self.scenario.sensors.reference_torque_noise_nm * self.rng.normal();
        row.clear();
        row.extend_from_slice(&[
            t,
            motor_angle,
            link_angle,
            motor_counts,
            link_counts,
            current,
            reference,
            tau,
            self.model.torsion_rad(&x),
            self.model.kinematic_error_rad(&x),
            ext,
            self.model.windup_rad(&x),
            tau_m,
            x.motor_angle_rad,
            x.link_angle_rad,
            x.link_speed_rad_s,
        ]);
        // Advance over the sample: motor torque held, hand torque at each sub-step's midpoint.
        let h = self.dt_s / self.n_sub as f64;
        let mut state = self.state;
        let mut guess = self.torque_guess_nm;
        for j in 0..self.n_sub {
            let ext_mid = self.external_nm(t + (j as f64 + 0.5) * h);
            self.model.rk4_step(&mut state, h, tau_m, ext_mid, &mut guess);
        }
        self.state = state;
        self.k += 1;
        true
    }
}

/// A whole arm run in memory: the joint twin's recording type (column names and one
/// `Vec` per column).
pub type ArmRecording = crate::simulator::Recording;

/// Runs an arm scenario to the end in memory.
pub fn simulate_arm(scenario: &ArmScenario) -> Result<ArmRecording, SimError> {
    let mut sim = ArmSimulator::new(scenario)?;
    let columns = sim.columns();
    let mut data = vec![Vec::with_capacity(sim.len() as usize); columns.len()];
    let mut row = Vec::with_capacity(columns.len());
    while sim.next_row(&mut row) {
        for (c, v) in data.iter_mut().zip(row.iter()) {
            c.push(*v);
        }
    }
    Ok(ArmRecording { columns, data })
}
