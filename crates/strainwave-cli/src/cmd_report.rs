//! `strainwave report`: a self-contained HTML report of a recording: torque over time,
//! spectra with the order lines (when a joint config gives the gear and angles), the
//! filter's result when the recording has its columns, and error tables against the
//! truth when the recording is simulated; with `filter --smooth`'s columns, the smoothed
//! torque and its band against the measurement, and `torque_denoised`'s group delay at
//! DC. One pass over the recording in constant
//! memory: the time plot is a min/max decimation per pixel column, the spectra are
//! averaged over segments.

use std::path::PathBuf;

use anyhow::{bail, Result};

use crate::report::html::{esc, table, Report, Section};
use crate::report::plot::{LinePlot, Marker, Series};
use crate::report::smoothed::{denoised_section, SmoothedTorque};
use crate::report::streaming::{ColumnStats, HeldSpeed, MinMaxDecimator, WelchAmplitude};
use strainwave_joint::JointConfig;

/// Arguments of `report`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Recording (any format `convert` reads; `-` for text on standard input).
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

/// Pixel columns of the time plot: each gets the minimum and maximum of its rows.
const PLOT_COLUMNS: usize = 1000;
/// Samples per segment of the averaged spectra (a recording shorter is taken whole).
const SPECTRUM_SEGMENT: usize = 1 << 16;

