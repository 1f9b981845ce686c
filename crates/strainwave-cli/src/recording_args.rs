//! The recording arguments the spectral commands share (`campbell`, `orders`,
//! `spectrogram`) and the columns they read, with one-line errors naming the flag.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use strainwave_io::Table;

/// The input recording and the signal column (`--in`, `--signal`).
#[derive(clap::Args, Debug)]
pub struct SignalArgs {
    /// Input recording.
    #[arg(long = "in")]
    pub input: PathBuf,
    /// Signal column (e.g. accel_torque, torsion_torque).
    #[arg(long)]
    pub signal: String,
}

impl SignalArgs {
    /// The recording, its signal column and its sample rate (from `time`).
    pub fn read(&self) -> Result<(Table, f64)> {
        let t = strainwave_io::read_all(&self.input)?;
        column(&t, &self.signal, "--signal", &self.input)?;
        let fs = sample_rate(&t, &self.input)?;
        Ok((t, fs))
    }

    /// The signal column of `t` (read by [`Self::read`]); an error naming the first row
    /// (1-based, data rows) whose value is not finite.
    pub fn signal<'a>(&self, t: &'a Table) -> Result<&'a [f64]> {
        let x = column(t, &self.signal, "--signal", &self.input)?;
        if let Some(i) = x.iter().position(|v| !v.is_finite()) {
            let at = strainwave_io::row_name(&self.input, t, i, "row");
            bail!("{}: {at}, column `{}`: {} is not finite", self.input.display(), self.signal, x[i]);
        }
        // A spectrum sums squares of the values: beyond this they overflow (and no
        // physical signal reaches it in any unit).
        if let Some(i) = x.iter().position(|v| v.abs() > MAX_SPECTRAL_VALUE) {
            let at = strainwave_io::row_name(&self.input, t, i, "row");
            bail!(
                "{}: {at}, column `{}`: {:?} is beyond ±{MAX_SPECTRAL_VALUE:e}, where its spectrum would overflow",
                self.input.display(),
                self.signal,
                x[i]
            );
        }
        Ok(x)
    }
}

/// Largest magnitude of a signal the spectral commands take.
pub const MAX_SPECTRAL_VALUE: f64 = 1e100;

/// The speed column and its unit (`--speed`, `--speed-unit`).
#[derive(clap::Args, Debug)]
pub struct SpeedArgs {
    /// Speed column.
    #[arg(long)]
    pub speed: String,
    /// Unit of the speed column.
    #[arg(long, value_enum, default_value = "rpm")]
    pub speed_unit: SpeedUnit,
}

/// `--speed-unit`.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum SpeedUnit {
    /// Revolutions per minute.
    Rpm,
    /// Radians per second (`rad_s` is accepted).
    #[value(name = "rad-s", alias = "rad_s")]
    RadS,
}

impl SpeedArgs {
    /// The speed column of `t` (read from `path`) in rpm.
    pub fn rpm(&self, t: &Table, path: &Path) -> Result<Vec<f64>> {
        speed_rpm(t, &self.speed, self.speed_unit, path)
    }
}

/// A recording column by name, with a one-line error naming it.
pub fn column<'a>(t: &'a Table, name: &str, flag: &str, path: &Path) -> Result<&'a [f64]> {
    t.column(name).with_context(|| format!("{flag}: no column `{name}` in {}", path.display()))
}

/// A time step more than this many times the typical (median) one is a gap or a glitch:
/// the spectral commands need evenly sampled recordings.
pub const MAX_STEP_RATIO: f64 = 100.0;

