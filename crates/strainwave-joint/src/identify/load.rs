//! Reading a recording for `identify`: encoder counts or angles into gear-convention
//! angles, the reference torque, non-finite values and impossible torques refused (or
//! skipped with `--lenient`).

use anyhow::{bail, Context, Result};
use strainwave_core::compliance::ThreeSlopeStiffness;
use strainwave_core::gear::Gear;
use strainwave_core::torsion::{EstimatorState, NoKinematicError, TorqueSolver, TorsionEstimator};
use strainwave_io::Channel;

use super::config::{ArmConfig, EncodersConfig};
use super::RunInput;
use crate::estimate::counts_hint;

/// A reference torque beyond this many times the gear's rated torque is not a reading
/// of it (a corrupt row): refused, or skipped with `--lenient`.
const REFERENCE_LIMIT_RATED: f64 = 100.0;

/// Motor and link angles (gear convention, unwrapped) of a recording, with the rows kept.
pub struct Run {
    /// WG angle, rad.
    pub motor: Vec<f64>,
    /// Output angle, rad.
    pub link: Vec<f64>,
    /// Reference torque, N·m (when asked for).
    pub reference: Option<Vec<f64>>,
    /// Time, s (when the config names a time channel).
    pub time: Option<Vec<f64>>,
    /// Rows skipped for non-finite values (`--lenient`).
    pub skipped: usize,
    /// First skipped data row (1-based).
    pub first_skipped: Option<usize>,
    /// The file and row of the first skipped row, as messages name it.
    pub first_skipped_at: Option<String>,
}

fn column<'a>(t: &'a strainwave_io::Table, ch: &Channel, key: &str, path: &str) -> Result<&'a [f64]> {
    t.column(ch.column_name()).with_context(|| {
        format!("{path}: no column `{}` (channels.{key}); columns: {}", ch.column_name(), t.columns.join(", "))
    })
}

/// Refuses a scale or offset on a channel of raw counts: counts are integers that the
/// `[encoders]` table turns into angles (zero, direction, counts per revolution).
pub fn refuse_count_scaling(ch: &Channel, key: &str) -> Result<()> {
    if let Channel::Mapped(t) = ch {
        if t.scale != 1.0 || t.offset != 0.0 {
            bail!(
                "channels.{key}: scale/offset are not applied to encoder counts; give the zero as \
                 encoders.{key}_offset_counts and the direction as encoders.{key}_direction = -1"
            );
        }
    }
    Ok(())
}

/// Unwraps raw counts into angles through the core's estimator (identity spring, no
/// kinematic error): the encoder handling is the one `estimate` uses.
fn angles_from_counts(
    gear: Gear<f64>,
    enc: &EncodersConfig,
    motor: &[f64],
    link: &[f64],
    rows: &[usize],
    (at, hint): (&dyn Fn(usize) -> String, &str),
) -> Result<(Vec<f64>, Vec<f64>)> {
    let (m, l) = enc.configs()?;
    let spring = ThreeSlopeStiffness::linear(1.0e4).map_err(|e| anyhow::anyhow!("{e}"))?;
    let solver = TorqueSolver::for_rated_torque(1.0e9).map_err(|e| anyhow::anyhow!("{e}"))?;
    let est = TorsionEstimator::new(gear, m, l, NoKinematicError, spring, solver);
    let mut st = EstimatorState::new();
    let n_s = gear.signed_ratio();
    let (mut ma, mut la) = (Vec::with_capacity(rows.len()), Vec::with_capacity(rows.len()));
    for &k in rows {
        let (mc, lc) = (motor[k], link[k]);
        if mc.fract() != 0.0 || lc.fract() != 0.0 {
            bail!("{}: encoder counts {mc:?}, {lc:?} are not whole numbers{}", at(k), hint);
        }
        // Beyond 2^53 counts a float no longer holds every whole number.
        if mc.abs() > 9.0e15 || lc.abs() > 9.0e15 {
            bail!("{}: encoder counts {mc:?}, {lc:?}: beyond ±9e15, not a counter", at(k));
        }
        let e = est.step_counts(&mut st, mc as i64, lc as i64).map_err(|e| anyhow::anyhow!("{}: {e}", at(k)))?;
        if e.flags.any_jump() {
            bail!("{}: encoder count jumped (wrapping counter? check encoders.single_turn)", at(k));
        }
        la.push(e.output_angle_rad);
        ma.push((e.output_angle_rad - e.torsion_rad) * n_s);
    }
    Ok((ma, la))
}

