//! `strainwave simulate`: scenario or preset in, recording out.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use strainwave_io::RecordingWriter;
use strainwave_sim::{presets, Scenario, Simulator};

mod arm;
mod bench;

/// Arguments of `simulate`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// A built-in scenario: taghirad (Taghirad rig), flexspline-fixed (embedded-sensor
    /// rig), kit-bench (motor test bench) or hda-arm (robot arm), and their variants.
    #[arg(long, conflicts_with = "scenario", required_unless_present = "scenario")]
    pub preset: Option<String>,
    /// A scenario TOML file (start one from `--preset NAME --print-scenario`).
    #[arg(long)]
    pub scenario: Option<PathBuf>,
    /// Output recording (.csv, .tsv, .parquet or .mcap, by its extension; `-` for CSV on
    /// standard output).
    #[arg(long, required_unless_present = "print_scenario")]
    pub out: Option<PathBuf>,
    /// Override the scenario's duration, s.
    #[arg(long)]
    pub duration: Option<f64>,
    /// Override the scenario's random seed.
    #[arg(long)]
    pub seed: Option<u64>,
    /// Run a calibration procedure on the scenario's sensor instead of the joint:
    /// `locked-wg` (Taghirad and Bélanger (1999): wave generator locked, arm and weights, loading and
    /// unloading both ways, four flexspline positions × low/full range, 5–35 °C).
    #[arg(long, value_parser = ["locked-wg"])]
    pub procedure: Option<String>,
    /// Print the scenario as TOML and exit.
    #[arg(long)]
    pub print_scenario: bool,
    /// No summary on stderr.
    #[arg(long, short)]
    pub quiet: bool,
}

/// The twin a scenario is for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Twin {
    Joint,
    Arm,
    Bench,
}

/// Which twin `--preset` or `--scenario` names: a preset by its name, a file by the tables
/// only that twin's scenario has (`[mechanics]` the bench's, `[controller]` the arm's).
fn twin(a: &Args) -> Result<Twin> {
    if let Some(name) = a.preset.as_deref() {
        return Ok(if strainwave_sim::bench::PRESET_NAMES.contains(&name) {
            Twin::Bench
        } else if arm::arm_preset(name).is_some() {
            Twin::Arm
        } else if presets::PRESETS.iter().any(|(n, _)| *n == name) {
            Twin::Joint
        } else {
            bail!("unknown preset `{name}` (known: {})", preset_names().join(", "))
        });
    }
    let Some(path) = a.scenario.as_deref() else { return Ok(Twin::Joint) };
    let text = std::fs::read_to_string(path).with_context(|| format!("{}", path.display()))?;
    let Ok(table) = text.parse::<toml::Table>() else { return Ok(Twin::Joint) };
    Ok(if table.contains_key("mechanics") {
        Twin::Bench
    } else if table.contains_key("controller") {
        Twin::Arm
    } else {
        Twin::Joint
    })
}

/// Every preset of every twin.
fn preset_names() -> Vec<String> {
    let joint = presets::PRESETS.iter().map(|(n, _)| n.to_string());
    let bench = strainwave_sim::bench::PRESET_NAMES.iter().map(|n| n.to_string());
    joint.chain(bench).chain(arm::preset_names()).collect()
}

/// The text of a `--scenario` file (for the arm and bench twins).
fn scenario_text(path: &Path) -> Result<String> {
    std::fs::read_to_string(path).with_context(|| format!("{}", path.display()))
}

/// Loads the scenario named by `--preset` or `--scenario`, with overrides applied.
pub fn load_scenario(
    preset: Option<&str>,
    file: Option<&Path>,
    duration: Option<f64>,
    seed: Option<u64>,
) -> Result<Scenario> {
    let mut s = match (preset, file) {
        (Some(name), _) => presets::preset(name)?,
        (None, Some(path)) => {
            let text = std::fs::read_to_string(path).with_context(|| format!("{}", path.display()))?;
            Scenario::from_toml(&text).with_context(|| format!("scenario {}", path.display()))?
        }
        (None, None) => bail!("give --preset NAME or --scenario FILE"),
    };
    overridden(&mut s, duration, seed)?;
    Ok(s)
}

/// A twin's scenario as `simulate` adjusts it: `--duration`, `--seed`, then the check.
pub trait Adjustable {
    /// Sets the run length, s.
    fn set_duration_s(&mut self, duration_s: f64);
    /// Sets the noise seed.
    fn set_seed(&mut self, seed: u64);
    /// Checks every value; the error names the key.
    fn check(&self) -> Result<(), strainwave_sim::SimError>;
}

macro_rules! adjustable {
    ($($t:ty),*) => {$(
        impl Adjustable for $t {
            fn set_duration_s(&mut self, duration_s: f64) {
                self.duration_s = duration_s;
            }
            fn set_seed(&mut self, seed: u64) {
                self.seed = seed;
            }
            fn check(&self) -> Result<(), strainwave_sim::SimError> {
                self.validate()
            }
        }
    )*};
}
adjustable!(Scenario, strainwave_sim::arm::ArmScenario, strainwave_sim::bench::BenchScenario);

