//! The demo's calibration section.

use anyhow::Result;

use crate::report::plot::LinePlot;

/// Text for the terminal, HTML for the report, plots.
pub fn section() -> Result<(String, String, Vec<LinePlot>)> {
    Ok((String::new(), String::new(), Vec::new()))
}
