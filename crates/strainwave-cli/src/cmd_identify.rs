//! `strainwave identify`: fit the kinematic error (no-load run) and the compliance (loaded
//! run against a reference torque) of an encoder-based torque estimator (SPEC §5), and
//! write the model `estimate` reads.
//!
//! The configuration (`--config ARM.toml`, see `examples/arm-hda.toml`) only maps the
//! recordings and the model choices onto `strainwave_analysis::ident`.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use serde::{Deserialize, Serialize};
use strainwave_analysis::ident::{
    fit_compliance, fit_kinematic_error, select_kinematic_basis, ComplianceFit, ComplianceFitOptions, ComplianceForm,
    ComplianceParams, FitMetrics, FittedHysteresis, HysteresisForm, JointAngles, KinematicBasis, KinematicFit,
    KinematicFitOptions,
};
use strainwave_core::compliance::ThreeSlopeStiffness;
use strainwave_core::gear::Gear;
use strainwave_core::torsion::{EstimatorState, MeshAngle, NoKinematicError, TorqueSolver, TorsionEstimator};
use strainwave_io::Channel;

mod config;
pub use config::{ArmConfig, Channels, EncodersConfig, GearConfig, KinematicConfig, Order};

/// Arguments of `identify`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Arm configuration (gear, channels, encoders, model choices); see examples/arm-hda.toml.
    #[arg(long)]
    pub config: PathBuf,
    /// No-load recording (the joint turns slowly, no load): fits the kinematic error.
    #[arg(long)]
    pub no_load: PathBuf,
    /// Loaded recording with a reference torque: fits the compliance.
    #[arg(long)]
    pub loaded: PathBuf,
    /// Output model TOML (read by `estimate --config`).
    #[arg(long)]
    pub out: PathBuf,
    /// No metrics table on stdout.
    #[arg(long, short)]
    pub quiet: bool,
}

/// Fitted spring parameters, as written to the model file.
pub type Spring = ComplianceParams;

/// Fitted hysteresis, as written to the model file.
pub type Hysteresis = FittedHysteresis;

/// The fitted kinematic error.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct KinematicModel {
    /// `fourier` or `polynomial`.
    pub basis: String,
    /// Output harmonics or polynomial order.
    pub order: usize,
    /// Mesh harmonics (relative angle), Fourier only.
    pub mesh_harmonics: usize,
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
}

impl ModelFile {
    /// Reads a model file.
    pub fn load(path: &Path) -> Result<Self> {
        let text = std::fs::read_to_string(path).with_context(|| format!("{}", path.display()))?;
        toml::from_str(&text).with_context(|| format!("model {}", path.display()))
    }

    /// The library's kinematic fit.
    pub fn kinematic_fit(&self) -> Result<KinematicFit> {
        let k = &self.kinematic;
        let basis = match k.basis.as_str() {
            "fourier" => KinematicBasis::Fourier {
                output_harmonics: k.order,
                mesh_harmonics: k.mesh_harmonics,
                mesh_angle: MeshAngle::Relative,
            },
            "polynomial" => KinematicBasis::Polynomial { order: k.order },
            other => bail!("kinematic.basis: `{other}` is neither fourier nor polynomial"),
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
        }
    }
}

/// Motor and link angles (gear convention, unwrapped) of a recording.
struct Run {
    motor: Vec<f64>,
    link: Vec<f64>,
    table: strainwave_io::Table,
}

fn column<'a>(t: &'a strainwave_io::Table, ch: &Channel, key: &str, path: &Path) -> Result<&'a [f64]> {
    t.column(ch.column_name()).with_context(|| {
        format!(
            "{}: no column `{}` (channel `{key}`); columns: {}",
            path.display(),
            ch.column_name(),
            t.columns.join(", ")
        )
    })
}

fn scaled(t: &strainwave_io::Table, ch: &Channel, key: &str, path: &Path) -> Result<Vec<f64>> {
    let (s, o) = ch.scale_offset();
    Ok(column(t, ch, key, path)?.iter().map(|v| v * s + o).collect())
}

/// Unwraps raw counts into angles through the core's estimator (identity spring, no
/// kinematic error): the encoder handling is the one `estimate` uses.
fn angles_from_counts(
    gear: Gear<f64>,
    enc: &EncodersConfig,
    motor: &[f64],
    link: &[f64],
    path: &Path,
) -> Result<(Vec<f64>, Vec<f64>)> {
    let (m, l) = enc.configs()?;
    let spring = ThreeSlopeStiffness::linear(1.0e4).map_err(|e| anyhow::anyhow!("{e}"))?;
    let solver = TorqueSolver::for_rated_torque(1.0e9).map_err(|e| anyhow::anyhow!("{e}"))?;
    let est = TorsionEstimator::new(gear, m, l, NoKinematicError, spring, solver);
    let mut st = EstimatorState::new();
    let n_s = gear.signed_ratio();
    let (mut ma, mut la) = (Vec::with_capacity(motor.len()), Vec::with_capacity(motor.len()));
    for (k, (mc, lc)) in motor.iter().zip(link).enumerate() {
        let e = est
            .step_counts(&mut st, *mc as i64, *lc as i64)
            .map_err(|e| anyhow::anyhow!("{}: data row {}: {e}", path.display(), k + 1))?;
        if e.flags.any_jump() {
            bail!(
                "{}: data row {}: encoder count jumped (wrapping counter? check encoders.single_turn)",
                path.display(),
                k + 1
            );
        }
        la.push(e.output_angle_rad);
        ma.push((e.output_angle_rad - e.torsion_rad) * n_s);
    }
    Ok((ma, la))
}

