//! The time column of a recording that `estimate` runs a model over. The model's
//! damping, velocities and accelerations were fitted at one sample rate, so time must be
//! finite and never go back, and the recording's typical step (the median, so that pauses
//! and jitter do not count) must be the model's: a log with every other row dropped would
//! otherwise give wrong torques.

use anyhow::{bail, Result};
use strainwave_io::Channel;

/// How far the recording's rate (from its median step) may be from the model's: 5 %. A
/// real arm's logs differ by 0.5 % from run to run.
pub const RATE_TOLERANCE: f64 = 0.05;

/// Resolution of the steps' histogram: bins per octave of the step over the model's
/// period (0.07 %), over ±[`OCTAVES`].
const BINS_PER_OCTAVE: usize = 1000;
/// Octaves of the histogram on either side of the model's period (steps beyond count in
/// the end bins).
const OCTAVES: usize = 4;

/// The time column as it is read, row by row.
#[derive(Debug, Clone)]
pub struct SampleClock {
    index: usize,
    column: String,
    scale: f64,
    offset: f64,
    model_hz: f64,
    last_s: Option<f64>,
    /// Steps per bin of `log₂(step × model_hz)`.
    steps: Vec<u64>,
    /// Steps of zero (a repeated time stamp).
    zero_steps: u64,
}

impl SampleClock {
    /// The model's time column `channels.time` in the recording's `columns`, to check
    /// against the model's rate `model_hz`; none when the recording lacks it.
    pub fn find(channel: &Channel, columns: &[String], model_hz: f64) -> Option<Self> {
        let (column, (scale, offset)) = (channel.column_name(), channel.scale_offset());
        let index = columns.iter().position(|c| c == column)?;
        let steps = vec![0; 2 * OCTAVES * BINS_PER_OCTAVE];
        Some(Self { index, column: column.to_string(), scale, offset, model_hz, last_s: None, steps, zero_steps: 0 })
    }

    /// Reads `row`'s time: an error if it is not finite or before the last row's (`name`
    /// names the row in messages).
    pub fn push(&mut self, row: &[f64], input: &str, name: impl Fn(&[f64]) -> String) -> Result<()> {
        let t = row[self.index] * self.scale + self.offset;
        let column = &self.column;
        if !t.is_finite() {
            bail!("{input}: {}: time (column `{column}`) is {t}", name(row));
        }
        if let Some(last) = self.last_s {
            if t < last {
                bail!(
                    "{input}: {}: time {t:?} s (column `{column}`) is before the previous row's {last:?} s",
                    name(row)
                );
            }
            if t == last {
                self.zero_steps += 1;
            } else {
                let octaves = ((t - last) * self.model_hz).log2();
                let bin = ((octaves + OCTAVES as f64) * BINS_PER_OCTAVE as f64).max(0.0) as usize;
                let last_bin = self.steps.len() - 1;
                self.steps[bin.min(last_bin)] += 1;
            }
        }
        self.last_s = Some(t);
        Ok(())
    }

    /// The rate of the median step of the rows read, Hz (none before two rows): infinite
    /// when the median step is zero; beyond 16 times the model's rate either way, the
    /// limit of the histogram (the end bin's rate).
    pub fn median_rate_hz(&self) -> Option<f64> {
        let n = self.steps.iter().sum::<u64>() + self.zero_steps;
        if n == 0 {
            return None;
        }
        if 2 * self.zero_steps >= n {
            return Some(f64::INFINITY);
        }
        let mut seen = self.zero_steps;
        let bin = self.steps.iter().position(|&c| {
            seen += c;
            2 * seen >= n
        })?;
        let octaves = (bin as f64 + 0.5) / BINS_PER_OCTAVE as f64 - OCTAVES as f64;
        Some(self.model_hz / octaves.exp2())
    }

    /// An error unless the median step's rate is within [`RATE_TOLERANCE`] of the model's
    /// `sample_rate_hz` (from file `config`).
    pub fn check_rate(&self, input: &str, config: &str) -> Result<()> {
        let Some(rate) = self.median_rate_hz() else { return Ok(()) };
        let model_hz = self.model_hz;
        if (rate / model_hz - 1.0).abs() > RATE_TOLERANCE {
            let limit = 2f64.powi(OCTAVES as i32);
            let steps = if rate.is_infinite() {
                "does not move forward (its median step is zero)".to_string()
            } else if rate > 0.99 * limit * model_hz {
                format!("steps over {limit:.0} times faster (its median step)")
            } else if rate < 1.01 * model_hz / limit {
                format!("steps over {limit:.0} times slower (its median step)")
            } else {
                format!("steps at about {rate:.0} Hz (its median step)")
            };
            bail!(
                "{input}: the time column `{}` {steps}, but the model was fitted at `sample_rate_hz` = {} Hz \
                 ({config}); resample the recording to that rate or identify a model at its own",
                self.column,
                hz(model_hz)
            );
        }
        Ok(())
    }
}

