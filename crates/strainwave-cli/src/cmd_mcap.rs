//! MCAP input for `convert` (ROS 2 logs): JointState and JSON messages become columns
//! (see `strainwave_io::mcap_in`), written as CSV or Parquet row by row. Log times of
//! several topics interleave, so the time axis is not checked for gaps here; a column is
//! NaN in the rows of other messages (and `--resample-hz` carries that NaN along).

use anyhow::{bail, Context, Result};
use strainwave_io::mcap_in::McapReader;
use strainwave_io::resample::LinearResampler;
use strainwave_io::RecordingWriter;

use crate::cmd_convert::write_row;

/// Converts an MCAP log to a recording.
pub fn convert(a: &crate::cmd_convert::Args) -> Result<()> {
    if a.time_column != "time" {
        bail!(
            "{}: --time-column does not apply to MCAP input (its time column is `time`, from the log time)",
            a.input.display()
        );
    }
    let mut r = McapReader::open(&a.input)?;
    for w in r.warnings() {
        eprintln!("warning: {}: {w}", a.input.display());
    }
    if r.rows() == 0 {
        bail!("{}: no JointState (CDR) or JSON messages with numeric values; nothing converted", a.input.display());
    }
    let columns: Vec<String> = r.columns().to_vec();
    let refs: Vec<&str> = columns.iter().map(String::as_str).collect();
    let mut resampler = match a.resample_hz {
        None => None,
        Some(hz) => Some(LinearResampler::new(0, hz).context("--resample-hz must be positive")?),
    };
    let mut w = RecordingWriter::create(&a.out, &refs)?;
    let mut row = Vec::with_capacity(columns.len());
    let mut skipped = 0u64;
    while r.read_row(&mut row)? {
        skipped += u64::from(
            !write_row(&mut w, resampler.as_mut(), &row, r.rows_read())
                .with_context(|| a.input.display().to_string())?,
        );
    }
    let rows = w.finish()?;
    if !a.quiet {
        eprintln!(
            "converted {} messages of {} -> {} rows, {} columns in {}",
            r.rows_read(),
            a.input.display(),
            rows,
            columns.len(),
            a.out.display()
        );
        if skipped > 0 {
            eprintln!("warning: {skipped} rows with non-increasing time were left out of the resampling");
        }
    }
    Ok(())
}
