//! The scenario: every physical parameter of the simulated joint, its motion and
//! load profiles, sample rate, duration and seed, as TOML (docs/physics.md §7).
//!
//! Unknown keys are rejected; [`Scenario::validate`] checks every value and names
//! the key at fault.

use serde::{Deserialize, Serialize};

use crate::error::SimError;

mod validate;

/// A full simulation scenario.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scenario {
    /// Short name, written into reports.
    pub name: String,
    /// Output sample rate, Hz.
    pub sample_rate_hz: f64,
    /// Length of the run, s.
    pub duration_s: f64,
    /// Random seed (noise, random placement errors).
    pub seed: u64,
    /// Seed of the measurement noise alone, if it should differ from `seed`: the same
    /// `seed` draws the same gauge placement (the same sensor), so a run with another
    /// `noise_seed` is the same joint measured again.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub noise_seed: Option<u64>,
    /// The strain wave gear.
    pub gear: GearParams,
    /// Motor and its speed controller.
    pub motor: MotorParams,
    /// Load on the output.
    pub load: LoadParams,
    /// Gear-meshing ripple torque (real torque at the relative-angle orders).
    pub ripple: RippleParams,
    /// Misalignment torque signature (1× output angle).
    pub misalignment: MisalignmentParams,
    /// Flexspline strain-gauge bridge and its signal chain.
    pub sensor: SensorParams,
    /// Encoders, tachometer, current sensor.
    pub encoders: EncoderParams,
    /// Motion profile, segments in order.
    #[serde(default)]
    pub motion: Vec<MotionSegment>,
    /// External torque on the load, the sum of these components.
    #[serde(default)]
    pub external_torque: Vec<ExternalTorque>,
    /// Further lines the sensor picks up (an order no canceller model lists, say).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub extra_lines: Vec<ExtraLine>,
}

/// The angle an extra line is periodic in.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum LineReference {
    /// Relative wave generator–flexspline angle (counted in `true_ripple`).
    Relative,
    /// Output angle (counted in `true_misalignment`).
    Output,
    /// Motor angle (counted in `true_ripple`).
    Motor,
}

/// A sensor-side line `amplitude_nm · sin(multiple · θ + phase_rad)` in output N·m.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ExtraLine {
    /// The angle `θ`.
    pub reference: LineReference,
    /// Multiple of `θ`.
    pub multiple: f64,
    /// Amplitude, N·m.
    pub amplitude_nm: f64,
    /// Phase, rad.
    #[serde(default)]
    pub phase_rad: f64,
}

/// Which gear element is fixed, as written in TOML: the core's enum, spelled as in every
/// configuration file (`circular_spline`, alias `circular-spline`, or `flexspline`).
pub use strainwave_core::gear::FixedElement as FixedElementName;

/// Gear parameters: ratio, configuration, catalogue stiffness, hysteresis, friction.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GearParams {
    /// Ratio `N`.
    pub ratio: f64,
    /// Fixed element.
    pub fixed: FixedElementName,
    /// Rated output torque, N·m (sets full scale in reports).
    pub rated_torque_nm: f64,
    /// Stiffness below `t1_nm`, N·m/rad.
    pub k1_nm_per_rad: f64,
    /// Stiffness between `t1_nm` and `t2_nm`, N·m/rad.
    pub k2_nm_per_rad: f64,
    /// Stiffness above `t2_nm`, N·m/rad.
    pub k3_nm_per_rad: f64,
    /// First break torque, N·m.
    pub t1_nm: f64,
    /// Second break torque, N·m.
    pub t2_nm: f64,
    /// Width of the hysteresis loop in twist (catalogue hysteresis loss), rad.
    pub hysteresis_rad: f64,
    /// Structural damping of the gear spring, N·m·s/rad.
    pub damping_nm_s_per_rad: f64,
    /// Viscous gear friction at the output, N·m·s/rad.
    pub friction_viscous_nm_s_per_rad: f64,
    /// Coulomb gear friction at the output, N·m.
    pub friction_coulomb_nm: f64,
}

/// Motor, current limit and speed loop.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MotorParams {
    /// Rotor + wave generator inertia, kg·m².
    pub inertia_kg_m2: f64,
    /// Torque constant, N·m/A.
    pub torque_constant_nm_per_a: f64,
    /// Viscous friction, N·m·s/rad.
    pub viscous_nm_s_per_rad: f64,
    /// Coulomb friction, N·m.
    pub coulomb_nm: f64,
    /// Current limit, A.
    pub current_limit_a: f64,
    /// Bandwidth of the PI speed loop, Hz.
    pub speed_loop_bandwidth_hz: f64,
}

/// Load on the output.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LoadParams {
    /// Load inertia, kg·m².
    pub inertia_kg_m2: f64,
    /// Viscous friction, N·m·s/rad.
    pub viscous_nm_s_per_rad: f64,
    /// Coulomb friction, N·m.
    pub coulomb_nm: f64,
}

