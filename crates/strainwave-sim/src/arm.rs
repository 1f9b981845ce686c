//! The harmonic-drive arm model of seed 002 (SPEC §5): motor, wave-generator and flexspline compliance, link, external torque.
//!
//! ```text
//! motor      J_m θ̈_m + r_m θ̇_m = τ_m − τ / n_s,        r_m = k_m I_0 / ω_0,  ω_0 = 2π n_0 / 60
//! link       J θ̈ = τ − b_L θ̇ + τ_d
//! wind-up    w = θ_m / n_s + θ_k(θ, φ) − θ            (the rigid output plus the kinematic error, minus the link)
//! springs    w + h z = θ_f(τ_s) + θ_w(τ_s / N) / N    (seed App. B, solved for τ_s by the core's Newton solver)
//! hysteresis z = Σ_i α_i (w − p_i) / r_i,  p_i = clamp(p_i, w − r_i, w + r_i)   (Maxwell-slip / Prandtl–Ishlinskii)
//! torque     τ = τ_s + c ẇ,  ẇ ≈ θ̇_m / n_s − θ̇         (structural damping; θ̇_k neglected in the damping)
//! ```
//!
//! Hysteresis: `h` is half the catalogue loss (loop width `2h` once every slip element
//! slides). The twin uses four play operators (Jenkin spring–slider elements) with
//! half-widths `r_i = h · (0.25, 0.6, 1.2, 2.5)` and weights `α_i = (0.3, 0.3, 0.25, 0.15)`,
//! the friction model of strain wave gear hysteresis in the literature. Unlike a Dahl
//! law, small vibrations inside the plays leave the branch alone (a Dahl state relaxes
//! towards 0 under any dither), and the estimator's Dahl model is only an approximation
//! of it: the comparison is not an inverse crime. Each play is advanced exactly from the
//! step's start in every RK4 stage.
//!
//! The circular spline is fixed (`n_s = −N`): the link turns opposite to the motor. `τ` is
//! the link torque, the torque the gear transmits to the link, positive when it drives the
//! link forward (`true_link_torque`); in static equilibrium it is `−τ_d`. The torsion
//! `θ_h = θ − θ_m/n_s = θ_k − w` is SPEC §5's. The kinematic error is periodic (output
//! and relative-angle harmonics) plus an optional polynomial in the output angle.
//!
//! The motor is either held by a digital PID on its angle (the seed's first experiment),
//! driven along a position ramp (a no-load run for identification), or given an
//! open-loop torque: constant (the seed's second experiment), a step or a sinusoid
//! (the seed's Fig. 4 simulations). A hand applies the external torque `τ_d`: smooth
//! steps and sinusoids. [`SeedExperiment`] builds each seed run from the preset.
//!
//! Encoders count `floor(θ/step + noise)`; with `single_turn` the counters wrap every
//! revolution, with the zero offsets added. The reference torque stands in for the seed's
//! six-axis sensor at the flange: `τ` plus white noise.

use serde::{Deserialize, Serialize};
use strainwave_core::compliance::{Compliance, FlexsplineStiffening, SeedCompliance, WaveGeneratorSoftening};
use strainwave_core::torsion::TorqueSolver;

use crate::check::{finite as fin, non_negative as nonneg, positive as pos};
use crate::error::SimError;
use crate::rng::Rng;

const TAU: f64 = std::f64::consts::TAU;

/// The preset's TOML text.
pub const PRESET_TOML: &str = include_str!("../presets/hda-arm.toml");

/// Largest `|ω h|` of the stiffest mode per RK4 sub-step (as in the joint twin).
pub const MAX_OMEGA_H: f64 = 0.6;

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

/// Gear: ratio and the seed's two springs.
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
    /// Polynomial `a_0, a_1, …` in the output angle (rad), e.g. seed 002 Table II; short runs only.
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

/// Motor (seed App. A).
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
    /// Viscous drag `b_L`, N·m·s/rad (not in the seed's model; see the preset).
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