/// Runs `report`: one pass over the recording, in memory that does not grow with it.
pub fn run(a: &Args) -> Result<()> {
    strainwave_io::output::refuse_input_as_output(&a.out, [a.input.as_path()].into_iter().chain(a.config.as_deref()))?;
    let cfg = a.config.as_deref().map(JointConfig::load).transpose()?;
    if let Some(cfg) = &cfg {
        // The report does not read them, but overwriting them would lose them.
        strainwave_io::output::refuse_input_as_output(&a.out, cfg.files_named())?;
    }
    let mut r = strainwave_io::RecordingReader::open(&a.input)?;
    if let Some(c) = &cfg {
        r.set_time_channel(&c.channels.time);
    }
    let columns = r.columns().to_vec();
    let input = a.input.display().to_string();
    let time_name = cfg.as_ref().map_or("time".to_string(), |c| c.channels.time.column_name().to_string());
    let time_at = r.column_index(&time_name)?;
    let at = |name: &str| columns.iter().position(|c| c == name);
    let mut torque_cols: Vec<String> =
        TORQUE_COLUMNS.iter().filter(|c| at(c).is_some()).map(|c| c.to_string()).collect();
    // The config's torque channel is a torque only when nothing turns it into one (no
    // calibration, no scale or offset): a bridge voltage is not plotted as N·m.
    let in_nm = |c: &JointConfig| {
        let gain_one = c.calibration.as_ref().is_none_or(|k| k.gain_nm_per_v == Some(1.0) && k.file.is_none());
        gain_one && c.channels.torque.scale_offset() == (1.0, 0.0)
    };
    let measured_nm = cfg.as_ref().filter(|c| in_nm(c)).map(|c| c.channels.torque.column_name().to_string());
    if let Some(name) = &measured_nm {
        if at(name).is_some() && !torque_cols.contains(name) {
            torque_cols.insert(0, name.clone());
        }
    }
    let torque_at: Vec<usize> = torque_cols.iter().filter_map(|c| at(c)).collect();
    let truth_at = at("true_torque");
    // The angles in radians (a channel's scale and offset applied).
    let angle_at = cfg.as_ref().and_then(|c| {
        let col = |ch: &Option<strainwave_io::Channel>| {
            ch.as_ref().and_then(|ch| at(ch.column_name()).map(|k| (k, ch.scale_offset())))
        };
        col(&c.channels.motor_angle).zip(col(&c.channels.output_angle))
    });
    let gear = match (&cfg, angle_at) {
        (Some(c), Some(_)) => Some(c.gear()?),
        _ => None,
    };
    let mut held = HeldSpeed::default();
    let measured_name = measured_nm.unwrap_or("measured_torque".to_string());
    let mut smoothed = SmoothedTorque::new(&columns, &measured_name, PLOT_COLUMNS)
        .or_else(|| SmoothedTorque::new(&columns, "measured_torque", PLOT_COLUMNS));
    // The guard's figures when the recording has the filter's columns (and the config,
    // if given, does not turn the guard off).
    let guard_on = cfg.as_ref().is_none_or(|c| c.filter.guard);
    let health_at = at("nis").zip(at("filter_flags")).filter(|_| guard_on);
    let mut health = crate::report::health::HealthCounts::default();
    // The one pass.
    let mut stats = vec![ColumnStats::default(); columns.len()];
    let mut plots: Vec<MinMaxDecimator> = torque_at.iter().map(|_| MinMaxDecimator::new(PLOT_COLUMNS)).collect();
    let mut spectra: Vec<WelchAmplitude> = torque_at.iter().map(|_| WelchAmplitude::new(SPECTRUM_SEGMENT)).collect();
    let mut errors = vec![ColumnStats::default(); torque_at.len()];
    let (mut first, mut last): (Option<Vec<f64>>, Vec<f64>) = (None, Vec::new());
    let mut row = Vec::with_capacity(columns.len());
    let mut prev_t = f64::NEG_INFINITY;
    while r.read_row(&mut row)? {
        let (n, t) = (r.rows_read(), row[time_at]);
        if !(t.is_finite() && t > prev_t) {
            let at = r.row_name(&row);
            bail!(
                "{input}: {at}, column `{time_name}`: time {t:?} s does not come after the row before ({prev_t:?} s)"
            );
        }
        prev_t = t;
        for (s, v) in stats.iter_mut().zip(&row) {
            s.push(*v);
        }
        for (k, &c) in torque_at.iter().enumerate() {
            plots[k].push(t, row[c]);
            spectra[k].push(row[c]);
            if let Some(tr) = truth_at {
                errors[k].push(row[c] - row[tr]);
            }
        }
        if let Some(s) = smoothed.as_mut() {
            s.push(n, t, &row);
        }
        if let Some((nis, flags)) = health_at {
            health.push(row[nis], row[flags]);
        }
        if let (Some(g), Some(((m, ms), (o, os)))) = (&gear, angle_at) {
            let (motor, output) = (row[m] * ms.0 + ms.1, row[o] * os.0 + os.1);
            held.push(t, g.relative_angle(motor, output), output);
        }
        if first.is_none() {
            first = Some(row.clone());
        }
        last.clone_from(&row);
    }
    let rows = r.rows_read();
    let first = first.unwrap_or_default();
    if rows < 16 {
        bail!("{input}: {rows} rows, too few for a report");
    }
    let span_s = last[time_at] - first[time_at];
    let fs = (rows - 1) as f64 / span_s;
    if !(fs.is_finite() && fs > 0.0) {
        bail!("{input}: time column `{time_name}` does not increase");
    }
    let mut sections = Vec::new();
    // Summary table.
    let table_rows: Vec<Vec<String>> = columns
        .iter()
        .zip(&stats)
        .map(|(c, s)| vec![c.clone(), format!("{}", s.non_finite), stat(s.mean()), stat(s.rms()), stat(s.max_abs)])
        .collect();
    let mut body = format!("<p>{rows} rows, {span_s:.3} s, {fs:.1} Hz mean rate, {} columns.</p>", columns.len());
    body += &table(&["column", "non-finite", "mean", "rms", "max |x|"], &table_rows);
    sections.push(Section { title: "Recording".into(), body });
    if !torque_cols.is_empty() {
        // Torque over time.
        let series = torque_cols
            .iter()
            .zip(&plots)
            .map(|(c, d)| {
                let (x, y) = d.points();
                Series { name: c.clone(), x, y }
            })
            .collect();
        let plot = LinePlot {
            title: "Torque over time (minimum and maximum per pixel column)".into(),
            x_label: format!("{time_name} (s)"),
            y_label: "torque (N·m)".into(),
            series,
            ..Default::default()
        };
        sections.push(Section { title: "Torque".into(), body: plot.to_svg() });
        // Spectra, with order lines from the joint config.
        let mut markers = Vec::new();
        if let Some((rel, out)) = held.speeds_rad_s() {
            let (rate, out_rate) = (rel / std::f64::consts::TAU, out / std::f64::consts::TAU);
            for (k, label) in [(2.0, "2×"), (4.0, "4×")] {
                markers.push(Marker { x: k * rate, label: format!("{label} {:.1} Hz (speed held)", k * rate) });
            }
            markers.push(Marker { x: out_rate, label: format!("1× output {out_rate:.2} Hz") });
        }
        let spec_series: Vec<Series> = torque_cols
            .iter()
            .zip(spectra)
            .filter(|(c, _)| c.as_str() != "true_torque")
            .filter_map(|(c, w)| w.finish(fs).map(|(x, y)| Series { name: c.clone(), x, y }))
            .collect();
        if !spec_series.is_empty() {
            let plot = LinePlot {
                title: format!("Amplitude spectrum (Hann, segments of up to {SPECTRUM_SEGMENT} samples averaged)"),
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
    if let Some(s) = smoothed {
        sections.push(s.section(&time_name, cfg.as_ref().and_then(|c| c.filter.noise_nm)));
    }
    if at("torque_denoised").is_some() {
        let delay = match &cfg {
            Some(c) => c.denoiser()?.map(|d| (c.filter.torque_bandwidth_hz.unwrap_or(f64::NAN), d.group_delay_s())),
            None => None,
        };
        sections.push(denoised_section(delay, cfg.is_some()));
    }
    // Errors against the truth.
    if truth_at.is_some() {
        let rows: Vec<Vec<String>> = torque_cols
            .iter()
            .zip(&errors)
            .filter(|(c, _)| c.as_str() != "true_torque")
            .map(|(c, e)| {
                vec![c.clone(), format!("{:.5}", e.mean()), format!("{:.5}", e.rms()), format!("{:.5}", e.max_abs)]
            })
            .collect();
        sections.push(Section {
            title: "Errors against true_torque".into(),
            body: table(&["signal", "mean error N·m", "RMS error N·m", "max |error| N·m"], &rows),
        });
    }
    if health_at.is_some() {
        let labels = cfg.as_ref().map_or_else(Vec::new, order_labels);
        let labels = if labels.is_empty() { (0..5).map(|i| format!("order {i}")).collect() } else { labels };
        let (rows, warnings) = health.table(&labels);
        let mut body = String::from(
            "<p>From <code>nis</code> and <code>filter_flags</code>: the share of the run each order's correction \
             was applied by the do-no-harm guard, the mean NIS against its expected value 1, and the time \
             the raw torque was passed through.</p>",
        );
        body += &table(&["", "value"], &rows);
        for w in warnings {
            body += &format!("<p><strong>warning:</strong> {}</p>", esc(&w));
        }
        sections.push(Section { title: "Filter health".into(), body });
    }
    let report = Report {
        title: format!(
            "strainwave report: {}",
            a.input.file_name().map_or(String::new(), |n| n.to_string_lossy().into_owned())
        ),
        subtitle: esc(&format!("strainwave {}", env!("CARGO_PKG_VERSION"))),
        sections,
    };
    strainwave_io::output::write_file(&a.out, report.to_html())?;
    Ok(())
}

/// The config's canceller orders as the health summary names them (empty if the model
/// cannot be built).
fn order_labels(cfg: &JointConfig) -> Vec<String> {
    struct Labels;
    impl strainwave_joint::canceller::ModelVisitor for Labels {
        type Output = Vec<String>;
        fn visit<const M: usize>(
            self,
            model: strainwave_core::ripple::RippleModel<f64, M>,
        ) -> anyhow::Result<Vec<String>> {
            Ok(model.orders().iter().map(strainwave_joint::health::order_label).collect())
        }
    }
    strainwave_joint::canceller::build_model(cfg, false, Labels).unwrap_or_default()
}

/// A figure of the recording table: six decimals, or six significant digits in the
/// exponent form where six decimals would show nothing or hundreds of digits.
fn stat(v: f64) -> String {
    if v == 0.0 || (1e-3..1e9).contains(&v.abs()) {
        format!("{v:.6}")
    } else {
        format!("{v:.5e}")
    }
}
