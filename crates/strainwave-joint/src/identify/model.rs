//! The model file `identify` writes and `estimate` reads: the fitted kinematic error and
//! compliance (and friction), with the gear, encoders and channels they were fitted for.

use std::path::Path;

use anyhow::{bail, Context, Result};
use serde::{Deserialize, Serialize};
use strainwave_analysis::ident::{
    ComplianceFit, ComplianceParams, FitMetrics, FittedHysteresis, FrictionParams, KinematicBasis, KinematicFit,
};
use strainwave_core::torsion::MeshAngle;

use super::config::{Basis, Channels, EncodersConfig, GearConfig};

/// Fitted spring parameters, as written to the model file.
pub type Spring = ComplianceParams;

/// Fitted hysteresis, as written to the model file.
pub type Hysteresis = FittedHysteresis;

/// The fitted kinematic error.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct KinematicModel {
    /// `fourier` or `polynomial`.
    pub basis: Basis,
    /// Output harmonics or polynomial order.
    pub order: usize,
    /// Mesh harmonics, Fourier only.
    pub mesh_harmonics: usize,
    /// The mesh angle of the harmonics: `relative` (WG relative to the output) or `motor`.
    #[serde(default)]
    pub mesh_angle: MeshAngle,
    /// Coefficients in the basis order, rad.
    pub coefficients: Vec<f64>,
}

/// The fitted compliance.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ComplianceModel {
    /// Structural damping, N·m·s/rad.
    pub damping_nm_s_per_rad: f64,
    /// Wind-up offset, rad.
    pub windup_offset_rad: f64,
    /// Rated torque the solver is set for, N·m.
    pub rated_torque_nm: f64,
    /// Spring.
    pub spring: Spring,
    /// Hysteresis.
    pub hysteresis: Hysteresis,
}

/// `identify`'s output, `estimate --config`'s input.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ModelFile {
    /// Sample rate the damping and plays were fitted at, Hz.
    pub sample_rate_hz: f64,
    /// Largest |torque| the model is valid for (1.25 × the loaded run's peak), N·m.
    pub torque_range_nm: f64,
    /// Gear.
    pub gear: GearConfig,
    /// Raw counts (absent: angle channels).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub encoders: Option<EncodersConfig>,
    /// Columns of the encoder channels.
    pub channels: Channels,
    /// Kinematic error.
    pub kinematic: KinematicModel,
    /// Compliance.
    pub compliance: ComplianceModel,
    /// Friction and rotor inertia referred to the link (when identified against a
    /// motor-current torque): `estimate` then also outputs `current_torque`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub friction: Option<FrictionParams>,
}

/// What kind of config `text` is when it is not a model file, which `identify` writes with
/// `sample_rate_hz` at the top: a joint config (`[filter]`) or an `identify` config.
fn other_kind(text: &str) -> Option<&'static str> {
    let table: toml::Table = toml::from_str(text).ok()?;
    if table.contains_key("sample_rate_hz") {
        return None;
    }
    if table.contains_key("filter") {
        Some("a joint config (for `filter`)")
    } else if table.contains_key("kinematic") || table.contains_key("compliance") {
        Some("an `identify` config")
    } else {
        None
    }
}

impl ModelFile {
    /// Reads a model file.
    pub fn load(path: &Path) -> Result<Self> {
        let text = std::fs::read_to_string(path).with_context(|| format!("{}", path.display()))?;
        toml::from_str(&text).map_err(|e| match other_kind(&text) {
            Some(kind) => anyhow::anyhow!(
                "{}: {kind}, not a model: pass the model file that `identify --out` writes",
                path.display()
            ),
            None => crate::toml_error::one_line(path, &text, &e),
        })
    }

    /// The model's plain numbers, by their keys: the sample rate, torque range and rated
    /// torque positive, the windup offset, damping and kinematic coefficients finite, 1 to
    /// 8 plays with one weight per half-width. (The spring and hysteresis constructors
    /// check the rest and name their keys.)
    pub fn check_numbers(&self) -> Result<()> {
        let c = &self.compliance;
        let positive = [
            ("sample_rate_hz", self.sample_rate_hz),
            ("torque_range_nm", self.torque_range_nm),
            ("compliance.rated_torque_nm", c.rated_torque_nm),
        ];
        for (key, v) in positive {
            if !(v.is_finite() && v > 0.0) {
                bail!("`{key}` must be positive, got {v:?}");
            }
        }
        for (key, v) in [
            ("compliance.windup_offset_rad", c.windup_offset_rad),
            ("compliance.damping_nm_s_per_rad", c.damping_nm_s_per_rad),
        ] {
            if !v.is_finite() {
                bail!("`{key}` must be finite, got {v:?}");
            }
        }
        if let Some((i, v)) = self.kinematic.coefficients.iter().enumerate().find(|(_, v)| !v.is_finite()) {
            bail!("`kinematic.coefficients` value {} must be finite, got {v:?}", i + 1);
        }
        if let Hysteresis::Plays { half_widths_rad, weights_rad } = &c.hysteresis {
            let (n, max) = (half_widths_rad.len(), strainwave_core::compliance::MAX_PLAYS);
            if !(1..=max).contains(&n) {
                bail!("`compliance.hysteresis.half_widths_rad`: {n} plays, 1 to {max}");
            }
            if weights_rad.len() != n {
                bail!("`compliance.hysteresis.weights_rad`: {} values, one per half-width ({n})", weights_rad.len());
            }
        }
        Ok(())
    }

    /// The library's kinematic fit.
    pub fn kinematic_fit(&self) -> Result<KinematicFit> {
        let k = &self.kinematic;
        let basis = match k.basis {
            Basis::Fourier => KinematicBasis::Fourier {
                output_harmonics: k.order,
                mesh_harmonics: k.mesh_harmonics,
                mesh_angle: k.mesh_angle,
            },
            Basis::Polynomial => KinematicBasis::Polynomial { order: k.order },
        };
        if k.coefficients.len() != basis.n_terms() {
            bail!("kinematic.coefficients: {} values, the basis has {}", k.coefficients.len(), basis.n_terms());
        }
        Ok(KinematicFit {
            basis,
            coefficients: k.coefficients.clone(),
            direction_offset_rad: 0.0,
            metrics: FitMetrics::of(&[], &[]),
        })
    }

    /// The library's compliance fit.
    pub fn compliance_fit(&self) -> ComplianceFit {
        let c = &self.compliance;
        ComplianceFit {
            params: c.spring,
            hysteresis: c.hysteresis.clone(),
            damping_nm_s_per_rad: c.damping_nm_s_per_rad,
            windup_offset_rad: c.windup_offset_rad,
            rated_torque_nm: c.rated_torque_nm,
            metrics: FitMetrics::of(&[], &[]),
            iterations: 0,
            termination: None,
            friction: self.friction,
            parameters: Vec::new(),
        }
    }
}
