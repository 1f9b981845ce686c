//! The bench configuration `fuse` reads (`--config BENCH.toml`, see
//! `examples/bench-kit.toml`): the columns, the accelerometer pair, the crossover and the
//! mechanics the corrected methods invert.

use std::path::Path;

use anyhow::{bail, Context, Result};
use serde::Deserialize;
use strainwave_core::fusion::{
    AccelerometerModel, CrossoverOrder, OnlineCorrectedFusion, OnlineCorrectionConfig, TorsionShaftModel,
};

/// Column names in the recording (`[channels]`, as in the joint and arm configs;
/// `[columns]` in older files).
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Columns {
    /// Time, s.
    #[serde(default = "default_time")]
    pub time: String,
    /// Torsion-shaft torque, N·m.
    pub torsion: String,
    /// First accelerometer, m/s² (with `accel_2`).
    pub accel_1: Option<String>,
    /// Second accelerometer, m/s², mounted opposite.
    pub accel_2: Option<String>,
    /// Accelerometer torque `J_S (a1 + a2) / (2R)`, N·m (instead of `accel_1`/`accel_2`).
    pub accel_torque: Option<String>,
}

fn default_time() -> String {
    "time".into()
}

/// Mechanics used by the `online-corrected` and `corrected` methods.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Model {
    /// `J_R`, kg·m².
    pub rotor_inertia_kg_m2: f64,
    /// `J_B`, kg·m².
    pub brake_inertia_kg_m2: f64,
    /// `k`, N·m/rad.
    pub shaft_stiffness_nm_per_rad: f64,
    /// `Γ` (the shaft sees `2Γ`), N·m·s/rad.
    pub bearing_damping_nm_s_per_rad: f64,
    /// `k_S`, N·m/rad.
    pub coupling_stiffness_nm_per_rad: f64,
    /// `Γ_LS`, N·m·s/rad.
    pub stator_damping_nm_s_per_rad: f64,
    /// Taps of each correction FIR (odd).
    #[serde(default = "default_taps")]
    pub fir_taps: usize,
    /// Crossover of `online-corrected` (`|LP| = |HP|`), Hz.
    #[serde(default = "default_online_crossover")]
    pub online_crossover_hz: f64,
    /// Below this the `online-corrected` torsion gain returns from `(J_B + J_R)/J_B` to 1
    /// (a steady torque is carried by the brake), Hz; 0: never.
    #[serde(default = "default_static_corner")]
    pub static_corner_hz: f64,
}

/// Most taps of a correction FIR (2¹⁸ + 1: 262 s at 1 kHz).
pub const MAX_FIR_TAPS: usize = (1 << 18) + 1;

fn default_taps() -> usize {
    8191
}

fn default_online_crossover() -> f64 {
    OnlineCorrectionConfig::<f64>::kit().crossover_hz
}

fn default_static_corner() -> f64 {
    OnlineCorrectionConfig::<f64>::kit().static_corner_hz
}

impl Model {
    /// The torsion-shaft and housing models (`J_S` from the top level).
    pub(super) fn paths(
        &self,
        stator_inertia_kg_m2: f64,
        config: &str,
    ) -> Result<(TorsionShaftModel<f64>, AccelerometerModel<f64>)> {
        let bad = |e: strainwave_core::Error| anyhow::anyhow!("{config}: [model]: {e}");
        // The shaft model's own names for its stiffness and damping, as the file spells them.
        let shaft_keys = |e: strainwave_core::Error| {
            let e = e.to_string().replace("`stiffness_nm_per_rad`", "`shaft_stiffness_nm_per_rad`");
            anyhow::anyhow!(
                "{config}: [model]: {}",
                e.replace("`damping_nm_s_per_rad`", "`bearing_damping_nm_s_per_rad`")
            )
        };
        let ts = TorsionShaftModel::new(
            self.rotor_inertia_kg_m2,
            self.brake_inertia_kg_m2,
            self.shaft_stiffness_nm_per_rad,
            self.bearing_damping_nm_s_per_rad,
        )
        .map_err(shaft_keys)?;
        let acc = AccelerometerModel::new(
            stator_inertia_kg_m2,
            self.coupling_stiffness_nm_per_rad,
            self.stator_damping_nm_s_per_rad,
        )
        .map_err(bad)?;
        Ok((ts, acc))
    }

