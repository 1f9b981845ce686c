//! Recordings in and out: any format the command line reads, as named columns.

use std::path::PathBuf;

use numpy::PyReadonlyArray1;
use pyo3::prelude::*;
use strainwave_io::{RecordingReader, RecordingWriter, Table};

use crate::columns::{to_numpy, Arrays, Columns};
use crate::error::to_py;

/// Reads the whole recording at `path` (CSV, Parquet, MCAP: the format its name says) into
/// the reader's warnings, and its column names and one array per column.
#[pyfunction]
pub fn read_recording(py: Python<'_>, path: PathBuf) -> PyResult<(Vec<String>, Columns<'_>)> {
    let (table, warnings) = py
        .detach(|| -> anyhow::Result<_> {
            let mut r = RecordingReader::open(&path)?;
            let names = r.columns().to_vec();
            let table = Table::collect(&path, &names, |row| r.read_row(row))?;
            // What the command line prints as warnings (a log cut short, repeated stamps).
            Ok((table, r.warnings().to_vec()))
        })
        .map_err(to_py)?;
    Ok((warnings, (table.columns, to_numpy(py, table.data))))
}

/// Writes the columns `arrays` named `names` to `path` (CSV or Parquet by its name), as
/// `strainwave` writes its outputs; returns the rows written.
#[pyfunction]
pub fn write_recording(
    py: Python<'_>,
    path: PathBuf,
    names: Vec<String>,
    arrays: Vec<PyReadonlyArray1<'_, f64>>,
) -> PyResult<u64> {
    let arrays = Arrays::new(&names, arrays)?;
    let slices = arrays.slices();
    py.detach(|| -> anyhow::Result<u64> {
        let refs: Vec<&str> = names.iter().map(String::as_str).collect();
        let mut w = RecordingWriter::create(&path, &refs)?;
        let rows = slices.first().map_or(0, |c| c.len());
        let mut row = Vec::with_capacity(slices.len());
        for k in 0..rows {
            row.clear();
            row.extend(slices.iter().map(|c| c[k]));
            w.write_row(&row)?;
        }
        Ok(w.finish()?)
    })
    .map_err(to_py)
}
