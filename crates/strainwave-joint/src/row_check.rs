//! What `filter` accepts row by row: every channel it reads finite and time moving
//! forward. By default the first bad row is an error naming the row, column and channel;
//! with `--lenient` such rows go to the canceller, which skips them with a flag (and
//! restarts phase after a gap), and the counts are reported at the end.

use anyhow::{bail, Result};
use strainwave_core::ripple::StepFlags;
use strainwave_io::{BoundChannel, TimeEvent, TimeMonitor};

/// The channels one row is checked on, with their config keys and column names.
pub struct RowCheck {
    channels: Vec<(&'static str, String, BoundChannel)>,
    time: BoundChannel,
    lenient: bool,
    sample_rate_hz: f64,
    monitor: TimeMonitor,
    /// Rows the canceller skipped (non-finite torque or angle), and the first of them.
    skipped: u64,
    first_skipped: Option<String>,
    /// Of those, rows whose speed the calibration rejects, and the first of them.
    rejected: u64,
    first_rejected: Option<String>,
    /// Whether the output is standard output (errors then say how much was written).
    to_stdout: bool,
}

impl RowCheck {
    /// `channels`: `(config key, channel)` of every channel read besides time; `columns`
    /// the recording's column names; `sample_rate_hz` the config's nominal rate.
    pub fn new(
        channels: &[(&'static str, Option<BoundChannel>)],
        time: BoundChannel,
        columns: &[String],
        sample_rate_hz: f64,
        lenient: bool,
        to_stdout: bool,
    ) -> Self {
        let channels = channels
            .iter()
            .filter_map(|(key, c)| c.map(|c| (*key, columns.get(c.index).cloned().unwrap_or_default(), c)))
            .collect();
        Self {
            channels,
            time,
            lenient,
            sample_rate_hz,
            monitor: TimeMonitor::new(Some(1.0 / sample_rate_hz)),
            skipped: 0,
            first_skipped: None,
            rejected: 0,
            first_rejected: None,
            to_stdout,
        }
    }

    /// Checks `row` before it is filtered, `written` rows after the first; `name` names a
    /// row in messages (see [`crate::run::RowSource::row_name`]).
    pub fn row(&mut self, row: &[f64], written: u64, name: impl Fn(&[f64]) -> String) -> Result<()> {
        let t = self.time.get(row);
        let event = self.monitor.push(t);
        if self.lenient {
            return Ok(());
        }
        let partial = || {
            if self.to_stdout && written > 0 {
                format!(" ({written} rows were already written to standard output)")
            } else {
                String::new()
            }
        };
        let hint = "or pass --lenient to skip such rows with a flag";
        for (key, column, c) in &self.channels {
            let v = row[c.index];
            if !v.is_finite() {
                bail!(
                    "{}: column `{column}` (`channels.{key}`) is {v}; fix the recording {hint}{}",
                    name(row),
                    partial()
                );
            }
            if !c.get(row).is_finite() {
                bail!(
                    "{}: column `{column}` (`channels.{key}`) is {v:?}, which its scale and offset make infinite; \
                     fix the recording or `channels.{key}`, {hint}{}",
                    name(row),
                    partial()
                );
            }
        }
        match event {
            TimeEvent::NonFinite => bail!("{}: time is {t}; fix the recording {hint}{}", name(row), partial()),
            TimeEvent::NonMonotonic => {
                let n = name(row);
                bail!("{n}: time {t} s is not after the previous row's; fix the recording {hint}{}", partial())
            }
            TimeEvent::Ok | TimeEvent::Gap => Ok(()),
        }
    }

    /// `row` has a finite torque reading that the calibration makes infinite
    /// (e.g. 1e308 V times the gain): an error naming the row and column, or with
    /// `--lenient` a skipped sample like a NaN in the file.
    pub fn calibration_overflow(&self, row: &[f64], name: impl Fn(&[f64]) -> String) -> Result<()> {
        if self.lenient {
            return Ok(());
        }
        let (key, column, value) = match self.channels.iter().find(|(k, ..)| *k == "torque") {
            Some((k, column, c)) => (*k, column.as_str(), row[c.index]),
            None => ("torque", "torque", f64::NAN),
        };
        bail!(
            "{}: column `{column}` (`channels.{key}`) is {value:?}, which the calibration makes infinite; \
             fix the recording or the calibration, or pass --lenient to skip such rows with a flag",
            name(row)
        )
    }

    /// Records the canceller's flags for `row`; `rejected`: the calibration rejected its
    /// speed (the reason it was skipped).
    pub fn flags(&mut self, flags: StepFlags, rejected: bool, row: &[f64], name: impl Fn(&[f64]) -> String) {
        if rejected {
            self.rejected += 1;
            self.first_rejected.get_or_insert_with(|| name(row));
        } else if flags.contains(StepFlags::MEASUREMENT_SKIPPED) || flags.contains(StepFlags::ANGLE_SKIPPED) {
            self.skipped += 1;
            self.first_skipped.get_or_insert_with(|| name(row));
        }
    }

    /// Warnings for stderr: skipped samples, time-axis problems, and a sample rate that
    /// the time column contradicts.
    pub fn warnings(&self, input: &str, rows: u64, span_s: Option<f64>) -> Vec<String> {
        let sample_rate_hz = self.sample_rate_hz;
        let mut w = Vec::new();
        if let Some(first) = &self.first_skipped {
            w.push(format!(
                "{input}: {} samples with a non-finite angle, or a torque not finite or beyond ±1e12 N·m (an overrange \
                 code), were skipped, the first at {first} \
                 (flag bits 0-1 in filter_flags)",
                self.skipped
            ));
        }
        if let Some(first) = &self.first_rejected {
            w.push(format!(
                "{input}: {} samples with a speed outside the calibration's range were skipped \
                 (`extrapolation = \"reject\"`), the first at {first} (flag bit 0 in filter_flags)",
                self.rejected
            ));
        }
        if let Some(msg) = self.monitor.report() {
            w.push(format!("{input}: {msg}"));
        }
        let regular = self.monitor.gaps == 0 && self.monitor.non_monotonic == 0;
        if let Some(span) = span_s.filter(|s| *s > 0.0 && rows > 10 && regular) {
            let measured_hz = (rows - 1) as f64 / span;
            if (measured_hz / sample_rate_hz - 1.0).abs() > 0.05 {
                w.push(format!(
                    "{input}: the time column gives {measured_hz:.1} Hz but `filter.sample_rate_hz` is \
                     {sample_rate_hz}; the filter's tuning assumes the latter"
                ));
            }
        }
        w
    }
}
