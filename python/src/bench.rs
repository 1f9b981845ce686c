//! `fuse_columns`: the bench's torque fusion of `strainwave fuse` on a caller's columns.

use std::path::PathBuf;

use numpy::{PyArray1, PyReadonlyArray1};
use pyo3::prelude::*;
use strainwave_bench::{BenchConfig, Fuse, Method};

use crate::columns::{to_numpy, Arrays, ColumnSink, ColumnSource};
use crate::error::to_py;

/// What `fuse_columns` returns: the added column names, their arrays and what the
/// command line prints about the design and the reference check.
type Fused<'py> = (Vec<String>, Vec<Bound<'py, PyArray1<f64>>>, String);

/// Fuses the columns `arrays` named `names` with the bench config `config` and `method`
/// as `strainwave fuse` does; returns only the column it adds (`fused_torque`) and the
/// text the command line prints. `reference` names a reference torque column to check
/// the fused torque's flatness against; `input_name` names the input in messages.
#[pyfunction]
#[pyo3(signature = (config, names, arrays, *, input_name, method=String::from("online-corrected"), reference=None))]
pub fn fuse_columns<'py>(
    py: Python<'py>,
    config: PathBuf,
    names: Vec<String>,
    arrays: Vec<PyReadonlyArray1<'py, f64>>,
    input_name: String,
    method: String,
    reference: Option<String>,
) -> PyResult<Fused<'py>> {
    let arrays = Arrays::new(&names, arrays)?;
    let slices = arrays.slices();
    let rows = slices.first().map_or(0, |c| c.len());
    let width = names.len();
    let (added, data, said) = py
        .detach(|| -> anyhow::Result<_> {
            let method = Method::parse(&method)?;
            let fuse = Fuse::new(BenchConfig::load(&config)?, &config, method)?;
            let mut source = ColumnSource::new(names, slices);
            let mut added = Vec::new();
            let mut data = Vec::new();
            let mut said = String::new();
            let mut say = |text: &str| -> anyhow::Result<()> {
                said.push_str(text);
                Ok(())
            };
            fuse.run(
                &mut source,
                |columns| {
                    added = columns[width.min(columns.len())..].iter().map(|c| c.to_string()).collect();
                    Ok(ColumnSink::new(&mut data, columns.len(), width, rows))
                },
                &input_name,
                reference.as_deref(),
                &mut say,
            )?;
            Ok((added, data, said))
        })
        .map_err(to_py)?;
    Ok((added, to_numpy(py, data), said))
}
