//! `strainwave identify`: fit the kinematic error and the compliance of an
//! encoder-based torque estimator from recorded runs, and write the model `estimate`
//! reads.
//!
//! The job (config, fits, model, summary) is `strainwave_joint::identify`; this module
//! maps the flags onto it, writes the files and prints the table.

use std::path::PathBuf;

use anyhow::Result;
use strainwave_joint::identify::{identify, load_config, IdentifyOptions, RunInput};

mod report;

/// Arguments of `identify`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Arm configuration (gear, channels, encoders, model choices); see examples/arm-hda.toml.
    #[arg(long)]
    pub config: PathBuf,
    /// No-load recording (the joint turns slowly, no load): fits the kinematic error.
    /// Without it the kinematic error's mesh harmonics come from the loaded run.
    #[arg(long)]
    pub no_load: Option<PathBuf>,
    /// Loaded recording with a reference torque: fits the compliance.
    #[arg(long)]
    pub loaded: PathBuf,
    /// Output model TOML (read by `estimate --config`).
    #[arg(long)]
    pub out: PathBuf,
    /// Also score the model out of sample: the loaded run cut into K contiguous blocks,
    /// each predicted by a model identified on the others, beside the plain linear fit.
    #[arg(long, value_name = "K")]
    pub holdout: Option<usize>,
    /// Write the model even when the Levenberg–Marquardt fit did not converge (else exit 1).
    #[arg(long)]
    pub allow_unconverged: bool,
    /// Skip rows with a non-finite value in a used column (counted in the summary)
    /// instead of stopping at the first; a text cell that is not a number (`OVL`) is read
    /// as NaN.
    #[arg(long)]
    pub lenient: bool,
    /// Write a JSON summary (fits, parameters with standard errors, holdout) here.
    #[arg(long, value_name = "PATH")]
    pub summary_json: Option<PathBuf>,
    /// No metrics table on stdout.
    #[arg(long, short)]
    pub quiet: bool,
}

/// Runs `identify`.
pub fn run(a: &Args) -> Result<()> {
    let mut inputs = vec![a.loaded.as_path(), a.config.as_path()];
    inputs.extend(a.no_load.as_deref());
    for out in std::iter::once(&a.out).chain(&a.summary_json) {
        strainwave_io::output::refuse_input_as_output(out, inputs.iter().copied())?;
    }
    strainwave_io::output::refuse_shared_outputs(
        [("--out", a.out.as_path())].into_iter().chain(a.summary_json.as_deref().map(|p| ("--summary-json", p))),
    )?;
    let opts = IdentifyOptions { holdout: a.holdout, lenient: a.lenient };
    let cfg = load_config(&a.config, a.no_load.is_some(), &opts)?;
    let found = identify(&cfg, RunInput::File(&a.loaded), a.no_load.as_deref().map(RunInput::File), &opts)?;
    if let Some(p) = &a.summary_json {
        strainwave_io::output::write_file(p, found.summary.json())?;
    }
    found.refuse_unconverged(a.allow_unconverged)?;
    strainwave_io::output::write_file(&a.out, found.model_text()?)?;
    if !a.quiet {
        let outputs = [Some(a.out.as_path()), a.summary_json.as_deref()];
        crate::stdout::print_report(&report::table(&found.summary, &a.out), outputs)?;
    }
    Ok(())
}
