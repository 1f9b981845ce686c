//! The demo's estimate section: the HDA-arm paper on the arm twin (docs/physics.md §5). Identify the
//! kinematic error (no-load run) and the compliance (loaded run against the noisy
//! reference), then estimate the link torque from the raw counts in the paper's
//! experiments and compare with the truth, the paper's figures and a plain linear spring.

use anyhow::{Context, Result};
use strainwave_analysis::ident::{
    fit_compliance, fit_kinematic_error, select_kinematic_basis, ComplianceFit, ComplianceFitOptions, ComplianceForm,
    FitMetrics, HysteresisForm, JointAngles, KinematicBasis, KinematicFit, KinematicFitOptions,
};
use strainwave_core::gear::{FixedElement, Gear};
use strainwave_core::torsion::{EncoderConfig, EstimatorState, MeshAngle, NoKinematicError};
use strainwave_sim::arm::{simulate_arm, ArmExperiment, ArmRecording, ArmScenario};

use crate::report::plot::{LinePlot, Series};

struct Run {
    rec: ArmRecording,
    scenario: ArmScenario,
}

fn run(e: ArmExperiment) -> Result<Run> {
    let scenario = ArmScenario::experiment(e)?;
    Ok(Run { rec: simulate_arm(&scenario)?, scenario })
}

fn col<'a>(r: &'a Run, name: &str) -> Result<&'a [f64]> {
    r.rec.column(name).with_context(|| format!("arm twin: no column {name}"))
}

fn angles(r: &Run) -> Result<JointAngles<'_>> {
    Ok(JointAngles {
        motor_angle_rad: col(r, "motor_angle")?,
        link_angle_rad: col(r, "link_angle")?,
        sample_rate_hz: r.scenario.sample_rate_hz,
    })
}

fn gear(s: &ArmScenario) -> Result<Gear<f64>> {
    Gear::new(s.gear.ratio, FixedElement::CircularSpline).map_err(|e| anyhow::anyhow!("{e}"))
}

fn estimate_counts(fit: &ComplianceFit, kin: &KinematicFit, r: &Run) -> Result<Vec<f64>> {
    let s = &r.scenario;
    let e = &s.encoders;
    let enc = |cpr: u64, off: i64| -> Result<EncoderConfig> {
        let c = if e.single_turn { EncoderConfig::single_turn(cpr) } else { EncoderConfig::multi_turn(cpr) };
        Ok(c.map_err(|e| anyhow::anyhow!("{e}"))?.with_offset(off))
    };
    let (m, l) =
        (enc(e.motor_counts_per_rev, e.motor_offset_counts)?, enc(e.link_counts_per_rev, e.link_offset_counts)?);
    let est = fit.estimator_for_counts(gear(s)?, m, l, kin.clone(), s.sample_rate_hz)?;
    let mut st = EstimatorState::new();
    Ok(col(r, "motor_counts")?
        .iter()
        .zip(col(r, "link_counts")?)
        .map(|(mc, lc)| est.step_counts(&mut st, *mc as i64, *lc as i64).map_or(f64::NAN, |e| e.link_torque_nm))
        .collect())
}

