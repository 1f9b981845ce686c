//! `strainwave identify`: fit the kinematic error and the compliance of an
//! encoder-based torque estimator from recorded runs, and write the model `estimate`
//! reads.
//!
//! A loaded run with a reference torque is enough. A no-load run, when there is one,
//! gives the kinematic error; otherwise its mesh harmonics (of the motor angle) are
//! fitted from the loaded run with a slow trend taking up the load, and the output-angle
//! harmonics are reported as not identifiable (as they are when the link turns less than
//! a revolution). With a `[friction]` table the reference is a motor-current torque and
//! friction and rotor inertia are identified with the compliance.
//!
//! The configuration (`--config ARM.toml`, see `examples/arm-hda.toml` and
//! `examples/lara8-joint3.toml`) only maps the recordings and the model choices onto
//! `strainwave_analysis::ident`.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use serde::{Deserialize, Serialize};
use strainwave_analysis::ident::{
    blocked_holdout, fit_compliance, fit_kinematic_error_on, lstsq_qr, select_kinematic_basis, training_rows,
    ComplianceFit, ComplianceFitOptions, ComplianceForm, ComplianceParams, FitMetrics, FittedHysteresis,
    FrictionFitOptions, FrictionParams, HysteresisForm, JointAngles, KinematicBasis, KinematicFit, KinematicFitOptions,
};
use strainwave_core::gear::Gear;
use strainwave_core::torsion::MeshAngle;

mod config;
mod load;
mod report;
mod stribeck;
pub use config::{ArmConfig, Channels, EncodersConfig, GearConfig, Order};
pub use load::refuse_count_scaling;
use load::{load_run, sample_rate};
use stribeck::{choose_stribeck_speed, stribeck_candidates};

/// Arguments of `identify`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Arm configuration (gear, channels, encoders, model choices); see examples/arm-hda.toml.
    #[arg(long)]
    pub config: PathBuf,
    /// No-load recording (the joint turns slowly, no load): fits the kinematic error.
    /// Without it the kinematic error's mesh harmonics come from the loaded run.
    #[arg(long)]
    pub no_load: Option<PathBuf>,
    /// Loaded recording with a reference torque: fits the compliance.
    #[arg(long)]
    pub loaded: PathBuf,
    /// Output model TOML (read by `estimate --config`).
    #[arg(long)]
    pub out: PathBuf,
    /// Also score the model out of sample: the loaded run cut into K contiguous blocks,
    /// each predicted by a model identified on the others, beside the plain linear fit.
    #[arg(long, value_name = "K")]
    pub holdout: Option<usize>,
    /// Write the model even when the Levenberg–Marquardt fit did not converge (else exit 1).
    #[arg(long)]
    pub allow_unconverged: bool,
    /// Skip rows with a non-finite value in a used column (counted in the summary)
    /// instead of stopping at the first.
    #[arg(long)]
    pub lenient: bool,
    /// Write a JSON summary (fits, parameters with standard errors, holdout) here.
    #[arg(long, value_name = "PATH")]
    pub summary_json: Option<PathBuf>,
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
    /// Mesh harmonics, Fourier only.
    pub mesh_harmonics: usize,
    /// The mesh angle of the harmonics: `relative` (WG relative to the output) or `motor`.
    #[serde(default = "relative")]
    pub mesh_angle: String,
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

fn relative() -> String {
    "relative".into()
}

impl ModelFile {
    /// Reads a model file.
    pub fn load(path: &Path) -> Result<Self> {
        let text = std::fs::read_to_string(path).with_context(|| format!("{}", path.display()))?;
        toml::from_str(&text).map_err(|e| strainwave_joint::toml_error::one_line(path, &text, &e))
    }

    /// The library's kinematic fit.
    pub fn kinematic_fit(&self) -> Result<KinematicFit> {
        let k = &self.kinematic;
        let basis = match k.basis.as_str() {
            "fourier" => KinematicBasis::Fourier {
                output_harmonics: k.order,
                mesh_harmonics: k.mesh_harmonics,
                mesh_angle: match k.mesh_angle.as_str() {
                    "relative" => MeshAngle::Relative,
                    "motor" => MeshAngle::Motor,
                    other => bail!("kinematic.mesh_angle: `{other}` is neither relative nor motor"),
                },
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
            termination: None,
            friction: self.friction,
            parameters: Vec::new(),
        }
    }
}

/// Slow-trend degree when the mesh harmonics come from a loaded run.
const SLOW_TREND_DEGREE: usize = 15;
/// Mesh harmonics fitted from a loaded run when the config does not say.
const DEFAULT_LOADED_MESH_HARMONICS: usize = 4;

fn span(x: &[f64]) -> f64 {
    let (lo, hi) = x.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| (a.min(*v), b.max(*v)));
    hi - lo
}

