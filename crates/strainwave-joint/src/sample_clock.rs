//! The time column of a recording that `estimate` runs a model over. The model's
//! damping, velocities and accelerations were fitted at one sample rate, so every time
//! must be finite and after the one before, and the recording's mean rate must be the
//! model's (a log with every other row dropped would otherwise give wrong torques).

use anyhow::{bail, Result};
use strainwave_io::Channel;

/// How far the recording's mean sample rate may be from the model's (5 %; a real arm's
/// logs differ by 0.5 % from run to run).
pub const RATE_TOLERANCE: f64 = 0.05;

/// The time column as it is read, row by row.
#[derive(Debug, Clone)]
pub struct SampleClock {
    index: usize,
    column: String,
    scale: f64,
    offset: f64,
    first_s: f64,
    last_s: f64,
    rows: u64,
}

impl SampleClock {
    /// The model's time column `channels.time` in the recording's `columns`; none when
    /// the model names none (its rate was given as a number, so a column called `time`
    /// may be in any unit: nothing to check). `input` and `config` name the files in
    /// messages.
    pub fn find(channel: Option<&Channel>, columns: &[String], input: &str, config: &str) -> Result<Option<Self>> {
        let Some(channel) = channel else { return Ok(None) };
        let (column, (scale, offset)) = (channel.column_name(), channel.scale_offset());
        let Some(index) = columns.iter().position(|c| c == column) else {
            bail!("{input}: missing time column `{column}` (channels.time of {config})");
        };
        let column = column.to_string();
        Ok(Some(Self { index, column, scale, offset, first_s: f64::NAN, last_s: f64::NAN, rows: 0 }))
    }

    /// Reads data row `k`'s time: an error unless it is finite and after the last row's.
    pub fn push(&mut self, row: &[f64], k: u64, input: &str) -> Result<()> {
        let t = row[self.index] * self.scale + self.offset;
        let column = &self.column;
        if !t.is_finite() {
            bail!("{input}: data row {k}: time (column `{column}`) is {t}");
        }
        if self.rows == 0 {
            self.first_s = t;
        } else if t <= self.last_s {
            bail!(
                "{input}: data row {k}: time {t} s (column `{column}`) is not after the previous row's {} s",
                self.last_s
            );
        }
        self.last_s = t;
        self.rows += 1;
        Ok(())
    }

    /// The mean sample rate of the rows read, Hz (none before two rows).
    pub fn mean_rate_hz(&self) -> Option<f64> {
        (self.rows >= 2).then(|| (self.rows - 1) as f64 / (self.last_s - self.first_s))
    }

    /// An error unless the mean rate is within [`RATE_TOLERANCE`] of the model's
    /// `sample_rate_hz` (from file `config`).
    pub fn check_rate(&self, model_hz: f64, input: &str, config: &str) -> Result<()> {
        let Some(rate) = self.mean_rate_hz() else { return Ok(()) };
        if (rate / model_hz - 1.0).abs() > RATE_TOLERANCE {
            bail!(
                "{input}: the time column `{}` gives {rate:.1} Hz, but the model was fitted at `sample_rate_hz` = \
                 {model_hz:.1} Hz ({config}); resample the recording to that rate or identify a model at its own",
                self.column
            );
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn clock(times: &[f64]) -> Result<SampleClock> {
        let cols = ["time".to_string(), "x".to_string()];
        let named = Channel::Column("time".into());
        let mut c = SampleClock::find(Some(&named), &cols, "in.csv", "m.toml")?.expect("a `time` column");
        for (k, &t) in times.iter().enumerate() {
            c.push(&[t, 0.0], k as u64 + 1, "in.csv")?;
        }
        Ok(c)
    }

    #[test]
    fn the_mean_rate_is_rows_over_the_span() {
        let c = clock(&[0.0, 0.001, 0.0021, 0.003]).unwrap();
        assert!((c.mean_rate_hz().unwrap() - 1000.0).abs() < 1e-9);
        c.check_rate(1000.0, "in.csv", "m.toml").unwrap();
        c.check_rate(1049.0, "in.csv", "m.toml").unwrap();
        let err = c.check_rate(2000.0, "in.csv", "m.toml").unwrap_err().to_string();
        assert!(err.contains("1000.0 Hz") && err.contains("2000.0 Hz") && err.contains("m.toml"), "{err}");
    }

    #[test]
    fn time_must_be_finite_and_increase() {
        let err = clock(&[0.0, f64::NAN]).unwrap_err().to_string();
        assert!(err.starts_with("in.csv: data row 2: time (column `time`) is NaN"), "{err}");
        let err = clock(&[0.0, 0.001, 0.001]).unwrap_err().to_string();
        assert!(err.contains("data row 3") && err.contains("not after"), "{err}");
        let err = clock(&[1.0, 0.5]).unwrap_err().to_string();
        assert!(err.contains("data row 2"), "{err}");
    }

    #[test]
    fn a_named_time_column_must_exist_and_none_is_checked_unless_named() {
        let cols = ["time".to_string()];
        assert!(SampleClock::find(None, &cols, "in.csv", "m.toml").unwrap().is_none());
        let named = Channel::Column("Timestamp".into());
        let err = SampleClock::find(Some(&named), &cols, "in.csv", "m.toml").unwrap_err().to_string();
        assert_eq!(err, "in.csv: missing time column `Timestamp` (channels.time of m.toml)");
    }
}
