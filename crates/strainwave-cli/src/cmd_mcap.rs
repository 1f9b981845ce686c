//! MCAP input for `convert` (ROS 2 logs).

use anyhow::{bail, Result};

/// Converts an MCAP log to a recording.
pub fn convert(a: &crate::cmd_convert::Args) -> Result<()> {
    bail!("{}: MCAP input is not built into this version yet", a.input.display())
}