/// How the kinematic error is fitted.
enum KinematicPlan {
    /// From the no-load run (fitted once).
    NoLoad(KinematicFit),
    /// From the loaded run's training rows with a slow trend.
    Loaded(KinematicBasis),
    /// No model (the motor turns less than a revolution).
    None,
}

fn no_model() -> KinematicFit {
    KinematicFit {
        basis: KinematicBasis::Fourier { output_harmonics: 0, mesh_harmonics: 0, mesh_angle: MeshAngle::Motor },
        coefficients: vec![0.0],
        direction_offset_rad: 0.0,
        metrics: FitMetrics::of(&[], &[]),
    }
}

impl KinematicPlan {
    fn fit(&self, gear: &Gear<f64>, loaded: &JointAngles, rows: &[usize]) -> Result<KinematicFit> {
        match self {
            KinematicPlan::NoLoad(k) => Ok(k.clone()),
            KinematicPlan::None => Ok(no_model()),
            KinematicPlan::Loaded(basis) => {
                let opts = KinematicFitOptions { slow_trend_degree: SLOW_TREND_DEGREE, ..Default::default() };
                Ok(fit_kinematic_error_on(gear, loaded, *basis, &opts, rows)?)
            }
        }
    }
}

/// Plans the kinematic fit and says what is not identifiable, and why.
fn plan_kinematic(
    cfg: &ArmConfig,
    gear: &Gear<f64>,
    no_load: Option<&JointAngles>,
    loaded: &JointAngles,
    notes: &mut Vec<String>,
) -> Result<(KinematicPlan, Option<f64>)> {
    let k = &cfg.kinematic;
    let cv = match &k.order {
        Order::Named(s) if s == "cv" => true,
        Order::Named(s) => bail!("kinematic.order: `{s}` is neither a number nor \"cv\""),
        Order::Fixed(_) => false,
    };
    let order = match k.order {
        Order::Fixed(o) => o,
        Order::Named(_) => 0,
    };
    if !matches!(k.basis.as_str(), "fourier" | "polynomial") {
        bail!("kinematic.basis: `{}` is neither fourier nor polynomial", k.basis);
    }
    let run = no_load.unwrap_or(loaded);
    let (link_span, motor_span) = (span(run.link_angle_rad), span(run.motor_angle_rad));
    let which = if no_load.is_some() { "no-load run" } else { "loaded run" };
    // The torsion cannot exceed a fraction of the link's motion unless one encoder is reversed.
    let torsion_span = span(&run.torsion_rad(gear));
    if link_span > 0.05 && torsion_span > 0.5 * link_span {
        bail!(
            "{which}: the torsion spans {torsion_span:.3} rad while the link turns {link_span:.3} rad: one encoder \
             counts the other way; set encoders.motor_direction = -1 (or encoders.link_direction = -1)"
        );
    }
    if motor_span < std::f64::consts::TAU {
        notes.push(format!(
            "kinematic error not identifiable: the motor turns {motor_span:.2} rad (< 1 rev) in the {which}; none used"
        ));
        return Ok((KinematicPlan::None, None));
    }
    let full_turn = link_span >= 0.95 * std::f64::consts::TAU;
    if k.basis == "polynomial" {
        let Some(nl) = no_load else {
            bail!("kinematic.basis = \"polynomial\" (in the output angle) needs --no-load: from a loaded run it is confounded with the load");
        };
        let opts = KinematicFitOptions::default();
        if cv {
            let candidates: Vec<KinematicBasis> = (1..=7).map(|o| KinematicBasis::Polynomial { order: o }).collect();
            let (fit, cvs) = select_kinematic_basis(gear, nl, &candidates, 5, &opts)?;
            return Ok((KinematicPlan::NoLoad(fit), Some(cvs.iter().copied().fold(f64::INFINITY, f64::min))));
        }
        let rows: Vec<usize> = (0..nl.motor_angle_rad.len()).collect();
        let fit = fit_kinematic_error_on(gear, nl, KinematicBasis::Polynomial { order }, &opts, &rows)?;
        return Ok((KinematicPlan::NoLoad(fit), None));
    }
    match no_load {
        Some(nl) if full_turn => {
            let opts = KinematicFitOptions::default();
            let basis_of = |ho: usize, hr: usize| KinematicBasis::Fourier {
                output_harmonics: ho,
                mesh_harmonics: hr,
                mesh_angle: MeshAngle::Relative,
            };
            if cv {
                let mut candidates = Vec::new();
                for ho in 1..=3 {
                    for hr in [0, 2, 4, 6] {
                        candidates.push(basis_of(ho, hr));
                    }
                }
                let (fit, cvs) = select_kinematic_basis(gear, nl, &candidates, 5, &opts)?;
                Ok((KinematicPlan::NoLoad(fit), Some(cvs.iter().copied().fold(f64::INFINITY, f64::min))))
            } else {
                let rows: Vec<usize> = (0..nl.motor_angle_rad.len()).collect();
                let basis = basis_of(order, k.mesh_harmonics.unwrap_or(0));
                Ok((KinematicPlan::NoLoad(fit_kinematic_error_on(gear, nl, basis, &opts, &rows)?), None))
            }
        }
        Some(nl) => {
            // Less than a revolution: mesh harmonics of the motor angle only.
            notes.push(format!(
                "output harmonics not identifiable: the link turns {link_span:.2} rad (< 1 rev) in the no-load run"
            ));
            let hr = k.mesh_harmonics.unwrap_or(DEFAULT_LOADED_MESH_HARMONICS);
            let opts = KinematicFitOptions::default();
            let basis =
                KinematicBasis::Fourier { output_harmonics: 0, mesh_harmonics: hr, mesh_angle: MeshAngle::Motor };
            let rows: Vec<usize> = (0..nl.motor_angle_rad.len()).collect();
            Ok((KinematicPlan::NoLoad(fit_kinematic_error_on(gear, nl, basis, &opts, &rows)?), None))
        }
        None => {
            notes.push(
                "output harmonics not identifiable without a no-load run (confounded with the load); mesh harmonics \
                 of the motor angle fitted from the loaded run with a slow trend"
                    .into(),
            );
            if cv || order > 0 {
                notes.push(format!("kinematic.order = {:?} not used: it needs --no-load", k.order));
            }
            let hr = k.mesh_harmonics.unwrap_or(DEFAULT_LOADED_MESH_HARMONICS);
            if hr == 0 {
                return Ok((KinematicPlan::None, None));
            }
            Ok((
                KinematicPlan::Loaded(KinematicBasis::Fourier {
                    output_harmonics: 0,
                    mesh_harmonics: hr,
                    mesh_angle: MeshAngle::Motor,
                }),
                None,
            ))
        }
    }
}

