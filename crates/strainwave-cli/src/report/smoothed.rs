//! The report's section on the offline smoothed torque (`torque_smoothed` and its 1σ
//! band `torque_smoothed_sd`, from `filter --smooth`) and the real-time denoised torque
//! (`torque_denoised`), kept while the recording streams through once, in memory that
//! does not grow with it: a min/max decimation per pixel column of the measurement, the
//! smoothed torque and both edges of its band over the whole recording, one short
//! window at full rate, and the sums behind the figures.

use super::html::{esc, table, Section};
use super::plot::{LinePlot, Series};
use super::streaming::{ColumnStats, MinMaxDecimator};

/// Rows of the full-rate window; it starts at [`ZOOM_START_ROW`] when the recording
/// reaches that far (past the start-up), else at its first row.
const ZOOM_ROWS: usize = 400;
/// First row of the preferred full-rate window.
const ZOOM_START_ROW: u64 = 1000;

/// Column indices the section reads.
#[derive(Debug, Clone, Copy)]
struct At {
    measured: usize,
    smoothed: usize,
    sd: usize,
    truth: Option<usize>,
}

/// One full-rate window: time, measurement, smoothed torque, its σ, truth (NaN: none).
#[derive(Debug, Clone, Default)]
struct Window {
    rows: Vec<[f64; 5]>,
}

impl Window {
    fn push(&mut self, v: [f64; 5]) {
        if self.rows.len() < ZOOM_ROWS {
            self.rows.push(v);
        }
    }
}

/// What the section keeps while the recording streams.
#[derive(Debug, Clone)]
pub struct SmoothedTorque {
    at: At,
    measured_name: String,
    plots: [MinMaxDecimator; 4],
    start: Window,
    later: Window,
    error: ColumnStats,
    sd: ColumnStats,
    covered: u64,
    compared: u64,
}

impl SmoothedTorque {
    /// The section's state when `columns` has `torque_smoothed`, `torque_smoothed_sd`
    /// and the measurement `measured` (`None` otherwise); `plot_columns` pixel columns.
    pub fn new(columns: &[String], measured: &str, plot_columns: usize) -> Option<Self> {
        let at = |name: &str| columns.iter().position(|c| c == name);
        let at = At {
            measured: at(measured)?,
            smoothed: at("torque_smoothed")?,
            sd: at("torque_smoothed_sd")?,
            truth: at("true_torque"),
        };
        Some(Self {
            at,
            measured_name: measured.to_string(),
            plots: std::array::from_fn(|_| MinMaxDecimator::new(plot_columns)),
            start: Window::default(),
            later: Window::default(),
            error: ColumnStats::default(),
            sd: ColumnStats::default(),
            covered: 0,
            compared: 0,
        })
    }

    /// Takes row number `row` (1-based) at time `t_s`.
    pub fn push(&mut self, row: u64, t_s: f64, values: &[f64]) {
        let (y, x, sd) = (values[self.at.measured], values[self.at.smoothed], values[self.at.sd]);
        let truth = self.at.truth.map_or(f64::NAN, |k| values[k]);
        for (plot, v) in self.plots.iter_mut().zip([y, x, x - sd, x + sd]) {
            plot.push(t_s, v);
        }
        let window = [t_s, y, x, sd, truth];
        self.start.push(window);
        if row > ZOOM_START_ROW {
            self.later.push(window);
        }
        self.sd.push(sd);
        if truth.is_finite() && x.is_finite() && sd.is_finite() {
            self.error.push(x - truth);
            self.compared += 1;
            self.covered += u64::from((x - truth).abs() <= sd);
        }
    }