/// Sample rate from the `time` column, which must be finite and increase on every row,
/// without steps of more than [`MAX_STEP_RATIO`] typical ones (errors name the row, see
/// [`strainwave_io::row_name`]).
pub fn sample_rate(t: &Table, path: &Path) -> Result<f64> {
    let time = column(t, "time", "time", path)?;
    if time.len() < 2 {
        bail!("{}: needs at least 2 samples, got {}", path.display(), time.len());
    }
    let mut steps = Vec::with_capacity(time.len() - 1);
    for (k, w) in time.windows(2).enumerate() {
        let dt = w[1] - w[0];
        if !(w[1].is_finite() && dt > 0.0) {
            let at = strainwave_io::row_name(path, t, k + 1, "row");
            bail!(
                "{}: {at}, column `time`: {:?} s does not come after {:?} s of the row before",
                path.display(),
                w[1],
                w[0]
            );
        }
        steps.push(dt);
    }
    if !time[0].is_finite() {
        bail!("{}: row 1, column `time`: {} is not a time", path.display(), time[0]);
    }
    let mut sorted = steps.clone();
    sorted.sort_by(f64::total_cmp);
    let typical = sorted[sorted.len() / 2];
    if let Some(k) = steps.iter().position(|dt| *dt > MAX_STEP_RATIO * typical) {
        bail!(
            "{}: {}, column `time`: a step of {} s, more than {MAX_STEP_RATIO} times the typical {typical} s; \
             this command needs an evenly sampled recording (fix the gap, or split the recording)",
            path.display(),
            strainwave_io::row_name(path, t, k + 1, "row"),
            steps[k]
        );
    }
    let dt = (time[time.len() - 1] - time[0]) / (time.len() - 1) as f64;
    Ok(1.0 / dt)
}

/// Speed bins of `bin_rpm` up to the fastest sample: more than
/// [`strainwave_analysis::campbell::MAX_SPEED_BINS`] is an error naming the row of that
/// sample (usually a glitch in the speed column), never an allocation it sizes.
pub fn speed_bins(speed_rpm: &[f64], bin_rpm: f64, name: &str, path: &Path) -> Result<usize> {
    let max = strainwave_analysis::campbell::MAX_SPEED_BINS;
    let (k, top) = speed_rpm.iter().copied().enumerate().fold((0, 0.0), |a, (k, v)| if v > a.1 { (k, v) } else { a });
    let bins = (top / bin_rpm).floor() + 1.0;
    if bins.is_nan() || bins > max as f64 {
        bail!(
            "{}: row {}, column `{name}`: {top:?} rpm in --speed-bin {bin_rpm:?} rpm bins needs more than {max} bins \
             (a glitch in the speed? fix it, or widen --speed-bin)",
            path.display(),
            k + 1
        );
    }
    Ok(bins as usize)
}

/// Largest speed magnitude the spectral commands take, rpm (10⁷: beyond any motor).
pub const MAX_SPEED_RPM: f64 = 1e7;

/// The speed column in rpm; an error naming it when it is zero or negative on average.
pub fn speed_rpm(t: &Table, name: &str, unit: SpeedUnit, path: &Path) -> Result<Vec<f64>> {
    let raw = column(t, name, "--speed", path)?;
    let k = if unit == SpeedUnit::RadS { 60.0 / std::f64::consts::TAU } else { 1.0 };
    let v: Vec<f64> = raw.iter().map(|x| x * k).collect();
    if let Some(i) = v.iter().position(|x| !x.is_finite()) {
        let at = strainwave_io::row_name(path, t, i, "row");
        bail!("{}: {at}, column `{name}`: speed {:?} is not finite", path.display(), raw[i]);
    }
    // A speed a recording's spectrum can take: beyond, one glitched row dominates the mean.
    if let Some(i) = v.iter().position(|x| x.abs() > MAX_SPEED_RPM) {
        let at = strainwave_io::row_name(path, t, i, "row");
        bail!("{}: {at}, column `{name}`: speed {:?} rpm is beyond ±{MAX_SPEED_RPM:e} rpm", path.display(), v[i]);
    }
    let mean = v.iter().sum::<f64>() / v.len().max(1) as f64;
    if mean.is_nan() || mean <= 0.0 {
        bail!(
            "{}: --speed: column `{name}` is zero or negative (mean {mean:.3} rpm); negate a reverse run",
            path.display()
        );
    }
    Ok(v)
}

/// Checks that the recording holds at least one window.
pub fn check_window(n: usize, nperseg: usize) -> Result<()> {
    if nperseg < 8 {
        bail!("--nperseg: must be at least 8, got {nperseg}");
    }
    if n < nperseg {
        bail!("--nperseg: the recording has {n} samples, fewer than one window of {nperseg}");
    }
    Ok(())
}

