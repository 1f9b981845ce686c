//! The arm scenario: its sections, parsing, presets of the paper's experiments and validation.

use super::*;

/// A full arm scenario.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ArmScenario {
    /// Short name.
    pub name: String,
    /// Output sample rate, Hz.
    pub sample_rate_hz: f64,
    /// Length of the run, s.
    pub duration_s: f64,
    /// Random seed of the noise.
    pub seed: u64,
    /// The strain wave gear (circular spline fixed).
    pub gear: ArmGear,
    /// Kinematic error of the transmission.
    pub kinematic_error: ArmKinematicError,
    /// The motor.
    pub motor: ArmMotor,
    /// The link.
    pub link: ArmLink,
    /// Position controller of the motor.
    pub controller: ArmController,
    /// Encoders.
    pub encoders: ArmEncoders,
    /// Current sensor and reference torque sensor.
    pub sensors: ArmSensors,
    /// What the motor does.
    pub command: MotorCommand,
    /// External torque on the link (components add).
    #[serde(default)]
    pub external_torque: Vec<HandTorque>,
}

/// Gear: ratio and the paper's two springs.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ArmGear {
    /// Ratio `N`.
    pub ratio: f64,
    /// Rated output torque, N·m.
    pub rated_torque_nm: f64,
    /// Flexspline initial stiffness `K_f0`, N·m/rad.
    pub flexspline_k0_nm_per_rad: f64,
    /// Flexspline stiffening `C_f`, 1/(N·m).
    pub flexspline_c_per_nm: f64,
    /// Wave-generator initial stiffness `K_w0` at the WG, N·m/rad.
    pub wave_generator_k0_nm_per_rad: f64,
    /// Wave-generator coefficient `c_w`, 1/(N·m) of WG torque.
    pub wave_generator_c_per_nm: f64,
    /// Hysteresis loop width in twist (catalogue hysteresis loss), rad; 0 = none.
    pub hysteresis_loss_rad: f64,
    /// Structural damping of the gear, N·m·s/rad.
    pub damping_nm_s_per_rad: f64,
}

/// One harmonic `A sin(order · angle + phase)`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Harmonic {
    /// Order (multiple of the angle), ≥ 1.
    pub order: u32,
    /// Amplitude, rad.
    pub amplitude_rad: f64,
    /// Phase, rad.
    #[serde(default)]
    pub phase_rad: f64,
}

/// Kinematic error `θ_k = offset + Σ output harmonics + Σ relative harmonics + Σ a_i θ^i`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct ArmKinematicError {
    /// Constant part, rad.
    #[serde(default)]
    pub offset_rad: f64,
    /// Harmonics of the output (link) angle.
    #[serde(default)]
    pub output: Vec<Harmonic>,
    /// Harmonics of the relative angle `φ = θ_m − θ`.
    #[serde(default)]
    pub relative: Vec<Harmonic>,
    /// Polynomial `a_0, a_1, …` in the output angle (rad), e.g. the HDA-arm paper Table II; short runs only.
    #[serde(default)]
    pub polynomial: Vec<f64>,
}

impl ArmKinematicError {
    /// `θ_k` at output angle `θ` and relative angle `φ`, rad.
    pub fn eval(&self, output_rad: f64, relative_rad: f64) -> f64 {
        let h = |list: &[Harmonic], x: f64| -> f64 {
            list.iter().map(|c| c.amplitude_rad * (c.order as f64 * x + c.phase_rad).sin()).sum()
        };
        let poly = self.polynomial.iter().rev().fold(0.0, |acc, a| acc * output_rad + a);
        self.offset_rad + h(&self.output, output_rad) + h(&self.relative, relative_rad) + poly
    }
}

/// Motor (the HDA-arm paper's App. A).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ArmMotor {
    /// Rotor and WG inertia, kg·m².
    pub inertia_kg_m2: f64,
    /// Torque constant `k_m`, N·m/A.
    pub torque_constant_nm_per_a: f64,
    /// No-load current `I_0`, A.
    pub no_load_current_a: f64,
    /// No-load speed `n_0`, rpm.
    pub no_load_speed_rpm: f64,
    /// Current limit, A.
    pub current_limit_a: f64,
}

