//! The motor test bench of Stoß et al. (2022) (docs/physics.md §6, §7): DUT rotor, torsion shaft, hysteresis
//! brake, stator housing on a helix coupling, two opposed accelerometers, a PMSM whose
//! torque carries harmonics of the electrical angle, a speed ramp or a current sweep.
//!
//! A run is a [`BenchScenario`] (TOML, unknown keys rejected, [`BenchScenario::validate`]
//! names the key at fault); [`preset`] has the paper's bench (`kit-bench`: speed ramp
//! 0 → 3200 rpm, Fig. 8) and its sweep (`kit-bench-sweep`: current injection at
//! standstill, §V). [`BenchSimulator`] streams rows like [`crate::Simulator`]; the columns
//! are in [`MEASURED_COLUMNS`] and [`TRUE_COLUMNS`]. The dynamics are in [`model`].
//!
//! ```
//! let s = strainwave_sim::bench::preset("kit-bench").unwrap();
//! let mut sim = strainwave_sim::bench::BenchSimulator::new(&s).unwrap();
//! let mut row = Vec::new();
//! assert!(sim.next_row(&mut row));
//! assert_eq!(row.len(), sim.columns().len());
//! ```

pub mod model;
mod simulator;
#[cfg(test)]
mod tests;

use serde::{Deserialize, Serialize};

use crate::check::{finite as fin, non_negative as nonneg, positive as pos};
use crate::error::SimError;

pub use simulator::{simulate_bench, BenchRecording, BenchSimulator, MEASURED_COLUMNS, TRUE_COLUMNS};

/// A bench run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BenchScenario {
    /// Short name.
    pub name: String,
    /// Output sample rate, Hz.
    pub sample_rate_hz: f64,
    /// Length of the run, s.
    pub duration_s: f64,
    /// Random seed (noise).
    pub seed: u64,
    /// Inertias, stiffnesses, dampings.
    pub mechanics: MechanicsParams,
    /// Hysteresis brake.
    pub brake: BrakeParams,
    /// The machine under test.
    pub dut: DutParams,
    /// Torsion-shaft sensor.
    pub torsion_sensor: TorsionSensorParams,
    /// The two accelerometers.
    pub accelerometers: AccelerometerParams,
    /// Encoder and current measurement.
    pub encoder: EncoderParams,
    /// What the drive does.
    pub profile: BenchProfile,
}

/// Mechanics (Stoß et al. (2022) Table I), SI units.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MechanicsParams {
    /// DUT rotor `J_R`, kg·m².
    pub rotor_inertia_kg_m2: f64,
    /// Brake rotor `J_B`, kg·m².
    pub brake_inertia_kg_m2: f64,
    /// DUT stator + housing `J_S,tot`, kg·m².
    pub stator_inertia_kg_m2: f64,
    /// Rotor–brake stiffness through the torsion shaft `k_RB,TS`, N·m/rad.
    pub shaft_stiffness_nm_per_rad: f64,
    /// Damping across the shaft (the paper's `2 Γ_LP` of eq. 1), N·m·s/rad.
    pub shaft_damping_nm_s_per_rad: f64,
    /// DUT bearing damping between rotor and housing (carries rotor motion into the
    /// accelerometers, Stoß et al. 2022, eq. 5), N·m·s/rad.
    pub rotor_bearing_damping_nm_s_per_rad: f64,
    /// Brake bearing damping to ground, N·m·s/rad.
    pub brake_bearing_damping_nm_s_per_rad: f64,
    /// Helix coupling `k_S`, N·m/rad.
    pub coupling_stiffness_nm_per_rad: f64,
    /// Housing bearing damping `Γ_LS`, N·m·s/rad.
    pub stator_damping_nm_s_per_rad: f64,
}

/// Hysteresis brake: speed-independent torque, no harmonics.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BrakeParams {
    /// Braking torque once engaged, N·m (≥ 0; 0: "connected but not braked").
    pub torque_nm: f64,
    /// The brake current ramps in over this time from the start (raised cosine), s (≥ 0).
    pub engage_s: f64,
    /// Speed below which the torque fades to zero (`ω/√(ω² + ε²)`), rad/s.
    pub speed_threshold_rad_s: f64,
}

/// One harmonic of the flux linkages in the electrical angle:
/// `ψ_d += A_d cos(k γ + φ)`, `ψ_q += A_q sin(k γ + φ)`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FluxHarmonic {
    /// Electrical order `k` (≥ 1).
    pub order_el: u32,
    /// `A_d`, V·s.
    pub d_amplitude_vs: f64,
    /// `A_q`, V·s.
    pub q_amplitude_vs: f64,
    /// `φ`, rad.
    pub phase_rad: f64,
}

