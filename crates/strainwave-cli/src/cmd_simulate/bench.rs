//! `strainwave simulate` for the bench presets (`kit-bench`, `kit-bench-sweep`).

use anyhow::{bail, Result};
use strainwave_sim::bench::{preset, BenchSimulator, PRESET_NAMES};

/// Runs the preset when it is one of this twin's; `Ok(false)` otherwise.
pub fn run(a: &super::Args) -> Result<bool> {
    let Some(name) = a.preset.as_deref().filter(|n| PRESET_NAMES.contains(n)) else {
        return Ok(false);
    };
    let mut s = preset(name)?;
    super::overridden(&mut s, a.duration, a.seed)?;
    if a.print_scenario {
        crate::stdout::print(&s.to_toml())?;
        return Ok(true);
    }
    let Some(out) = a.out.as_deref() else {
        bail!("--out: give the output recording");
    };
    let mut sim = BenchSimulator::new(&s)?;
    let columns = sim.columns();
    let mut wtr = strainwave_io::RecordingWriter::create(out, &columns)?;
    let mut row = Vec::with_capacity(columns.len());
    while sim.next_row(&mut row) {
        wtr.write_row(&row)?;
    }
    let rows = wtr.finish()?;
    if !a.quiet {
        let (ts, acc) = sim.clipped_samples();
        eprintln!(
            "{}: {rows} rows × {} columns, {} s at {} Hz (seed {}; clipped: torsion {ts}, accelerometers {acc})",
            out.display(),
            columns.len(),
            s.duration_s,
            s.sample_rate_hz,
            s.seed
        );
    }
    Ok(true)
}