/// A rate as messages give it: one decimal, or in exponent form far from any joint's.
fn hz(v: f64) -> String {
    if (1e-3..1e7).contains(&v) {
        format!("{v:.1}")
    } else {
        format!("{v:e}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn clock(times: &[f64], model_hz: f64) -> Result<SampleClock> {
        let cols = ["time".to_string(), "x".to_string()];
        let named = Channel::Column("time".into());
        let mut c = SampleClock::find(&named, &cols, model_hz).expect("a `time` column");
        for (k, &t) in times.iter().enumerate() {
            c.push(&[t, 0.0], "in.csv", |_| format!("data row {}", k + 1))?;
        }
        Ok(c)
    }

    #[test]
    fn the_rate_is_the_median_steps_so_pauses_and_jitter_do_not_count() {
        // 1 kHz with jitter, a repeated stamp and a 5 s pause.
        let mut t: Vec<f64> = (0..1000).map(|k| 0.001 * k as f64 + 2e-4 * ((k % 3) as f64 - 1.0)).collect();
        t.push(t[999]);
        t.extend((0..1000).map(|k| 6.0 + 0.001 * k as f64));
        let c = clock(&t, 1000.0).unwrap();
        assert!((c.median_rate_hz().unwrap() / 1000.0 - 1.0).abs() < 2e-3, "{:?}", c.median_rate_hz());
        c.check_rate("in.csv", "m.toml").unwrap();
        // Every other row: 500 Hz.
        let half: Vec<f64> = t.iter().step_by(2).copied().collect();
        let err = clock(&half, 1000.0).unwrap().check_rate("in.csv", "m.toml").unwrap_err().to_string();
        assert!(err.contains("steps at about 500 Hz") && err.contains("1000.0 Hz") && err.contains("m.toml"), "{err}");
        assert!(clock(&[0.0], 1000.0).unwrap().median_rate_hz().is_none());
    }

    /// Beyond the histogram's 16 times either way, or a time that stands still: said so,
    /// not a rate read off the end bin (before: "about 6252 Hz" for 1 kHz against a model
    /// at 100 kHz, "about 15994 Hz" for a constant time).
    #[test]
    fn rates_far_off_are_named_without_a_false_figure() {
        let t: Vec<f64> = (0..100).map(|k| 0.001 * k as f64).collect();
        let message = |times: &[f64], model_hz: f64| {
            clock(times, model_hz).unwrap().check_rate("in.csv", "m.toml").unwrap_err().to_string()
        };
        let slow = message(&t, 1e5);
        assert!(slow.contains("steps over 16 times slower") && slow.contains("= 100000.0 Hz"), "{slow}");
        let fast = message(&t, 10.0);
        assert!(fast.contains("steps over 16 times faster") && fast.contains("= 10.0 Hz"), "{fast}");
        let near = message(&t, 200.0);
        assert!(near.contains("steps at about 1000 Hz"), "{near}");
        let still = message(&[5.0; 50], 1000.0);
        assert!(still.contains("does not move forward (its median step is zero)"), "{still}");
        let huge = message(&t, 1e308);
        assert!(huge.contains("= 1e308 Hz"), "{huge}");
    }

    #[test]
    fn time_must_be_finite_and_never_go_back() {
        let err = clock(&[0.0, f64::NAN], 1000.0).unwrap_err().to_string();
        assert!(err.starts_with("in.csv: data row 2: time (column `time`) is NaN"), "{err}");
        let err = clock(&[1.0, 0.5], 1000.0).unwrap_err().to_string();
        assert!(err.contains("data row 2: time 0.5 s") && err.contains("before the previous row's 1.0 s"), "{err}");
        clock(&[0.0, 0.001, 0.001, 0.002], 1000.0).unwrap();
    }

    #[test]
    fn a_missing_time_column_is_none() {
        let named = Channel::Column("Timestamp".into());
        assert!(SampleClock::find(&named, &["t".to_string()], 1000.0).is_none());
    }
}
