//! `strainwave filter --smooth`: the offline zero-phase smoother (forward filter plus
//! Rauch–Tung–Striebel pass) over a whole recording.

use anyhow::{bail, Context, Result};
use strainwave_analysis::smoother::smooth as rts_smooth;
use strainwave_core::ripple::{RippleInput, RippleModel};
use strainwave_io::{RecordingReader, RecordingWriter};

use crate::filter_rows::RowCheck;

/// The smoother keeps every sample's covariance: recordings longer than this are refused
/// (about 1.6 GB for the full configuration) rather than exhausting memory.
pub const MAX_SMOOTH_ROWS: u64 = 1_000_000;

/// Runs the smoother over the whole recording and writes the smoothed columns.
pub fn smooth<const M: usize>(
    a: &crate::cmd_filter::Args,
    model: &RippleModel<f64, M>,
    r: &mut RecordingReader,
    columns: &[&str],
    check: &mut RowCheck,
    input_and_time: impl Fn(&[f64]) -> (RippleInput<f64>, f64),
) -> Result<()> {
    let mut rows: Vec<Vec<f64>> = Vec::new();
    let mut ins: Vec<RippleInput<f64>> = Vec::new();
    let mut row = Vec::new();
    let (mut first_t, mut last_t): (Option<f64>, Option<f64>) = (None, None);
    while r.read_row(&mut row)? {
        if r.rows_read() > MAX_SMOOTH_ROWS {
            bail!(
                "{}: --smooth holds the whole recording in memory and takes at most {MAX_SMOOTH_ROWS} rows; \
                 split the file or filter without --smooth",
                a.input.display()
            );
        }
        check.row(&row, r.rows_read(), 0).with_context(|| a.input.display().to_string())?;
        let (mut input, t) = input_and_time(&row);
        if let Some(t0) = last_t.filter(|t0| t.is_finite() && t > *t0) {
            input = input.with_dt(t - t0);
        }
        if t.is_finite() {
            first_t.get_or_insert(t);
            last_t = Some(t);
        }
        ins.push(input);
        rows.push(std::mem::take(&mut row));
    }
    if rows.is_empty() {
        bail!("{}: no data rows", a.input.display());
    }
    let out = rts_smooth(model, &ins).map_err(|e| anyhow::anyhow!("{}: smoother: {e}", a.input.display()))?;
    let mut w = RecordingWriter::create(&a.out, columns)?;
    for ((mut row, s), f) in rows.into_iter().zip(&out.smoothed).zip(&out.filtered) {
        row.extend_from_slice(&[
            s.torque_nm,
            s.ripple_nm,
            s.misalignment_nm,
            f.innovation_nm,
            f.nis,
            f.flags.bits() as f64,
        ]);
        w.write_row(&row)?;
    }
    let n = w.finish()?;
    for (k, f) in out.filtered.iter().enumerate() {
        check.flags(f.flags, k as u64 + 1);
    }
    if !a.quiet {
        eprintln!("smoothed {n} rows of {} -> {} (zero phase, offline)", a.input.display(), a.out.display());
        let span = first_t.zip(last_t).map(|(t0, t1)| t1 - t0);
        for w in check.warnings(&a.input.display().to_string(), n, span) {
            eprintln!("warning: {w}");
        }
    }
    Ok(())
}
