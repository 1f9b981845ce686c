//! `identify` as a job: fit the kinematic error and the compliance of an encoder-based
//! torque estimator from recorded runs, giving the model `estimate` reads. The command
//! line and the Python package both run it through [`load_config`] and [`identify`].
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

use std::path::Path;

use anyhow::{bail, Context, Result};
use strainwave_analysis::ident::{
    fit_compliance, fit_kinematic_error_on, select_kinematic_basis, ComplianceFitOptions, ComplianceForm, FitMetrics,
    FrictionFitOptions, HysteresisForm, JointAngles, KinematicBasis, KinematicFit, KinematicFitOptions,
};
use strainwave_core::gear::Gear;
use strainwave_core::torsion::MeshAngle;

mod config;
mod holdout;
mod load;
mod model;
mod stribeck;
mod summary;
pub use config::{
    ArmConfig, Basis, Channels, ComplianceConfig, EncodersConfig, Fixed, FrictionConfig, GearConfig, HysteresisChoice,
    KinematicConfig, Order, SpeedChoice, SpringChoice, RATIO_RANGE,
};
use holdout::holdout_scores;
pub use holdout::Holdout;
pub use load::refuse_count_scaling;
use load::{load_run, sample_rate};
pub use model::{ComplianceModel, Hysteresis, KinematicModel, ModelFile, Spring};
use stribeck::{choose_stribeck_speed, stribeck_candidates};
pub use summary::Summary;

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
    let cv = k.order == Order::CrossValidated;
    let order = match k.order {
        Order::Fixed(o) => o,
        Order::CrossValidated => 0,
    };
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
    if k.basis == Basis::Polynomial {
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
                notes.push(format!("kinematic.order = {} not used: it needs --no-load", k.order));
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
    let (basis, order, mesh, mesh_angle) = match fit.basis {
        KinematicBasis::Polynomial { order } => (Basis::Polynomial, order, 0, MeshAngle::Relative),
        KinematicBasis::Fourier { output_harmonics, mesh_harmonics, mesh_angle } => {
            (Basis::Fourier, output_harmonics, mesh_harmonics, mesh_angle)
        }
    };
    KinematicModel { basis, order, mesh_harmonics: mesh, mesh_angle, coefficients: fit.coefficients.clone() }
}