fn kinematic_model(fit: &KinematicFit) -> KinematicModel {
    let (basis, order, mesh, angle) = match fit.basis {
        KinematicBasis::Polynomial { order } => ("polynomial", order, 0, MeshAngle::Relative),
        KinematicBasis::Fourier { output_harmonics, mesh_harmonics, mesh_angle } => {
            ("fourier", output_harmonics, mesh_harmonics, mesh_angle)
        }
    };
    let mesh_angle = match angle {
        MeshAngle::Relative => "relative",
        MeshAngle::Motor => "motor",
    };
    KinematicModel {
        basis: basis.into(),
        order,
        mesh_harmonics: mesh,
        mesh_angle: mesh_angle.into(),
        coefficients: fit.coefficients.clone(),
    }
}

fn compliance_options(cfg: &ArmConfig, windup_offset: bool) -> Result<ComplianceFitOptions> {
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
                    (1.0 + 4.0 * e.noise()) * (link + motor)
                }
                None => 1.0e-5,
            };
            HysteresisForm::geometric_plays(deadband, 2.0, 6)
        }
        other => bail!("compliance.hysteresis: `{other}` is neither plays nor none"),
    };
    opts.damping = c.damping;
    opts.decimation = c.decimation.unwrap_or(5).max(1);
    opts.max_iterations = c.max_iterations.unwrap_or(40).max(1);
    opts.windup_offset = windup_offset;
    opts.friction = cfg.friction.as_ref().map(|f| FrictionFitOptions {
        coulomb: f.coulomb,
        viscous: f.viscous,
        stribeck_speed_rad_s: stribeck_candidates(cfg).ok().and_then(|c| c.first().copied()),
        load_dependent: f.load_dependent,
        inertia: f.rotor_inertia,
        smoothing_speed_rad_s: f.smoothing_speed_rad_s,
        rate_span: f.rate_span,
    });
    Ok(opts)
}

/// Explains a negative stiffness with the settings that fix it.
fn stiffness_hint(e: anyhow::Error) -> anyhow::Error {
    if format!("{e:#}").contains("negative stiffness") {
        e.context(
            "the torsion and the reference torque have opposite signs: flip both encoders.motor_direction and \
             encoders.link_direction, or give channels.reference_torque a scale = -1",
        )
    } else {
        e
    }
}

