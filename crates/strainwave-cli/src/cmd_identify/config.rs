//! The arm configuration `identify` reads (`--config ARM.toml`): gear, channels,
//! encoders and the model choices.

use anyhow::Result;
use serde::{Deserialize, Serialize};
use strainwave_core::gear::{FixedElement, Gear};
use strainwave_core::torsion::EncoderConfig;
use strainwave_io::Channel;

/// Which element is fixed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum Fixed {
    /// Circular spline fixed (usual robot joint).
    #[default]
    CircularSpline,
    /// Flexspline fixed.
    Flexspline,
}

/// The gear.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GearConfig {
    /// Ratio `N`.
    pub ratio: f64,
    /// Rated output torque, N·m (scales the fit, sets the solver).
    pub rated_torque_nm: f64,
    /// The fixed element.
    #[serde(default)]
    pub fixed: Fixed,
}

impl GearConfig {
    /// The core's gear.
    pub fn gear(&self) -> Result<Gear<f64>> {
        let fixed = match self.fixed {
            Fixed::CircularSpline => FixedElement::CircularSpline,
            Fixed::Flexspline => FixedElement::Flexspline,
        };
        Gear::new(self.ratio, fixed).map_err(|e| anyhow::anyhow!("gear: {e}"))
    }
}

/// Raw encoder counts (when absent, the motor and link channels are angles in rad).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EncodersConfig {
    /// Motor (wave generator) counts per revolution.
    pub motor_counts_per_rev: u64,
    /// Link counts per revolution.
    pub link_counts_per_rev: u64,
    /// Counters wrap every revolution.
    #[serde(default)]
    pub single_turn: bool,
    /// Raw motor count at zero angle.
    #[serde(default)]
    pub motor_offset_counts: i64,
    /// Raw link count at zero angle.
    #[serde(default)]
    pub link_offset_counts: i64,
    /// Interpolation noise, counts rms (sets the narrowest hysteresis play).
    #[serde(default = "default_noise")]
    pub noise_counts: f64,
}

fn default_noise() -> f64 {
    0.2
}

impl EncodersConfig {
    /// The core's encoder configurations `(motor, link)`.
    pub fn configs(&self) -> Result<(EncoderConfig, EncoderConfig)> {
        let mk = |cpr: u64, off: i64, what: &str| -> Result<EncoderConfig> {
            let e = if self.single_turn { EncoderConfig::single_turn(cpr) } else { EncoderConfig::multi_turn(cpr) };
            Ok(e.map_err(|e| anyhow::anyhow!("encoders.{what}_counts_per_rev: {e}"))?
                .with_offset(off)
                .with_max_step(cpr / 4))
        };
        Ok((
            mk(self.motor_counts_per_rev, self.motor_offset_counts, "motor")?,
            mk(self.link_counts_per_rev, self.link_offset_counts, "link")?,
        ))
    }
}

/// Columns of the recordings.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Channels {
    /// Motor encoder: counts with `[encoders]`, else angle (rad after scaling).
    pub motor: Channel,
    /// Link encoder: counts with `[encoders]`, else angle (rad after scaling).
    pub link: Channel,
    /// Time, s (for the sample rate when `sample_rate_hz` is not given).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub time: Option<Channel>,
    /// Reference link torque of the loaded run, N·m.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reference_torque: Option<Channel>,
}

/// Order of the kinematic basis: a number or `"cv"` (chosen by 5-fold cross-validation).
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(untagged)]
pub enum Order {
    /// Fixed.
    Fixed(usize),
    /// `"cv"`.
    Named(String),
}

/// Kinematic-error model choice.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct KinematicConfig {
    /// `fourier` or `polynomial`.
    pub basis: String,
    /// Output harmonics (Fourier) or power (polynomial), or `"cv"`.
    pub order: Order,
    /// Mesh (relative-angle) harmonics of a Fourier basis with a fixed order.
    #[serde(default)]
    pub mesh_harmonics: usize,
}

/// Compliance model choice.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ComplianceConfig {
    /// `linear`, `cubic`, `three-slope` or `seed`.
    pub spring: String,
    /// Three-slope break torques, N·m (default 25 % and 60 % of rated).
    #[serde(default)]
    pub t1_nm: Option<f64>,
    /// Second break torque, N·m.
    #[serde(default)]
    pub t2_nm: Option<f64>,
    /// `plays` (default) or `none`.
    #[serde(default = "default_hysteresis")]
    pub hysteresis: String,
    /// Fit structural damping.
    #[serde(default = "yes")]
    pub damping: bool,
    /// Fit on every n-th sample.
    #[serde(default = "five")]
    pub decimation: usize,
}

fn default_hysteresis() -> String {
    "plays".into()
}
fn yes() -> bool {
    true
}
fn five() -> usize {
    5
}

/// `identify --config` file.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ArmConfig {
    /// Sample rate, Hz (else from the time channel).
    #[serde(default)]
    pub sample_rate_hz: Option<f64>,
    /// Gear.
    pub gear: GearConfig,
    /// Raw counts.
    #[serde(default)]
    pub encoders: Option<EncodersConfig>,
    /// Columns.
    pub channels: Channels,
    /// Kinematic model.
    pub kinematic: KinematicConfig,
    /// Compliance model.
    pub compliance: ComplianceConfig,
}
