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

/// The arm presets' names.
pub fn preset_names() -> impl Iterator<Item = String> {
    std::iter::once("hda-arm".to_string()).chain(ArmExperiment::ALL.iter().map(|e| format!("hda-arm-{}", e.name())))
}

/// Runs the arm preset or scenario file of `a`.
pub fn run(a: &super::Args) -> Result<()> {
    let (mut s, name) = match (a.preset.as_deref(), a.scenario.as_deref()) {
        (Some(name), _) => (arm_preset(name).context("not an arm preset")??, name.to_string()),
        (None, Some(path)) => {
            let s = ArmScenario::from_toml(&super::scenario_text(path)?)
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
        bail!("--procedure applies to the joint twin, not to the arm (`{name}`)");
    }
    let Some(out) = a.out.as_deref() else { bail!("--out FILE is required") };
    let mut sim = ArmSimulator::new(&s)?;
    let columns = sim.columns();
    let mut w = RecordingWriter::create(out, &columns)?;
    let mut row = Vec::with_capacity(columns.len());
    while sim.next_row(&mut row) {
        super::finite_row(&row, &columns, &name)?;
        w.write_row(&row)?;
    }
    let rows = w.finish()?;
    if !a.quiet {
        note!(
            "simulated `{}`: {rows} rows at {} Hz ({} RK4 sub-steps per sample) -> {}",
            s.name,
            s.sample_rate_hz,
            sim.substeps(),
            out.display()
        );
    }
    Ok(())
}
