//! Out-of-sample scores of an identified model: the loaded run cut into contiguous blocks,
//! each predicted by a model identified on the others, beside the plain linear fit.

use anyhow::{Context, Result};
use strainwave_analysis::ident::{
    blocked_holdout, fit_compliance, lstsq_qr, training_rows, ComplianceFitOptions, FitMetrics, JointAngles,
};
use strainwave_core::gear::Gear;

use super::stribeck::choose_stribeck_speed;
use super::KinematicPlan;

/// Out-of-sample scores of the model and of the plain linear fit.
#[derive(Debug, Clone)]
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

pub(super) fn holdout_scores(
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
