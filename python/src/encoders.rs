//! `identify_runs` and `estimate_columns`: the encoder-based torque estimator of
//! `strainwave identify` and `strainwave estimate` on a caller's recordings.

use std::path::PathBuf;

use numpy::{PyArray1, PyReadonlyArray1};
use pyo3::prelude::*;
use strainwave_io::Table;
use strainwave_joint::estimate::Estimator;
use strainwave_joint::identify::{identify, load_config, IdentifyOptions, RunInput};

use crate::columns::{to_numpy, Arrays, ColumnSink, ColumnSource};
use crate::error::to_py;

/// A run as Python passes it: a file, or `(name, column names, arrays)`.
#[derive(FromPyObject)]
pub enum RunArg<'py> {
    /// A recording file.
    Path(PathBuf),
    /// Columns named `.0` in messages.
    Columns(String, Vec<String>, Vec<PyReadonlyArray1<'py, f64>>),
}

/// A run copied out of Python (the GIL is released while it is fitted).
enum OwnedRun {
    Path(PathBuf),
    Table(String, Table),
}

impl OwnedRun {
    fn new(run: RunArg<'_>) -> PyResult<Self> {
        Ok(match run {
            RunArg::Path(p) => OwnedRun::Path(p),
            RunArg::Columns(name, names, arrays) => {
                let arrays = Arrays::new(&names, arrays)?;
                let data = arrays.slices().iter().map(|c| c.to_vec()).collect();
                OwnedRun::Table(name, Table { columns: names, data })
            }
        })
    }

    fn input(&self) -> RunInput<'_> {
        match self {
            OwnedRun::Path(p) => RunInput::File(p),
            OwnedRun::Table(name, table) => RunInput::Table { table, name },
        }
    }
}

/// Fits the model of the arm configuration `config` on the `loaded` run (and `no_load`)
/// as `strainwave identify` does; returns the model file's text and the JSON summary
/// (`--summary-json`). With `out` the model file is written there too.
#[pyfunction]
#[pyo3(signature = (config, loaded, no_load=None, *, out=None, holdout=None, lenient=false, allow_unconverged=false))]
#[allow(clippy::too_many_arguments)]
pub fn identify_runs(
    py: Python<'_>,
    config: PathBuf,
    loaded: RunArg<'_>,
    no_load: Option<RunArg<'_>>,
    out: Option<PathBuf>,
    holdout: Option<usize>,
    lenient: bool,
    allow_unconverged: bool,
) -> PyResult<(String, String)> {
    let loaded = OwnedRun::new(loaded)?;
    let no_load = no_load.map(OwnedRun::new).transpose()?;
    py.detach(|| -> anyhow::Result<(String, String)> {
        if let Some(out) = &out {
            let mut inputs = vec![config.as_path()];
            for r in [Some(&loaded), no_load.as_ref()].into_iter().flatten() {
                if let OwnedRun::Path(p) = r {
                    inputs.push(p);
                }
            }
            strainwave_io::output::refuse_input_as_output(out, inputs)?;
        }
        let opts = IdentifyOptions { holdout, lenient };
        let cfg = load_config(&config, no_load.is_some(), &opts)?;
        let found = identify(&cfg, loaded.input(), no_load.as_ref().map(OwnedRun::input), &opts)?;
        found.refuse_unconverged(allow_unconverged)?;
        let text = found.model_text()?;
        if let Some(out) = &out {
            strainwave_io::output::write_file(out, text.clone())?;
        }
        Ok((text, found.summary.json()))
    })
    .map_err(to_py)
}

/// What `estimate_columns` returns: the added column names, their arrays and the
/// warning the command line prints (empty without one).
type Estimated<'py> = (Vec<String>, Vec<Bound<'py, PyArray1<f64>>>, String);

/// Runs the model file `config` (written by `identify`) over the columns `arrays` named
/// `names`, as `strainwave estimate` does; returns only the columns it adds. `input_name`
/// names the input in messages.
#[pyfunction]
#[pyo3(signature = (config, names, arrays, *, input_name))]
pub fn estimate_columns<'py>(
    py: Python<'py>,
    config: PathBuf,
    names: Vec<String>,
    arrays: Vec<PyReadonlyArray1<'py, f64>>,
    input_name: String,
) -> PyResult<Estimated<'py>> {
    let arrays = Arrays::new(&names, arrays)?;
    let slices = arrays.slices();
    let rows = slices.first().map_or(0, |c| c.len());
    let width = names.len();
    let (added, data, warning) = py
        .detach(|| -> anyhow::Result<_> {
            let est = Estimator::load(&config)?;
            let mut source = ColumnSource::new(names, slices);
            let mut added = Vec::new();
            let mut data = Vec::new();
            let summary = est.run(
                &mut source,
                |columns| {
                    added = columns[width.min(columns.len())..].iter().map(|c| c.to_string()).collect();
                    Ok(ColumnSink::new(&mut data, columns.len(), width, rows))
                },
                &input_name,
            )?;
            Ok((added, data, summary.warning().unwrap_or_default()))
        })
        .map_err(to_py)?;
    Ok((added, to_numpy(py, data), warning))
}
