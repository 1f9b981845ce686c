//! `strainwave._native`: the Rust side of the `strainwave` Python package.
//!
//! Each function takes and returns plain column arrays (a list of names and a list of
//! one-dimensional `float64` numpy arrays); the Python package wraps them in pandas
//! DataFrames. Rust work runs with the GIL released, and every error is a
//! `strainwave.StrainwaveError` carrying the command line's one-line message.

use pyo3::prelude::*;

mod bench;
mod calibrate;
mod canceller;
mod columns;
mod encoders;
mod error;
mod filter;
mod recording;
mod simulate;
mod spectra;

/// The extension module.
#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("StrainwaveError", m.py().get_type::<error::StrainwaveError>())?;
    m.add_function(wrap_pyfunction!(recording::read_recording, m)?)?;
    m.add_function(wrap_pyfunction!(recording::write_recording, m)?)?;
    m.add_function(wrap_pyfunction!(filter::filter_columns, m)?)?;
    m.add_function(wrap_pyfunction!(filter::filter_file, m)?)?;
    m.add_function(wrap_pyfunction!(simulate::simulate, m)?)?;
    m.add_class::<canceller::RippleCanceller>()?;
    m.add_function(wrap_pyfunction!(calibrate::calibrate_experiments, m)?)?;
    m.add_function(wrap_pyfunction!(spectra::welch_psd, m)?)?;
    m.add_function(wrap_pyfunction!(spectra::stft_frames, m)?)?;
    m.add_function(wrap_pyfunction!(spectra::order_slice_blocks, m)?)?;
    m.add_function(wrap_pyfunction!(encoders::identify_runs, m)?)?;
    m.add_function(wrap_pyfunction!(encoders::estimate_columns, m)?)?;
    m.add_function(wrap_pyfunction!(bench::fuse_columns, m)?)?;
    m.add("OUTPUT_COLUMNS", strainwave_joint::OUTPUT_COLUMNS.to_vec())?;
    Ok(())
}
