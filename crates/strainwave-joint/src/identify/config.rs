//! The arm configuration `identify` reads (`--config ARM.toml`): gear, channels,
//! encoders and the model choices.

use anyhow::Result;
use serde::{Deserialize, Serialize};
use strainwave_core::gear::Gear;
use strainwave_core::torsion::EncoderConfig;
use strainwave_io::Channel;

/// Which element is fixed: the core's [`FixedElement`](strainwave_core::gear::FixedElement), spelled as in every
/// configuration file (`circular_spline`, alias `circular-spline`, or `flexspline`).
pub use strainwave_core::gear::FixedElement as Fixed;

/// The ratios a configuration file may give (the core's [`RATIO_RANGE`](strainwave_core::gear::RATIO_RANGE)).
pub use strainwave_core::gear::RATIO_RANGE;

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
    /// The core's gear; an error naming the key when the rated torque is not positive or
    /// the ratio is outside [`RATIO_RANGE`].
    pub fn gear(&self) -> Result<Gear<f64>> {
        let rated = self.rated_torque_nm;
        if !(rated.is_finite() && rated > 0.0) {
            anyhow::bail!("gear.rated_torque_nm: must be positive, got {rated}");
        }
        let (ratio, range) = (self.ratio, RATIO_RANGE);
        if !range.contains(&ratio) {
            anyhow::bail!("gear.ratio: must be between {} and {}, got {ratio:?}", range.start(), range.end());
        }
        Gear::new(ratio, self.fixed).map_err(|e| anyhow::anyhow!("gear: {e}"))
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
    /// Interpolation noise, counts rms (sets the narrowest hysteresis play; default 0.2).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub noise_counts: Option<f64>,
    /// `1` when the motor encoder counts up as the wave generator turns forward, `-1`
    /// when it counts the other way.
    #[serde(default = "plus_one")]
    pub motor_direction: i8,
    /// `1` when the link encoder counts up as the output turns forward, `-1` otherwise.
    #[serde(default = "plus_one")]
    pub link_direction: i8,
}

fn plus_one() -> i8 {
    1
}

impl EncodersConfig {
    /// The core's encoder configurations `(motor, link)`.
    pub fn configs(&self) -> Result<(EncoderConfig, EncoderConfig)> {
        let mk = |cpr: u64, off: i64, dir: i8, what: &str| -> Result<EncoderConfig> {
            let e = if self.single_turn { EncoderConfig::single_turn(cpr) } else { EncoderConfig::multi_turn(cpr) };
            let e = e
                .map_err(|e| anyhow::anyhow!("encoders.{what}_counts_per_rev: {e}"))?
                .with_offset(off)
                .with_max_step(cpr / 4);
            match dir {
                1 => Ok(e),
                -1 => Ok(e.reversed()),
                d => anyhow::bail!("encoders.{what}_direction: must be 1 or -1, got {d}"),
            }
        };
        Ok((
            mk(self.motor_counts_per_rev, self.motor_offset_counts, self.motor_direction, "motor")?,
            mk(self.link_counts_per_rev, self.link_offset_counts, self.link_direction, "link")?,
        ))
    }

    /// The interpolation noise given, if any, checked: positive.
    pub fn check_noise(&self) -> Result<()> {
        match self.noise_counts {
            Some(n) if !(n.is_finite() && n > 0.0) => anyhow::bail!("encoders.noise_counts: must be positive, got {n}"),
            _ => Ok(()),
        }
    }

    /// The interpolation noise, counts rms.
    pub fn noise(&self) -> f64 {
        self.noise_counts.unwrap_or(0.2)
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
    /// Time, s: the sample rate when `sample_rate_hz` is not given. In a model file, the
    /// column `estimate` checks against the model's rate.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub time: Option<Channel>,
    /// Reference link torque of the loaded run, N·m.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reference_torque: Option<Channel>,
}

/// Order of the kinematic basis: a number or `"cv"` (chosen by 5-fold cross-validation).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Order {
    /// Fixed.
    Fixed(usize),
    /// `"cv"`.
    CrossValidated,
}