impl ArmMotor {
    /// Viscous friction `r_m = k_m I_0 / ω_0`, `ω_0 = 2π n_0 / 60`, N·m·s/rad.
    pub fn viscous_nm_s_per_rad(&self) -> f64 {
        self.torque_constant_nm_per_a * self.no_load_current_a / (TAU * self.no_load_speed_rpm / 60.0)
    }
}

/// The link.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ArmLink {
    /// Inertia `J`, kg·m².
    pub inertia_kg_m2: f64,
    /// Viscous drag `b_L`, N·m·s/rad (not in the paper's model; see the preset).
    pub viscous_nm_s_per_rad: f64,
}

/// PID on the motor angle, tuned on the motor plus reflected link inertia.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ArmController {
    /// Closed-loop bandwidth, Hz.
    pub bandwidth_hz: f64,
    /// Damping ratio of the PD part.
    pub damping_ratio: f64,
    /// Integral time, s.
    pub integral_time_s: f64,
}

/// Encoders.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ArmEncoders {
    /// Motor encoder counts per revolution.
    pub motor_counts_per_rev: u64,
    /// Link encoder counts per revolution.
    pub link_counts_per_rev: u64,
    /// Motor encoder noise, counts rms.
    pub motor_noise_counts: f64,
    /// Link encoder noise, counts rms.
    pub link_noise_counts: f64,
    /// Counters wrap every revolution (else they count multi-turn).
    pub single_turn: bool,
    /// Raw motor count at zero angle.
    #[serde(default)]
    pub motor_offset_counts: i64,
    /// Raw link count at zero angle.
    #[serde(default)]
    pub link_offset_counts: i64,
}

/// Current sensor and reference torque sensor.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ArmSensors {
    /// Current sensor noise, A rms.
    pub current_noise_a: f64,
    /// Reference (six-axis-like) torque sensor noise, N·m rms.
    pub reference_torque_noise_nm: f64,
}

impl ArmScenario {
    /// Parses TOML; unknown keys and wrong types are errors; then validates.
    pub fn from_toml(text: &str) -> Result<Self, SimError> {
        let s: ArmScenario = crate::check::parse_toml(text)?;
        s.validate()?;
        Ok(s)
    }

    /// The scenario as TOML.
    pub fn to_toml(&self) -> String {
        toml::to_string(self).unwrap_or_else(|e| format!("# could not serialize scenario: {e}\n"))
    }

    /// The `hda-arm` preset (the HDA-arm paper's arm, step experiment).
    ///
    /// ```
    /// let s = strainwave_sim::arm::ArmScenario::preset().unwrap();
    /// assert_eq!(s.gear.ratio, 100.0);
    /// assert!((s.motor.viscous_nm_s_per_rad() - 2.149e-5).abs() < 1e-8);
    /// ```
    pub fn preset() -> Result<Self, SimError> {
        Self::from_toml(PRESET_TOML)
    }

    /// A HDA-arm run on the preset arm.
    ///
    /// ```
    /// use strainwave_sim::arm::{ArmScenario, ArmExperiment};
    /// let s = ArmScenario::experiment(ArmExperiment::PeriodicHold).unwrap();
    /// assert_eq!(s.external_torque.len(), 1);
    /// ```
    pub fn experiment(which: ArmExperiment) -> Result<Self, SimError> {
        let mut s = Self::preset()?;
        s.with_experiment(which);
        s.validate()?;
        Ok(s)
    }

