//! `strainwave convert`: recordings between formats, streaming. Any input the readers
//! take (text, Parquet, MCAP, rosbag2) goes to any output the writers take (text,
//! Parquet, MCAP), with the global read options (`--topic`, `--align`, `--resample-hz`,
//! `--delimiter`, …); units found in the input go with the columns. Time-axis problems
//! of a table are reported; resampling happens only when asked.

use std::path::{Path, PathBuf};

use anyhow::{bail, Result};
use strainwave_io::{RecordingReader, RecordingWriter, TimeMonitor};

/// Arguments of `convert`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Input recording (.csv/.tsv/.txt, .parquet, .mcap, .db3, either compressed whole as
    /// .zstd, a rosbag2 folder; `-` for text on standard input).
    #[arg(long = "in")]
    pub input: PathBuf,
    /// Output recording (.csv, .parquet or .mcap; `-` for CSV on standard output).
    #[arg(long)]
    pub out: PathBuf,
    /// Name of a table's time column: read in seconds (from `ms`, `us`, `ns`, `min`, `h`
    /// in its header) and the clock of `--resample-hz`.
    #[arg(long, default_value = "time")]
    pub time_column: String,
    /// No summary on stderr.
    #[arg(long, short)]
    pub quiet: bool,
}

/// Runs `convert`.
pub fn run(a: &Args) -> Result<()> {
    strainwave_io::output::refuse_input_as_output(&a.out, [a.input.as_path()])?;
    let options = strainwave_io::default_read_options();
    let log = matches!(
        strainwave_io::format_of(&a.input)?,
        strainwave_io::Format::Mcap | strainwave_io::Format::Db3 | strainwave_io::Format::RosbagFolder
    );
    if log && a.time_column != "time" {
        bail!("{}: --time-column does not apply to a log (its time column is `time`)", a.input.display());
    }
    let mut r = RecordingReader::open(&a.input)?;
    let columns: Vec<String> = r.columns().to_vec();
    let refs: Vec<&str> = columns.iter().map(String::as_str).collect();
    let units: Vec<Option<&str>> = r.units().iter().map(Option::as_deref).collect();
    let time_index = columns.iter().position(|c| *c == a.time_column);
    if options.resample_hz.is_some() && time_index.is_none() {
        bail!("{}: --resample-hz needs a `{}` column (set --time-column)", a.input.display(), a.time_column)
    }
    let mut w = RecordingWriter::create_with_units(&a.out, &refs, &units)?;
    let mut monitor = TimeMonitor::new(None);
    let mut row = Vec::with_capacity(columns.len());
    while r.read_row(&mut row)? {
        if let Some(ti) = time_index {
            monitor.push(row[ti]);
        }
        w.write_row(&row)?;
        if a.out.as_os_str() == "-" && r.rows_read() % strainwave_io::DEFAULT_CHUNK_ROWS as u64 == 0 {
            w.flush()?;
        }
    }
    if r.rows_read() == 0 {
        bail!("{}: no data rows (header only); nothing converted", a.input.display());
    }
    let rows = w.finish()?;
    if !a.quiet {
        note!("{}", summary(&r, &a.input, &a.out, rows, columns.len()));
        if !log {
            if let Some(msg) = monitor.report() {
                note!(
                    "warning: {}: {msg}{}",
                    a.input.display(),
                    if options.resample_hz.is_none() {
                        " (kept as is; --resample-hz makes the rate uniform)"
                    } else {
                        ""
                    }
                );
            }
        }
        if let (n @ 1.., Some((gap_s, at_s))) = r.resample_gaps() {
            note!(
                "warning: {}: {n} gap(s) longer than --max-gap left NaN in the resampled rows, the longest {gap_s} s ending at time {at_s} s",
                a.input.display()
            );
        }
        if r.resample_skipped() > 0 {
            note!("warning: {} rows with non-increasing time were left out of the resampling", r.resample_skipped());
        }
    }
    Ok(())
}

/// The summary line: what was read (a log's messages per topic, a table's rows), what
/// was written.
fn summary(r: &RecordingReader, input: &Path, out: &Path, rows_written: u64, columns: usize) -> String {
    let read = match r.messages_per_topic() {
        Some(topics) => {
            let each: Vec<String> = topics.iter().map(|(t, n)| format!("{t} {n}")).collect();
            format!("{} messages ({})", r.input_rows(), each.join(", "))
        }
        None => format!("{} rows", r.input_rows()),
    };
    format!("converted {read} of {} -> {rows_written} rows, {columns} columns in {}", input.display(), out.display())
}