impl std::fmt::Display for Order {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Order::Fixed(n) => write!(f, "{n}"),
            Order::CrossValidated => f.write_str("\"cv\""),
        }
    }
}

impl<'de> Deserialize<'de> for Order {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
        struct V;
        impl serde::de::Visitor<'_> for V {
            type Value = Order;
            fn expecting(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                f.write_str("a number or `cv`")
            }
            fn visit_i64<E: serde::de::Error>(self, v: i64) -> std::result::Result<Order, E> {
                usize::try_from(v)
                    .map(Order::Fixed)
                    .map_err(|_| E::invalid_value(serde::de::Unexpected::Signed(v), &self))
            }
            fn visit_u64<E: serde::de::Error>(self, v: u64) -> std::result::Result<Order, E> {
                usize::try_from(v)
                    .map(Order::Fixed)
                    .map_err(|_| E::invalid_value(serde::de::Unexpected::Unsigned(v), &self))
            }
            fn visit_str<E: serde::de::Error>(self, v: &str) -> std::result::Result<Order, E> {
                match v {
                    "cv" => Ok(Order::CrossValidated),
                    _ => Err(E::invalid_value(serde::de::Unexpected::Str(v), &self)),
                }
            }
        }
        d.deserialize_any(V)
    }
}

/// `kinematic.basis`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Basis {
    /// Fourier series in the output and mesh angles.
    Fourier,
    /// Polynomial in the output angle.
    Polynomial,
}

impl Basis {
    /// Its name in files and messages.
    pub fn name(self) -> &'static str {
        match self {
            Basis::Fourier => "fourier",
            Basis::Polynomial => "polynomial",
        }
    }
}

/// Kinematic-error model choice.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct KinematicConfig {
    /// `fourier` or `polynomial`.
    pub basis: Basis,
    /// Output harmonics (Fourier) or power (polynomial), or `"cv"`.
    pub order: Order,
    /// Mesh harmonics of a Fourier basis with a fixed order, or of a kinematic error
    /// fitted from the loaded run (default 4 there).
    #[serde(default)]
    pub mesh_harmonics: Option<usize>,
}

/// `compliance.spring`: the spring law fitted.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum SpringChoice {
    /// Linear stiffness.
    Linear,
    /// Linear plus cubic stiffness.
    Cubic,
    /// Three slopes with break torques `t1_nm`, `t2_nm`.
    #[serde(alias = "three_slope")]
    ThreeSlope,
    /// The arm's harmonic drive compliance law (flexspline and wave generator springs);
    /// `seed` is its older name.
    #[serde(alias = "seed")]
    Hda,
}

impl SpringChoice {
    /// Its name in files and messages.
    pub fn name(self) -> &'static str {
        match self {
            SpringChoice::Linear => "linear",
            SpringChoice::Cubic => "cubic",
            SpringChoice::ThreeSlope => "three-slope",
            SpringChoice::Hda => "hda",
        }
    }
}

/// `compliance.hysteresis`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum HysteresisChoice {
    /// Play operators (default).
    #[default]
    Plays,
    /// None.
    None,
}

impl HysteresisChoice {
    /// Its name in files and messages.
    pub fn name(self) -> &'static str {
        match self {
            HysteresisChoice::Plays => "plays",
            HysteresisChoice::None => "none",
        }
    }
}

/// Compliance model choice.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ComplianceConfig {
    /// `linear`, `cubic`, `three-slope` or `hda`.
    pub spring: SpringChoice,
    /// Three-slope break torques, N·m (default 25 % and 60 % of rated).
    #[serde(default)]
    pub t1_nm: Option<f64>,
    /// Second break torque, N·m.
    #[serde(default)]
    pub t2_nm: Option<f64>,
    /// `plays` (default) or `none`.
    #[serde(default)]
    pub hysteresis: HysteresisChoice,
    /// Fit structural damping.
    #[serde(default = "yes")]
    pub damping: bool,
    /// Fit on every n-th sample (Levenberg–Marquardt fits only; default 5).
    #[serde(default)]
    pub decimation: Option<usize>,
    /// Levenberg–Marquardt iteration cap (default 40).
    #[serde(default)]
    pub max_iterations: Option<usize>,
}

