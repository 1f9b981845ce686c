//! The printed and plotted calibration report that `calibrate` and the demo share: the
//! experiments' rows, text tables of the fits, the DIN figures, the fit-and-residual
//! plots. Formatting only; the numbers come from `strainwave_analysis::calibration`.

use std::fmt::Write as _;

use anyhow::{bail, Result};
use strainwave_analysis::calibration::{
    din51309_figures, group_by_levels, split_load_series, AffineFit, CalibrationError, DinOptions, DinReport,
    ErrorMetrics, Extrapolation, GainCalibration, GainFit, LoadSeries, SpeedFit,
};

use crate::report::plot::{LinePlot, Series};
use crate::report::text::text_table;

/// One experiment's rows, every value finite.
#[derive(Debug, Clone, Default)]
pub struct ExperimentRows {
    /// Label for reports and errors.
    pub label: String,
    /// Reference torque, N·m.
    pub reference: Vec<f64>,
    /// Sensor reading.
    pub sensor: Vec<f64>,
    /// Speed, rad/s (when asked for).
    pub speed: Vec<f64>,
    /// Time, s (for `--held`).
    pub time: Vec<f64>,
    /// Mounting position, degrees (for `--din`).
    pub mounting: Vec<f64>,
    /// The file the rows come from, for messages (empty: no file).
    pub file: String,
    /// The data row (1-based, as users count) of each entry in the file (empty: none).
    pub file_rows: Vec<u64>,
    /// The time (s) of each entry, that names a row the reader made (resampled or
    /// aligned) as users can find it (empty: none).
    pub file_times: Vec<f64>,
}

impl ExperimentRows {
    /// Entry `row`'s name in its file, as messages give it: `{plain} N` of the file, or
    /// `resampled row N (time T s)` where the rows are not the file's; `None` without a
    /// file.
    pub fn row_name(&self, row: usize, plain: &str) -> Option<String> {
        let n = self.file_rows.get(row).copied()?;
        let t = self.file_times.get(row).copied().unwrap_or(f64::NAN);
        (!self.file.is_empty()).then(|| strainwave_io::row_label(&self.file, n, t, plain))
    }
}

/// Columns of the error table.
pub const METRICS_HEADER: [&str; 6] = ["fit", "rows", "max |e| N·m", "RMS N·m", "mean e N·m", "RMS % FS"];

/// One row of the error table.
pub fn metrics_row(name: &str, m: &ErrorMetrics) -> Vec<String> {
    vec![
        name.to_string(),
        m.rows.to_string(),
        format!("{:.4}", m.max_abs_error_nm),
        format!("{:.4}", m.rms_error_nm),
        format!("{:+.4}", m.mean_error_nm),
        m.rms_percent_fs.map_or("-".into(), |p| format!("{p:.3}")),
    ]
}

/// The gain table: per experiment, then the final gain and its consistency.
pub fn gain_report(g: &GainCalibration) -> String {
    let offset = g.fit == GainFit::WithOffset;
    let mut rows: Vec<Vec<String>> = g
        .experiments
        .iter()
        .map(|e| {
            let mut r = vec![
                e.label.clone(),
                e.metrics.rows.to_string(),
                format!("{:.5}", e.gain_nm_per_v),
                e.gain_std_error_nm_per_v.map_or("-".into(), |s| format!("{s:.5}")),
            ];
            if offset {
                r.push(format!("{:+.4}", e.offset_nm));
            }
            r.extend([format!("{:.4}", e.metrics.max_abs_error_nm), format!("{:.4}", e.metrics.rms_error_nm)]);
            r
        })
        .collect();
    let mut header = vec!["experiment", "rows", "gain N·m/V", "std err"];
    if offset {
        header.push("offset N·m");
    }
    header.extend(["max |e| N·m", "RMS N·m"]);
    let mut last = vec![
        "final (mean)".into(),
        g.metrics.rows.to_string(),
        format!("{:.5}", g.gain_nm_per_v),
        g.gain_std_nm_per_v.map_or("-".into(), |s| format!("sd {s:.5}")),
    ];
    if offset {
        last.push(format!("{:+.4}", g.offset_nm));
    }
    last.extend([format!("{:.4}", g.metrics.max_abs_error_nm), format!("{:.4}", g.metrics.rms_error_nm)]);
    rows.push(last);
    let mut s = text_table(&header, &rows);
    let _ = writeln!(
        s,
        "  gain {:.5} N·m/V, consistency (sample std / mean over {} experiments) {}",
        g.gain_nm_per_v,
        g.experiments.len(),
        g.consistency_percent().map_or("n/a (one experiment)".into(), |c| format!("{c:.3} %"))
    );
    s
}