/// Meshing ripple: `Σ_h (a_h + b_h |T|) sin(2h φ + p_h)`, output N·m.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RippleParams {
    /// 2× amplitude at zero load, N·m.
    pub amplitude_2x_nm: f64,
    /// 2× amplitude growth per N·m of transmitted torque.
    pub amplitude_2x_per_nm: f64,
    /// 2× phase, rad.
    pub phase_2x_rad: f64,
    /// 4× amplitude at zero load, N·m.
    pub amplitude_4x_nm: f64,
    /// 4× amplitude growth per N·m of transmitted torque.
    pub amplitude_4x_per_nm: f64,
    /// 4× phase, rad.
    pub phase_4x_rad: f64,
}

/// Misalignment signature `A sin(θ_out + p)` picked up by the sensor, N·m.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MisalignmentParams {
    /// Amplitude, N·m.
    pub amplitude_nm: f64,
    /// Phase, rad.
    pub phase_rad: f64,
}

/// Gauge layout name.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum LayoutName {
    /// Taghirad and Bélanger (1999): four rosettes.
    #[serde(alias = "four_rosettes")]
    FourRosettes,
    /// the embedded-sensor article: eight gauges in four T pairs.
    #[serde(alias = "eight_gauge_t")]
    EightGaugeT,
}

/// Bridge equation.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum BridgeModel {
    /// `U/E = (K/4)(ε1 − ε2 + ε3 − ε4)`: outputs add exactly.
    #[default]
    #[serde(alias = "small_strain")]
    SmallStrain,
    /// The nonlinear bridge equation.
    Exact,
}

/// One interference harmonic, microstrain.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct InterferenceParams {
    /// Shear part, µε.
    pub shear_microstrain: f64,
    /// Normal-difference part, µε.
    pub normal_microstrain: f64,
    /// Common part, µε.
    pub common_microstrain: f64,
    /// Phase, rad.
    pub phase_rad: f64,
}

/// Placement error of one gauge (index 0..8 in the layout order).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GaugePlacement {
    /// Gauge index, 0..8.
    pub gauge: usize,
    /// Radial offset, mm.
    #[serde(default)]
    pub radial_mm: f64,
    /// Circumferential offset, degrees.
    #[serde(default)]
    pub circumferential_deg: f64,
    /// Orientation offset, degrees.
    #[serde(default)]
    pub angular_deg: f64,
}

/// Random placement tolerances (standard deviations), drawn once per run from the seed.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct PlacementTolerance {
    /// Radial, mm.
    pub radial_mm: f64,
    /// Circumferential, degrees.
    pub circumferential_deg: f64,
    /// Angular, degrees.
    pub angular_deg: f64,
}

/// Flexspline sensor: diaphragm, gauges, bridge, amplifier, ADC, noise.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SensorParams {
    /// Gauge layout.
    pub layout: LayoutName,
    /// Bridge equation.
    #[serde(default)]
    pub bridge_model: BridgeModel,
    /// Gauge factor `K`.
    pub gauge_factor: f64,
    /// Bridge excitation, V.
    pub excitation_v: f64,
    /// Diaphragm hub radius `r1`, m.
    pub hub_radius_m: f64,
    /// Diaphragm outer radius `r2`, m.
    pub outer_radius_m: f64,
    /// Diaphragm thickness `a`, m.
    pub thickness_m: f64,
    /// Shear modulus `G`, Pa.
    pub shear_modulus_pa: f64,
    /// Nominal gauge radius, m.
    pub gauge_radius_m: f64,
    /// 2× elliptical interference.
    pub interference_2x: InterferenceParams,
    /// 4× elliptical interference.
    pub interference_4x: InterferenceParams,
    /// Explicit placement errors per gauge.
    #[serde(default)]
    pub placement: Vec<GaugePlacement>,
    /// Random placement tolerances, added to the explicit errors.
    #[serde(default)]
    pub placement_tolerance: PlacementTolerance,
    /// Amplifier gain, V/V.
    pub amplifier_gain: f64,
    /// ADC bits.
    pub adc_bits: u32,
    /// ADC range `±adc_range_v`, V.
    pub adc_range_v: f64,
    /// White noise at the amplifier output, V rms.
    pub noise_v_rms: f64,
}

/// Encoders, tachometer and current sensor.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EncoderParams {
    /// Motor encoder counts per revolution.
    pub motor_counts_per_rev: u64,
    /// Output encoder counts per revolution.
    pub output_counts_per_rev: u64,
    /// Tachometer white noise, rad/s rms.
    pub tacho_noise_rad_s: f64,
    /// Current sensor white noise, A rms.
    pub current_noise_a: f64,
    /// Reference torque sensor on the output (the embedded-sensor article): white noise, N·m rms; absent = no sensor.
    #[serde(default)]
    pub reference_torque_noise_nm: Option<f64>,
}

