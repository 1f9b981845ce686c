//! The joint's twin: a preset or scenario file run to columns.

use std::path::PathBuf;

use anyhow::{bail, Context};
use pyo3::prelude::*;
use strainwave_sim::{presets, Scenario, Simulator};

use crate::columns::{to_numpy, Columns};
use crate::error::to_py;

/// Runs the joint twin of the preset `preset` (or the scenario TOML `scenario`), with the
/// duration (s) and seed overridden when given, as `strainwave simulate` does; returns
/// column names and arrays (measured channels, then the `true_*` columns).
#[pyfunction]
#[pyo3(signature = (preset=None, *, scenario=None, duration=None, seed=None))]
pub fn simulate(
    py: Python<'_>,
    preset: Option<String>,
    scenario: Option<PathBuf>,
    duration: Option<f64>,
    seed: Option<u64>,
) -> PyResult<Columns<'_>> {
    let (names, data) = py
        .detach(|| -> anyhow::Result<_> {
            let mut s = match (&preset, &scenario) {
                (Some(name), None) => presets::preset(name)?,
                (None, Some(path)) => {
                    let text = std::fs::read_to_string(path).with_context(|| format!("{}", path.display()))?;
                    Scenario::from_toml(&text).with_context(|| format!("scenario {}", path.display()))?
                }
                _ => bail!("give a preset name or scenario=FILE (one of them)"),
            };
            if let Some(d) = duration {
                s.duration_s = d;
            }
            if let Some(seed) = seed {
                s.seed = seed;
            }
            s.validate().context(if duration.is_some() { "duration" } else { "scenario" })?;
            let mut sim = Simulator::new(&s)?;
            let names: Vec<String> = sim.columns().iter().map(|c| c.to_string()).collect();
            // The run is held in memory whole: bounded as a recording read whole is.
            let values = sim.len().saturating_mul(names.len() as u64);
            if values > strainwave_io::MAX_TABLE_VALUES {
                bail!(
                    "duration: {} samples × {} columns is more than {} values (1 GiB) in memory; \
                     write it to a file with `strainwave simulate --out` instead",
                    sim.len(),
                    names.len(),
                    strainwave_io::MAX_TABLE_VALUES
                );
            }
            // Room for the whole run, up to a bound (a very long run grows as it goes).
            let rows = usize::try_from(sim.len()).unwrap_or(0).min(1 << 22);
            let mut data: Vec<Vec<f64>> = names.iter().map(|_| Vec::with_capacity(rows)).collect();
            let mut row = Vec::with_capacity(names.len());
            while sim.next_row(&mut row) {
                for (c, v) in data.iter_mut().zip(&row) {
                    c.push(*v);
                }
            }
            Ok((names, data))
        })
        .map_err(to_py)?;
    Ok((names, to_numpy(py, data)))
}