/// The affine fit: coefficients and the error table.
pub fn affine_report(name: &str, f: &AffineFit) -> String {
    let se = |v: Option<f64>| v.map_or(String::new(), |s| format!(" ± {s:.5}"));
    let mut s = format!(
        "  {name}: T_ref = {:.5}{} · sensor {:+.5}{} N·m\n",
        f.alpha,
        se(f.alpha_std_error),
        f.beta_nm,
        se(f.beta_std_error_nm)
    );
    s += &text_table(&METRICS_HEADER, &[metrics_row(name, &f.metrics)]);
    s
}

/// The speed model: coefficients, extrapolation choice and the error table.
pub fn speed_report(f: &SpeedFit, speed_col: &str) -> String {
    let mut s = String::new();
    if f.bins.is_empty() {
        let rows: Vec<Vec<String>> = (0..f.alpha.len())
            .map(|k| vec![format!("ω^{k}"), format!("{:.6e}", f.alpha[k]), format!("{:.6e}", f.beta_nm[k])])
            .collect();
        s += &text_table(&["term", "α coefficient", "β coefficient N·m"], &rows);
    } else {
        let rows: Vec<Vec<String>> = f
            .bins
            .iter()
            .map(|b| {
                vec![
                    format!("[{:.3}, {:.3}]", b.lo_rad_s, b.hi_rad_s),
                    b.rows.to_string(),
                    format!("{:.3}", b.mean_speed_rad_s),
                    format!("{:.5}", b.alpha),
                    format!("{:+.5}", b.beta_nm),
                ]
            })
            .collect();
        s += &text_table(&["bin rad/s", "rows", "breakpoint rad/s", "α", "β N·m"], &rows);
        for (lo, hi) in &f.empty_bins {
            let _ = writeln!(s, "  bin [{lo:.3}, {hi:.3}] rad/s has no rows: skipped");
        }
    }
    let (lo, hi) = f.speed_range_rad_s;
    let how = match f.extrapolation {
        Extrapolation::Clamp => "evaluated with the end coefficients held (clamp)",
        Extrapolation::Linear => "evaluated along the end slope (linear)",
        Extrapolation::Reject => "refused by the calibration (reject) and left out of the metrics",
    };
    let _ = writeln!(
        s,
        "  extrapolation `{}`: {} rows of `{speed_col}` lie outside the calibrated range [{lo:.3}, {hi:.3}] rad/s, {how}",
        match f.extrapolation {
            Extrapolation::Clamp => "clamp",
            Extrapolation::Linear => "linear",
            Extrapolation::Reject => "reject",
        },
        f.rows_extrapolated,
    );
    if f.rows_unbinned > 0 {
        let _ = writeln!(s, "  {} rows lie outside the bin edges: not fitted, extrapolated as above", f.rows_unbinned);
    }
    let name = if f.bins.is_empty() { "speed polynomial" } else { "speed table" };
    s += &text_table(&METRICS_HEADER, &[metrics_row(name, &f.metrics)]);
    s
}

/// Loading series of every experiment (library: `split_load_series`), with labels. A
/// row error names the file and its data row; a series error names the series by its
/// label, steps counted from 1.
pub fn din_series(exps: &[ExperimentRows]) -> Result<(Vec<LoadSeries>, Vec<String>)> {
    let (mut series, mut labels) = (Vec::new(), Vec::new());
    for e in exps {
        let m = (!e.mounting.is_empty()).then_some(e.mounting.as_slice());
        let s = split_load_series(&e.reference, &e.sensor, m).map_err(|err| din_row_error(e, err))?;
        for (k, x) in s.into_iter().enumerate() {
            let label = format!("{} series {}", e.label, k + 1);
            // Checked one by one, so an error names this series.
            if let Err(err) = group_by_levels(std::slice::from_ref(&x)) {
                let why = match err {
                    CalibrationError::Invalid { why, .. } => why,
                    other => other.to_string(),
                };
                match e.file.is_empty() {
                    true => bail!("--din on `{label}`: {why}"),
                    false => bail!("{}: --din on `{label}`: {why}", e.file),
                }
            }
            labels.push(label);
            series.push(x);
        }
    }
    Ok((series, labels))
}

/// A `split_load_series` error with the row given as the file's data row.
fn din_row_error(e: &ExperimentRows, err: CalibrationError) -> anyhow::Error {
    let at = |row: usize| e.row_name(row, "data row").unwrap_or_else(|| format!("data row {}", row + 1));
    let (file, label) = (&e.file, &e.label);
    match err {
        CalibrationError::AtRow { row, why, .. } if !file.is_empty() => {
            anyhow::anyhow!("{file}: {} (--din on `{label}`): {why}", at(row))
        }
        CalibrationError::NonFiniteRow { row, column, .. } if !file.is_empty() => {
            anyhow::anyhow!("{file}: {} (--din on `{label}`): `{column}` is not finite", at(row))
        }
        other => anyhow::anyhow!("--din on `{label}`: {other}"),
    }
}