/// `--duration` and `--seed` applied to `s`, then its values checked (the error names
/// `--duration` when one was given).
pub fn overridden<S: Adjustable>(s: &mut S, duration: Option<f64>, seed: Option<u64>) -> Result<()> {
    if let Some(d) = duration {
        s.set_duration_s(d);
    }
    if let Some(seed) = seed {
        s.set_seed(seed);
    }
    s.check().context(if duration.is_some() { "--duration" } else { "scenario" })?;
    Ok(())
}

/// Runs `simulate`.
/// A row of a twin's recording: every value finite, else an error naming the scenario,
/// the first column that is not and the time (an extreme scenario value makes the
/// dynamics or a sensor's reading overflow; the row is not written).
pub fn finite_row(row: &[f64], columns: &[&str], scenario: &str) -> Result<()> {
    if let Some(k) = row.iter().position(|v| !v.is_finite()) {
        bail!(
            "{scenario}: column `{}` is not finite at t = {} s ({}): look for an extreme value among the \
             scenario's keys",
            columns.get(k).unwrap_or(&"?"),
            row.first().copied().unwrap_or(f64::NAN),
            row[k]
        );
    }
    Ok(())
}

pub fn run(a: &Args) -> Result<()> {
    if let Some(out) = &a.out {
        strainwave_io::output::refuse_input_as_output(out, a.scenario.as_deref())?;
    }
    // The arm and bench twins have their own presets and scenarios.
    match twin(a)? {
        Twin::Arm => return arm::run(a),
        Twin::Bench => return bench::run(a),
        Twin::Joint => {}
    }
    if a.print_scenario {
        match (&a.preset, &a.scenario) {
            (Some(name), _) if a.duration.is_none() && a.seed.is_none() => {
                crate::stdout::print(presets::preset_text(name)?)?
            }
            _ => crate::stdout::print(
                &load_scenario(a.preset.as_deref(), a.scenario.as_deref(), a.duration, a.seed)?.to_toml(),
            )?,
        }
        return Ok(());
    }
    let scenario = load_scenario(a.preset.as_deref(), a.scenario.as_deref(), a.duration, a.seed)?;
    let Some(out) = a.out.as_deref() else { bail!("--out FILE is required") };
    // What the twin builds from the scenario (its sensor) is checked as it is built: an
    // error there names the scenario file.
    let source =
        || a.scenario.as_deref().map_or_else(|| "scenario".to_string(), |p| format!("scenario {}", p.display()));
    if a.procedure.is_some() {
        let run = strainwave_sim::calibration_rig::LockedWgProcedure::default().run(&scenario).with_context(source)?;
        let mut w = RecordingWriter::create(out, strainwave_sim::calibration_rig::COLUMNS)?;
        for r in &run.rows {
            w.write_row(r)?;
        }
        let rows = w.finish()?;
        if !a.quiet {
            let (mean, consistency) = run.true_gain_and_consistency();
            note!(
                "locked-wg calibration procedure on `{}`: {} experiments, {rows} readings -> {}; true gain {:.4} N·m/V, consistency {:.2} %",
                scenario.name,
                run.true_gains.len(),
                out.display(),
                mean,
                100.0 * consistency
            );
        }
        return Ok(());
    }
    let mut sim = Simulator::new(&scenario).with_context(source)?;
    let columns = sim.columns();
    let mut w = RecordingWriter::create(out, &columns)?;
    let mut row = Vec::with_capacity(columns.len());
    while sim.next_row(&mut row) {
        if sim.diverged_at_s().is_none() {
            finite_row(&row, &columns, &source())?;
        }
        w.write_row(&row)?;
    }
    if let Some(t) = sim.diverged_at_s() {
        bail!(
            "{}: the joint's dynamics diverged at t = {t} s (its true values are no longer finite); \
             look for an extreme value among the gear, motor and load keys",
            source()
        );
    }
    let rows = w.finish()?;
    if !a.quiet {
        let sensor = sim.sensor();
        note!(
            "simulated `{}`: {rows} rows at {} Hz ({} RK4 sub-steps per sample) -> {}",
            scenario.name,
            scenario.sample_rate_hz,
            sim.substeps(),
            out.display()
        );
        note!(
            "sensor: true gain {:.4} N·m/V, full scale {:.1} N·m, white-noise floor {:.4} N·m rms",
            sensor.gain_nm_per_v(),
            sensor.full_scale_nm(),
            sensor.noise_floor_nm()
        );
        if sim.clipped_samples() > 0 {
            note!(
                "warning: the ADC clipped on {} samples (bridge_voltage saturated at ±{} V)",
                sim.clipped_samples(),
                scenario.sensor.adc_range_v
            );
        }
    }
    Ok(())
}