/// Reads a recording. `with_reference` asks for the reference torque. A non-finite
/// value in a used column is an error naming the data row (1-based) and column, or with
/// `lenient` the row is skipped and counted.
pub fn load_run(cfg: &ArmConfig, input: RunInput<'_>, with_reference: bool, lenient: bool) -> Result<Run> {
    let read;
    let from_file = matches!(input, RunInput::File(_));
    let (table, path) = match input {
        RunInput::File(p) => {
            // The reader's errors name the file.
            read = strainwave_io::read_all_with_time(p, cfg.channels.time.as_ref())?;
            (&read, p.display().to_string())
        }
        RunInput::Table { table, name } => (table, name.to_string()),
    };
    let path = path.as_str();
    if table.rows() < 20 {
        bail!("{}: {} rows, too short to identify from", path, table.rows());
    }
    let gear = cfg.gear.gear()?;
    let ch = &cfg.channels;
    let mut used: Vec<(&str, &Channel)> = vec![("motor", &ch.motor), ("link", &ch.link)];
    if with_reference {
        let Some(r) = &ch.reference_torque else { bail!("channels.reference_torque: needed for the loaded run") };
        used.push(("reference_torque", r));
    }
    if let Some(t) = &ch.time {
        used.push(("time", t));
    }
    let cols: Vec<(&str, &Channel, &[f64])> =
        used.iter().map(|(k, c)| Ok((*k, *c, column(table, c, k, path)?))).collect::<Result<_>>()?;
    let limit_nm = REFERENCE_LIMIT_RATED * cfg.gear.rated_torque_nm;
    // Why a value cannot be used: not finite, or a reference torque no gear can carry.
    let unusable = |key: &str, c: &Channel, x: f64| -> Option<String> {
        let (scale, offset) = c.scale_offset();
        let torque_nm = x * scale + offset;
        if !x.is_finite() {
            Some(format!("is {x:?}"))
        } else if key == "reference_torque" && (!torque_nm.is_finite() || torque_nm.abs() > limit_nm) {
            Some(format!("is {torque_nm:?} N·m, beyond {REFERENCE_LIMIT_RATED} × gear.rated_torque_nm"))
        } else {
            None
        }
    };
    // `file: data row N`, or the row's time where the reader made the rows (resampled,
    // a log's rows aligned on one clock).
    let at = |k: usize| -> String {
        if !from_file {
            return format!("{path}: data row {}", k + 1);
        }
        let (name, (scale, offset)) =
            ch.time.as_ref().map_or(("time", (1.0, 0.0)), |c| (c.column_name(), c.scale_offset()));
        let t = table.column(name).and_then(|v| v.get(k)).map_or(f64::NAN, |v| v * scale + offset);
        format!("{path}: {}", strainwave_io::row_label(path, k as u64 + 1, t, "data row"))
    };
    let mut rows = Vec::with_capacity(table.rows());
    let (mut skipped, mut first_skipped, mut first_skipped_at) = (0usize, None, None);
    for k in 0..table.rows() {
        if let Some((key, c, why)) = cols.iter().find_map(|(key, c, v)| Some((key, c, unusable(key, c, v[k])?))) {
            if !lenient {
                bail!(
                    "{}: column `{}` (channels.{key}) {why} (use --lenient to skip such rows)",
                    at(k),
                    c.column_name(),
                );
            }
            skipped += 1;
            first_skipped.get_or_insert(k + 1);
            first_skipped_at.get_or_insert_with(|| at(k));
            continue;
        }
        rows.push(k);
    }
    if rows.len() < 20 {
        bail!("{}: {} usable rows, too few to identify from", path, rows.len());
    }
    let scaled = |c: &Channel, v: &[f64]| -> Vec<f64> {
        let (s, o) = c.scale_offset();
        rows.iter().map(|&k| v[k] * s + o).collect()
    };
    let get = |key: &str| cols.iter().find(|(k, _, _)| *k == key).map(|(_, c, v)| (*c, *v));
    let (mc, mv) = get("motor").context("motor channel")?;
    let (lc, lv) = get("link").context("link channel")?;
    let (motor, link) = match &cfg.encoders {
        Some(enc) => {
            refuse_count_scaling(mc, "motor")?;
            refuse_count_scaling(lc, "link")?;
            let hint = if from_file { counts_hint(path) } else { String::new() };
            angles_from_counts(gear, enc, mv, lv, &rows, (&at, &hint))?
        }
        None => (scaled(mc, mv), scaled(lc, lv)),
    };
    let reference = get("reference_torque").map(|(c, v)| scaled(c, v));
    let time = get("time").map(|(c, v)| scaled(c, v));
    Ok(Run { motor, link, reference, time, skipped, first_skipped, first_skipped_at })
}

/// The sample rate: given, or from the time channel.
pub fn sample_rate(cfg: &ArmConfig, run: &Run, path: &str) -> Result<f64> {
    if let Some(fs) = cfg.sample_rate_hz {
        if !(fs.is_finite() && fs > 0.0) {
            bail!("sample_rate_hz: must be positive, got {fs}");
        }
        return Ok(fs);
    }
    let Some(t) = &run.time else { bail!("give sample_rate_hz or channels.time") };
    let span = t[t.len() - 1] - t[0];
    if !(span.is_finite() && span > 0.0) {
        bail!("{}: time does not increase", path);
    }
    Ok((t.len() - 1) as f64 / span)
}
