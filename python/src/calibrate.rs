//! `calibrate_experiments`: the sensor calibration fits of `strainwave calibrate` on a
//! caller's experiments, returning the calibration file's TOML text.

use anyhow::{bail, Context, Result};
use numpy::PyReadonlyArray1;
use pyo3::prelude::*;
use strainwave_analysis::calibration::{
    calibrate_gain, fit_affine, fit_speed_dependent, Experiment, Extrapolation, GainFit, ModelKind, SpeedBins,
    SpeedDependence,
};

use crate::error::to_py;

/// One experiment: its label, reference torque (N·m), sensor reading and speed (rad/s;
/// empty when not used).
type Rows<'py> = (String, PyReadonlyArray1<'py, f64>, PyReadonlyArray1<'py, f64>, PyReadonlyArray1<'py, f64>);

/// An experiment's rows copied out of Python (the GIL is released while they are fitted).
type Owned = (String, Vec<f64>, Vec<f64>, Vec<f64>);

/// Fits `model` (`gain`, `static`, `dynamic`, `speed-table`, `speed-poly`) to the
/// experiments as `strainwave calibrate` does, and returns the calibration file (TOML)
/// with `description`. `inputs` names the data in errors.
#[pyfunction]
#[pyo3(signature = (model, experiments, *, inputs, description, speed_column=String::new(), with_offset=false, full_scale=None, bins=None, speed_edges=None, degree=1, extrapolation=String::from("clamp")))]
#[allow(clippy::too_many_arguments)]
pub fn calibrate_experiments(
    py: Python<'_>,
    model: String,
    experiments: Vec<Rows<'_>>,
    inputs: String,
    description: String,
    speed_column: String,
    with_offset: bool,
    full_scale: Option<f64>,
    bins: Option<usize>,
    speed_edges: Option<Vec<f64>>,
    degree: usize,
    extrapolation: String,
) -> PyResult<String> {
    let exps: Vec<Owned> = experiments
        .iter()
        .map(|(l, r, s, v)| (l.clone(), r.as_array().to_vec(), s.as_array().to_vec(), v.as_array().to_vec()))
        .collect();
    py.detach(|| -> Result<String> {
        let extrapolation: Extrapolation =
            extrapolation.parse().map_err(|e| anyhow::anyhow!("--extrapolation: {e}"))?;
        let kind: ModelKind = model.parse().map_err(|e| anyhow::anyhow!("--model: {e}"))?;
        if kind != ModelKind::Gain && with_offset {
            bail!("--with-offset applies to --model gain (static and dynamic models always fit an offset)");
        }
        if (bins.is_some() || speed_edges.is_some()) && !matches!(kind, ModelKind::SpeedTable | ModelKind::Dynamic) {
            bail!("--bins / --speed-edges apply to --model speed-table (or dynamic with --speed)");
        }
        let table = || match &speed_edges {
            Some(e) => SpeedBins::Edges(e.clone()),
            None => SpeedBins::EqualWidth(bins.unwrap_or(3)),
        };
        // The experiments pooled, as the non-gain models fit them.
        let (mut sensor, mut reference, mut speed) = (Vec::new(), Vec::new(), Vec::new());
        for (_, r, s, v) in &exps {
            reference.extend_from_slice(r);
            sensor.extend_from_slice(s);
            speed.extend_from_slice(v);
        }
        let mut file = match kind {
            ModelKind::Gain => {
                let fit = if with_offset { GainFit::WithOffset } else { GainFit::ThroughOrigin };
                let e: Vec<Experiment> = exps.iter().map(|(l, r, s, _)| Experiment::new(l, r, s)).collect();
                calibrate_gain(&e, fit, full_scale).context("fitting the gain")?.to_file()
            }
            ModelKind::Static | ModelKind::Dynamic => {
                let f = fit_affine(&sensor, &reference, full_scale)
                    .with_context(|| format!("fitting the {model} model to {inputs}"))?;
                if kind == ModelKind::Static {
                    f.to_static_file()
                } else {
                    f.to_dynamic_file()
                }
            }
            ModelKind::SpeedTable | ModelKind::SpeedPoly => {
                let dep = if kind == ModelKind::SpeedTable {
                    SpeedDependence::Table(table())
                } else {
                    SpeedDependence::Polynomial { degree }
                };
                fit_speed_dependent(&sensor, &reference, &speed, &dep, extrapolation, full_scale)
                    .with_context(|| format!("fitting the speed model to {inputs} (speed column `{speed_column}`)"))?
                    .to_file()
            }
        };
        file.description = Some(description);
        Ok(file.to_toml_string()?)
    })
    .map_err(to_py)
}
