//! What drives the arm: the motor command, the hand torque and the paper's experiments.

use super::*;

/// What the motor does.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case", deny_unknown_fields)]
pub enum MotorCommand {
    /// PID holds the motor at its starting angle.
    #[serde(alias = "hold_position")]
    HoldPosition,
    /// PID tracks a link-angle ramp at `link_speed_rad_s` (reached with a 1 s raised-cosine
    /// acceleration), reversing over 2 s from `reverse_at_s`.
    #[serde(alias = "position_ramp")]
    PositionRamp {
        /// Link speed of the reference, rad/s.
        link_speed_rad_s: f64,
        /// Time of the reversal, s (none when beyond the run).
        reverse_at_s: f64,
    },
    /// Constant open-loop motor torque (N·m at the motor shaft) from t = 0.
    #[serde(alias = "constant_torque")]
    ConstantTorque {
        /// Motor torque, N·m.
        motor_torque_nm: f64,
    },
    /// Open-loop motor torque step.
    #[serde(alias = "torque_step")]
    TorqueStep {
        /// Motor torque after the step, N·m.
        motor_torque_nm: f64,
        /// Time of the step, s.
        at_s: f64,
    },
    /// Open-loop sinusoidal motor torque.
    #[serde(alias = "torque_sine")]
    TorqueSine {
        /// Amplitude, N·m.
        amplitude_nm: f64,
        /// Frequency, Hz.
        frequency_hz: f64,
    },
}

/// A hand pushing on the link (components add).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case", deny_unknown_fields)]
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
pub(super) fn smooth_ramp(t: f64, t0: f64, rise: f64) -> f64 {
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

/// The HDA-arm runs, built from the preset.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ArmExperiment {
    /// No load: the PID turns the link one revolution forward and back at 0.2 rad/s
    /// (for the kinematic error; the paper's Fig. 7 runs).
    NoLoad,
    /// Motor held, a multi-sine hand torque (0.2 to 7 Hz) up to ±59 N·m (for the compliance fit).
    LoadedHold,
    /// Paper §IV-A, step: motor held, 15 N·m step by hand at 1 s, released at 4 s.
    StepHold,
    /// Paper §IV-A, periodic: motor held, 12 N·m at 1 Hz by hand.
    PeriodicHold,
    /// Paper §IV-B, step: constant motor torque (4.14 N·m at the link: read at the motor
    /// shaft, the paper's 4.14 N·m would be 414 N·m at the link, ten times the rating) turning the arm
    /// about one revolution, 3 N·m step by hand from 1.0 to 2.2 s.
    StepConstantTorque,
    /// Paper §IV-B, periodic: constant motor torque, 5 N·m at 1.5 Hz by hand.
    PeriodicConstantTorque,
    /// Paper Fig. 4 (a, b): motor torque step (10 N·m at the link) on the free arm.
    Fig4Step,
    /// Paper Fig. 4 (c, d): sinusoidal motor torque (10 N·m at the link, 2 Hz) on the free arm.
    Fig4Sine,
}

impl ArmExperiment {
    /// All runs, in order.
    pub const ALL: [ArmExperiment; 8] = [
        ArmExperiment::NoLoad,
        ArmExperiment::LoadedHold,
        ArmExperiment::StepHold,
        ArmExperiment::PeriodicHold,
        ArmExperiment::StepConstantTorque,
        ArmExperiment::PeriodicConstantTorque,
        ArmExperiment::Fig4Step,
        ArmExperiment::Fig4Sine,
    ];

    /// Short name.
    pub fn name(self) -> &'static str {
        match self {
            ArmExperiment::NoLoad => "no-load",
            ArmExperiment::LoadedHold => "loaded-hold",
            ArmExperiment::StepHold => "step-hold",
            ArmExperiment::PeriodicHold => "periodic-hold",
            ArmExperiment::StepConstantTorque => "step-constant-torque",
            ArmExperiment::PeriodicConstantTorque => "periodic-constant-torque",
            ArmExperiment::Fig4Step => "fig4-step",
            ArmExperiment::Fig4Sine => "fig4-sine",
        }
    }

    /// The paper's mean and max |error| for this run, N·m (§IV), where it gives them.
    pub fn paper_figures_nm(self) -> Option<(f64, f64)> {
        match self {
            ArmExperiment::StepHold => Some((0.46, 2.54)),
            ArmExperiment::PeriodicHold => Some((0.62, 2.8)),
            ArmExperiment::StepConstantTorque => Some((1.27, 5.89)),
            ArmExperiment::PeriodicConstantTorque => Some((1.33, 4.5)),
            _ => None,
        }
    }
}
