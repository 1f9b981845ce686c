//! `strainwave filter`: the real-time ripple and misalignment canceller over a
//! recording, streaming in constant memory (or the offline smoother with `--smooth`).

use std::path::{Path, PathBuf};

use anyhow::{bail, Result};
use strainwave_io::{IoError, RecordingWriter};
use strainwave_joint::run::RowSink;
use strainwave_joint::{filter_recording, FilterOptions, JointConfig};

/// Arguments of `filter`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Joint configuration (gear, channels, calibration, filter); see examples/joint-taghirad.toml.
    #[arg(long)]
    pub config: PathBuf,
    /// Input recording (any format `convert` reads; `-` for text on standard input). With --learn,
    /// several recordings may follow (`--in a.csv b.csv`): each run is learned from and
    /// merged into FILE in turn; --out then takes the last run's output, or is left out.
    #[arg(long = "in", required = true, num_args = 1..)]
    pub input: Vec<PathBuf>,
    /// Output recording: the input columns plus torque, ripple, misalignment, innovation, nis,
    /// filter_flags (bits 0-7 the canceller's, 8-12 the do-no-harm guard's: pass-through,
    /// order withheld, order contradicted, standstill bound, load-scaled order withheld
    /// on a glitched load step; bit 16 + i: order i not applied); then torque_denoised when the config sets `filter.torque_bandwidth_hz`
    /// (causal, the clean torque filtered as a torque state: group delay at DC
    /// (1 − α)/(α fs) with α = 1 − exp(−2π f/fs), about 1/(2π f), e.g. 16 ms at 10 Hz; load
    /// steps restart it); then, with --smooth, torque_smoothed and torque_smoothed_sd.
    #[arg(long, required_unless_present = "learn")]
    pub out: Option<PathBuf>,
    /// Offline: forward filter plus Rauch–Tung–Striebel smoother (zero phase; reads the whole
    /// recording). `torque` stays the measurement minus the smoothed ripple and misalignment;
    /// torque_smoothed is that torque smoothed as a level-and-rate torque state (60 Hz, zero
    /// phase, white noise averaged out; a jump beyond 4σ restarts it, so load steps stay
    /// sharp), torque_smoothed_sd its 1σ band (the noise's share of its error).
    #[arg(long)]
    pub smooth: bool,
    /// Learn from this run (any run: a canceller of the same joint learns cold beside
    /// the output filter) and write what it learned to FILE, for `filter.learned`. An
    /// existing FILE of the same joint is merged with the run by the coefficients'
    /// covariances; a FILE of another joint is refused. An order analysis of the
    /// innovation adds the lines the model lacks (reported). See docs/commissioning.md.
    #[arg(long, value_name = "FILE", conflicts_with = "smooth")]
    pub learn: Option<PathBuf>,
    /// Prefix for the added columns (when the input already has a `torque` column).
    #[arg(long, default_value = "")]
    pub prefix: String,
    /// Go on over bad rows instead of stopping at the first: samples with a non-finite
    /// torque or angle are skipped by the canceller (flag bits 0-1 in filter_flags) and
    /// time that does not move forward restarts the phase; a text cell that is not a
    /// number (`OVL`) is read as NaN; counts are reported at the end.
    #[arg(long)]
    pub lenient: bool,
    /// No summary on stderr.
    #[arg(long, short)]
    pub quiet: bool,
}

/// Runs `filter`.
pub fn run(a: &Args) -> Result<()> {
    if a.input.len() > 1 && a.learn.is_none() {
        bail!("several --in recordings need --learn (each is learned from in turn)");
    }
    if a.learn.as_deref().is_some_and(strainwave_io::output::is_stdout) {
        // The learned file is read back and merged into: it must be a file.
        bail!("--learn -: the learned file is a file the next run merges into; name one");
    }
    let inputs: Vec<&Path> = a.input.iter().map(PathBuf::as_path).collect();
    for out in a.out.iter().chain(&a.learn) {
        strainwave_io::output::refuse_input_as_output(out, inputs.iter().copied().chain([a.config.as_path()]))?;
    }
    let outputs = [("--out", &a.out), ("--learn", &a.learn)];
    strainwave_io::output::refuse_shared_outputs(outputs.into_iter().filter_map(|(f, p)| Some((f, p.as_deref()?))))?;
    let cfg = JointConfig::load(&a.config)?;
    // The files the config reads are inputs too (`--learn` may update the learned file).
    let calibration = cfg.calibration.as_ref().and_then(|c| c.file.as_deref());
    if let Some(out) = &a.out {
        strainwave_io::output::refuse_input_as_output(out, cfg.files_named())?;
    }
    if let Some(learn) = &a.learn {
        strainwave_io::output::refuse_input_as_output(learn, calibration)?;
    }
    // Several runs merge into the learned file in turn: if one fails or the run is
    // interrupted, the file is put back as it was.
    let rollback = match &a.learn {
        Some(learn) if a.input.len() > 1 => Some(strainwave_io::output::Rollback::arm(learn)?),
        _ => None,
    };
    let last = a.input.len() - 1;
    for (i, input) in a.input.iter().enumerate() {
        // Only the last run's output is kept; the others go nowhere.
        let out = if i == last { a.out.as_deref() } else { None };
        filter_one(a, &cfg, input, out).map_err(|e| lenient_hint(e, a.lenient))?;
    }
    if let Some(r) = rollback {
        r.keep();
    }
    Ok(())
}