    /// Replaces the command, hand torque, duration and name by one of the paper's runs.
    pub fn with_experiment(&mut self, which: ArmExperiment) {
        let n = self.gear.ratio;
        // CS fixed: a negative motor torque drives the link forward.
        let drive = -4.14 / n;
        let step = |at_s: f64, torque_nm: f64, release_s: Option<f64>| HandTorque::Step {
            at_s,
            torque_nm,
            rise_s: 0.1,
            release_s,
        };
        let sine = |amplitude_nm: f64, frequency_hz: f64, start_s: f64| HandTorque::Sine {
            amplitude_nm,
            frequency_hz,
            phase_rad: 0.0,
            start_s,
            end_s: None,
        };
        let (command, external, duration) = match which {
            ArmExperiment::NoLoad => {
                // Slow enough that the 2× relative-angle error (at 2 N v) stays far below
                // the link mode (≈ 28 Hz held): the torsion is then kinematic, not dynamic.
                let v = 0.2;
                let reverse = TAU / v + 1.0;
                (MotorCommand::PositionRamp { link_speed_rad_s: v, reverse_at_s: reverse }, vec![], 2.0 * reverse + 1.0)
            }
            ArmExperiment::LoadedHold => (
                MotorCommand::HoldPosition,
                vec![sine(40.0, 0.2, 0.5), sine(10.0, 1.3, 0.5), sine(5.0, 3.1, 0.5), sine(4.0, 7.0, 0.5)],
                15.0,
            ),
            ArmExperiment::StepHold => (MotorCommand::HoldPosition, vec![step(1.0, 15.0, Some(4.0))], 6.0),
            ArmExperiment::PeriodicHold => (MotorCommand::HoldPosition, vec![sine(12.0, 1.0, 1.0)], 6.0),
            ArmExperiment::StepConstantTorque => {
                (MotorCommand::ConstantTorque { motor_torque_nm: drive }, vec![step(1.0, 3.0, Some(2.2))], 3.0)
            }
            ArmExperiment::PeriodicConstantTorque => {
                (MotorCommand::ConstantTorque { motor_torque_nm: drive }, vec![sine(5.0, 1.5, 0.5)], 3.5)
            }
            ArmExperiment::Fig4Step => {
                (MotorCommand::TorqueStep { motor_torque_nm: -10.0 / n, at_s: 0.1 }, vec![], 1.0)
            }
            ArmExperiment::Fig4Sine => {
                (MotorCommand::TorqueSine { amplitude_nm: 10.0 / n, frequency_hz: 2.0 }, vec![], 2.0)
            }
        };
        self.command = command;
        self.external_torque = external;
        self.duration_s = duration;
        self.name = format!("hda-arm/{}", which.name());
    }