fn compliance_options(cfg: &ArmConfig, windup_offset: bool) -> Result<ComplianceFitOptions> {
    let c = &cfg.compliance;
    let rated = cfg.gear.rated_torque_nm;
    let form = match c.spring {
        SpringChoice::Linear => ComplianceForm::Linear,
        SpringChoice::Cubic => ComplianceForm::Cubic,
        SpringChoice::ThreeSlope => {
            ComplianceForm::ThreeSlope { t1_nm: c.t1_nm.unwrap_or(0.25 * rated), t2_nm: c.t2_nm.unwrap_or(0.6 * rated) }
        }
        SpringChoice::Hda => ComplianceForm::Seed { ratio: cfg.gear.ratio },
    };
    let mut opts = ComplianceFitOptions::new(form, rated);
    opts.hysteresis = match c.hysteresis {
        HysteresisChoice::None => HysteresisForm::None,
        HysteresisChoice::Plays => {
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

/// Friction that cannot be identified (a joint that holds still): how to fit without it.
fn friction_hint(e: strainwave_analysis::AnalysisError) -> anyhow::Error {
    match &e {
        strainwave_analysis::AnalysisError::Invalid { what: "friction", why }
            if why.starts_with("not identifiable") =>
        {
            anyhow::anyhow!("{e} (a joint config without a [friction] table)")
        }
        _ => e.into(),
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
        e.check_noise()?;
        load::refuse_count_scaling(&cfg.channels.motor, "motor")?;
        load::refuse_count_scaling(&cfg.channels.link, "link")?;
    }
    compliance_options(cfg, windup_offset)?;
    stribeck_candidates(cfg)?;
    kinematic_sizes(&cfg.kinematic)
}

/// Most harmonics (or highest power) of a kinematic-error basis: beyond it the fit's
/// design matrix would take gigabytes, and no gear's error needs it.
const MAX_KINEMATIC_ORDER: usize = 64;

/// Refuses a kinematic basis larger than [`MAX_KINEMATIC_ORDER`].
fn kinematic_sizes(k: &KinematicConfig) -> Result<()> {
    let order = match k.order {
        Order::Fixed(n) => Some(n),
        Order::CrossValidated => None,
    };
    for (key, n) in [("kinematic.order", order), ("kinematic.mesh_harmonics", k.mesh_harmonics)] {
        if let Some(n) = n.filter(|&n| n > MAX_KINEMATIC_ORDER) {
            bail!("{key}: at most {MAX_KINEMATIC_ORDER}, got {n}");
        }
    }
    Ok(())
}

/// A recording to identify from: a file (read whole), or a caller's table named `name`
/// in messages.
#[derive(Debug, Clone, Copy)]
pub enum RunInput<'a> {
    /// A recording file in any format the readers know.
    File(&'a Path),
    /// Columns already in memory.
    Table {
        /// The columns.
        table: &'a strainwave_io::Table,
        /// What messages call it.
        name: &'a str,
    },
}

impl RunInput<'_> {
    /// What messages and the summary call the recording.
    pub fn name(&self) -> String {
        match self {
            RunInput::File(p) => p.display().to_string(),
            RunInput::Table { name, .. } => (*name).to_string(),
        }
    }
}

/// How to run `identify` (the command line's flags).
#[derive(Debug, Clone, Copy, Default)]
pub struct IdentifyOptions {
    /// Score the model out of sample on this many contiguous blocks (`--holdout K`).
    pub holdout: Option<usize>,
    /// Skip rows with a non-finite value in a used column instead of stopping (`--lenient`).
    pub lenient: bool,
}

/// What `identify` found: the model and the summary of its fits.
pub struct Identified {
    /// The model file `estimate` reads.
    pub model: ModelFile,
    /// The fits, their parameters and the holdout scores.
    pub summary: Summary,
}

impl Identified {
    /// Refuses a model whose Levenberg–Marquardt fit did not converge, unless `allow`
    /// (`--allow-unconverged`).
    pub fn refuse_unconverged(&self, allow: bool) -> Result<()> {
        let fit = &self.summary.fit;
        if !fit.converged() && !allow {
            bail!(
                "compliance fit: {} after {} iterations; no model written (--allow-unconverged writes it anyway)",
                fit.termination.map_or("not converged", |t| t.describe()),
                fit.iterations
            );
        }
        Ok(())
    }

    /// The model file's text: a comment naming the runs, then the model as TOML.
    pub fn model_text(&self) -> Result<String> {
        let text = toml::to_string(&self.model).context("serializing the model")?;
        let header = format!(
            "# strainwave identify: {} (no load), {} (loaded)\n",
            self.summary.no_load.as_deref().unwrap_or("-"),
            self.summary.loaded
        );
        Ok(header + &text)
    }
}

/// An error naming the loaded run and `gear.rated_torque_nm` when the reference torque
/// varies by less than 0.1 % of the rated torque (RMS): no load to fit a compliance to,
/// or a rated torque in the wrong unit (the fit would only say that it has no load).
fn refuse_unloaded(reference: &[f64], rated_nm: f64, loaded: &str) -> Result<()> {
    let n = reference.len().max(1) as f64;
    let mean = reference.iter().sum::<f64>() / n;
    let rms = (reference.iter().map(|v| (v - mean) * (v - mean)).sum::<f64>() / n).sqrt();
    if rms < 1e-3 * rated_nm {
        bail!(
            "{loaded}: the reference torque varies by {rms:.3e} N·m rms, under 0.1 % of `gear.rated_torque_nm` = \
             {rated_nm:e} N·m: no load to identify the compliance from, or a rated torque in the wrong unit"
        );
    }
    Ok(())
}

/// Reads and checks an arm configuration (`identify --config`) for runs with or without a
/// no-load run: every error names `path`, before any recording is read.
pub fn load_config(path: &Path, has_no_load: bool, opts: &IdentifyOptions) -> Result<ArmConfig> {
    let text = std::fs::read_to_string(path).with_context(|| format!("{}", path.display()))?;
    let cfg: ArmConfig = toml::from_str(&text).map_err(|e| crate::toml_error::one_line(path, &text, &e))?;
    cfg.refuse_unused(has_no_load).with_context(|| format!("{}", path.display()))?;
    if let Some(k) = opts.holdout {
        if k < 2 {
            bail!("--holdout: needs at least 2 blocks, got {k}");
        }
    }
    check_config(&cfg, !has_no_load).with_context(|| format!("{}", path.display()))?;
    Ok(cfg)
}

/// Fits the kinematic error and the compliance of `cfg` (from [`load_config`]) on the
/// `loaded` run, with the kinematic error from `no_load` when there is one.
pub fn identify(
    cfg: &ArmConfig,
    loaded: RunInput<'_>,
    no_load: Option<RunInput<'_>>,
    opts: &IdentifyOptions,
) -> Result<Identified> {
    let gear = cfg.gear.gear()?;
    let ld = load_run(cfg, loaded, true, opts.lenient)?;
    let fs = sample_rate(cfg, &ld, &loaded.name())?;
    let nl = match no_load {
        Some(p) => Some(load_run(cfg, p, false, opts.lenient)?),
        None => None,
    };
    let reference = ld.reference.clone().context("reference torque")?;
    refuse_unloaded(&reference, cfg.gear.rated_torque_nm, &loaded.name())?;
    let ld_angles = JointAngles { motor_angle_rad: &ld.motor, link_angle_rad: &ld.link, sample_rate_hz: fs };
    let nl_angles =
        nl.as_ref().map(|r| JointAngles { motor_angle_rad: &r.motor, link_angle_rad: &r.link, sample_rate_hz: fs });
    let mut notes = Vec::new();
    let (plan, cv) = plan_kinematic(cfg, &gear, nl_angles.as_ref(), &ld_angles, &mut notes)
        .with_context(|| format!("{}: kinematic-error fit", loaded.name()))?;
    let n = reference.len();
    let all: Vec<usize> = (0..n).collect();
    let kin = plan.fit(&gear, &ld_angles, &all).with_context(|| format!("{}: kinematic-error fit", loaded.name()))?;
    // Without a no-load run nothing fixes the zero of the wind-up: fit it.
    let mut fit_opts = compliance_options(cfg, nl.is_none())?;
    let stribeck = stribeck_candidates(cfg)?;
    let loaded_name = loaded.name();
    let fit_all = |o: &ComplianceFitOptions| {
        fit_compliance(&gear, &kin, &ld_angles, &reference, o)
            .map_err(friction_hint)
            .map_err(stiffness_hint)
            .with_context(|| format!("{loaded_name}: compliance fit"))
    };
    // The first candidate's fit comes first: a wrong direction or a still joint is
    // reported as such, not as a failed choice.
    let mut fit = fit_all(&fit_opts)?;
    if stribeck.len() > 1 {
        let folds = opts.holdout.unwrap_or(5);
        let (vs, rms, scored) =
            choose_stribeck_speed(&stribeck, folds, &all, &gear, &plan, &ld_angles, &reference, &fit_opts)
                .context("choosing the Stribeck speed")?;
        if let Some(f) = fit_opts.friction.as_mut() {
            f.stribeck_speed_rad_s = Some(vs);
        }
        let tried: Vec<String> = stribeck.iter().zip(&rms).map(|(v, r)| format!("{v} ({r:.2} N·m)")).collect();
        notes.push(format!(
            "friction.stribeck_speed_rad_s = {vs} chosen by {folds}-block cross-validation ({scored} blocks \
             identifiable; RMS per candidate: {})",
            tried.join(", ")
        ));
        fit = fit_all(&fit_opts)?;
    }
    let holdout = match opts.holdout {
        None => None,
        // Each block's model chooses its Stribeck speed on the other blocks, split again.
        Some(k) if k < 3 && stribeck.len() > 1 => bail!(
            "--holdout {k}: choosing among the {} candidates of `friction.stribeck_speed_rad_s` on each \
             block's training rows needs at least 3 blocks; use --holdout 3 or more, or one candidate",
            stribeck.len()
        ),
        Some(k) => Some(holdout_scores(k, &gear, &plan, &ld_angles, &reference, &fit_opts, &stribeck)?),
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
            time: cfg.channels.time.clone(),
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
    let summary = Summary {
        loaded: loaded.name(),
        no_load: no_load.map(|r| r.name()),
        spring: cfg.compliance.spring.name().into(),
        hysteresis: cfg.compliance.hysteresis.name().into(),
        kin,
        cv,
        fit,
        notes,
        holdout,
        skipped: ld.skipped + nl.as_ref().map_or(0, |r| r.skipped),
        first_skipped: ld.first_skipped.or(nl.as_ref().and_then(|r| r.first_skipped)),
        first_skipped_at: ld.first_skipped_at.clone().or(nl.as_ref().and_then(|r| r.first_skipped_at.clone())),
        rows: n,
        sample_rate_hz: fs,
    };
    Ok(Identified { model, summary })
}