/// The reference torque is the motor-current torque: friction and rotor inertia
/// (referred to the link) are identified with the compliance, and `estimate` outputs
/// the current torque the model predicts.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FrictionConfig {
    /// Coulomb friction.
    #[serde(default = "yes")]
    pub coulomb: bool,
    /// Viscous friction.
    #[serde(default = "yes")]
    pub viscous: bool,
    /// Stribeck excess with this decay speed, rad/s (absent: none), or a list of
    /// candidate speeds chosen by blocked cross-validation on the training rows.
    #[serde(default)]
    pub stribeck_speed_rad_s: Option<SpeedChoice>,
    /// Friction growing with the link torque, `μ |τ_link|` (strain wave gears' mesh friction).
    #[serde(default)]
    pub load_dependent: bool,
    /// Rotor inertia times acceleration.
    #[serde(default = "yes")]
    pub rotor_inertia: bool,
    /// Smoothing speed of the friction's sign, rad/s.
    #[serde(default = "smoothing")]
    pub smoothing_speed_rad_s: f64,
    /// Samples the speed and acceleration differences span.
    #[serde(default = "span")]
    pub rate_span: usize,
}

/// A fixed speed or candidates to choose from by cross-validation.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(untagged)]
pub enum SpeedChoice {
    /// This speed, rad/s.
    Fixed(f64),
    /// Candidate speeds, rad/s.
    Candidates(Vec<f64>),
}

impl SpeedChoice {
    /// The candidates (one for a fixed speed), checked: 1 ..= 12 positive finite values.
    pub fn candidates(&self, key: &str) -> Result<Vec<f64>> {
        let c = match self {
            SpeedChoice::Fixed(v) => vec![*v],
            SpeedChoice::Candidates(c) => c.clone(),
        };
        if c.is_empty() || c.len() > 12 {
            anyhow::bail!("{key}: give 1 to 12 speeds, got {}", c.len());
        }
        if let Some(bad) = c.iter().find(|v| !(v.is_finite() && **v > 0.0)) {
            anyhow::bail!("{key}: {bad} is not a positive speed (rad/s)");
        }
        let (lo, hi) = (*STRIBECK_SPEEDS_RAD_S.start(), *STRIBECK_SPEEDS_RAD_S.end());
        if let Some(bad) = c.iter().find(|v| !STRIBECK_SPEEDS_RAD_S.contains(*v)) {
            anyhow::bail!("{key}: {bad:e} rad/s is outside {lo:e} to {hi:e} rad/s (a joint's friction changes over 1e-3 to 1 rad/s)");
        }
        Ok(c)
    }
}

/// The Stribeck speeds a fit can tell apart: slower, the term is zero at every sampled
/// speed; faster, it is constant.
const STRIBECK_SPEEDS_RAD_S: std::ops::RangeInclusive<f64> = 1e-6..=1e3;

fn smoothing() -> f64 {
    0.01
}
fn span() -> usize {
    4
}

fn yes() -> bool {
    true
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
    /// Present when the reference torque comes from the motor current.
    #[serde(default)]
    pub friction: Option<FrictionConfig>,
}

impl ArmConfig {
    /// Whether the compliance fit is one linear least-squares solve (no iteration).
    pub fn linear_fit(&self) -> bool {
        self.compliance.hysteresis == HysteresisChoice::None && self.compliance.spring == SpringChoice::Linear
    }

