//! `strainwave simulate` for the bench presets (`kit-bench`, `kit-bench-sweep`).

use anyhow::{bail, Context, Result};
use strainwave_sim::bench::{preset, BenchScenario, BenchSimulator};

/// Runs the bench preset or scenario file of `a`.
pub fn run(a: &super::Args) -> Result<()> {
    let (mut s, name) = match (a.preset.as_deref(), a.scenario.as_deref()) {
        (Some(name), _) => (preset(name)?, name.to_string()),
        (None, Some(path)) => {
            let s = BenchScenario::from_toml(&super::scenario_text(path)?)
                .with_context(|| format!("scenario {}", path.display()))?;
            (s, path.display().to_string())
        }
        (None, None) => bail!("give --preset NAME or --scenario FILE"),
    };
    super::overridden(&mut s, a.duration, a.seed)?;
    if a.print_scenario {
        crate::stdout::print(&s.to_toml())?;
        return Ok(());
    }
    if a.procedure.is_some() {
        bail!("--procedure applies to the joint twin, not to the bench (`{name}`)");
    }
    let Some(out) = a.out.as_deref() else {
        bail!("--out: give the output recording");
    };
    let mut sim = BenchSimulator::new(&s)?;
    let columns = sim.columns();
    let mut wtr = strainwave_io::RecordingWriter::create(out, &columns)?;
    let mut row = Vec::with_capacity(columns.len());
    while sim.next_row(&mut row) {
        super::finite_row(&row, &columns, &name)?;
        wtr.write_row(&row)?;
    }
    let rows = wtr.finish()?;
    if !a.quiet {
        let (ts, acc) = sim.clipped_samples();
        note!(
            "{}: {rows} rows × {} columns, {} s at {} Hz (seed {}; clipped: torsion {ts}, accelerometers {acc})",
            out.display(),
            columns.len(),
            s.duration_s,
            s.sample_rate_hz,
            s.seed
        );
    }
    Ok(())
}