fn load_run(cfg: &ArmConfig, path: &Path) -> Result<Run> {
    let table = strainwave_io::read_all(path).with_context(|| format!("{}", path.display()))?;
    if table.rows() < 20 {
        bail!("{}: {} rows, too short to identify from", path.display(), table.rows());
    }
    let gear = cfg.gear.gear()?;
    let (motor, link) = match &cfg.encoders {
        Some(enc) => {
            let m = column(&table, &cfg.channels.motor, "motor", path)?;
            let l = column(&table, &cfg.channels.link, "link", path)?;
            angles_from_counts(gear, enc, m, l, path)?
        }
        None => {
            (scaled(&table, &cfg.channels.motor, "motor", path)?, scaled(&table, &cfg.channels.link, "link", path)?)
        }
    };
    Ok(Run { motor, link, table })
}

fn sample_rate(cfg: &ArmConfig, run: &Run, path: &Path) -> Result<f64> {
    if let Some(fs) = cfg.sample_rate_hz {
        return Ok(fs);
    }
    let Some(ch) = &cfg.channels.time else { bail!("give sample_rate_hz or channels.time") };
    let t = scaled(&run.table, ch, "time", path)?;
    let span = t[t.len() - 1] - t[0];
    if !(span.is_finite() && span > 0.0) {
        bail!("{}: time does not increase", path.display());
    }
    Ok((t.len() - 1) as f64 / span)
}

fn fit_kinematic(cfg: &KinematicConfig, gear: &Gear<f64>, angles: &JointAngles) -> Result<(KinematicFit, Option<f64>)> {
    let opts = KinematicFitOptions::default();
    let cv = match &cfg.order {
        Order::Named(s) if s == "cv" => true,
        Order::Named(s) => bail!("kinematic.order: `{s}` is neither a number nor \"cv\""),
        Order::Fixed(_) => false,
    };
    let basis_of = |order: usize, mesh: usize| -> Result<KinematicBasis> {
        Ok(match cfg.basis.as_str() {
            "fourier" => KinematicBasis::Fourier {
                output_harmonics: order,
                mesh_harmonics: mesh,
                mesh_angle: MeshAngle::Relative,
            },
            "polynomial" => KinematicBasis::Polynomial { order },
            other => bail!("kinematic.basis: `{other}` is neither fourier nor polynomial"),
        })
    };
    if cv {
        let mut candidates = Vec::new();
        if cfg.basis == "polynomial" {
            for o in 1..=7 {
                candidates.push(basis_of(o, 0)?);
            }
        } else {
            for ho in 1..=3 {
                for hr in [0, 2, 4, 6] {
                    candidates.push(basis_of(ho, hr)?);
                }
            }
        }
        let (fit, cvs) = select_kinematic_basis(gear, angles, &candidates, 5, &opts)?;
        let best = cvs.iter().cloned().fold(f64::INFINITY, f64::min);
        Ok((fit, Some(best)))
    } else {
        let Order::Fixed(o) = cfg.order else { unreachable!() };
        Ok((fit_kinematic_error(gear, angles, basis_of(o, cfg.mesh_harmonics)?, &opts)?, None))
    }
}

fn kinematic_model(fit: &KinematicFit) -> KinematicModel {
    let (basis, order, mesh) = match fit.basis {
        KinematicBasis::Polynomial { order } => ("polynomial", order, 0),
        KinematicBasis::Fourier { output_harmonics, mesh_harmonics, .. } => {
            ("fourier", output_harmonics, mesh_harmonics)
        }
    };
    KinematicModel { basis: basis.into(), order, mesh_harmonics: mesh, coefficients: fit.coefficients.clone() }
}

