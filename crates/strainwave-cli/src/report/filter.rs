//! The report's filter section: the smoothed torque (`filter --smooth`) with its 1σ
//! band and the causal denoised torque, plotted against the measurement, with their
//! error, coverage and delay figures.

use strainwave_io::Table;
use strainwave_joint::JointConfig;

use super::html::{esc, table, Section};
use super::plot::{LinePlot, Series};

/// Samples plotted at most (the window around the largest smoothed step, or the start).
const WINDOW_SAMPLES: usize = 2000;

/// The window of `n` samples shown: centred on the largest jump of `y` between two
/// samples (a load step, where sharpness shows), else the first samples.
fn window(y: &[f64]) -> core::ops::Range<usize> {
    let n = y.len();
    let jump = (1..n)
        .filter(|&k| (y[k] - y[k - 1]).is_finite())
        .max_by(|&a, &b| (y[a] - y[a - 1]).abs().total_cmp(&(y[b] - y[b - 1]).abs()))
        .unwrap_or(0);
    let start = jump.saturating_sub(WINDOW_SAMPLES / 2).min(n.saturating_sub(WINDOW_SAMPLES));
    start..(start + WINDOW_SAMPLES).min(n)
}

/// The section, when the recording has `torque_smoothed` or `torque_denoised`.
/// `measured` names the measured torque column; `time` is the time axis.
pub fn section(t: &Table, time: &[f64], measured: Option<&str>, cfg: Option<&JointConfig>) -> Option<Section> {
    let smoothed = t.column("torque_smoothed");
    let denoised = t.column("torque_denoised");
    if smoothed.is_none() && denoised.is_none() {
        return None;
    }
    let mut body = String::new();
    let truth = t.column("true_torque");
    let key = smoothed.or(denoised).unwrap_or(&[]);
    let w = window(key);
    let cut = |y: &[f64]| y.get(w.clone()).unwrap_or(&[]).to_vec();
    let x = cut(time);
    let mut series = Vec::new();
    for name in [measured.unwrap_or("measured_torque"), "torque", "torque_denoised", "torque_smoothed"] {
        if let Some(y) = t.column(name) {
            series.push(Series { name: name.into(), x: x.clone(), y: cut(y) });
        }
    }
    let sd = t.column("torque_smoothed_sd");
    if let (Some(s), Some(sd)) = (smoothed, sd) {
        for (sign, label) in [(1.0, "torque_smoothed + 1σ"), (-1.0, "torque_smoothed − 1σ")] {
            let y: Vec<f64> = w.clone().map(|k| s[k] + sign * sd[k]).collect();
            series.push(Series { name: label.into(), x: x.clone(), y });
        }
    }
    if let Some(y) = truth {
        series.push(Series { name: "true_torque".into(), x: x.clone(), y: cut(y) });
    }
    let plot = LinePlot {
        title: format!("Clean, denoised and smoothed torque against the measurement, {} samples", x.len()),
        x_label: "time (s)".into(),
        y_label: "torque (N·m)".into(),
        series,
        ..Default::default()
    };
    body += &plot.to_svg();
    body += "<p><code>torque</code>: measurement minus ripple and misalignment (no delay). ";
    if smoothed.is_some() {
        body += "<code>torque_smoothed</code>: <code>torque</code> after the Rauch–Tung–Striebel smoother, \
                 smoothed as a level-and-rate torque state (offline, zero phase, 40 Hz; a jump beyond 4σ \
                 restarts it, so steps stay sharp), <code>torque_smoothed_sd</code> its 1σ. ";
    }
    if denoised.is_some() {
        match cfg.and_then(|c| c.denoiser().ok().flatten().map(|d| (c, d))) {
            Some((c, d)) => {
                body += &esc(&format!(
                    "torque_denoised: causal, {} Hz torque-state filter, group delay at DC {:.2} ms \
                     ({:.2} samples; steps the filter detected restart it).",
                    c.filter.torque_bandwidth_hz.unwrap_or(f64::NAN),
                    1e3 * d.group_delay_s(),
                    d.group_delay_s() * c.filter.sample_rate_hz
                ))
            }
            None => body += "torque_denoised: causal (its group delay needs the joint config: --config).",
        }
    }
    body += "</p>";
    if let Some(truth) = truth {
        let mut rows = Vec::new();
        for name in ["torque", "torque_denoised", "torque_smoothed"] {
            let Some(y) = t.column(name) else { continue };
            let pairs: Vec<(f64, f64, usize)> = (0..y.len().min(truth.len()))
                .map(|k| (y[k], truth[k], k))
                .filter(|p| (p.0 - p.1).is_finite())
                .collect();
            let n = pairs.len().max(1) as f64;
            let rms = (pairs.iter().map(|p| (p.0 - p.1).powi(2)).sum::<f64>() / n).sqrt();
            let coverage = match (name, sd) {
                ("torque_smoothed", Some(sd)) => {
                    let inside = pairs.iter().filter(|p| (p.0 - p.1).abs() <= sd[p.2]).count();
                    format!("{:.1} %", 100.0 * inside as f64 / n)
                }
                _ => String::new(),
            };
            rows.push(vec![name.to_string(), format!("{rms:.5}"), coverage]);
        }
        body += &table(&["signal", "RMS error vs true_torque N·m", "truth within ±1σ (68.3 % when honest)"], &rows);
    }
    Some(Section { title: "Filter: smoothed and denoised torque".into(), body })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn table_of(cols: &[(&str, Vec<f64>)]) -> Table {
        Table {
            columns: cols.iter().map(|c| c.0.to_string()).collect(),
            data: cols.iter().map(|c| c.1.clone()).collect(),
        }
    }

    #[test]
    fn section_shows_the_smoothed_band_and_its_coverage() {
        let n = 3000;
        let time: Vec<f64> = (0..n).map(|k| k as f64 * 1e-3).collect();
        let truth: Vec<f64> = (0..n).map(|k| if k < 1800 { 1.0 } else { 3.0 }).collect();
        // Errors alternate ±0.5 and ±2 against a σ of 1: half the samples covered.
        let smoothed: Vec<f64> = (0..n).map(|k| truth[k] + if k % 2 == 0 { 0.5 } else { -2.0 }).collect();
        let t = table_of(&[
            ("time", time.clone()),
            ("measured_torque", truth.clone()),
            ("torque", truth.clone()),
            ("torque_smoothed", smoothed),
            ("torque_smoothed_sd", vec![1.0; n]),
            ("true_torque", truth),
        ]);
        let s = section(&t, &time, None, None).unwrap();
        assert!(s.body.contains("torque_smoothed + 1σ") && s.body.contains("<svg"), "plot with the band");
        assert!(s.body.contains("50.0 %"), "coverage: {}", s.body);
        assert!(s.body.contains(">1.45774<"), "RMS of ±0.5/±2: {}", s.body);
        assert_eq!(window(&t.data[3]), 800..2800, "the window is centred on the step");
        assert!(section(&table_of(&[("time", time.clone())]), &time, None, None).is_none());
    }
}