/// One cogging component `c sin(N θ + φ)`, `θ` the mechanical rotor–stator angle.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CoggingHarmonic {
    /// Mechanical order `N` (≥ 1).
    pub order_mech: u32,
    /// `c`, N·m.
    pub amplitude_nm: f64,
    /// `φ`, rad.
    pub phase_rad: f64,
}

/// The PMSM under test (Stoß et al. (2022) Table II) with its torque harmonics.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DutParams {
    /// Pole pairs `p` (≥ 1).
    pub pole_pairs: u32,
    /// `Ψ_PM`, V·s.
    pub pm_flux_linkage_vs: f64,
    /// `L_d`, H.
    pub d_inductance_h: f64,
    /// `L_q`, H.
    pub q_inductance_h: f64,
    /// Flux-linkage harmonics (torque harmonics through eq. 12).
    #[serde(default)]
    pub flux_harmonics: Vec<FluxHarmonic>,
    /// Cogging torque (not in eq. 12: a model cannot see it).
    #[serde(default)]
    pub cogging: Vec<CoggingHarmonic>,
}

/// Torsion-shaft sensor (Kistler 4503B in the paper).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TorsionSensorParams {
    /// Range `±range_nm`; readings clip there, N·m.
    pub range_nm: f64,
    /// White noise per sample, 1σ (rms), N·m (`noise_nm_rms` in older files).
    #[serde(alias = "noise_nm_rms")]
    pub noise_nm: f64,
}

/// A vibration of the housing that both accelerometers see with opposite signs (it
/// cancels in their sum): at a fixed frequency or at an order of the rotor speed.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Vibration {
    /// Amplitude, m/s².
    pub amplitude_m_s2: f64,
    /// Fixed frequency, Hz (give this or `order_mech`).
    #[serde(default)]
    pub frequency_hz: Option<f64>,
    /// Order of the rotor speed (give this or `frequency_hz`).
    #[serde(default)]
    pub order_mech: Option<f64>,
}

/// The two opposed accelerometers (PCB 352B in the paper).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AccelerometerParams {
    /// Radius `R`, m.
    pub radius_m: f64,
    /// Range `±range_m_s2`; readings clip there, m/s².
    pub range_m_s2: f64,
    /// White noise per sensor and sample, m/s² rms.
    pub noise_m_s2_rms: f64,
    /// Relative sensitivity error of sensor 2 (vibration then leaks into the sum).
    #[serde(default)]
    pub gain_error_2: f64,
    /// Housing vibrations.
    #[serde(default)]
    pub vibration: Vec<Vibration>,
}

/// Rotor encoder inside the housing (rotor–stator angle) and measured currents.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EncoderParams {
    /// Counts per revolution (iC-Haus MH8 12 bit: 4096).
    pub counts_per_rev: u32,
    /// White noise on the speed channel, rpm rms.
    pub speed_noise_rpm: f64,
    /// White noise on each measured current, A rms.
    pub current_noise_a: f64,
}

/// Log or linear frequency law of a sweep.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum SweepSpacing {
    /// `f(t) = f0 (f1/f0)^(t/T)`.
    Log,
    /// `f(t) = f0 + (f1 − f0) t / T`.
    Linear,
}

/// What the drive does.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case", deny_unknown_fields)]
pub enum BenchProfile {
    /// Speed-controlled ramp (paper §IV): a PI speed loop sets `i_q`, `i_d` is held.
    #[serde(alias = "speed_ramp")]
    SpeedRamp {
        /// Start speed, rpm (≥ 0).
        from_rpm: f64,
        /// End speed, rpm (≥ `from_rpm`).
        to_rpm: f64,
        /// Ramp time, s (then the speed holds).
        ramp_s: f64,
        /// `i_d`, A (ramps in with the brake).
        d_current_a: f64,
        /// Speed loop bandwidth, Hz.
        speed_loop_bandwidth_hz: f64,
    },
    /// Current injection at standstill (paper §V): `i_q = I cos φ(t)`, `i_d = 0`, in the
    /// rotor frame (ideal current loop), the frequency swept from `from_hz` to `to_hz` over
    /// the run.
    #[serde(alias = "current_sweep")]
    CurrentSweep {
        /// `I`, A.
        amplitude_a: f64,
        /// Start frequency, Hz.
        from_hz: f64,
        /// End frequency, Hz (below `sample_rate_hz / 2`).
        to_hz: f64,
        /// Frequency law.
        spacing: SweepSpacing,
    },
}

