//! `strainwave filter --smooth`: the offline zero-phase smoother.

use anyhow::{bail, Result};
use strainwave_core::ripple::{RippleInput, RippleModel};
use strainwave_io::RecordingReader;

/// Runs the smoother over the whole recording.
pub fn smooth<const M: usize>(
    a: &crate::cmd_filter::Args,
    _model: &RippleModel<f64, M>,
    _gear: &strainwave_core::gear::Gear<f64>,
    _cal: &strainwave_core::calibration::Calibration<f64, { crate::joint_config::MAX_TABLE_LEN }>,
    _r: &mut RecordingReader,
    _columns: &[&str],
    _inputs: impl Fn(&[f64]) -> (RippleInput<f64>, bool),
) -> Result<()> {
    bail!("{}: --smooth is not available in this build", a.input.display())
}