/// One segment of the motion profile (motor-side speed, or open-loop current).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case", deny_unknown_fields)]
pub enum MotionSegment {
    /// Linear ramp of the motor speed to `to_rad_s` (a reversal when the sign changes).
    Ramp {
        /// Target motor speed, rad/s.
        to_rad_s: f64,
        /// Segment length, s.
        duration_s: f64,
    },
    /// Hold the current speed (standstill when it is 0).
    Hold {
        /// Segment length, s.
        duration_s: f64,
    },
    /// Sinusoid around the current speed.
    Sine {
        /// Amplitude, rad/s.
        amplitude_rad_s: f64,
        /// Frequency, Hz.
        frequency_hz: f64,
        /// Segment length, s.
        duration_s: f64,
    },
    /// Open-loop motor current (torque steps), speed loop off.
    Current {
        /// Motor current, A.
        current_a: f64,
        /// Segment length, s.
        duration_s: f64,
    },
}

/// One component of the external torque on the load (they add).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case", deny_unknown_fields)]
pub enum ExternalTorque {
    /// Step of `torque_nm` at `at_s` (negative steps remove load).
    Step {
        /// Time of the step, s.
        at_s: f64,
        /// Size, N·m.
        torque_nm: f64,
    },
    /// Sinusoid from `start_s` on.
    Sine {
        /// Amplitude, N·m.
        amplitude_nm: f64,
        /// Frequency, Hz.
        frequency_hz: f64,
        /// Phase, rad.
        #[serde(default)]
        phase_rad: f64,
        /// Start time, s.
        #[serde(default)]
        start_s: f64,
    },
    /// Linear rise from 0 at `from_s` to `torque_nm` at `to_s`, then held.
    Ramp {
        /// Start, s.
        from_s: f64,
        /// End, s.
        to_s: f64,
        /// Final torque, N·m.
        torque_nm: f64,
    },
}

impl Scenario {
    /// Parses TOML; unknown keys and wrong types are errors naming the key.
    pub fn from_toml(text: &str) -> Result<Self, SimError> {
        let s: Scenario = crate::check::parse_toml(text)?;
        s.validate()?;
        Ok(s)
    }

    /// The scenario as TOML.
    pub fn to_toml(&self) -> String {
        toml::to_string(self).unwrap_or_else(|e| format!("# could not serialize scenario: {e}\n"))
    }

    /// Highest motor speed the profile asks for, rad/s.
    pub fn top_motor_speed_rad_s(&self) -> f64 {
        let mut speed: f64 = 0.0;
        let mut top: f64 = 0.0;
        for seg in &self.motion {
            match seg {
                MotionSegment::Ramp { to_rad_s, .. } => {
                    speed = *to_rad_s;
                    top = top.max(speed.abs());
                }
                MotionSegment::Sine { amplitude_rad_s, .. } => top = top.max(speed.abs() + amplitude_rad_s.abs()),
                MotionSegment::Hold { .. } | MotionSegment::Current { .. } => {}
            }
        }
        top
    }

    /// Constant-speed windows of the motion profile `(start_s, end_s, motor_speed_rad_s)`:
    /// every `hold` segment at non-zero speed, minus `settle_s` at its start.
    ///
    /// ```
    /// let s = strainwave_sim::presets::preset("taghirad").unwrap();
    /// let w = s.hold_windows(0.2);
    /// assert_eq!(w[0], (0.6000000000000001, 2.0, 156.0));
    /// ```
    pub fn hold_windows(&self, settle_s: f64) -> Vec<(f64, f64, f64)> {
        let mut t = 0.0;
        let mut speed = 0.0;
        let mut out = Vec::new();
        for seg in &self.motion {
            match seg {
                MotionSegment::Ramp { to_rad_s, duration_s } => {
                    t += duration_s;
                    speed = *to_rad_s;
                }
                MotionSegment::Hold { duration_s } => {
                    if speed != 0.0 && *duration_s > settle_s {
                        out.push((t + settle_s, (t + duration_s).min(self.duration_s), speed));
                    }
                    t += duration_s;
                }
                MotionSegment::Sine { duration_s, .. } | MotionSegment::Current { duration_s, .. } => t += duration_s,
            }
        }
        out.retain(|w| w.1 > w.0);
        out
    }

    /// Total length of the motion profile, s.
    pub fn motion_length_s(&self) -> f64 {
        self.motion
            .iter()
            .map(|m| match m {
                MotionSegment::Ramp { duration_s, .. }
                | MotionSegment::Hold { duration_s }
                | MotionSegment::Sine { duration_s, .. }
                | MotionSegment::Current { duration_s, .. } => *duration_s,
            })
            .sum()
    }
}