impl BenchScenario {
    /// Parses TOML and validates it.
    ///
    /// ```
    /// let text = strainwave_sim::bench::preset_text("kit-bench").unwrap();
    /// let s = strainwave_sim::bench::BenchScenario::from_toml(text).unwrap();
    /// assert_eq!(s.mechanics.shaft_stiffness_nm_per_rad, 258.0);
    /// assert!(strainwave_sim::bench::BenchScenario::from_toml("name = 1").is_err());
    /// ```
    pub fn from_toml(text: &str) -> Result<Self, SimError> {
        let s: BenchScenario = crate::check::parse_toml(text)?;
        s.validate()?;
        Ok(s)
    }

    /// The scenario as TOML.
    pub fn to_toml(&self) -> String {
        toml::to_string(self).unwrap_or_else(|e| format!("# could not serialize scenario: {e}\n"))
    }

    /// Checks every value; the error names the key.
    pub fn validate(&self) -> Result<(), SimError> {
        crate::check::run_length(self.duration_s, self.sample_rate_hz)?;
        let m = &self.mechanics;
        pos(m.rotor_inertia_kg_m2, "mechanics.rotor_inertia_kg_m2")?;
        pos(m.brake_inertia_kg_m2, "mechanics.brake_inertia_kg_m2")?;
        pos(m.stator_inertia_kg_m2, "mechanics.stator_inertia_kg_m2")?;
        pos(m.shaft_stiffness_nm_per_rad, "mechanics.shaft_stiffness_nm_per_rad")?;
        nonneg(m.shaft_damping_nm_s_per_rad, "mechanics.shaft_damping_nm_s_per_rad")?;
        nonneg(m.rotor_bearing_damping_nm_s_per_rad, "mechanics.rotor_bearing_damping_nm_s_per_rad")?;
        nonneg(m.brake_bearing_damping_nm_s_per_rad, "mechanics.brake_bearing_damping_nm_s_per_rad")?;
        pos(m.coupling_stiffness_nm_per_rad, "mechanics.coupling_stiffness_nm_per_rad")?;
        nonneg(m.stator_damping_nm_s_per_rad, "mechanics.stator_damping_nm_s_per_rad")?;
        let b = &self.brake;
        nonneg(b.torque_nm, "brake.torque_nm")?;
        nonneg(b.engage_s, "brake.engage_s")?;
        pos(b.speed_threshold_rad_s, "brake.speed_threshold_rad_s")?;
        let d = &self.dut;
        if d.pole_pairs == 0 {
            return Err(SimError::invalid("dut.pole_pairs", "must be at least 1".into()));
        }
        pos(d.pm_flux_linkage_vs, "dut.pm_flux_linkage_vs")?;
        pos(d.d_inductance_h, "dut.d_inductance_h")?;
        pos(d.q_inductance_h, "dut.q_inductance_h")?;
        for h in &d.flux_harmonics {
            if h.order_el == 0 {
                return Err(SimError::invalid("dut.flux_harmonics.order_el", "must be at least 1".into()));
            }
            fin(h.d_amplitude_vs, "dut.flux_harmonics.d_amplitude_vs")?;
            fin(h.q_amplitude_vs, "dut.flux_harmonics.q_amplitude_vs")?;
            fin(h.phase_rad, "dut.flux_harmonics.phase_rad")?;
        }
        for c in &d.cogging {
            if c.order_mech == 0 {
                return Err(SimError::invalid("dut.cogging.order_mech", "must be at least 1".into()));
            }
            nonneg(c.amplitude_nm, "dut.cogging.amplitude_nm")?;
            fin(c.phase_rad, "dut.cogging.phase_rad")?;
        }
        pos(self.torsion_sensor.range_nm, "torsion_sensor.range_nm")?;
        nonneg(self.torsion_sensor.noise_nm, "torsion_sensor.noise_nm")?;
        let a = &self.accelerometers;
        pos(a.radius_m, "accelerometers.radius_m")?;
        pos(a.range_m_s2, "accelerometers.range_m_s2")?;
        nonneg(a.noise_m_s2_rms, "accelerometers.noise_m_s2_rms")?;
        if !(a.gain_error_2.is_finite() && a.gain_error_2 > -1.0) {
            return Err(SimError::invalid(
                "accelerometers.gain_error_2",
                format!("must be > −1, got {}", a.gain_error_2),
            ));
        }
        for v in &a.vibration {
            nonneg(v.amplitude_m_s2, "accelerometers.vibration.amplitude_m_s2")?;
            match (v.frequency_hz, v.order_mech) {
                (Some(f), None) => nonneg(f, "accelerometers.vibration.frequency_hz")?,
                (None, Some(o)) => nonneg(o, "accelerometers.vibration.order_mech")?,
                _ => {
                    return Err(SimError::invalid(
                        "accelerometers.vibration",
                        "give exactly one of frequency_hz and order_mech".into(),
                    ))
                }
            }
        }
        if self.encoder.counts_per_rev == 0 {
            return Err(SimError::invalid("encoder.counts_per_rev", "must be positive".into()));
        }
        nonneg(self.encoder.speed_noise_rpm, "encoder.speed_noise_rpm")?;
        nonneg(self.encoder.current_noise_a, "encoder.current_noise_a")?;
        match &self.profile {
            BenchProfile::SpeedRamp { from_rpm, to_rpm, ramp_s, d_current_a, speed_loop_bandwidth_hz } => {
                nonneg(*from_rpm, "profile.from_rpm")?;
                nonneg(*to_rpm, "profile.to_rpm")?;
                if to_rpm < from_rpm {
                    return Err(SimError::invalid("profile.to_rpm", "must be at least profile.from_rpm".into()));
                }
                pos(*ramp_s, "profile.ramp_s")?;
                fin(*d_current_a, "profile.d_current_a")?;
                pos(*speed_loop_bandwidth_hz, "profile.speed_loop_bandwidth_hz")?;
                if *speed_loop_bandwidth_hz >= 0.1 * self.sample_rate_hz {
                    return Err(SimError::invalid(
                        "profile.speed_loop_bandwidth_hz",
                        format!("must be below a tenth of sample_rate_hz, got {speed_loop_bandwidth_hz}"),
                    ));
                }
            }
            BenchProfile::CurrentSweep { amplitude_a, from_hz, to_hz, .. } => {
                nonneg(*amplitude_a, "profile.amplitude_a")?;
                pos(*from_hz, "profile.from_hz")?;
                pos(*to_hz, "profile.to_hz")?;
                if to_hz < from_hz {
                    return Err(SimError::invalid("profile.to_hz", "must be at least profile.from_hz".into()));
                }
                if *to_hz >= 0.5 * self.sample_rate_hz {
                    return Err(SimError::invalid(
                        "profile.to_hz",
                        format!("must be below the Nyquist frequency {}", 0.5 * self.sample_rate_hz),
                    ));
                }
            }
        }
        Ok(())
    }
}

