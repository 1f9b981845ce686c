//! The joint configuration (TOML): the gear, the channel mapping, the calibration and the
//! canceller settings. `examples/joint-taghirad.toml` is a complete example.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use serde::Deserialize;
use strainwave_core::calibration::Calibration;
use strainwave_core::denoise::TorqueDenoiser;
use strainwave_core::gear::{FixedElement, Gear};
use strainwave_io::Channel;

/// Largest calibration table the filter accepts.
pub const MAX_TABLE_LEN: usize = strainwave_analysis::calibration::MAX_TABLE_LEN;

/// The whole file.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct JointConfig {
    /// Gear.
    pub gear: GearConfig,
    /// Where each signal comes from.
    pub channels: Channels,
    /// Turns the torque channel into N·m; absent when it already is.
    #[serde(default)]
    pub calibration: Option<CalibrationConfig>,
    /// Canceller settings.
    pub filter: FilterConfig,
    /// The file it was read from, for messages (empty when built in code).
    #[serde(skip)]
    pub path: PathBuf,
}

/// `[gear]`.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GearConfig {
    /// Ratio `N`.
    pub ratio: f64,
    /// `circular_spline` or `flexspline`.
    pub fixed: String,
}

/// `[channels]`.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Channels {
    /// Time, s.
    pub time: Channel,
    /// Torque (N·m), or the sensor signal the calibration converts.
    pub torque: Channel,
    /// Motor (wave generator) angle, rad.
    pub motor_angle: Option<Channel>,
    /// Output angle, rad.
    pub output_angle: Option<Channel>,
    /// Motor velocity, rad/s (tachometer phase, speed-dependent calibrations).
    pub motor_velocity: Option<Channel>,
    /// Expected torque (seed 000: load inertia × load acceleration), N·m.
    pub expected_torque: Option<Channel>,
}

/// `[calibration]`: a gain, or a file from `strainwave calibrate`.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CalibrationConfig {
    /// N·m per unit of the torque channel.
    pub gain_nm_per_v: Option<f64>,
    /// A calibration TOML (relative paths are relative to the joint config).
    pub file: Option<PathBuf>,
}

/// `[filter]`.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FilterConfig {
    /// `full` (default), `product`, `seed-4th-order`, `seed-6th-order` or `orders`.
    #[serde(default = "default_model")]
    pub model: String,
    /// Nominal sample rate, Hz.
    pub sample_rate_hz: f64,
    /// Product model: white noise of the torque signal, N·m (1σ).
    pub noise_nm: Option<f64>,
    /// `angle` (encoders; default) or `velocity` (tachometer only).
    #[serde(default = "default_phase")]
    pub phase: String,
    /// `orders` model: the oscillators.
    #[serde(default)]
    pub orders: Vec<OrderConfig>,
    /// `orders` model: measurement noise variance, N·m².
    pub r_nm2: Option<f64>,
    /// `orders` model: torque/bias random-walk variance per sample, N·m² (absent: no bias state).
    pub bias_q_nm2: Option<f64>,
    /// Bandwidth of the causal denoised torque (`torque_denoised` column), Hz: the clean
    /// torque filtered as a random-walk torque state, group delay at DC about
    /// `1 / (2π f)` (see `strainwave_core::denoise`). Absent (default): no such column.
    pub torque_bandwidth_hz: Option<f64>,
    /// Coefficients learned on a commissioning run (`strainwave filter --learn FILE`);
    /// relative paths are relative to the joint config. Absent: learn from zero.
    pub learned: Option<PathBuf>,
}

fn default_model() -> String {
    "full".into()
}

fn default_phase() -> String {
    "angle".into()
}

/// One oscillator of an `orders` model.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OrderConfig {
    /// `relative`, `output` or `motor`.
    pub reference: String,
    /// Multiple of the reference angle.
    pub multiple: f64,
    /// Process noise per sample, N·m².
    #[serde(default)]
    pub q_per_sample_nm2: f64,
    /// Process noise per radian of the order's phase, N·m².
    #[serde(default)]
    pub q_per_rad_nm2: f64,
}

impl JointConfig {
    /// Reads and checks a config file.
    pub fn load(path: &Path) -> Result<Self> {
        let text = std::fs::read_to_string(path).with_context(|| format!("{}", path.display()))?;
        let mut c: Self = toml::from_str(&text).map_err(|e| {
            // Line and column of the offending text, on one line.
            let at = e.span().map_or(String::new(), |s| {
                let before = text.get(..s.start).unwrap_or(&text);
                let line = before.matches('\n').count() + 1;
                let column = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
                format!("line {line}, column {column}: ")
            });
            anyhow::anyhow!("{}: {at}{}", path.display(), e.message().trim().replace('\n', "; "))
        })?;
        c.path = path.to_path_buf();
        if let Some(cal) = c.calibration.as_mut() {
            if let Some(f) = cal.file.as_mut() {
                if f.is_relative() {
                    *f = path.parent().unwrap_or(Path::new(".")).join(&*f);
                }
            }
        }
        if let Some(f) = c.filter.learned.as_mut() {
            if f.is_relative() {
                *f = path.parent().unwrap_or(Path::new(".")).join(&*f);
            }
        }
        c.gear().with_context(|| format!("{}", path.display()))?;
        if !(c.filter.sample_rate_hz.is_finite() && c.filter.sample_rate_hz > 0.0) {
            bail!("{}: `filter.sample_rate_hz` must be positive", path.display());
        }
        c.denoiser().with_context(|| format!("{}", path.display()))?;
        Ok(c)
    }

    /// The gear; errors name `gear.ratio` / `gear.fixed`.
    pub fn gear(&self) -> Result<Gear<f64>> {
        let fixed = match self.gear.fixed.as_str() {
            "circular_spline" => FixedElement::CircularSpline,
            "flexspline" => FixedElement::Flexspline,
            other => bail!("`gear.fixed` must be `circular_spline` or `flexspline`, got `{other}`"),
        };
        Gear::new(self.gear.ratio, fixed)
            .map_err(|_| anyhow::anyhow!("`gear.ratio` must be positive, got {}", self.gear.ratio))
    }

    /// The causal torque denoiser of `filter.torque_bandwidth_hz`, if set; the error
    /// names the key.
    pub fn denoiser(&self) -> Result<Option<TorqueDenoiser<f64>>> {
        let Some(f) = self.filter.torque_bandwidth_hz else { return Ok(None) };
        TorqueDenoiser::new(f, self.filter.sample_rate_hz).map(Some).map_err(|_| {
            anyhow::anyhow!(
                "`filter.torque_bandwidth_hz` must be positive and below 0.45 × `filter.sample_rate_hz` ({} Hz), got {f}",
                0.45 * self.filter.sample_rate_hz
            )
        })
    }

    /// The calibration to apply to the torque channel (identity when absent).
    pub fn calibration(&self) -> Result<Calibration<f64, MAX_TABLE_LEN>> {
        let Some(c) = &self.calibration else { return Ok(Calibration::gain(1.0)?) };
        match (c.gain_nm_per_v, &c.file) {
            (Some(g), None) => Calibration::gain(g).map_err(|e| anyhow::anyhow!("`calibration.gain_nm_per_v`: {e}")),
            (None, Some(f)) => {
                let file = strainwave_analysis::calibration::CalibrationFile::load(f).context("`calibration.file`")?;
                Ok(file.to_core::<f64, MAX_TABLE_LEN>().with_context(|| format!("{}", f.display()))?)
            }
            _ => bail!("`[calibration]` needs exactly one of `gain_nm_per_v` and `file`"),
        }
    }
}
