//! `strainwave simulate` for the arm presets.

use anyhow::{bail, Context, Result};
use strainwave_io::RecordingWriter;
use strainwave_sim::arm::{ArmExperiment, ArmScenario, ArmSimulator};

/// The arm scenario named by `name` (`hda-arm` or `hda-arm-<experiment>`), if it is one.
pub fn arm_preset(name: &str) -> Option<Result<ArmScenario>> {
    if name == "hda-arm" {
        return Some(ArmScenario::preset().context("preset hda-arm"));
    }
    let which = name.strip_prefix("hda-arm-")?;
    let Some(e) = ArmExperiment::ALL.into_iter().find(|e| e.name() == which) else {
        let names: Vec<String> = ArmExperiment::ALL.iter().map(|e| format!("hda-arm-{}", e.name())).collect();
        return Some(Err(anyhow::anyhow!("unknown arm preset `{name}`; known: hda-arm, {}", names.join(", "))));
    };
    Some(ArmScenario::experiment(e).with_context(|| format!("preset {name}")))
}

/// Runs the preset when it is one of this twin's; `Ok(false)` otherwise.
pub fn run(a: &super::Args) -> Result<bool> {
    let Some(name) = a.preset.as_deref() else { return Ok(false) };
    let Some(scenario) = arm_preset(name) else { return Ok(false) };
    let mut s = scenario?;
    super::overridden(&mut s, a.duration, a.seed)?;
    if a.print_scenario {
        crate::stdout::print(&s.to_toml())?;
        return Ok(true);
    }
    if a.procedure.is_some() {
        bail!("--procedure applies to the joint presets, not to `{name}`");
    }
    let Some(out) = a.out.as_deref() else { bail!("--out FILE is required") };
    let mut sim = ArmSimulator::new(&s)?;
    let columns = sim.columns();
    let mut w = RecordingWriter::create(out, &columns)?;
    let mut row = Vec::with_capacity(columns.len());
    while sim.next_row(&mut row) {
        w.write_row(&row)?;
    }
    let rows = w.finish()?;
    if !a.quiet {
        eprintln!(
            "simulated `{}`: {rows} rows at {} Hz ({} RK4 sub-steps per sample) -> {}",
            s.name,
            s.sample_rate_hz,
            sim.substeps(),
            out.display()
        );
    }
    Ok(true)
}