/// The commented TOML of the paper's bench.
pub const KIT_BENCH_TOML: &str = include_str!("../../presets/kit-bench.toml");

/// Preset names.
pub const PRESET_NAMES: &[&str] = &["kit-bench", "kit-bench-sweep"];

/// The TOML text of a preset; `kit-bench-sweep` is `kit-bench` with its sweep (see
/// [`preset`]), so it has no text of its own and gives `kit-bench`'s.
pub fn preset_text(name: &str) -> Result<&'static str, SimError> {
    if PRESET_NAMES.contains(&name) {
        Ok(KIT_BENCH_TOML)
    } else {
        Err(SimError::UnknownPreset(name.to_string(), PRESET_NAMES.join(", ")))
    }
}

/// A bench preset, validated:
///
/// - `kit-bench`: Table I/II bench, speed ramp 0 → 3200 rpm at `i_d = −4 A` (Stoß et al. 2022, Fig. 8);
/// - `kit-bench-sweep`: the same bench at standstill, brake not braked, `i_q` of 0.1 A
///   swept logarithmically from 0.5 Hz to 8 kHz over 40 s (paper §V: 100 Hz … 8 kHz,
///   extended down into the torsion sensor's range).
///
/// ```
/// use strainwave_sim::bench::{preset, BenchProfile};
/// let s = preset("kit-bench-sweep").unwrap();
/// assert!(matches!(s.profile, BenchProfile::CurrentSweep { .. }));
/// assert!(preset("nope").is_err());
/// ```
pub fn preset(name: &str) -> Result<BenchScenario, SimError> {
    let mut s = BenchScenario::from_toml(preset_text(name)?)?;
    if name == "kit-bench-sweep" {
        s.name = name.to_string();
        s.duration_s = 40.0;
        s.brake.torque_nm = 0.0;
        s.profile =
            BenchProfile::CurrentSweep { amplitude_a: 0.1, from_hz: 0.5, to_hz: 8000.0, spacing: SweepSpacing::Log };
        s.validate()?;
    }
    Ok(s)
}