    /// Checks every value; the error names the key.
    pub fn validate(&self) -> Result<(), SimError> {
        crate::check::run_length(self.duration_s, self.sample_rate_hz)?;
        let g = &self.gear;
        crate::check::gear_ratio(g.ratio)?;
        pos(g.rated_torque_nm, "gear.rated_torque_nm")?;
        pos(g.flexspline_k0_nm_per_rad, "gear.flexspline_k0_nm_per_rad")?;
        nonneg(g.flexspline_c_per_nm, "gear.flexspline_c_per_nm")?;
        pos(g.wave_generator_k0_nm_per_rad, "gear.wave_generator_k0_nm_per_rad")?;
        fin(g.wave_generator_c_per_nm, "gear.wave_generator_c_per_nm")?;
        nonneg(g.hysteresis_loss_rad, "gear.hysteresis_loss_rad")?;
        nonneg(g.damping_nm_s_per_rad, "gear.damping_nm_s_per_rad")?;
        let k = &self.kinematic_error;
        fin(k.offset_rad, "kinematic_error.offset_rad")?;
        for (list, key) in [(&k.output, "kinematic_error.output"), (&k.relative, "kinematic_error.relative")] {
            for h in list {
                if h.order == 0 {
                    return Err(SimError::invalid(key, "order must be ≥ 1".into()));
                }
                fin(h.amplitude_rad, key)?;
                fin(h.phase_rad, key)?;
            }
        }
        for a in &k.polynomial {
            fin(*a, "kinematic_error.polynomial")?;
        }
        let m = &self.motor;
        pos(m.inertia_kg_m2, "motor.inertia_kg_m2")?;
        pos(m.torque_constant_nm_per_a, "motor.torque_constant_nm_per_a")?;
        nonneg(m.no_load_current_a, "motor.no_load_current_a")?;
        pos(m.no_load_speed_rpm, "motor.no_load_speed_rpm")?;
        pos(m.current_limit_a, "motor.current_limit_a")?;
        pos(self.link.inertia_kg_m2, "link.inertia_kg_m2")?;
        nonneg(self.link.viscous_nm_s_per_rad, "link.viscous_nm_s_per_rad")?;
        let c = &self.controller;
        pos(c.bandwidth_hz, "controller.bandwidth_hz")?;
        if c.bandwidth_hz > 0.2 * self.sample_rate_hz {
            return Err(SimError::invalid(
                "controller.bandwidth_hz",
                format!("{} Hz is above a fifth of the sample rate", c.bandwidth_hz),
            ));
        }
        pos(c.damping_ratio, "controller.damping_ratio")?;
        pos(c.integral_time_s, "controller.integral_time_s")?;
        let e = &self.encoders;
        for (v, key) in [
            (e.motor_counts_per_rev, "encoders.motor_counts_per_rev"),
            (e.link_counts_per_rev, "encoders.link_counts_per_rev"),
        ] {
            if !(4..=(1u64 << 40)).contains(&v) {
                return Err(SimError::invalid(key, format!("must be 4 ..= 2^40, got {v}")));
            }
        }
        nonneg(e.motor_noise_counts, "encoders.motor_noise_counts")?;
        nonneg(e.link_noise_counts, "encoders.link_noise_counts")?;
        nonneg(self.sensors.current_noise_a, "sensors.current_noise_a")?;
        nonneg(self.sensors.reference_torque_noise_nm, "sensors.reference_torque_noise_nm")?;
        match &self.command {
            MotorCommand::HoldPosition => {}
            MotorCommand::PositionRamp { link_speed_rad_s, reverse_at_s } => {
                fin(*link_speed_rad_s, "command.link_speed_rad_s")?;
                fin(*reverse_at_s, "command.reverse_at_s")?;
            }
            MotorCommand::ConstantTorque { motor_torque_nm } => fin(*motor_torque_nm, "command.motor_torque_nm")?,
            MotorCommand::TorqueStep { motor_torque_nm, at_s } => {
                fin(*motor_torque_nm, "command.motor_torque_nm")?;
                fin(*at_s, "command.at_s")?;
            }
            MotorCommand::TorqueSine { amplitude_nm, frequency_hz } => {
                fin(*amplitude_nm, "command.amplitude_nm")?;
                pos(*frequency_hz, "command.frequency_hz")?;
            }
        }
        for h in &self.external_torque {
            match h {
                HandTorque::Step { at_s, torque_nm, rise_s, release_s } => {
                    fin(*at_s, "external_torque.at_s")?;
                    fin(*torque_nm, "external_torque.torque_nm")?;
                    pos(*rise_s, "external_torque.rise_s")?;
                    if let Some(r) = release_s {
                        fin(*r, "external_torque.release_s")?;
                        if *r < at_s + rise_s {
                            return Err(SimError::invalid(
                                "external_torque.release_s",
                                "must come after at_s + rise_s".into(),
                            ));
                        }
                    }
                }
                HandTorque::Sine { amplitude_nm, frequency_hz, phase_rad, start_s, end_s } => {
                    fin(*amplitude_nm, "external_torque.amplitude_nm")?;
                    nonneg(*frequency_hz, "external_torque.frequency_hz")?;
                    fin(*phase_rad, "external_torque.phase_rad")?;
                    fin(*start_s, "external_torque.start_s")?;
                    if let Some(e) = end_s {
                        fin(*e, "external_torque.end_s")?;
                    }
                }
            }
        }
        // The springs themselves must build.
        ArmModel::new(self).map(|_| ())
    }
}
