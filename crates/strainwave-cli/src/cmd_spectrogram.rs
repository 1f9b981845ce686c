//! `strainwave spectrogram`: power spectral density per STFT frame, as an SVG heat map.

use std::path::PathBuf;

use anyhow::{bail, Result};
use strainwave_analysis::psd::SpectralConfig;
use strainwave_analysis::stft::spectrogram;

use crate::recording_args::{check_window, SignalArgs};
use crate::report::heatmap::{pool_freqs, HeatMap};

/// Arguments of `spectrogram`.
#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(flatten)]
    pub source: SignalArgs,
    /// Output SVG.
    #[arg(long)]
    pub out: PathBuf,
    /// Segment length, samples (Hann, 50 % overlap).
    #[arg(long, default_value_t = 4096)]
    pub nperseg: usize,
    /// Highest frequency shown, Hz (default: Nyquist).
    #[arg(long)]
    pub max_hz: Option<f64>,
}

/// Runs `spectrogram`.
pub fn run(a: &Args) -> Result<()> {
    strainwave_io::output::refuse_input_as_output(&a.out, [a.source.input.as_path()])?;
    if let Some(f) = a.max_hz.filter(|f| !(f.is_finite() && *f > 0.0)) {
        bail!("--max-hz: must be positive, got {f:?}");
    }
    let (t, fs) = a.source.read()?;
    let x = a.source.signal(&t)?;
    check_window(x.len(), a.nperseg)?;
    let cfg = SpectralConfig::new(a.nperseg).with_noverlap(a.nperseg / 2);
    let s = spectrogram(x, fs, &cfg)?;
    // At most 400 frames: average neighbours.
    let g = s.times_s.len().div_ceil(400).max(1);
    let mut times = Vec::new();
    let mut cols = Vec::new();
    for (ts, ps) in s.times_s.chunks(g).zip(s.power.chunks(g)) {
        times.push(ts.iter().sum::<f64>() / ts.len() as f64);
        let mut m = vec![0.0; s.freqs_hz.len()];
        for p in ps {
            m.iter_mut().zip(p).for_each(|(a, b)| *a += b / ps.len() as f64);
        }
        cols.push(m.into_iter().map(|v: f64| 10.0 * v.max(1e-300).log10()).collect::<Vec<f64>>());
    }
    let max_hz = a.max_hz.unwrap_or(fs / 2.0).min(fs / 2.0);
    let (y, z) = pool_freqs(&s.freqs_hz, &cols, max_hz, 200);
    let map = HeatMap {
        title: format!(
            "Spectrogram of {} (Hann, nperseg {}, {:.2} Hz bins)",
            a.source.signal,
            a.nperseg,
            fs / a.nperseg as f64
        ),
        x_label: "time (s)".into(),
        y_label: "frequency (Hz)".into(),
        z_label: format!("PSD (dB re 1 ({})²/Hz)", a.source.signal),
        x: times,
        y,
        z,
        range_db: 100.0,
        lines: Vec::new(),
    };
    strainwave_io::output::write_file(&a.out, map.to_svg())?;
    note!("spectrogram of `{}` -> {}", a.source.signal, a.out.display());
    Ok(())
}
