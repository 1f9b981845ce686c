//! `strainwave report`: a self-contained HTML report of a recording: torque over time,
//! spectra with the order lines (when a joint config gives the gear and angles), the
//! filter's result when the recording has its columns, and error tables against the
//! truth when the recording is simulated.

use std::path::PathBuf;

use anyhow::{Context, Result};
use strainwave_analysis::spectrum::amplitude_spectrum;
use strainwave_analysis::stats::{max_abs, mean, rms};

use crate::report::html::{esc, table, Report, Section};
use crate::report::plot::{LinePlot, Marker, Series};
use strainwave_joint::JointConfig;

/// Arguments of `report`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Recording (.csv or .parquet).
    #[arg(long = "in")]
    pub input: PathBuf,
    /// Joint configuration, for order lines and channel names.
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Output HTML file.
    #[arg(long)]
    pub out: PathBuf,
}

/// Torque-like columns shown when present, in this order.
const TORQUE_COLUMNS: &[&str] =
    &["measured_torque", "reference_torque", "torque", "torque_denoised", "torque_smoothed", "true_torque"];

/// Runs `report`.
pub fn run(a: &Args) -> Result<()> {
    let t = strainwave_io::read_all(&a.input)?;
    let cfg = a.config.as_deref().map(JointConfig::load).transpose()?;
    let time_name = cfg.as_ref().map_or("time".to_string(), |c| c.channels.time.column_name().to_string());
    let time = t.column(&time_name).with_context(|| format!("{}: no time column `{time_name}`", a.input.display()))?;
    if time.len() < 16 {
        anyhow::bail!("{}: {} rows, too few for a report", a.input.display(), time.len());
    }
    let fs = (time.len() - 1) as f64 / (time[time.len() - 1] - time[0]);
    if !(fs.is_finite() && fs > 0.0) {
        anyhow::bail!("{}: time column `{time_name}` does not increase", a.input.display());
    }
    let mut sections = Vec::new();
    let mut torque_cols: Vec<String> =
        TORQUE_COLUMNS.iter().filter(|c| t.column(c).is_some()).map(|c| c.to_string()).collect();
    if let Some(c) = &cfg {
        let name = c.channels.torque.column_name().to_string();
        if t.column(&name).is_some() && !torque_cols.contains(&name) {
            torque_cols.insert(0, name);
        }
    }
    // Summary table.
    let mut rows = Vec::new();
    for c in &t.columns {
        let v = t.column(c).unwrap_or(&[]);
        let finite: Vec<f64> = v.iter().copied().filter(|x| x.is_finite()).collect();
        rows.push(vec![
            c.clone(),
            format!("{}", v.len() - finite.len()),
            format!("{:.6}", mean(&finite)),
            format!("{:.6}", rms(&finite)),
            format!("{:.6}", max_abs(&finite)),
        ]);
    }
    let mut body = format!(
        "<p>{} rows, {:.3} s, {:.1} Hz mean rate, {} columns.</p>",
        time.len(),
        time[time.len() - 1] - time[0],
        fs,
        t.columns.len()
    );
    body += &table(&["column", "non-finite", "mean", "rms", "max |x|"], &rows);
    sections.push(Section { title: "Recording".into(), body });
    // Torque over time.
    if !torque_cols.is_empty() {
        let series = torque_cols
            .iter()
            .filter_map(|c| t.column(c).map(|y| Series { name: c.clone(), x: time.to_vec(), y: y.to_vec() }))
            .collect();
        let plot = LinePlot {
            title: "Torque over time".into(),
            x_label: format!("{time_name} (s)"),
            y_label: "torque (N·m)".into(),
            series,
            ..Default::default()
        };
        sections.push(Section { title: "Torque".into(), body: plot.to_svg() });
        // Spectra, with order lines from the joint config.
        let mut markers = Vec::new();
        if let Some(c) = &cfg {
            let gear = c.gear()?;
            let angle = |ch: &Option<strainwave_io::Channel>| ch.as_ref().and_then(|ch| t.column(ch.column_name()));
            if let (Some(m), Some(o)) = (angle(&c.channels.motor_angle), angle(&c.channels.output_angle)) {
                let n = m.len();
                let phi0 = gear.relative_angle(m[0], o[0]);
                let phi1 = gear.relative_angle(m[n - 1], o[n - 1]);
                let rate = ((phi1 - phi0) / (time[n - 1] - time[0])).abs() / std::f64::consts::TAU;
                let out_rate = ((o[n - 1] - o[0]) / (time[n - 1] - time[0])).abs() / std::f64::consts::TAU;
                for (k, label) in [(2.0, "2×"), (4.0, "4×")] {
                    markers.push(Marker { x: k * rate, label: format!("{label} (mean speed)") });
                }
                markers.push(Marker { x: out_rate, label: "1× output".into() });
            }
        }
        let mut spec_series = Vec::new();
        for c in torque_cols.iter().filter(|c| c.as_str() != "true_torque") {
            let y: Vec<f64> = t.column(c).unwrap_or(&[]).iter().map(|v| if v.is_finite() { *v } else { 0.0 }).collect();
            if let Ok(s) = amplitude_spectrum(&y, fs) {
                spec_series.push(Series { name: c.clone(), x: s.freqs_hz, y: s.amplitude });
            }
        }
        if !spec_series.is_empty() {
            let plot = LinePlot {
                title: "Amplitude spectrum (Hann, whole recording)".into(),
                x_label: "frequency (Hz)".into(),
                y_label: "amplitude (N·m)".into(),
                series: spec_series,
                markers,
                log_y: true,
                ..Default::default()
            };
            sections.push(Section { title: "Spectra".into(), body: plot.to_svg() });
        }
    }
    // The smoothed and denoised torque, with their band, coverage and delay.
    let measured = cfg.as_ref().map(|c| c.channels.torque.column_name().to_string());
    if let Some(s) = crate::report::filter::section(&t, time, measured.as_deref(), cfg.as_ref()) {
        sections.push(s);
    }
    // Errors against the truth.
    if let Some(truth) = t.column("true_torque") {
        let mut rows = Vec::new();
        for c in torque_cols.iter().filter(|c| c.as_str() != "true_torque") {
            let y = t.column(c).unwrap_or(&[]);
            let e: Vec<f64> = y.iter().zip(truth).map(|(a, b)| a - b).filter(|x| x.is_finite()).collect();
            rows.push(vec![
                c.clone(),
                format!("{:.5}", mean(&e)),
                format!("{:.5}", rms(&e)),
                format!("{:.5}", max_abs(&e)),
            ]);
        }
        sections.push(Section {
            title: "Errors against true_torque".into(),
            body: table(&["signal", "mean error N·m", "RMS error N·m", "max |error| N·m"], &rows),
        });
    }
    let report = Report {
        title: format!(
            "strainwave report: {}",
            a.input.file_name().map_or(String::new(), |n| n.to_string_lossy().into_owned())
        ),
        subtitle: esc(&format!("strainwave {}", env!("CARGO_PKG_VERSION"))),
        sections,
    };
    std::fs::write(&a.out, report.to_html()).with_context(|| format!("{}", a.out.display()))?;
    Ok(())
}