/// What the motor does.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum MotorCommand {
    /// PID holds the motor at its starting angle.
    HoldPosition,
    /// PID tracks a link-angle ramp at `link_speed_rad_s` (reached with a 1 s raised-cosine
    /// acceleration), reversing over 2 s from `reverse_at_s`.
    PositionRamp {
        /// Link speed of the reference, rad/s.
        link_speed_rad_s: f64,
        /// Time of the reversal, s (none when beyond the run).
        reverse_at_s: f64,
    },
    /// Constant open-loop motor torque (N·m at the motor shaft) from t = 0.
    ConstantTorque {
        /// Motor torque, N·m.
        motor_torque_nm: f64,
    },
    /// Open-loop motor torque step.
    TorqueStep {
        /// Motor torque after the step, N·m.
        motor_torque_nm: f64,
        /// Time of the step, s.
        at_s: f64,
    },
    /// Open-loop sinusoidal motor torque.
    TorqueSine {
        /// Amplitude, N·m.
        amplitude_nm: f64,
        /// Frequency, Hz.
        frequency_hz: f64,
    },
}

/// A hand pushing on the link (components add).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum HandTorque {
    /// Raised-cosine step to `torque_nm` over `rise_s` from `at_s`, back to 0 from `release_s`.
    Step {
        /// Start, s.
        at_s: f64,
        /// Size, N·m.
        torque_nm: f64,
        /// Rise (and fall) time, s.
        rise_s: f64,
        /// Start of the release, s (none = held to the end).
        #[serde(default)]
        release_s: Option<f64>,
    },
    /// `A sin(2π f (t − start) + phase)` between `start_s` and `end_s`.
    Sine {
        /// Amplitude, N·m.
        amplitude_nm: f64,
        /// Frequency, Hz.
        frequency_hz: f64,
        /// Phase, rad.
        #[serde(default)]
        phase_rad: f64,
        /// Start, s.
        #[serde(default)]
        start_s: f64,
        /// End, s (none = to the end).
        #[serde(default)]
        end_s: Option<f64>,
    },
}

/// Raised-cosine ramp 0 → 1 over `[t0, t0 + rise]`.
fn smooth_ramp(t: f64, t0: f64, rise: f64) -> f64 {
    if t <= t0 {
        0.0
    } else if t >= t0 + rise {
        1.0
    } else {
        0.5 - 0.5 * (std::f64::consts::PI * (t - t0) / rise).cos()
    }
}

impl HandTorque {
    /// Torque at time `t`, N·m.
    pub fn at(&self, t: f64) -> f64 {
        match self {
            HandTorque::Step { at_s, torque_nm, rise_s, release_s } => {
                let up = smooth_ramp(t, *at_s, *rise_s);
                let down = release_s.map_or(0.0, |r| smooth_ramp(t, r, *rise_s));
                torque_nm * (up - down)
            }
            HandTorque::Sine { amplitude_nm, frequency_hz, phase_rad, start_s, end_s } => {
                if t < *start_s || end_s.is_some_and(|e| t > e) {
                    0.0
                } else {
                    amplitude_nm * (TAU * frequency_hz * (t - start_s) + phase_rad).sin()
                }
            }
        }
    }
}

/// The seed-002 runs, built from the preset.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SeedExperiment {
    /// No load: the PID turns the link one revolution forward and back at 0.2 rad/s
    /// (for the kinematic error; the seed's Fig. 7 runs).
    NoLoad,
    /// Motor held, a multi-sine hand torque (0.2 to 7 Hz) up to ±59 N·m (for the compliance fit).
    LoadedHold,
    /// Seed §IV-A, step: motor held, 15 N·m step by hand at 1 s, released at 4 s.
    StepHold,
    /// Seed §IV-A, periodic: motor held, 12 N·m at 1 Hz by hand.
    PeriodicHold,
    /// Seed §IV-B, step: constant motor torque (4.14 N·m at the link: read at the motor
    /// shaft, the seed's 4.14 N·m would be 414 N·m at the link, ten times the rating) turning the arm
    /// about one revolution, 3 N·m step by hand from 1.0 to 2.2 s.
    StepConstantTorque,
    /// Seed §IV-B, periodic: constant motor torque, 5 N·m at 1.5 Hz by hand.
    PeriodicConstantTorque,
    /// Seed Fig. 4 (a, b): motor torque step (10 N·m at the link) on the free arm.
    Fig4Step,
    /// Seed Fig. 4 (c, d): sinusoidal motor torque (10 N·m at the link, 2 Hz) on the free arm.
    Fig4Sine,
}