/// How every command reads its recordings (global options: they go before or after the
/// command name). Logs: `--topic`, `--time`, `--align`, `--max-gap`, `--resample-hz`;
/// text: `--delimiter`.
#[derive(clap::Args, Debug, Clone)]
#[command(next_help_heading = "Reading recordings (every command that reads one)")]
pub struct ReadArgs {
    /// Log topic to read (repeatable; default: every topic).
    #[arg(long = "topic", global = true, value_name = "TOPIC")]
    pub topics: Vec<String>,
    /// Log message time: `header` (header.stamp where a message has one) or `log` (receive time).
    // Its own id: `calibrate --time-column` is a field called `time` too.
    #[arg(id = "log_clock", long = "time", global = true, value_name = "CLOCK", value_enum)]
    pub time: Option<TimeArg>,
    /// How log topics at different rates meet on one clock: linear, hold, nearest, or none
    /// (one row per message).
    #[arg(long, global = true, value_name = "MODE", value_enum)]
    pub align: Option<AlignArg>,
    /// A column's value is NaN where its own samples are further apart than this, s
    /// [default: logs 4 mean periods of its topic, at most 10 s; tables resampled 10 s].
    #[arg(long, global = true, value_name = "S")]
    pub max_gap: Option<f64>,
    /// Put every column on a uniform clock at this rate, Hz (logs: default the fastest
    /// topic's message times; tables: linear between rows).
    #[arg(long, global = true, value_name = "HZ")]
    pub resample_hz: Option<f64>,
    /// Delimiter of text tables: comma, semicolon, tab, or one character [default: detected].
    #[arg(long, global = true, value_name = "D")]
    pub delimiter: Option<String>,
}

/// `--time`: which clock a log message's time is read from.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum TimeArg {
    /// header.stamp where a message has one.
    Header,
    /// The receive time.
    Log,
}

/// `--align`: how log topics at different rates meet on one clock.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum AlignArg {
    /// Linear between a topic's samples.
    Linear,
    /// The last sample held.
    Hold,
    /// The nearest sample.
    Nearest,
    /// One row per message.
    None,
}

impl ReadArgs {
    /// The reader options these flags ask for.
    pub fn options(&self) -> Result<strainwave_io::ReadOptions> {
        use strainwave_io::read_options::Align;
        let delimiter = match self.delimiter.as_deref() {
            None => None,
            Some("comma" | ",") => Some(b','),
            Some("semicolon" | ";") => Some(b';'),
            Some("tab" | "\\t" | "\t") => Some(b'\t'),
            Some("space" | " ") => Some(b' '),
            Some(d) if d.len() == 1 && d.is_ascii() && d != "\"" && d != "#" => Some(d.as_bytes()[0]),
            Some("#") => bail!("--delimiter: `#` starts a comment line; pick another (comma, semicolon, tab, space)"),
            Some(d) => bail!("--delimiter: `{d}` is not one ASCII character (comma, semicolon, tab, space)"),
        };
        if let Some(g) = self.max_gap {
            if !(g.is_finite() && g >= 0.0) {
                bail!("--max-gap: must be zero or a positive number of seconds, got {g}");
            }
        }
        if let Some(hz) = self.resample_hz {
            if !(hz.is_finite() && hz > 0.0) {
                bail!("--resample-hz: must be a positive rate, got {hz}");
            }
        }
        Ok(strainwave_io::ReadOptions {
            topics: self.topics.clone(),
            time: match self.time {
                Some(TimeArg::Log) => strainwave_io::TimeSource::Log,
                Some(TimeArg::Header) | None => strainwave_io::TimeSource::Header,
            },
            align: match self.align {
                Some(AlignArg::Hold) => Align::Hold,
                Some(AlignArg::Nearest) => Align::Nearest,
                Some(AlignArg::None) => Align::None,
                Some(AlignArg::Linear) | None => Align::Linear,
            },
            max_gap_s: self.max_gap,
            resample_hz: self.resample_hz,
            delimiter,
            time_column: None,
            print_warnings: true,
            unreadable_as_nan: false,
        })
    }
}