/// The config's own checks, before any recording is read, so that their errors can
/// name the config file.
fn check_config(cfg: &ArmConfig, windup_offset: bool) -> Result<()> {
    cfg.gear.gear()?;
    match cfg.sample_rate_hz {
        Some(fs) if !(fs.is_finite() && fs > 0.0) => bail!("sample_rate_hz: must be positive, got {fs}"),
        None if cfg.channels.time.is_none() => bail!("give sample_rate_hz or channels.time"),
        _ => {}
    }
    if cfg.channels.reference_torque.is_none() {
        bail!("channels.reference_torque: needed for the loaded run");
    }
    if let Some(e) = &cfg.encoders {
        e.configs()?;
        load::refuse_count_scaling(&cfg.channels.motor, "motor")?;
        load::refuse_count_scaling(&cfg.channels.link, "link")?;
    }
    compliance_options(cfg, windup_offset)?;
    Ok(())
}

/// Runs `identify`.
pub fn run(a: &Args) -> Result<()> {
    let mut inputs = vec![a.loaded.as_path(), a.config.as_path()];
    inputs.extend(a.no_load.as_deref());
    strainwave_io::output::refuse_input_as_output(&a.out, inputs)?;
    let text = std::fs::read_to_string(&a.config).with_context(|| format!("{}", a.config.display()))?;
    let cfg: ArmConfig =
        toml::from_str(&text).map_err(|e| strainwave_joint::toml_error::one_line(&a.config, &text, &e))?;
    cfg.refuse_unused(a.no_load.is_some()).with_context(|| format!("{}", a.config.display()))?;
    if let Some(k) = a.holdout {
        if k < 2 {
            bail!("--holdout: needs at least 2 blocks, got {k}");
        }
    }
    check_config(&cfg, a.no_load.is_none()).with_context(|| format!("{}", a.config.display()))?;
    let gear = cfg.gear.gear()?;
    let ld = load_run(&cfg, &a.loaded, true, a.lenient)?;
    let fs = sample_rate(&cfg, &ld, &a.loaded)?;
    let nl = match &a.no_load {
        Some(p) => Some(load_run(&cfg, p, false, a.lenient)?),
        None => None,
    };
    let reference = ld.reference.clone().context("reference torque")?;
    let ld_angles = JointAngles { motor_angle_rad: &ld.motor, link_angle_rad: &ld.link, sample_rate_hz: fs };
    let nl_angles =
        nl.as_ref().map(|r| JointAngles { motor_angle_rad: &r.motor, link_angle_rad: &r.link, sample_rate_hz: fs });
    let mut notes = Vec::new();
    let (plan, cv) =
        plan_kinematic(&cfg, &gear, nl_angles.as_ref(), &ld_angles, &mut notes).context("kinematic-error fit")?;
    let n = reference.len();
    let all: Vec<usize> = (0..n).collect();
    let kin = plan.fit(&gear, &ld_angles, &all).context("kinematic-error fit")?;
    // Without a no-load run nothing fixes the zero of the wind-up: fit it.
    let mut opts = compliance_options(&cfg, nl.is_none())?;
    let stribeck = stribeck_candidates(&cfg)?;
    let fit_all = |opts: &ComplianceFitOptions| {
        fit_compliance(&gear, &kin, &ld_angles, &reference, opts)
            .map_err(anyhow::Error::from)
            .map_err(stiffness_hint)
            .context("compliance fit")
    };
    // The first candidate's fit comes first: a wrong direction or a still joint is
    // reported as such, not as a failed choice.
    let mut fit = fit_all(&opts)?;
    if stribeck.len() > 1 {
        let folds = a.holdout.unwrap_or(5);
        let (vs, rms, scored) =
            choose_stribeck_speed(&stribeck, folds, &all, &gear, &plan, &ld_angles, &reference, &opts)
                .context("choosing the Stribeck speed")?;
        if let Some(f) = opts.friction.as_mut() {
            f.stribeck_speed_rad_s = Some(vs);
        }
        let tried: Vec<String> = stribeck.iter().zip(&rms).map(|(v, r)| format!("{v} ({r:.2} N·m)")).collect();
        notes.push(format!(
            "friction.stribeck_speed_rad_s = {vs} chosen by {folds}-block cross-validation ({scored} blocks \
             identifiable; RMS per candidate: {})",
            tried.join(", ")
        ));
        fit = fit_all(&opts)?;
    }
    let holdout = match a.holdout {
        None => None,
        Some(k) => Some(holdout_scores(k, &gear, &plan, &ld_angles, &reference, &opts, &stribeck)?),
    };
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
        friction: fit.friction,
    };
    let summary = report::Summary {
        args: a,
        cfg: &cfg,
        kin: &kin,
        cv,
        fit: &fit,
        notes: &notes,
        holdout: holdout.as_ref(),
        skipped: ld.skipped + nl.as_ref().map_or(0, |r| r.skipped),
        first_skipped: ld.first_skipped.or(nl.as_ref().and_then(|r| r.first_skipped)),
        rows: n,
        sample_rate_hz: fs,
    };
    if let Some(p) = &a.summary_json {
        strainwave_io::output::write_file(p, summary.json())?;
    }
    if !fit.converged() && !a.allow_unconverged {
        bail!(
            "compliance fit: {} after {} iterations; no model written (--allow-unconverged writes it anyway)",
            fit.termination.map_or("not converged", |t| t.describe()),
            fit.iterations
        );
    }
    let text = toml::to_string(&model).context("serializing the model")?;
    let header = format!(
        "# strainwave identify: {} (no load), {} (loaded)\n",
        a.no_load.as_deref().map_or("-".into(), |p| p.display().to_string()),
        a.loaded.display()
    );
    strainwave_io::output::write_file(&a.out, header + &text)?;
    if !a.quiet {
        crate::stdout::print(&summary.table())?;
    }
    Ok(())
}