/// Text for the terminal, HTML for the report, plots.
pub fn section() -> Result<(String, String, Vec<LinePlot>)> {
    let no_load = run(ArmExperiment::NoLoad)?;
    let loaded = run(ArmExperiment::LoadedHold)?;
    let s = &no_load.scenario;
    let g = gear(s)?;
    let opts = KinematicFitOptions::default();
    let mut candidates = Vec::new();
    for ho in 1..=3 {
        for hr in [0, 2, 4] {
            candidates.push(KinematicBasis::Fourier {
                output_harmonics: ho,
                mesh_harmonics: hr,
                mesh_angle: MeshAngle::Relative,
            });
        }
    }
    let nl = angles(&no_load)?;
    let (fourier, _) = select_kinematic_basis(&g, &nl, &candidates, 5, &opts)?;
    let poly = fit_kinematic_error(&g, &nl, KinematicBasis::Polynomial { order: 5 }, &opts)?;
    // Kinematic error over the full revolution of the no-load run, against the twin's truth.
    let true_kin = col(&no_load, "true_kinematic_error")?;
    let kin_fourier = FitMetrics::of(&fourier.eval_run(&g, &nl), true_kin);
    let kin_poly = FitMetrics::of(&poly.eval_run(&g, &nl), true_kin);

    let e = &s.encoders;
    let deadband = (1.0 + 4.0 * e.link_noise_counts) * std::f64::consts::TAU / e.link_counts_per_rev as f64
        + (1.0 + 4.0 * e.motor_noise_counts) * std::f64::consts::TAU / e.motor_counts_per_rev as f64 / s.gear.ratio;
    let mut copts = ComplianceFitOptions::new(ComplianceForm::Seed { ratio: s.gear.ratio }, s.gear.rated_torque_nm);
    copts.hysteresis = HysteresisForm::geometric_plays(deadband, 2.0, 6);
    copts.damping = true;
    copts.decimation = 5;
    let la = angles(&loaded)?;
    let reference = col(&loaded, "reference_torque")?;
    let ours = fit_compliance(&g, &fourier, &la, reference, &copts)?;
    let linear = fit_compliance(
        &g,
        &NoKinematicError,
        &la,
        reference,
        &ComplianceFitOptions::new(ComplianceForm::Linear, s.gear.rated_torque_nm),
    )?;

    let fmt = |m: &FitMetrics| format!("{:.3}/{:.3}", m.mean_abs, m.max_abs);
    let mut rows = Vec::new();
    let mut plots = Vec::new();
    for e in [
        ArmExperiment::StepHold,
        ArmExperiment::PeriodicHold,
        ArmExperiment::StepConstantTorque,
        ArmExperiment::PeriodicConstantTorque,
    ] {
        let r = run(e)?;
        let truth = col(&r, "true_link_torque")?;
        let est = estimate_counts(&ours, &fourier, &r)?;
        let m_ours = FitMetrics::of(&est, truth);
        let m_lin = FitMetrics::of(&linear.predict(&gear(&r.scenario)?, NoKinematicError, &angles(&r)?)?, truth);
        let (paper, ratio) = match e.paper_figures_nm() {
            Some((mean, max)) => (format!("{mean}/{max}"), format!("{:.1}×", mean / m_ours.mean_abs)),
            None => ("—".into(), "—".into()),
        };
        rows.push(vec![e.name().to_string(), paper, fmt(&m_lin), fmt(&m_ours), ratio]);
        if e == ArmExperiment::StepHold {
            let t = col(&r, "time")?.to_vec();
            plots.push(LinePlot {
                title: "HDA arm step (position held): link torque from the encoders".into(),
                x_label: "time (s)".into(),
                y_label: "link torque (N·m)".into(),
                series: vec![
                    Series { name: "true".into(), x: t.clone(), y: truth.to_vec() },
                    Series { name: "estimated (counts)".into(), x: t, y: est },
                ],
                ..Default::default()
            });
        }
    }
    let header = ["experiment", "paper mean/max |e| (N·m)", "plain linear", "ours", "paper/ours (mean)"];
    let kin_header = ["kinematic model (full revolution)", "rms vs truth (rad)", "max |e| (rad)"];
    let kin_rows = vec![
        vec![
            match fourier.basis {
                KinematicBasis::Fourier { output_harmonics: o, mesh_harmonics: m, .. } => {
                    format!("Fourier, {o} output + {m} mesh harmonics (5-fold CV)")
                }
                b => format!("{b:?}"),
            },
            format!("{:.3e}", kin_fourier.rms),
            format!("{:.3e}", kin_fourier.max_abs),
        ],
        vec![
            "polynomial, 5th order (paper)".into(),
            format!("{:.3e}", kin_poly.rms),
            format!("{:.3e}", kin_poly.max_abs),
        ],
    ];
    let mut text = String::from("Encoder-based torque estimation (HDA-arm paper, arm twin)\n");
    text.push_str(&crate::report::text::text_table(&header, &rows));
    text.push_str(&crate::report::text::text_table(&kin_header, &kin_rows));
    let mut html = String::from("<p>HDA arm on the arm twin: link torque from the raw encoder counts, mean/max |error| against the true link torque (N·m).</p>\n");
    html.push_str(&crate::report::html::table(&header, &rows));
    html.push_str(&crate::report::html::table(&kin_header, &kin_rows));
    Ok((text, html, plots))
}