/// DIN figures per group of series sharing their torque steps.
pub fn din_groups(series: &[LoadSeries], resolution: Option<f64>) -> Result<Vec<(Vec<usize>, DinReport)>> {
    let opts = DinOptions { resolution, ..DinOptions::default() };
    let mut out = Vec::new();
    for g in group_by_levels(series)? {
        let members: Vec<LoadSeries> = g.iter().map(|&i| series[i].clone()).collect();
        let r = din51309_figures(&members, &opts)?;
        out.push((g, r));
    }
    Ok(out)
}

fn pct(v: Option<f64>) -> String {
    v.map_or("-".into(), |x| format!("{:.3}", 100.0 * x))
}

/// The DIN report: one table per group, one row per torque step.
pub fn din_report(series: &[LoadSeries], labels: &[String], resolution: Option<f64>) -> Result<String> {
    let mut s = String::new();
    for (k, (g, r)) in din_groups(series, resolution)?.iter().enumerate() {
        let pos: Vec<String> = r.mounting_positions_deg.iter().map(|p| format!("{p}°")).collect();
        let _ = writeln!(
            s,
            "  group {}: {} series ({} … {}), mounting positions {}",
            k + 1,
            g.len(),
            labels[g[0]],
            labels[g[g.len() - 1]],
            pos.join(", ")
        );
        let rows: Vec<Vec<String>> = r
            .steps
            .iter()
            .map(|st| {
                vec![
                    format!("{:.3}", st.torque_nm),
                    format!("{:.5}", st.mean_deflection),
                    pct(st.repeatability),
                    pct(st.reproducibility),
                    pct(st.reversibility),
                    format!("{:+.3}", 100.0 * st.interpolation),
                    pct(st.resolution),
                ]
            })
            .collect();
        s += &text_table(&["torque N·m", "X̄_r", "b' %", "b %", "h %", "f_c %", "r %"], &rows);
        let _ = writeln!(s, "  zero error f0 max {} %", pct(r.max_zero_error));
    }
    s += "  (b' needs two series in one position; h needs unloading; f0 a zero reading after unloading)\n";
    Ok(s)
}

/// Fit and residual plots from the calibration applied to the rows.
pub fn fit_plots(
    title: &str,
    sensor: &[f64],
    reference: &[f64],
    calibrated: &[f64],
    sensor_label: &str,
) -> [LinePlot; 2] {
    let mut by_x: Vec<usize> = (0..sensor.len()).collect();
    by_x.sort_by(|&i, &j| sensor[i].total_cmp(&sensor[j]));
    let mut by_t = by_x.clone();
    by_t.sort_by(|&i, &j| reference[i].total_cmp(&reference[j]));
    let pick = |idx: &[usize], v: &[f64]| idx.iter().map(|&i| v[i]).collect::<Vec<f64>>();
    let fit = LinePlot {
        title: format!("{title}: reference torque against the sensor"),
        x_label: sensor_label.to_string(),
        y_label: "torque (N·m)".into(),
        series: vec![
            Series { name: "reference".into(), x: pick(&by_x, sensor), y: pick(&by_x, reference) },
            Series { name: "calibrated sensor".into(), x: pick(&by_x, sensor), y: pick(&by_x, calibrated) },
        ],
        ..Default::default()
    };
    let resid: Vec<f64> = by_t.iter().map(|&i| calibrated[i] - reference[i]).collect();
    let res = LinePlot {
        title: format!("{title}: residual (calibrated − reference) against the reference torque"),
        x_label: "reference torque (N·m)".into(),
        y_label: "residual (N·m)".into(),
        series: vec![Series { name: "residual".into(), x: pick(&by_t, reference), y: resid }],
        ..Default::default()
    };
    [fit, res]
}

/// Two plots stacked in one standalone SVG file.
pub fn stacked_svg(plots: &[LinePlot]) -> String {
    let (w, h) = (860, 320);
    let mut s = format!(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{w}\" height=\"{}\" viewBox=\"0 0 {w} {}\">",
        h * plots.len(),
        h * plots.len()
    );
    for (k, p) in plots.iter().enumerate() {
        s += &p.to_svg().replacen("<svg ", &format!("<svg x=\"0\" y=\"{}\" width=\"{w}\" height=\"{h}\" ", k * h), 1);
    }
    s + "</svg>\n"
}
