//! The joint configuration (TOML): the gear, the channel mapping, the calibration and the
//! canceller settings. `examples/joint-taghirad.toml` is a complete example.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use serde::{Deserialize, Serialize};
use strainwave_core::calibration::Calibration;
use strainwave_core::denoise::TorqueDenoiser;
use strainwave_core::gear::Gear;
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
    /// Warnings found at load (two channels reading one column), one line each.
    #[serde(skip)]
    pub warnings: Vec<String>,
}

/// `[gear]`.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GearConfig {
    /// Ratio `N`.
    pub ratio: f64,
    /// The fixed element.
    pub fixed: Fixed,
}

/// `gear.fixed`: which element is fixed (the other one is the output): the core's
/// [`FixedElement`](strainwave_core::gear::FixedElement), spelled as in every configuration file (`circular_spline`, alias
/// `circular-spline`, or `flexspline`).
pub use strainwave_core::gear::FixedElement as Fixed;

/// `filter.model`: which canceller model.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum ModelChoice {
    /// 2× and 4× relative, the same load-scaled, 1× output misalignment, torque random walk.
    #[default]
    Full,
    /// 2× and 4× relative and 1× output with a torque random walk, no learned file.
    Product,
    /// The two ripple lines of Taghirad and Bélanger (1999).
    #[serde(rename = "taghirad-4th-order", alias = "seed-4th-order")]
    Taghirad4thOrder,
    /// The two ripple lines plus the misalignment line of Taghirad and Bélanger (1999).
    #[serde(rename = "taghirad-6th-order", alias = "seed-6th-order")]
    Taghirad6thOrder,
    /// Orders listed in `filter.orders`.
    Orders,
}

impl ModelChoice {
    /// The value as a config writes it (`taghirad-6th-order`).
    pub fn name(self) -> &'static str {
        match self {
            Self::Full => "full",
            Self::Product => "product",
            Self::Taghirad4thOrder => "taghirad-4th-order",
            Self::Taghirad6thOrder => "taghirad-6th-order",
            Self::Orders => "orders",
        }
    }
}

/// `filter.phase`: where the oscillators' phase comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum PhaseChoice {
    /// Motor and output encoders.
    #[default]
    Angle,
    /// The tachometer alone (the angles are integrated).
    Velocity,
}

/// `filter.orders.reference`: the angle an order is a multiple of.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum ReferenceChoice {
    /// The relative wave generator–flexspline angle (meshing ripple).
    Relative,
    /// The output angle (misalignment).
    Output,
    /// The motor angle.
    Motor,
}

impl PhaseChoice {
    /// Its name in files and messages.
    pub fn name(self) -> &'static str {
        match self {
            PhaseChoice::Angle => "angle",
            PhaseChoice::Velocity => "velocity",
        }
    }
}

impl ReferenceChoice {
    /// Its name in files and messages.
    pub fn name(self) -> &'static str {
        match self {
            ReferenceChoice::Relative => "relative",
            ReferenceChoice::Output => "output",
            ReferenceChoice::Motor => "motor",
        }
    }
}

impl From<strainwave_core::ripple::Reference> for ReferenceChoice {
    fn from(r: strainwave_core::ripple::Reference) -> Self {
        use strainwave_core::ripple::Reference;
        match r {
            Reference::Relative => Self::Relative,
            Reference::Output => Self::Output,
            Reference::Motor => Self::Motor,
        }
    }
}

impl From<ReferenceChoice> for strainwave_core::ripple::Reference {
    fn from(r: ReferenceChoice) -> Self {
        match r {
            ReferenceChoice::Relative => Self::Relative,
            ReferenceChoice::Output => Self::Output,
            ReferenceChoice::Motor => Self::Motor,
        }
    }
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
    /// Expected torque (Taghirad and Bélanger (1999): load inertia × load acceleration), N·m.
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
    /// The canceller model.
    #[serde(default)]
    pub model: ModelChoice,
    /// Nominal sample rate, Hz.
    pub sample_rate_hz: f64,
    /// White noise of the calibrated torque signal, N·m (1σ): the measurement noise of
    /// every model that has one.
    pub noise_nm: Option<f64>,
    /// Where the phase comes from.
    #[serde(default)]
    pub phase: PhaseChoice,
    /// `orders` model: the oscillators.
    #[serde(default)]
    pub orders: Vec<OrderConfig>,
    /// `orders` model, older spelling of the measurement noise as a variance, N·m²
    /// (`noise_nm` squared); `noise_nm` is the one to write.
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
    /// The do-no-harm guard (`strainwave_core::guard`): apply each order only while the
    /// data support it. Default on; `false` gives the bare canceller.
    #[serde(default = "guard_default")]
    pub guard: bool,
}

