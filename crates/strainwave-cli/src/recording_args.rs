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

    /// The signal column of `t` (read by [`Self::read`]).
    pub fn signal<'a>(&self, t: &'a Table) -> Result<&'a [f64]> {
        column(t, &self.signal, "--signal", &self.input)
    }
}

/// The speed column and its unit (`--speed`, `--speed-unit`).
#[derive(clap::Args, Debug)]
pub struct SpeedArgs {
    /// Speed column.
    #[arg(long)]
    pub speed: String,
    /// Unit of the speed column.
    #[arg(long, default_value = "rpm", value_parser = ["rpm", "rad_s"])]
    pub speed_unit: String,
}

impl SpeedArgs {
    /// The speed column of `t` (read from `path`) in rpm.
    pub fn rpm(&self, t: &Table, path: &Path) -> Result<Vec<f64>> {
        speed_rpm(t, &self.speed, &self.speed_unit, path)
    }
}

/// A recording column by name, with a one-line error naming it.
pub fn column<'a>(t: &'a Table, name: &str, flag: &str, path: &Path) -> Result<&'a [f64]> {
    t.column(name).with_context(|| format!("{flag}: no column `{name}` in {}", path.display()))
}

/// Sample rate from the `time` column.
pub fn sample_rate(t: &Table, path: &Path) -> Result<f64> {
    let time = column(t, "time", "time", path)?;
    if time.len() < 2 {
        bail!("{}: needs at least 2 samples, got {}", path.display(), time.len());
    }
    let dt = (time[time.len() - 1] - time[0]) / (time.len() - 1) as f64;
    if !(dt.is_finite() && dt > 0.0) {
        bail!("{}: `time` must increase", path.display());
    }
    Ok(1.0 / dt)
}

/// The speed column in rpm; an error naming it when it is zero or negative on average.
pub fn speed_rpm(t: &Table, name: &str, unit: &str, path: &Path) -> Result<Vec<f64>> {
    let raw = column(t, name, "--speed", path)?;
    let k = if unit == "rad_s" { 60.0 / std::f64::consts::TAU } else { 1.0 };
    let v: Vec<f64> = raw.iter().map(|x| x * k).collect();
    let mean = v.iter().sum::<f64>() / v.len().max(1) as f64;
    if mean.is_nan() || mean <= 0.0 {
        bail!("--speed: column `{name}` is zero or negative (mean {mean:.3} rpm); negate a reverse run");
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
