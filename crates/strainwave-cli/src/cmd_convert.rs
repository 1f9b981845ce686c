//! `strainwave convert`: recordings between formats, streaming; time-axis problems are
//! reported, and resampling happens only when asked.

use std::path::PathBuf;

use anyhow::{bail, Context, Result};
use strainwave_io::resample::LinearResampler;
use strainwave_io::{RecordingReader, RecordingWriter, TimeMonitor};

/// Arguments of `convert`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Input recording (.csv, .parquet, .mcap; `-` for CSV on standard input).
    #[arg(long = "in")]
    pub input: PathBuf,
    /// Output recording (.csv or .parquet; `-` for CSV on standard output).
    #[arg(long)]
    pub out: PathBuf,
    /// Resample to this uniform rate by linear interpolation (needs a `time` column).
    #[arg(long)]
    pub resample_hz: Option<f64>,
    /// Name of the time column.
    #[arg(long, default_value = "time")]
    pub time_column: String,
    /// No summary on stderr.
    #[arg(long, short)]
    pub quiet: bool,
}

/// Writes `row` to `w`, through `resampler` when resampling; `false` when the resampler
/// left it out (its time is not finite or does not increase). `n` is the 1-based data row,
/// for messages.
pub fn write_row(
    w: &mut RecordingWriter,
    resampler: Option<&mut LinearResampler>,
    row: &[f64],
    n: u64,
) -> Result<bool> {
    let Some(rs) = resampler else {
        w.write_row(row)?;
        return Ok(true);
    };
    let mut err = None;
    let kept = rs.push(row, |o| match w.write_row(o) {
        Ok(()) => true,
        Err(e) => {
            err = Some(e);
            false
        }
    });
    let kept =
        kept.map_err(|e| anyhow::anyhow!("row {n}: {e}; fix the time column, or convert without --resample-hz"))?;
    match err {
        Some(e) => Err(e.into()),
        None => Ok(kept),
    }
}

/// Runs `convert`.
pub fn run(a: &Args) -> Result<()> {
    strainwave_io::output::refuse_input_as_output(&a.out, [a.input.as_path()])?;
    if strainwave_io::format_of(&a.input)? == strainwave_io::Format::Mcap {
        return crate::cmd_mcap::convert(a);
    }
    let mut r = RecordingReader::open(&a.input)?;
    let columns: Vec<String> = r.columns().to_vec();
    let refs: Vec<&str> = columns.iter().map(String::as_str).collect();
    let time_index = columns.iter().position(|c| *c == a.time_column);
    let mut resampler = match a.resample_hz {
        None => None,
        Some(hz) => {
            let Some(ti) = time_index else {
                bail!("{}: --resample-hz needs a `{}` column (set --time-column)", a.input.display(), a.time_column)
            };
            Some(LinearResampler::new(ti, hz).context("--resample-hz must be positive")?)
        }
    };
    let mut w = RecordingWriter::create(&a.out, &refs)?;
    let mut monitor = TimeMonitor::new(None);
    let mut row = Vec::with_capacity(columns.len());
    let mut skipped = 0u64;
    while r.read_row(&mut row)? {
        if let Some(ti) = time_index {
            monitor.push(row[ti]);
        }
        skipped += u64::from(
            !write_row(&mut w, resampler.as_mut(), &row, r.rows_read())
                .with_context(|| a.input.display().to_string())?,
        );
        if a.out.as_os_str() == "-" && r.rows_read() % strainwave_io::DEFAULT_CHUNK_ROWS as u64 == 0 {
            w.flush()?;
        }
    }
    if r.rows_read() == 0 {
        bail!("{}: no data rows (header only); nothing converted", a.input.display());
    }
    let rows = w.finish()?;
    if !a.quiet {
        eprintln!("converted {} rows of {} -> {} rows in {}", r.rows_read(), a.input.display(), rows, a.out.display());
        if let Some(msg) = monitor.report() {
            eprintln!(
                "warning: {}: {msg}{}",
                a.input.display(),
                if a.resample_hz.is_none() { " (kept as is; --resample-hz makes the rate uniform)" } else { "" }
            );
        }
        if skipped > 0 {
            eprintln!("warning: {skipped} rows with non-increasing time were left out of the resampling");
        }
    }
    Ok(())
}