/// Runs `identify`.
pub fn run(a: &Args) -> Result<()> {
    strainwave_io::output::refuse_input_as_output(
        &a.out,
        [a.no_load.as_path(), a.loaded.as_path(), a.config.as_path()],
    )?;
    let text = std::fs::read_to_string(&a.config).with_context(|| format!("{}", a.config.display()))?;
    let cfg: ArmConfig = toml::from_str(&text).with_context(|| format!("config {}", a.config.display()))?;
    let gear = cfg.gear.gear()?;
    // Kinematic error from the no-load run.
    let nl = load_run(&cfg, &a.no_load)?;
    let fs = sample_rate(&cfg, &nl, &a.no_load)?;
    let nl_angles = JointAngles { motor_angle_rad: &nl.motor, link_angle_rad: &nl.link, sample_rate_hz: fs };
    let (kin, cv) = fit_kinematic(&cfg.kinematic, &gear, &nl_angles).context("kinematic-error fit")?;
    // Compliance from the loaded run.
    let ld = load_run(&cfg, &a.loaded)?;
    let Some(ref_ch) = &cfg.channels.reference_torque else {
        bail!("channels.reference_torque: needed for the loaded run")
    };
    let reference = scaled(&ld.table, ref_ch, "reference_torque", &a.loaded)?;
    let ld_angles = JointAngles { motor_angle_rad: &ld.motor, link_angle_rad: &ld.link, sample_rate_hz: fs };
    let c = &cfg.compliance;
    let rated = cfg.gear.rated_torque_nm;
    let form = match c.spring.as_str() {
        "linear" => ComplianceForm::Linear,
        "cubic" => ComplianceForm::Cubic,
        "three-slope" => {
            ComplianceForm::ThreeSlope { t1_nm: c.t1_nm.unwrap_or(0.25 * rated), t2_nm: c.t2_nm.unwrap_or(0.6 * rated) }
        }
        "seed" => ComplianceForm::Seed { ratio: cfg.gear.ratio },
        other => bail!("compliance.spring: `{other}` is not linear, cubic, three-slope or seed"),
    };
    let mut opts = ComplianceFitOptions::new(form, rated);
    opts.hysteresis = match c.hysteresis.as_str() {
        "none" => HysteresisForm::None,
        "plays" => {
            // Narrowest play: the torsion's resolution plus noise, peak to peak.
            let deadband = match &cfg.encoders {
                Some(e) => {
                    let link = std::f64::consts::TAU / e.link_counts_per_rev as f64;
                    let motor = std::f64::consts::TAU / e.motor_counts_per_rev as f64 / cfg.gear.ratio;
                    (1.0 + 4.0 * e.noise_counts) * (link + motor)
                }
                None => 1.0e-5,
            };
            HysteresisForm::geometric_plays(deadband, 2.0, 6)
        }
        other => bail!("compliance.hysteresis: `{other}` is neither plays nor none"),
    };
    opts.damping = c.damping;
    opts.decimation = c.decimation.max(1);
    let fit = fit_compliance(&gear, &kin, &ld_angles, &reference, &opts).context("compliance fit")?;
    let peak = reference.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let model = ModelFile {
        sample_rate_hz: fs,
        torque_range_nm: 1.25 * peak,
        gear: cfg.gear.clone(),
        encoders: cfg.encoders.clone(),
        channels: Channels {
            motor: cfg.channels.motor.clone(),
            link: cfg.channels.link.clone(),
            time: None,
            reference_torque: None,
        },
        kinematic: kinematic_model(&kin),
        compliance: ComplianceModel {
            damping_nm_s_per_rad: fit.damping_nm_s_per_rad,
            windup_offset_rad: fit.windup_offset_rad,
            rated_torque_nm: fit.rated_torque_nm,
            spring: fit.params,
            hysteresis: fit.hysteresis.clone(),
        },
    };
    let text = toml::to_string(&model).context("serializing the model")?;
    let header = format!("# strainwave identify: {} (no load), {} (loaded)\n", a.no_load.display(), a.loaded.display());
    strainwave_io::output::write_file(&a.out, header + &text)?;
    if !a.quiet {
        let kb = match kin.basis {
            KinematicBasis::Polynomial { order } => format!("polynomial, order {order}"),
            KinematicBasis::Fourier { output_harmonics, mesh_harmonics, .. } => {
                format!("Fourier, {output_harmonics} output + {mesh_harmonics} mesh harmonics")
            }
        };
        let m = &kin.metrics;
        let f = &fit.metrics;
        let mut rows = vec![vec![
            "kinematic error (no-load torsion)".to_string(),
            kb,
            format!("{:.4}", m.r_squared),
            format!("{:.3e} rad", m.rms),
            format!("{:.3e} rad", m.mean_abs),
            format!("{:.3e} rad", m.max_abs),
        ]];
        if let Some(cv) = cv {
            rows.push(vec![
                "  5-fold cross-validation".into(),
                "best candidate".into(),
                "".into(),
                format!("{cv:.3e} rad"),
                "".into(),
                "".into(),
            ]);
        }
        rows.push(vec![
            "compliance (loaded, vs reference)".to_string(),
            format!("{}, {} hysteresis, {} LM iterations", c.spring, c.hysteresis, fit.iterations),
            format!("{:.4}", f.r_squared),
            format!("{:.3} N·m", f.rms),
            format!("{:.3} N·m", f.mean_abs),
            format!("{:.3} N·m", f.max_abs),
        ]);
        let header = ["fit", "model", "R²", "rms", "mean |e|", "max |e|"];
        let mut out = crate::report::text::text_table(&header, &rows);
        out.push_str(&format!("model -> {}\n", a.out.display()));
        crate::stdout::print(&out)?;
    }
    Ok(())
}