    /// The online corrected fusion at `fs` (`fs_from` says where that rate comes from).
    pub(super) fn online(
        &self,
        stator_inertia_kg_m2: f64,
        (fs, fs_from): (f64, &str),
        config: &str,
    ) -> Result<OnlineCorrectedFusion<f64>> {
        let (ts, acc) = self.paths(stator_inertia_kg_m2, config)?;
        let cfg =
            OnlineCorrectionConfig { crossover_hz: self.online_crossover_hz, static_corner_hz: self.static_corner_hz };
        OnlineCorrectedFusion::new(&ts, &acc, &cfg, fs).map_err(|e| {
            let e = e.to_string().replace("`crossover_hz`", "`online_crossover_hz`");
            anyhow::anyhow!("{config}: [model]: {e} (at {fs:?} Hz sampling, from {fs_from})")
        })
    }
}

/// The lowest crossover, as a fraction of the sample rate.
const MIN_CROSSOVER_PER_RATE: f64 = 1e-6;

/// A bench configuration file.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BenchConfig {
    /// Columns (`[channels]`; `[columns]` is the older name).
    #[serde(alias = "columns")]
    pub channels: Columns,
    /// `J_S`, kg·m².
    pub stator_inertia_kg_m2: f64,
    /// `R`, m.
    pub radius_m: f64,
    /// Crossover, Hz.
    pub crossover_hz: f64,
    /// Order of the complementary pair (the crossover's filters): 1 or 2 (`order` in
    /// older files).
    #[serde(default = "default_order", alias = "order")]
    pub crossover_order: u32,
    /// Sample rate, Hz (default: from the time column).
    pub sample_rate_hz: Option<f64>,
    /// Mechanics for `corrected`.
    pub model: Option<Model>,
}

fn default_order() -> u32 {
    2
}

impl BenchConfig {
    /// Reads and checks a configuration.
    pub fn load(path: &Path) -> Result<Self> {
        let text = std::fs::read_to_string(path).with_context(|| format!("{}", path.display()))?;
        let c: Self = toml::from_str(&text).map_err(|e| strainwave_joint::toml_error::one_line(path, &text, &e))?;
        // What a test bench has: from the stator of a servo motor the size of a thumb to
        // that of a megawatt machine, accelerometers from a millimetre off the axis to metres
        // (beyond these a typo or a unit slip, not a bench).
        for (v, key, (least, most, unit)) in [
            (c.stator_inertia_kg_m2, "stator_inertia_kg_m2", (1e-8, 1e4, "kg·m²")),
            (c.radius_m, "radius_m", (1e-3, 10.0, "m")),
            (c.crossover_hz, "crossover_hz", (0.0, f64::INFINITY, "Hz")),
        ] {
            if !(v.is_finite() && v > 0.0) {
                bail!("{}: `{key}` must be positive, got {v:?}", path.display());
            }
            if v > most {
                bail!("{}: `{key}` = {v:e} {unit}: at most {most:e} {unit}", path.display());
            }
            if v < least {
                bail!("{}: `{key}` = {v:e} {unit}: at least {least:e} {unit}", path.display());
            }
        }
        if !matches!(c.crossover_order, 1 | 2) {
            bail!("{}: `crossover_order` must be 1 or 2, got {}", path.display(), c.crossover_order);
        }
        let cols = &c.channels;
        match (&cols.accel_1, &cols.accel_2, &cols.accel_torque) {
            (Some(_), Some(_), None) | (None, None, Some(_)) => {}
            _ => bail!("{}: `channels` needs `accel_1` and `accel_2`, or `accel_torque`", path.display()),
        }
        Ok(c)
    }

    pub(super) fn crossover_order(&self) -> CrossoverOrder {
        if self.crossover_order == 1 {
            CrossoverOrder::First
        } else {
            CrossoverOrder::Second
        }
    }

    /// The `[model]` section, required by `method`.
    pub(super) fn model(&self, method: &str, config: &str) -> Result<&Model> {
        self.model.as_ref().with_context(|| format!("{config}: the `{method}` method needs a `[model]` section"))
    }

    /// Checks the crossover against the sample rate: below the Nyquist frequency and
    /// above a millionth of the rate (the crossover filters' poles must differ from 1).
    pub(super) fn check_crossover(&self, fs: f64, config: &str) -> Result<()> {
        if self.crossover_hz < fs * MIN_CROSSOVER_PER_RATE {
            bail!(
                "{config}: `crossover_hz` = {:e} Hz is below a millionth of the sample rate ({} Hz)",
                self.crossover_hz,
                fs * MIN_CROSSOVER_PER_RATE
            );
        }
        if self.crossover_hz >= fs / 2.0 {
            bail!(
                "{config}: `crossover_hz` = {:?} Hz is at or above the Nyquist frequency {} Hz",
                self.crossover_hz,
                fs / 2.0
            );
        }
        Ok(())
    }
}