/// A cell that is not a number stops a run; the message says how to go on over it.
fn lenient_hint(e: anyhow::Error, lenient: bool) -> anyhow::Error {
    let not_a_number = e.chain().any(|c| matches!(c.downcast_ref(), Some(IoError::NotANumber { .. })));
    if lenient || !not_a_number {
        return e;
    }
    anyhow::anyhow!("{}; pass --lenient to read such cells as missing (NaN)", strainwave_joint::one_line(&e))
}

/// One recording through the filter (and the learning beside it).
fn filter_one(a: &Args, cfg: &JointConfig, input: &Path, out: Option<&Path>) -> Result<()> {
    let to_stdout = out.is_some_and(|o| o.as_os_str() == "-");
    let scratch_dir = match out.and_then(Path::parent) {
        _ if to_stdout => None,
        Some(p) if !p.as_os_str().is_empty() => Some(p.to_path_buf()),
        _ => Some(PathBuf::from(".")),
    };
    let opts = FilterOptions {
        input_name: input.display().to_string(),
        smooth: a.smooth,
        learn: a.learn.clone(),
        prefix: a.prefix.clone(),
        lenient: a.lenient,
        streaming_output: to_stdout,
        scratch_dir,
    };
    let mut r = strainwave_io::RecordingReader::open(input)?;
    r.set_time_channel(&cfg.channels.time);
    let progress = crate::progress::Progress::new("filter", a.quiet, None);
    let create = |columns: &[&str]| -> Result<Sink> {
        Ok(match out {
            Some(o) => Sink::File(Box::new(RecordingWriter::create(o, columns)?)),
            None => Sink::Discard(0),
        })
    };
    let summary = filter_recording(cfg, &mut r, create, &opts, &mut |rows| progress.set(rows))?;
    progress.finish();
    if a.quiet {
        return Ok(());
    }
    for note in &summary.notes {
        note!("note: {note}");
    }
    if let Some(path) = &a.learn {
        note!("learned coefficients -> {} (set `filter.learned` to use them)", path.display());
    }
    let how = if a.smooth { " (zero phase, offline)" } else { "" };
    let verb = if a.smooth { "smoothed" } else { "filtered" };
    let dest = out.map_or("nowhere (learning only)".to_string(), |o| o.display().to_string());
    note!("{verb} {} rows of {} -> {dest}{how}", summary.rows, input.display());
    for line in summary.health.iter().flat_map(|h| h.lines()) {
        note!("{line}");
    }
    if summary.extrapolated > 0 {
        note!(
            "warning: {} samples used the calibration outside its speed range (its extrapolation policy)",
            summary.extrapolated
        );
    }
    for w in &summary.warnings {
        note!("warning: {w}");
    }
    Ok(())
}

/// Where the rows go: a recording, or nowhere when only learning.
enum Sink {
    File(Box<RecordingWriter>),
    Discard(u64),
}

impl RowSink for Sink {
    fn write_row(&mut self, row: &[f64]) -> Result<(), IoError> {
        match self {
            Sink::File(w) => w.write_row(row),
            Sink::Discard(n) => {
                *n += 1;
                Ok(())
            }
        }
    }
    fn flush(&mut self) -> Result<(), IoError> {
        match self {
            Sink::File(w) => w.flush(),
            Sink::Discard(_) => Ok(()),
        }
    }
    fn finish(self) -> Result<u64, IoError> {
        match self {
            Sink::File(w) => w.finish(),
            Sink::Discard(n) => Ok(n),
        }
    }
}
