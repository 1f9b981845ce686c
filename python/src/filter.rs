//! `filter_columns`: the joint's canceller over a caller's columns, exactly as
//! `strainwave filter` runs it over a file.

use std::path::PathBuf;

use numpy::{PyArray1, PyReadonlyArray1};
use pyo3::prelude::*;
use strainwave_joint::{filter_recording, FilterOptions, JointConfig};

use crate::columns::{to_numpy, Arrays, ColumnSink, ColumnSource};
use crate::error::to_py;

/// What `filter_columns` returns: the added column names, their arrays, the notes, the
/// warnings and the count of samples the calibration extrapolated.
type Filtered<'py> = (Vec<String>, Vec<Bound<'py, PyArray1<f64>>>, Vec<String>, Vec<String>, u64);

/// Runs the canceller of the joint config `config` over the columns `arrays` named
/// `names`; returns only the columns it adds. `input_name` names the input in messages.
#[pyfunction]
#[pyo3(signature = (config, names, arrays, *, input_name, smooth=false, lenient=false, prefix=String::new(), learn=None, scratch_dir=None))]
#[allow(clippy::too_many_arguments)]
pub fn filter_columns<'py>(
    py: Python<'py>,
    config: PathBuf,
    names: Vec<String>,
    arrays: Vec<PyReadonlyArray1<'py, f64>>,
    input_name: String,
    smooth: bool,
    lenient: bool,
    prefix: String,
    learn: Option<PathBuf>,
    scratch_dir: Option<PathBuf>,
) -> PyResult<Filtered<'py>> {
    let arrays = Arrays::new(&names, arrays)?;
    let slices = arrays.slices();
    let rows = slices.first().map_or(0, |c| c.len());
    let width = names.len();
    let opts = FilterOptions { input_name, smooth, learn, prefix, lenient, streaming_output: false, scratch_dir };
    let (added, data, summary) = py
        .detach(|| -> anyhow::Result<_> {
            let cfg = JointConfig::load(&config)?;
            let mut source = ColumnSource::new(names, slices);
            let mut added = Vec::new();
            let mut data = Vec::new();
            let summary = filter_recording(
                &cfg,
                &mut source,
                |columns| {
                    added = columns[width.min(columns.len())..].iter().map(|c| c.to_string()).collect();
                    Ok(ColumnSink::new(&mut data, columns.len(), width, rows))
                },
                &opts,
                &mut |_| {},
            )?;
            Ok((added, data, summary))
        })
        .map_err(to_py)?;
    Ok((added, to_numpy(py, data), summary.notes, summary.warnings, summary.extrapolated))
}

/// What `filter_file` returns: the rows written, the notes, the warnings and the count of
/// samples the calibration extrapolated.
type FiledSummary = (u64, Vec<String>, Vec<String>, u64);

/// `strainwave filter --config CONFIG --in INPUT --out OUTPUT` in this process: the
/// recording streamed from file to file in constant memory, no arrays through Python
/// (what a fleet's worker runs). `input_name` names the input in messages.
#[pyfunction]
#[pyo3(signature = (config, input, output, *, smooth=false, lenient=false, prefix=String::new()))]
pub fn filter_file(
    py: Python<'_>,
    config: PathBuf,
    input: PathBuf,
    output: PathBuf,
    smooth: bool,
    lenient: bool,
    prefix: String,
) -> PyResult<FiledSummary> {
    py.detach(|| -> anyhow::Result<FiledSummary> {
        strainwave_io::output::refuse_input_as_output(&output, [input.as_path(), config.as_path()])?;
        let cfg = JointConfig::load(&config)?;
        let scratch_dir = match output.parent() {
            Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
            _ => PathBuf::from("."),
        };
        let opts = FilterOptions {
            input_name: input.display().to_string(),
            smooth,
            learn: None,
            prefix,
            lenient,
            streaming_output: false,
            scratch_dir: Some(scratch_dir),
        };
        let mut reader = strainwave_io::RecordingReader::open(&input)?;
        let create = |columns: &[&str]| -> anyhow::Result<strainwave_io::RecordingWriter> {
            Ok(strainwave_io::RecordingWriter::create(&output, columns)?)
        };
        let s = filter_recording(&cfg, &mut reader, create, &opts, &mut |_| {})?;
        Ok((s.rows, s.notes, s.warnings, s.extrapolated))
    })
    .map_err(to_py)
}
