//! `strainwave filter`: the real-time ripple and misalignment canceller over a
//! recording, streaming in constant memory (or the offline smoother with `--smooth`).

use std::path::PathBuf;

use anyhow::Result;
use strainwave_io::RecordingWriter;
use strainwave_joint::{filter_recording, FilterOptions, JointConfig};

/// Arguments of `filter`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Joint configuration (gear, channels, calibration, filter); see examples/joint-taghirad.toml.
    #[arg(long)]
    pub config: PathBuf,
    /// Input recording (.csv, .parquet; `-` for CSV on standard input).
    #[arg(long = "in")]
    pub input: PathBuf,
    /// Output recording: the input columns plus torque, ripple, misalignment, innovation, nis,
    /// filter_flags (bits 0-7 the canceller's, 8-11 the do-no-harm guard's: pass-through,
    /// order withheld, order contradicted, standstill bound; bit 16 + i: order i not
    /// applied); then torque_denoised when the config sets `filter.torque_bandwidth_hz`
    /// (causal, the clean torque filtered as a torque state: group delay at DC
    /// (1 − α)/(α fs) with α = 1 − exp(−2π f/fs), about 1/(2π f), e.g. 16 ms at 10 Hz; load
    /// steps restart it); then, with --smooth, torque_smoothed and torque_smoothed_sd.
    #[arg(long)]
    pub out: PathBuf,
    /// Offline: forward filter plus Rauch–Tung–Striebel smoother (zero phase; reads the whole
    /// recording). `torque` stays the measurement minus the smoothed ripple and misalignment;
    /// torque_smoothed is that torque smoothed as a level-and-rate torque state (40 Hz, zero
    /// phase, white noise averaged out; a jump beyond 4σ restarts it, so load steps stay
    /// sharp), torque_smoothed_sd its 1σ.
    #[arg(long)]
    pub smooth: bool,
    /// Commissioning: learn the ripple and misalignment coefficients over this run (the
    /// `full` model uses its learning tuning) and write them to FILE, for `filter.learned`.
    #[arg(long, value_name = "FILE", conflicts_with = "smooth")]
    pub learn: Option<PathBuf>,
    /// Prefix for the added columns (when the input already has a `torque` column).
    #[arg(long, default_value = "")]
    pub prefix: String,
    /// Go on over bad rows instead of stopping at the first: samples with a non-finite
    /// torque or angle are skipped by the canceller (flag bits 0-1 in filter_flags) and
    /// time that does not move forward restarts the phase; counts are reported at the end.
    #[arg(long)]
    pub lenient: bool,
    /// No summary on stderr.
    #[arg(long, short)]
    pub quiet: bool,
}

/// Runs `filter`.
pub fn run(a: &Args) -> Result<()> {
    for out in std::iter::once(&a.out).chain(&a.learn) {
        strainwave_io::output::refuse_input_as_output(out, [a.input.as_path(), a.config.as_path()])?;
    }
    let cfg = JointConfig::load(&a.config)?;
    let to_stdout = a.out.as_os_str() == "-";
    let scratch_dir = match a.out.parent() {
        _ if to_stdout => None,
        Some(p) if !p.as_os_str().is_empty() => Some(p.to_path_buf()),
        _ => Some(PathBuf::from(".")),
    };
    let opts = FilterOptions {
        input_name: a.input.display().to_string(),
        smooth: a.smooth,
        learn: a.learn.clone(),
        prefix: a.prefix.clone(),
        lenient: a.lenient,
        streaming_output: to_stdout,
        scratch_dir,
    };
    let mut r = strainwave_io::RecordingReader::open(&a.input)?;
    let progress = crate::progress::Progress::new("filter", a.quiet, None);
    let summary =
        filter_recording(&cfg, &mut r, |columns| Ok(RecordingWriter::create(&a.out, columns)?), &opts, &mut |rows| {
            progress.set(rows)
        })?;
    progress.finish();
    if a.quiet {
        return Ok(());
    }
    for note in &summary.notes {
        eprintln!("note: {note}");
    }
    if let Some(path) = &a.learn {
        eprintln!("learned coefficients -> {} (set `filter.learned` to use them)", path.display());
    }
    let how = if a.smooth { " (zero phase, offline)" } else { "" };
    let verb = if a.smooth { "smoothed" } else { "filtered" };
    eprintln!("{verb} {} rows of {} -> {}{how}", summary.rows, a.input.display(), a.out.display());
    for line in summary.health.iter().flat_map(|h| h.lines()) {
        eprintln!("{line}");
    }
    if summary.extrapolated > 0 {
        eprintln!(
            "warning: {} samples used the calibration outside its speed range (its extrapolation policy)",
            summary.extrapolated
        );
    }
    for w in &summary.warnings {
        eprintln!("warning: {w}");
    }
    Ok(())
}