/// Out-of-sample scores of the model and of the plain linear fit.
pub struct Holdout {
    /// Blocks.
    pub blocks: usize,
    /// The configured model (the reference it predicts: link or current torque).
    pub model: FitMetrics,
    /// The plain linear torsion fit on the same split.
    pub plain: FitMetrics,
    /// Blocks whose fit did not converge.
    pub unconverged: usize,
    /// The Stribeck speed each block's model chose on its own training rows (when
    /// candidates were given), rad/s.
    pub stribeck_speeds_rad_s: Vec<f64>,
}

fn holdout_scores(
    blocks: usize,
    gear: &Gear<f64>,
    plan: &KinematicPlan,
    angles: &JointAngles,
    reference: &[f64],
    opts: &ComplianceFitOptions,
    stribeck: &[f64],
) -> Result<Holdout> {
    let n = reference.len();
    let mut unconverged = 0;
    let mut stribeck_speeds_rad_s = Vec::new();
    let model = blocked_holdout(reference, blocks, |b, block| {
        let rows = training_rows(n, block);
        let kin = plan.fit(gear, angles, &rows).map_err(|e| strainwave_analysis::AnalysisError::Invalid {
            what: "holdout kinematic fit",
            why: format!("block {}: {e:#}", b + 1),
        })?;
        let mut o = ComplianceFitOptions { train_rows: Some(rows.clone()), ..opts.clone() };
        if stribeck.len() > 1 {
            // Chosen on this block's training rows only (K − 1 inner blocks).
            let (vs, ..) = choose_stribeck_speed(stribeck, blocks - 1, &rows, gear, plan, angles, reference, opts)
                .map_err(|e| strainwave_analysis::AnalysisError::Invalid {
                    what: "holdout Stribeck speed",
                    why: format!("block {}: {e:#}", b + 1),
                })?;
            if let Some(f) = o.friction.as_mut() {
                f.stribeck_speed_rad_s = Some(vs);
            }
            stribeck_speeds_rad_s.push(vs);
        }
        let fit = fit_compliance(gear, &kin, angles, reference, &o)?;
        if !fit.converged() {
            unconverged += 1;
        }
        Ok(fit.predict_reference(gear, kin, angles)?[block.clone()].to_vec())
    })
    .context("holdout of the model")?;
    // Plain: ordinary least squares of the reference on the torsion and a constant.
    let torsion = angles.torsion_rad(gear);
    let plain = blocked_holdout(reference, blocks, |_, block| {
        let rows = training_rows(n, block);
        let cols = [rows.iter().map(|&k| torsion[k]).collect(), vec![1.0; rows.len()]];
        let b: Vec<f64> = rows.iter().map(|&k| reference[k]).collect();
        let c = lstsq_qr(&cols, &b)?;
        Ok(block.clone().map(|k| c[0] * torsion[k] + c[1]).collect())
    })
    .context("holdout of the plain linear fit")?;
    Ok(Holdout { blocks, model, plain, unconverged, stribeck_speeds_rad_s })
}
