//! `strainwave estimate`: link torque from the motor and link encoders with a model
//! written by `identify`, streamed row by row. When the model holds friction and rotor
//! inertia (identified against a motor-current torque), a `current_torque` column gives
//! the motor-current torque the model predicts, to check against a log that has only current.
//! The job is `strainwave_joint::estimate`; this module maps the flags onto it.

use std::path::PathBuf;

use anyhow::{bail, Result};
use strainwave_io::{RecordingReader, RecordingWriter};
use strainwave_joint::estimate::Estimator;

/// Arguments of `estimate`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Model TOML written by `strainwave identify`.
    #[arg(long)]
    pub config: PathBuf,
    /// Input recording.
    #[arg(long = "in")]
    pub input: PathBuf,
    /// Output recording: the input columns plus torque, torsion, kinematic_error,
    /// estimate_flags (and current_torque when the model has friction).
    #[arg(long)]
    pub out: PathBuf,
    /// No summary on stderr.
    #[arg(long, short)]
    pub quiet: bool,
}

/// Runs `estimate`.
pub fn run(a: &Args) -> Result<()> {
    strainwave_io::output::refuse_input_as_output(&a.out, [a.input.as_path(), a.config.as_path()])?;
    if strainwave_io::default_read_options().resample_hz.is_some() {
        // Interpolated counts are not counts (and a wrap between two rows would be averaged).
        bail!("--resample-hz interpolates the encoder counts, which must stay whole: estimate first, then resample");
    }
    let est = Estimator::load(&a.config)?;
    // The reader's errors name the file.
    let mut reader = RecordingReader::open(&a.input)?;
    if let Some(time) = est.time_channel() {
        reader.set_time_channel(time);
    }
    let input = a.input.display().to_string();
    let s = est.run(&mut reader, |names| Ok(RecordingWriter::create(&a.out, names)?), &input)?;
    for w in s.warning().iter().flat_map(|w| w.lines()) {
        note!("warning: {w}");
    }
    if !a.quiet {
        note!("estimated {} rows ({} with counter wraps) -> {}", s.rows, s.wraps, a.out.display());
    }
    Ok(())
}