    /// Refuses keys that the chosen models and runs would not use: a setting that is
    /// silently ignored misleads more than an error.
    pub fn refuse_unused(&self, has_no_load: bool) -> Result<()> {
        let unused = |key: &str, why: &str| -> Result<()> { anyhow::bail!("{key}: unused {why}; remove it") };
        if self.sample_rate_hz.is_some() && self.channels.time.is_some() {
            unused("channels.time", "when sample_rate_hz is given (the rate comes from one of them)")?;
        }
        let c = &self.compliance;
        if c.spring != SpringChoice::ThreeSlope && (c.t1_nm.is_some() || c.t2_nm.is_some()) {
            unused("compliance.t1_nm / t2_nm", "unless spring = \"three-slope\"")?;
        }
        if self.linear_fit() && c.decimation.is_some() {
            unused("compliance.decimation", "with a linear spring and no hysteresis (one least-squares solve)")?;
        }
        if self.linear_fit() && c.max_iterations.is_some() {
            unused("compliance.max_iterations", "with a linear spring and no hysteresis (one least-squares solve)")?;
        }
        if c.hysteresis != HysteresisChoice::Plays && self.encoders.as_ref().is_some_and(|e| e.noise_counts.is_some()) {
            unused("encoders.noise_counts", "without hysteresis = \"plays\" (it sets the narrowest play)")?;
        }
        let k = &self.kinematic;
        if has_no_load && k.order == Order::CrossValidated && k.mesh_harmonics.is_some() {
            unused("kinematic.mesh_harmonics", "with order = \"cv\" (cross-validation chooses it)")?;
        }
        if k.basis == Basis::Polynomial && k.mesh_harmonics.is_some() {
            unused("kinematic.mesh_harmonics", "with basis = \"polynomial\"")?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const ARM: &str = "[gear]\nratio = 100.0\nrated_torque_nm = 40.0\nfixed = \"circular_spline\"\n\
        [channels]\nmotor = \"m\"\nlink = \"l\"\n\
        [kinematic]\nbasis = \"fourier\"\norder = \"cv\"\n\
        [compliance]\nspring = \"hda\"\nhysteresis = \"plays\"\n";

    fn parse(text: &str) -> std::result::Result<ArmConfig, String> {
        toml::from_str(text)
            .map_err(|e| crate::toml_error::one_line(std::path::Path::new("arm.toml"), text, &e).to_string())
    }

    #[test]
    fn every_spelling_of_a_choice_loads() {
        for (from, to) in [
            ("\"circular_spline\"", "\"circular-spline\""),
            ("\"circular_spline\"", "\"flexspline\""),
            ("\"hda\"", "\"seed\""),
            ("\"hda\"", "\"three-slope\""),
            ("\"hda\"", "\"three_slope\""),
            ("\"cv\"", "3"),
        ] {
            let c = parse(&ARM.replacen(from, to, 1)).unwrap_or_else(|e| panic!("{to}: {e}"));
            assert_eq!(c.gear.fixed == Fixed::Flexspline, to == "\"flexspline\"");
        }
        let c = parse(ARM).unwrap();
        assert_eq!(c.gear.fixed, Fixed::CircularSpline);
        assert_eq!((c.compliance.spring, c.kinematic.order), (SpringChoice::Hda, Order::CrossValidated));
        let c = parse(&ARM.replace("\"hda\"", "\"seed\"")).unwrap();
        assert_eq!(c.compliance.spring, SpringChoice::Hda);
        let c = parse(&ARM.replace("\"circular_spline\"", "\"circular-spline\"")).unwrap();
        assert_eq!(c.gear.fixed, Fixed::CircularSpline);
    }

    #[test]
    fn an_unknown_value_lists_the_accepted_ones() {
        for (from, to, key, accepted) in [
            ("\"circular_spline\"", "\"ring\"", "gear.fixed", &["`circular_spline`", "`flexspline`"][..]),
            ("\"hda\"", "\"quartic\"", "compliance.spring", &["`linear`", "`cubic`", "`three-slope`", "`hda`"]),
            ("\"plays\"", "\"dahl\"", "compliance.hysteresis", &["`plays` or `none`"]),
            ("\"fourier\"", "\"spline\"", "kinematic.basis", &["`fourier` or `polynomial`"]),
            ("\"cv\"", "\"auto\"", "kinematic.order", &["a number or `cv`"]),
        ] {
            let e = parse(&ARM.replacen(from, to, 1)).unwrap_err();
            assert!(e.starts_with("arm.toml: line "), "{e}");
            assert!(e.contains(&format!("`{key}`: ")), "{e}");
            assert!(accepted.iter().all(|a| e.contains(a)), "{e}");
            assert!(!e.contains('\n'), "{e}");
        }
    }
}