    /// The section: both plots and, with the truth, the RMS error and the coverage of
    /// the band; `noise_nm`: the sensor's white-noise floor, when the config states it.
    pub fn section(self, time_label: &str, noise_nm: Option<f64>) -> Section {
        let names = [self.measured_name.clone(), "torque_smoothed".into(), "−1σ".into(), "+1σ".into()];
        let series = names
            .iter()
            .zip(&self.plots)
            .map(|(n, d)| {
                let (x, y) = d.points();
                Series { name: n.clone(), x, y }
            })
            .collect();
        let whole = LinePlot {
            title: "Smoothed torque and its 1σ band against the measurement (minimum and maximum per pixel column)"
                .into(),
            x_label: format!("{time_label} (s)"),
            y_label: "torque (N·m)".into(),
            series,
            ..Default::default()
        };
        let window = if self.later.rows.len() == ZOOM_ROWS { self.later } else { self.start };
        let column = |k: usize| window.rows.iter().map(|r| r[k]).collect::<Vec<f64>>();
        let t = column(0);
        let (x, sd) = (column(2), column(3));
        let mut zoom = vec![
            Series { name: self.measured_name.clone(), x: t.clone(), y: column(1) },
            Series { name: "torque_smoothed".into(), x: t.clone(), y: x.clone() },
            Series { name: "−1σ".into(), x: t.clone(), y: x.iter().zip(&sd).map(|(a, b)| a - b).collect() },
            Series { name: "+1σ".into(), x: t.clone(), y: x.iter().zip(&sd).map(|(a, b)| a + b).collect() },
        ];
        if self.at.truth.is_some() {
            zoom.push(Series { name: "true_torque".into(), x: t, y: column(4) });
        }
        let zoom = LinePlot {
            title: format!("The same over {} rows at full rate", window.rows.len()),
            x_label: format!("{time_label} (s)"),
            y_label: "torque (N·m)".into(),
            series: zoom,
            ..Default::default()
        };
        let mut body = String::from(
            "<p><code>torque_smoothed</code> is the offline, zero-phase estimate of the transmitted torque \
             (<code>filter --smooth</code>): the clean torque smoothed as a level-and-rate state, load steps kept \
             sharp. <code>torque_smoothed_sd</code> is its 1σ band: the noise's share of its error (around fast \
             transients the lag adds to it).</p>",
        );
        body += &whole.to_svg();
        body += &zoom.to_svg();
        let mut rows =
            vec![vec!["RMS of the 1σ (torque_smoothed_sd)".to_string(), format!("{:.5} N·m", self.sd.rms())]];
        if let Some(n) = noise_nm {
            rows.push(vec!["white-noise floor (filter.noise_nm)".into(), format!("{n:.5} N·m")]);
        }
        if self.compared > 0 {
            let rms = self.error.rms();
            rows.push(vec!["RMS error against true_torque".into(), format!("{rms:.5} N·m")]);
            if let Some(n) = noise_nm.filter(|n| *n > 0.0) {
                rows.push(vec!["RMS error / floor".into(), format!("{:.3}", rms / n)]);
            }
            let coverage = 100.0 * self.covered as f64 / self.compared as f64;
            rows.push(vec!["truth within ±1σ (68 % when honest)".into(), format!("{coverage:.1} %")]);
        }
        body += &table(&["smoothed torque", "value"], &rows);
        Section { title: "Smoothed torque (offline)".into(), body }
    }
}

/// The section on `torque_denoised`: its bandwidth and group delay at DC when the config
/// sets `filter.torque_bandwidth_hz` (`delay`: bandwidth Hz, delay s), else how to find
/// them (`config_given`: a joint config was passed, without the key).
pub fn denoised_section(delay: Option<(f64, f64)>, config_given: bool) -> Section {
    let body = match delay {
        Some((bw, d)) => format!(
            "<p><code>torque_denoised</code> is the causal torque state at {} Hz \
             (<code>filter.torque_bandwidth_hz</code>): it lags the torque by its group delay at DC, \
             <b>{:.2} ms</b>. Load steps the canceller detects pass without the delay.</p>",
            esc(&format!("{bw}")),
            1e3 * d
        ),
        None if config_given => "<p><code>torque_denoised</code> is the causal torque state; its group delay at DC \
                                 follows from <code>filter.torque_bandwidth_hz</code>, which the joint config given \
                                 does not set: pass the one the recording was filtered with.</p>"
            .into(),
        None => "<p><code>torque_denoised</code> is the causal torque state; its group delay at DC follows from \
                 <code>filter.torque_bandwidth_hz</code>: pass the joint config (<code>--config</code>) that set \
                 it to have it stated here.</p>"
            .into(),
    };
    Section { title: "Denoised torque (real time)".into(), body }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn columns() -> Vec<String> {
        ["time", "measured_torque", "torque_smoothed", "torque_smoothed_sd", "true_torque"]
            .iter()
            .map(|s| s.to_string())
            .collect()
    }

    #[test]
    fn coverage_and_error_against_the_truth() {
        let mut s = SmoothedTorque::new(&columns(), "measured_torque", 100).unwrap();
        // Errors alternating 0.05 and 0.2 against a σ of 0.1: half covered.
        for k in 0..2000u64 {
            let e = if k % 2 == 0 { 0.05 } else { 0.2 };
            s.push(k + 1, k as f64 * 1e-3, &[k as f64 * 1e-3, 1.0, 1.0 + e, 0.1, 1.0]);
        }
        assert_eq!((s.covered, s.compared), (1000, 2000));
        assert!(s.plots.iter().all(|p| p.points().0.len() <= 400));
        let html = s.section("time", Some(0.1)).body;
        assert!(html.contains("50.0 %"), "{html}");
        assert!(html.contains("400 rows at full rate"), "{html}");
    }

    #[test]
    fn no_section_without_the_columns() {
        let cols: Vec<String> = ["time", "measured_torque", "torque_smoothed"].iter().map(|s| s.to_string()).collect();
        assert!(SmoothedTorque::new(&cols, "measured_torque", 100).is_none());
        assert!(SmoothedTorque::new(&columns(), "torque_raw", 100).is_none());
    }

    #[test]
    fn the_denoised_section_states_the_delay() {
        assert!(denoised_section(Some((20.0, 7.47e-3)), true).body.contains("7.47 ms"));
        assert!(denoised_section(None, false).body.contains("--config"));
        assert!(denoised_section(None, true).body.contains("does not set"));
    }
}
