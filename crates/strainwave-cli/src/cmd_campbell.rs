//! `strainwave campbell`: Campbell diagram (frequency vs speed, amplitude as colour, order
//! lines).

use std::path::PathBuf;

use anyhow::{bail, Result};
use strainwave_analysis::campbell::{campbell, order_hz, CampbellConfig};

use crate::recording_args::{check_window, SignalArgs, SpeedArgs};
use crate::report::heatmap::{pool_freqs, HeatMap};

/// Arguments of `campbell`.
#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(flatten)]
    pub source: SignalArgs,
    #[command(flatten)]
    pub speed: SpeedArgs,
    /// Order lines to draw (mechanical orders, cycles per revolution).
    #[arg(long, value_delimiter = ',', default_values_t = [18.0, 36.0])]
    pub orders: Vec<f64>,
    /// STFT segment length, samples.
    #[arg(long, default_value_t = 2048)]
    pub nperseg: usize,
    /// Width of a speed bin, rpm.
    #[arg(long, default_value_t = 100.0)]
    pub speed_bin: f64,
    /// Highest frequency shown, Hz (default: Nyquist).
    #[arg(long)]
    pub max_hz: Option<f64>,
    /// Output SVG.
    #[arg(long)]
    pub out: PathBuf,
}

/// Runs `campbell`.
pub fn run(a: &Args) -> Result<()> {
    strainwave_io::output::refuse_input_as_output(&a.out, [a.source.input.as_path()])?;
    if let Some(f) = a.max_hz.filter(|f| !(f.is_finite() && *f > 0.0)) {
        bail!("--max-hz: must be positive, got {f:?}");
    }
    let (t, fs) = a.source.read()?;
    let signal = a.source.signal(&t)?;
    let speed = a.speed.rpm(&t, &a.source.input)?;
    check_window(signal.len(), a.nperseg)?;
    if !(a.speed_bin.is_finite() && a.speed_bin > 0.0) {
        bail!("--speed-bin: must be positive, got {:?}", a.speed_bin);
    }
    crate::recording_args::speed_bins(&speed, a.speed_bin, &a.speed.speed, &a.source.input)?;
    if let Some(o) = a.orders.iter().find(|o| !(o.is_finite() && **o > 0.0)) {
        bail!("--orders: must be positive, got {o:?}");
    }
    let c = campbell(signal, &speed, fs, &CampbellConfig::new(a.nperseg, a.speed_bin))?;
    let amp_db: Vec<Vec<f64>> =
        c.grid.iter().map(|row| row.iter().map(|v| 20.0 * v.max(1e-300).log10()).collect()).collect();
    let max_hz = a.max_hz.unwrap_or(fs / 2.0).min(fs / 2.0);
    let (y, z) = pool_freqs(&c.freqs_hz, &amp_db, max_hz, 200);
    let lines = a
        .orders
        .iter()
        .map(|&o| {
            let n_max = c.speed_axis_rpm.last().copied().unwrap_or(0.0) + a.speed_bin;
            // From the origin to the right edge, or to the top where it leaves the plot
            // first (a large order, even an infinite frequency, ends at the top).
            let hz = order_hz(o, n_max);
            let end = if hz <= max_hz { (n_max, hz) } else { (n_max * (max_hz / hz), max_hz) };
            (format!("{o}×"), vec![(0.0, 0.0), end])
        })
        .collect();
    let map = HeatMap {
        title: format!(
            "Campbell diagram of {} (nperseg {}, {:.2} Hz bins)",
            a.source.signal,
            a.nperseg,
            c.resolution_hz()
        ),
        x_label: "speed (rpm)".into(),
        y_label: "frequency (Hz)".into(),
        z_label: format!("amplitude (dB re 1 unit of {})", a.source.signal),
        x: c.speed_axis_rpm.clone(),
        y,
        z,
        range_db: 80.0,
        lines,
    };
    strainwave_io::output::write_file(&a.out, map.to_svg())?;
    note!("Campbell diagram of `{}` -> {}", a.source.signal, a.out.display());
    Ok(())
}