fn guard_default() -> bool {
    true
}

/// One oscillator of an `orders` model.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OrderConfig {
    /// The angle the order is a multiple of.
    pub reference: ReferenceChoice,
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
    /// The files the config names for reading: `calibration.file` and `filter.learned`
    /// (outputs must not overwrite them).
    pub fn files_named(&self) -> impl Iterator<Item = &Path> {
        let calibration = self.calibration.as_ref().and_then(|c| c.file.as_deref());
        calibration.into_iter().chain(self.filter.learned.as_deref())
    }

    /// Reads and checks a config file.
    pub fn load(path: &Path) -> Result<Self> {
        let text = std::fs::read_to_string(path).with_context(|| format!("{}", path.display()))?;
        let mut c: Self = toml::from_str(&text).map_err(|e| crate::toml_error::one_line(path, &text, &e))?;
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
        // The models use the variance: a positive value's square must be usable too.
        if let Some(n) = c.filter.noise_nm {
            if n > 0.0 && !(n * n).is_normal() {
                bail!(
                    "{}: `filter.noise_nm` = {n:?} N·m: its square (the variance) must be finite and positive",
                    path.display()
                );
            }
        }
        c.warnings = c.duplicate_channels();
        Ok(c)
    }

    /// The mapped channels, `(key, channel)`, in the order of `[channels]`.
    pub fn channel_list(&self) -> Vec<(&'static str, &Channel)> {
        let ch = &self.channels;
        let optional = [
            ("motor_angle", &ch.motor_angle),
            ("output_angle", &ch.output_angle),
            ("motor_velocity", &ch.motor_velocity),
            ("expected_torque", &ch.expected_torque),
        ];
        let mut out = vec![("time", &ch.time), ("torque", &ch.torque)];
        out.extend(optional.into_iter().filter_map(|(k, c)| c.as_ref().map(|c| (k, c))));
        out
    }

    /// One warning per pair of channels that read the same column: a copy-paste slip
    /// that would feed, say, the motor angle as the output angle.
    pub fn duplicate_channels(&self) -> Vec<String> {
        let list = self.channel_list();
        let mut out = Vec::new();
        for (i, (a, ca)) in list.iter().enumerate() {
            for (b, cb) in &list[i + 1..] {
                if ca.column_name() == cb.column_name() {
                    out.push(format!(
                        "{}: `channels.{a}` and `channels.{b}` both read column `{}`",
                        self.path.display(),
                        ca.column_name()
                    ));
                }
            }
        }
        out
    }

    /// The gear; errors name `gear.ratio` / `gear.fixed`.
    pub fn gear(&self) -> Result<Gear<f64>> {
        let (ratio, range) = (self.gear.ratio, crate::identify::RATIO_RANGE);
        if !range.contains(&ratio) {
            bail!("`gear.ratio` must be between {} and {}, got {ratio:?}", range.start(), range.end());
        }
        Gear::new(ratio, self.gear.fixed).map_err(|e| anyhow::anyhow!("`gear.ratio`: {e}"))
    }

    /// The measurement noise of the `orders` model, 1σ, N·m: `noise_nm`, or the square
    /// root of the older variance key `r_nm2`; errors name the key the user wrote.
    pub fn orders_noise_nm(&self) -> Result<f64> {
        match (self.filter.noise_nm, self.filter.r_nm2) {
            (Some(_), Some(_)) => bail!("`filter.noise_nm` and `filter.r_nm2` say the same thing; keep `noise_nm`"),
            (Some(n), None) if n.is_finite() && n > 0.0 => Ok(n),
            (Some(n), None) => bail!("`filter.noise_nm` must be positive, got {n}"),
            (None, Some(r)) if r.is_finite() && r > 0.0 => Ok(r.sqrt()),
            (None, Some(r)) => bail!("`filter.r_nm2` must be positive, got {r}"),
            (None, None) => bail!("`filter.noise_nm` is needed by the orders model"),
        }
    }

    /// The causal torque denoiser of `filter.torque_bandwidth_hz`, if set; the error
    /// names the key.
    pub fn denoiser(&self) -> Result<Option<TorqueDenoiser<f64>>> {
        let Some(f) = self.filter.torque_bandwidth_hz else { return Ok(None) };
        TorqueDenoiser::new(f, self.filter.sample_rate_hz).map(Some).map_err(|_| {
            anyhow::anyhow!(
                "`filter.torque_bandwidth_hz` must be positive and below 0.45 × `filter.sample_rate_hz` ({:?} Hz), got {f:?}",
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

#[cfg(test)]
mod tests {
    use super::*;

    const BASE: &str = "[gear]\nratio = 100.0\nfixed = \"circular_spline\"\n[channels]\ntime = \"time\"\n\
        torque = \"t\"\n[filter]\nmodel = \"orders\"\nsample_rate_hz = 1000.0\nnoise_nm = 0.02\n";

    fn load(text: &str) -> Result<JointConfig> {
        // Tests run in parallel threads: each call gets its own file.
        static NEXT: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
        let n = NEXT.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        let path = std::env::temp_dir().join(format!("sw-joint-config-{}-{n}.toml", std::process::id()));
        std::fs::write(&path, text)?;
        let c = JointConfig::load(&path);
        std::fs::remove_file(&path)?;
        c
    }

    #[test]
    fn unknown_choice_lists_the_accepted_ones() {
        let err = load(&BASE.replace("\"orders\"", "\"magic\"")).unwrap_err().to_string();
        assert!(err.contains("`filter.model`") && err.contains("taghirad-6th-order"), "{err}");
        let err = load(&BASE.replace("\"circular_spline\"", "\"ring\"")).unwrap_err().to_string();
        assert!(err.contains("`gear.fixed`") && err.contains("flexspline"), "{err}");
    }

    #[test]
    fn older_spellings_are_aliases() {
        let c = load(&BASE.replace("\"circular_spline\"", "\"circular-spline\"")).unwrap();
        assert_eq!(c.gear.fixed, Fixed::CircularSpline);
        let c = load(&BASE.replace("\"orders\"", "\"seed-6th-order\"")).unwrap();
        assert_eq!(c.filter.model, ModelChoice::Taghirad6thOrder);
    }

    #[test]
    fn one_name_for_the_measurement_noise() {
        let c = load(BASE).unwrap();
        assert_eq!(c.orders_noise_nm().unwrap(), 0.02);
        // The older variance key is the square of the noise, not an alias of it.
        let c = load(&BASE.replace("noise_nm = 0.02", "r_nm2 = 4e-4")).unwrap();
        assert!((c.orders_noise_nm().unwrap() - 0.02).abs() < 1e-17);
        let c = load(&BASE.replace("noise_nm = 0.02", "noise_nm = 0.02\nr_nm2 = 4e-4")).unwrap();
        assert!(c.orders_noise_nm().unwrap_err().to_string().contains("keep `noise_nm`"));
    }

    #[test]
    fn two_channels_on_one_column_are_a_warning() {
        assert!(load(BASE).unwrap().warnings.is_empty());
        let text = BASE.replace(
            "torque = \"t\"\n",
            "torque = \"t\"\nmotor_angle = \"a\"\noutput_angle = { column = \"a\", scale = 0.01 }\n",
        );
        let c = load(&text).unwrap();
        assert_eq!(c.warnings.len(), 1, "{:?}", c.warnings);
        let w = &c.warnings[0];
        assert!(w.contains("`channels.motor_angle` and `channels.output_angle` both read column `a`"), "{w}");
        assert!(w.contains(".toml: ") && !w.contains('\n'), "{w}");
    }
}
