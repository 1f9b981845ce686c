//! The Stribeck term's decay speed: one given, or chosen among candidates by blocked
//! cross-validation on the rows the model is identified on (never on a held-out block).

use anyhow::{bail, Result};
use strainwave_analysis::ident::{fit_compliance, ComplianceFitOptions, JointAngles};
use strainwave_core::gear::Gear;

use super::{ArmConfig, KinematicPlan};

/// The Stribeck speeds to choose from (empty: no Stribeck term).
pub(super) fn stribeck_candidates(cfg: &ArmConfig) -> Result<Vec<f64>> {
    match cfg.friction.as_ref().and_then(|f| f.stribeck_speed_rad_s.as_ref()) {
        None => Ok(Vec::new()),
        Some(c) => c.candidates("friction.stribeck_speed_rad_s"),
    }
}

/// Chooses the Stribeck speed among `candidates` by blocked cross-validation on `rows`
/// alone: `rows` cut into `folds` contiguous pieces, each predicted by a model (kinematic
/// error included) identified on the others; the speed with the least pooled squared
/// error wins. A fold where some candidate cannot be identified (its training rows do
/// not excite a term, e.g. a joint that never stops) is left out for every candidate.
/// Returns the speed, the pooled RMS per candidate and the folds scored.
#[allow(clippy::too_many_arguments)]
pub(super) fn choose_stribeck_speed(
    candidates: &[f64],
    folds: usize,
    rows: &[usize],
    gear: &Gear<f64>,
    plan: &KinematicPlan,
    angles: &JointAngles,
    reference: &[f64],
    opts: &ComplianceFitOptions,
) -> Result<(f64, Vec<f64>, usize)> {
    let pieces = strainwave_analysis::ident::holdout_blocks(rows.len(), folds)?;
    // Squared error and count per candidate and fold (None: not identifiable there).
    let mut sse: Vec<Vec<Option<(f64, usize)>>> = Vec::with_capacity(candidates.len());
    let mut first_error = None;
    for &vs in candidates {
        let mut o = opts.clone();
        if let Some(f) = o.friction.as_mut() {
            f.stribeck_speed_rad_s = Some(vs);
        }
        let per_fold = pieces
            .iter()
            .map(|piece| {
                let train: Vec<usize> = rows[..piece.start].iter().chain(&rows[piece.end..]).copied().collect();
                let pred = plan.fit(gear, angles, &train).and_then(|kin| {
                    let o = ComplianceFitOptions { train_rows: Some(train), ..o.clone() };
                    let fit = fit_compliance(gear, &kin, angles, reference, &o)?;
                    Ok(fit.predict_reference(gear, kin, angles)?)
                });
                match pred {
                    Ok(pred) => {
                        let test = &rows[piece.clone()];
                        Some((test.iter().map(|&k| (pred[k] - reference[k]).powi(2)).sum::<f64>(), test.len()))
                    }
                    Err(e) => {
                        first_error.get_or_insert_with(|| format!("{e:#}"));
                        None
                    }
                }
            })
            .collect();
        sse.push(per_fold);
    }
    let scored: Vec<usize> = (0..pieces.len()).filter(|&f| sse.iter().all(|c| c[f].is_some())).collect();
    if scored.is_empty() {
        bail!(
            "friction.stribeck_speed_rad_s: no fold where every candidate of {candidates:?} can be identified ({})",
            first_error.unwrap_or_default()
        );
    }
    let rms: Vec<f64> = sse
        .iter()
        .map(|c| {
            let (e, n) = scored.iter().filter_map(|&f| c[f]).fold((0.0, 0), |(e, n), (a, b)| (e + a, n + b));
            (e / n as f64).sqrt()
        })
        .collect();
    let best = (0..candidates.len()).min_by(|&a, &b| rms[a].total_cmp(&rms[b])).unwrap_or(0);
    Ok((candidates[best], rms, scored.len()))
}