impl SeedExperiment {
    /// All runs, in order.
    pub const ALL: [SeedExperiment; 8] = [
        SeedExperiment::NoLoad,
        SeedExperiment::LoadedHold,
        SeedExperiment::StepHold,
        SeedExperiment::PeriodicHold,
        SeedExperiment::StepConstantTorque,
        SeedExperiment::PeriodicConstantTorque,
        SeedExperiment::Fig4Step,
        SeedExperiment::Fig4Sine,
    ];

    /// Short name.
    pub fn name(self) -> &'static str {
        match self {
            SeedExperiment::NoLoad => "no-load",
            SeedExperiment::LoadedHold => "loaded-hold",
            SeedExperiment::StepHold => "step-hold",
            SeedExperiment::PeriodicHold => "periodic-hold",
            SeedExperiment::StepConstantTorque => "step-constant-torque",
            SeedExperiment::PeriodicConstantTorque => "periodic-constant-torque",
            SeedExperiment::Fig4Step => "fig4-step",
            SeedExperiment::Fig4Sine => "fig4-sine",
        }
    }

    /// The seed's mean and max |error| for this run, N·m (§IV), where it gives them.
    pub fn seed_figures_nm(self) -> Option<(f64, f64)> {
        match self {
            SeedExperiment::StepHold => Some((0.46, 2.54)),
            SeedExperiment::PeriodicHold => Some((0.62, 2.8)),
            SeedExperiment::StepConstantTorque => Some((1.27, 5.89)),
            SeedExperiment::PeriodicConstantTorque => Some((1.33, 4.5)),
            _ => None,
        }
    }
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

    /// The `hda-arm` preset (seed 002's arm, step experiment).
    ///
    /// ```
    /// let s = strainwave_sim::arm::ArmScenario::preset().unwrap();
    /// assert_eq!(s.gear.ratio, 100.0);
    /// assert!((s.motor.viscous_nm_s_per_rad() - 2.149e-5).abs() < 1e-8);
    /// ```
    pub fn preset() -> Result<Self, SimError> {
        Self::from_toml(PRESET_TOML)
    }

    /// A seed-002 run on the preset arm.
    ///
    /// ```
    /// use strainwave_sim::arm::{ArmScenario, SeedExperiment};
    /// let s = ArmScenario::seed_experiment(SeedExperiment::PeriodicHold).unwrap();
    /// assert_eq!(s.external_torque.len(), 1);
    /// ```
    pub fn seed_experiment(which: SeedExperiment) -> Result<Self, SimError> {
        let mut s = Self::preset()?;
        s.with_experiment(which);
        s.validate()?;
        Ok(s)
    }

    /// Replaces the command, hand torque, duration and name by one of the seed's runs.
    pub fn with_experiment(&mut self, which: SeedExperiment) {
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
            SeedExperiment::NoLoad => {
                // Slow enough that the 2× relative-angle error (at 2 N v) stays far below
                // the link mode (≈ 28 Hz held): the torsion is then kinematic, not dynamic.
                let v = 0.2;
                let reverse = TAU / v + 1.0;
                (MotorCommand::PositionRamp { link_speed_rad_s: v, reverse_at_s: reverse }, vec![], 2.0 * reverse + 1.0)
            }
            SeedExperiment::LoadedHold => (
                MotorCommand::HoldPosition,
                vec![sine(40.0, 0.2, 0.5), sine(10.0, 1.3, 0.5), sine(5.0, 3.1, 0.5), sine(4.0, 7.0, 0.5)],
                15.0,
            ),
            SeedExperiment::StepHold => (MotorCommand::HoldPosition, vec![step(1.0, 15.0, Some(4.0))], 6.0),
            SeedExperiment::PeriodicHold => (MotorCommand::HoldPosition, vec![sine(12.0, 1.0, 1.0)], 6.0),
            SeedExperiment::StepConstantTorque => {
                (MotorCommand::ConstantTorque { motor_torque_nm: drive }, vec![step(1.0, 3.0, Some(2.2))], 3.0)
            }
            SeedExperiment::PeriodicConstantTorque => {
                (MotorCommand::ConstantTorque { motor_torque_nm: drive }, vec![sine(5.0, 1.5, 0.5)], 3.5)
            }
            SeedExperiment::Fig4Step => {
                (MotorCommand::TorqueStep { motor_torque_nm: -10.0 / n, at_s: 0.1 }, vec![], 1.0)
            }
            SeedExperiment::Fig4Sine => {
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
        pos(self.sample_rate_hz, "sample_rate_hz")?;
        pos(self.duration_s, "duration_s")?;
        if self.duration_s * self.sample_rate_hz > 1e9 {
            return Err(SimError::invalid("duration_s", "more than 1e9 samples".into()));
        }
        let g = &self.gear;
        pos(g.ratio, "gear.ratio")?;
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

/// Mechanical state.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ArmState {
    /// Motor angle `θ_m`, rad.
    pub motor_angle_rad: f64,
    /// Motor speed, rad/s.
    pub motor_speed_rad_s: f64,
    /// Link angle `θ`, rad.
    pub link_angle_rad: f64,
    /// Link speed, rad/s.
    pub link_speed_rad_s: f64,
    /// Play-operator outputs `p_i` of the hysteresis, rad.
    pub plays: [f64; PLAYS],
}

/// Number of play operators of the twin's hysteresis.
pub const PLAYS: usize = 4;
/// Play half-widths as multiples of `h`.
const PLAY_WIDTHS: [f64; PLAYS] = [0.25, 0.6, 1.2, 2.5];
/// Play weights (sum 1).
const PLAY_WEIGHTS: [f64; PLAYS] = [0.3, 0.3, 0.25, 0.15];

impl ArmState {
    fn axpy(&self, k: f64, d: &ArmState) -> ArmState {
        ArmState {
            motor_angle_rad: self.motor_angle_rad + k * d.motor_angle_rad,
            motor_speed_rad_s: self.motor_speed_rad_s + k * d.motor_speed_rad_s,
            link_angle_rad: self.link_angle_rad + k * d.link_angle_rad,
            link_speed_rad_s: self.link_speed_rad_s + k * d.link_speed_rad_s,
            plays: self.plays,
        }
    }
}

/// The arm's physics (no controller, no sensors).
#[derive(Debug, Clone)]
pub struct ArmModel {
    springs: SeedCompliance<f64>,
    half_width_rad: f64,
    solver: TorqueSolver<f64>,
    kinematic: ArmKinematicError,
    n_s: f64,
    damping: f64,
    jm: f64,
    rm: f64,
    jl: f64,
    bl: f64,
}

impl ArmModel {
    /// Builds the model from a scenario (parameters checked by the core).
    pub fn new(s: &ArmScenario) -> Result<Self, SimError> {
        let g = &s.gear;
        let springs = SeedCompliance::new(
            FlexsplineStiffening::new(g.flexspline_k0_nm_per_rad, g.flexspline_c_per_nm)?,
            WaveGeneratorSoftening::new(g.wave_generator_k0_nm_per_rad, g.wave_generator_c_per_nm)?,
            g.ratio,
        )?;

        // Truth is solved far tighter than any estimator, with a wide bracket.
        let solver = TorqueSolver::new(20.0 * g.rated_torque_nm, 1e-12 * g.rated_torque_nm, 120)?;
        Ok(Self {
            springs,
            half_width_rad: 0.5 * g.hysteresis_loss_rad,
            solver,
            kinematic: s.kinematic_error.clone(),
            n_s: -g.ratio,
            damping: g.damping_nm_s_per_rad,
            jm: s.motor.inertia_kg_m2,
            rm: s.motor.viscous_nm_s_per_rad(),
            jl: s.link.inertia_kg_m2,
            bl: s.link.viscous_nm_s_per_rad,
        })
    }

    /// The seed's springs.
    pub fn springs(&self) -> &SeedCompliance<f64> {
        &self.springs
    }

    /// Half loop width `h`, rad (0 = no hysteresis).
    pub fn hysteresis_half_width_rad(&self) -> f64 {
        self.half_width_rad
    }

    /// Hysteresis state `z = Σ α_i (w − p_i)/r_i ∈ [−1, 1]` at a state.
    pub fn hysteresis_state(&self, x: &ArmState) -> f64 {
        if self.half_width_rad <= 0.0 {
            return 0.0;
        }
        let w = self.windup_rad(x);
        (0..PLAYS).map(|i| PLAY_WEIGHTS[i] * (w - x.plays[i]) / (PLAY_WIDTHS[i] * self.half_width_rad)).sum()
    }

    /// The plays after moving the wind-up to `w` from `plays0` (exact for a monotone path).
    fn advance_plays(&self, plays0: &[f64; PLAYS], w: f64) -> [f64; PLAYS] {
        let mut p = *plays0;
        if self.half_width_rad > 0.0 {
            for (pi, r) in p.iter_mut().zip(PLAY_WIDTHS) {
                let r = r * self.half_width_rad;
                *pi = pi.clamp(w - r, w + r);
            }
        }
        p
    }

    /// Signed ratio `n_s = −N`.
    pub fn signed_ratio(&self) -> f64 {
        self.n_s
    }

    /// Kinematic error at a state, rad.
    pub fn kinematic_error_rad(&self, x: &ArmState) -> f64 {
        self.kinematic.eval(x.link_angle_rad, x.motor_angle_rad - x.link_angle_rad)
    }

    /// Wind-up `w = θ_m/n_s + θ_k − θ`, rad.
    pub fn windup_rad(&self, x: &ArmState) -> f64 {
        x.motor_angle_rad / self.n_s + self.kinematic_error_rad(x) - x.link_angle_rad
    }

    /// Torsion `θ_h = θ − θ_m/n_s`, rad.
    pub fn torsion_rad(&self, x: &ArmState) -> f64 {
        x.link_angle_rad - x.motor_angle_rad / self.n_s
    }

    /// Spring torque for an elastic twist, N·m (clamped at the bracket if beyond it).
    fn spring_torque_nm(&self, elastic_rad: f64, guess_nm: f64) -> f64 {
        match self.solver.solve(&self.springs, elastic_rad, guess_nm) {
            Ok(s) => s.torque_nm,
            Err(_) => self.solver.torque_limit_nm() * elastic_rad.signum(),
        }
    }

    /// Link torque `τ = τ_s(w + h z) + c ẇ`, N·m.
    pub fn link_torque_nm(&self, x: &ArmState, guess_nm: f64) -> f64 {
        let w = self.windup_rad(x);
        let elastic = w + self.half_width_rad * self.hysteresis_state(x);
        let rate = x.motor_speed_rad_s / self.n_s - x.link_speed_rad_s;
        self.spring_torque_nm(elastic, guess_nm) + self.damping * rate
    }

    fn derivative(&self, x: &ArmState, motor_torque_nm: f64, ext_nm: f64, guess: &mut f64) -> ArmState {
        let tau = self.link_torque_nm(x, *guess);
        *guess = tau;
        ArmState {
            motor_angle_rad: x.motor_speed_rad_s,
            motor_speed_rad_s: (motor_torque_nm - self.rm * x.motor_speed_rad_s - tau / self.n_s) / self.jm,
            link_angle_rad: x.link_speed_rad_s,
            link_speed_rad_s: (tau - self.bl * x.link_speed_rad_s + ext_nm) / self.jl,
            plays: [0.0; PLAYS],
        }
    }

    /// One RK4 step with the motor torque held and `τ_d` sampled at mid-step; the
    /// plays are advanced exactly from the step's start in every stage.
    pub fn rk4_step(&self, x: &mut ArmState, h_s: f64, motor_torque_nm: f64, ext_nm: f64, guess: &mut f64) {
        let plays0 = x.plays;
        let stage = |y: ArmState| ArmState { plays: self.advance_plays(&plays0, self.windup_rad(&y)), ..y };
        let k1 = self.derivative(x, motor_torque_nm, ext_nm, guess);
        let k2 = self.derivative(&stage(x.axpy(0.5 * h_s, &k1)), motor_torque_nm, ext_nm, guess);
        let k3 = self.derivative(&stage(x.axpy(0.5 * h_s, &k2)), motor_torque_nm, ext_nm, guess);
        let k4 = self.derivative(&stage(x.axpy(h_s, &k3)), motor_torque_nm, ext_nm, guess);
        let w = h_s / 6.0;
        let next = x.axpy(w, &k1).axpy(2.0 * w, &k2).axpy(2.0 * w, &k3).axpy(w, &k4);
        *x = stage(next);
    }

    /// Highest natural frequency (stiffest tangent at 3 × rated torque, raised by the
    /// plays' slopes `1 + Σ α_i h / r_i` while they stick), or the damping rate if larger, rad/s.
    pub fn max_rate_rad_s(&self, rated_torque_nm: f64) -> f64 {
        let k = 1.0 / self.springs.compliance_rad_per_nm(3.0 * rated_torque_nm);
        let stick: f64 = if self.half_width_rad > 0.0 {
            PLAY_WEIGHTS.iter().zip(PLAY_WIDTHS).map(|(a, r)| a / r).sum()
        } else {
            0.0
        };
        let k = (1.0 + stick) * k;
        let inv_j = 1.0 / self.jl + 1.0 / (self.jm * self.n_s * self.n_s);
        (k * inv_j).sqrt().max(self.damping * inv_j)
    }
}

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
            let clipped = u.clamp(-limit, limit);
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
        u.clamp(-limit, limit)
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

/// A whole arm run in memory: column names and one `Vec` per column.
#[derive(Debug, Clone)]
pub struct ArmRecording {
    /// Column names.
    pub columns: Vec<&'static str>,
    /// Column data, `data[c][k]`.
    pub data: Vec<Vec<f64>>,
}

impl ArmRecording {
    /// A column by name.
    pub fn column(&self, name: &str) -> Option<&[f64]> {
        self.columns.iter().position(|c| *c == name).map(|i| self.data[i].as_slice())
    }
}

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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn preset_parses_and_round_trips() {
        let s = ArmScenario::preset().unwrap();
        assert_eq!(ArmScenario::from_toml(&s.to_toml()).unwrap(), s);
        for e in SeedExperiment::ALL {
            ArmScenario::seed_experiment(e).unwrap();
        }
    }

    #[test]
    fn bad_values_name_their_key() {
        let bad = PRESET_TOML.replace("ratio = 100.0", "ratio = -1.0");
        match ArmScenario::from_toml(&bad) {
            Err(SimError::Invalid { key, .. }) => assert_eq!(key, "gear.ratio"),
            other => panic!("{other:?}"),
        }
        let unknown = PRESET_TOML.replace("[link]", "[link]\nmass_kg = 3.0");
        assert!(matches!(ArmScenario::from_toml(&unknown), Err(SimError::Parse { .. })));
    }

    #[test]
    fn hand_step_is_smooth_and_released() {
        let h = HandTorque::Step { at_s: 1.0, torque_nm: 10.0, rise_s: 0.1, release_s: Some(2.0) };
        assert_eq!(h.at(0.5), 0.0);
        assert!((h.at(1.05) - 5.0).abs() < 1e-9);
        assert_eq!(h.at(1.5), 10.0);
        assert!(h.at(3.0).abs() < 1e-12);
    }
}
