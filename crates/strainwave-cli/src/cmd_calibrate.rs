//! `strainwave calibrate`: fit a calibration from experiments, print the report, write the file.
//!
//! Thin over `strainwave_analysis::calibration`: this file reads the recordings, checks
//! the columns, hands the rows to the library and prints what comes back.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use strainwave_analysis::calibration::{
    calibrate_gain, din51309_figures, fit_affine, fit_speed_dependent, group_by_levels, held_rows, quantization_step,
    split_load_series, AffineFit, DinOptions, DinReport, ErrorMetrics, Experiment, Extrapolation, GainCalibration,
    GainFit, LoadSeries, SpeedBins, SpeedDependence, SpeedFit,
};

use crate::report::plot::{LinePlot, Series};
use crate::report::text::text_table;

/// The model to fit.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum Model {
    /// `T = g V` per experiment; final gain = mean, consistency = std/mean (seed 000).
    Gain,
    /// `T = α x + β` on quasi-static data (seed 001); use `--held` for held loads only.
    Static,
    /// `T = α x + β` on sinusoidal-load data (seed 001); `--speed` adds a per-speed look.
    Dynamic,
    /// `α(ω)`, `β(ω)` as a lookup table over speed bins.
    SpeedTable,
    /// `α(ω)`, `β(ω)` as polynomials in speed.
    SpeedPoly,
}

impl Model {
    /// The name on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Model::Gain => "gain",
            Model::Static => "static",
            Model::Dynamic => "dynamic",
            Model::SpeedTable => "speed-table",
            Model::SpeedPoly => "speed-poly",
        }
    }
}

/// Policy outside the calibrated speed range.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum ExtrapolationArg {
    /// Hold the end coefficients.
    Clamp,
    /// Continue the end slope.
    Linear,
    /// Refuse: rows outside `--speed-edges` are an error; the file refuses such speeds.
    Reject,
}

impl From<ExtrapolationArg> for Extrapolation {
    fn from(e: ExtrapolationArg) -> Self {
        match e {
            ExtrapolationArg::Clamp => Extrapolation::Clamp,
            ExtrapolationArg::Linear => Extrapolation::Linear,
            ExtrapolationArg::Reject => Extrapolation::Reject,
        }
    }
}

/// Arguments of `calibrate`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Input recordings (CSV or Parquet), one per experiment; repeat the option.
    #[arg(long = "in", required = true, value_name = "REC")]
    pub inputs: Vec<PathBuf>,
    /// A column numbering the experiments inside each input (instead of one file each).
    #[arg(long, value_name = "COL")]
    pub experiment_column: Option<String>,
    /// Reference (applied) torque column, N·m.
    #[arg(long, value_name = "COL")]
    pub reference: String,
    /// Sensor column: bridge voltage (V) or an uncalibrated torque reading.
    #[arg(long, value_name = "COL")]
    pub sensor: String,
    /// Speed column, rad/s (speed-table, speed-poly; optional for dynamic).
    #[arg(long, value_name = "COL")]
    pub speed: Option<String>,
    /// The model.
    #[arg(long, value_enum, default_value = "gain")]
    pub model: Model,
    /// Gain model: fit `T = g V + c` instead of through the origin (writes a `static` file).
    #[arg(long)]
    pub with_offset: bool,
    /// Rated full-scale torque, N·m, for the % FS figures.
    #[arg(long, value_name = "NM")]
    pub full_scale: Option<f64>,
    /// Use only rows where the reference has been steady for this long, s (quasi-static).
    #[arg(long, value_name = "S")]
    pub held: Option<f64>,
    /// Peak-to-peak band of a steady reference for `--held`, N·m [default: 2 % of its span].
    #[arg(long, value_name = "NM", requires = "held")]
    pub held_band: Option<f64>,
    /// Time column for `--held`, s.
    #[arg(long, value_name = "COL", default_value = "time")]
    pub time: String,
    /// Speed table: this many equal-width bins between the smallest and largest speed.
    #[arg(long, value_name = "N", conflicts_with = "speed_edges")]
    pub bins: Option<usize>,
    /// Speed table: bin edges, rad/s, increasing (rows outside are not fitted).
    #[arg(long, value_name = "A,B,C", value_delimiter = ',', num_args = 1..)]
    pub speed_edges: Option<Vec<f64>>,
    /// Speed polynomial degree.
    #[arg(long, value_name = "N", default_value_t = 1)]
    pub degree: usize,
    /// Outside the calibrated speed range (speed models).
    #[arg(long, value_enum, default_value = "clamp")]
    pub extrapolation: ExtrapolationArg,
    /// DIN 51309 / EURAMET cg-14 figures: each experiment read as loading/unloading series
    /// (steps = runs of equal reference torque, series cut at zero torque).
    #[arg(long)]
    pub din: bool,
    /// Mounting-position column for `--din`, degrees [default: `position_deg` if present].
    #[arg(long, value_name = "COL")]
    pub mounting_column: Option<String>,
    /// Resolution of the sensor reading for `--din` [default: its quantization step].
    #[arg(long, value_name = "X")]
    pub resolution: Option<f64>,
    /// Write the calibration here (TOML; read by `filter` and `estimate`).
    #[arg(long, value_name = "FILE")]
    pub out: Option<PathBuf>,
    /// Write the fit and its residuals as SVG.
    #[arg(long, value_name = "FILE.svg")]
    pub plot: Option<PathBuf>,
    /// Print nothing but errors.
    #[arg(long, short)]
    pub quiet: bool,
}

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
}

fn column<'a>(t: &'a strainwave_io::Table, path: &Path, name: &str, option: &str) -> Result<&'a [f64]> {
    let c = t.column(name).with_context(|| {
        format!("{}: no column `{name}` for {option} (columns: {})", path.display(), t.columns.join(", "))
    })?;
    if let Some(row) = c.iter().position(|v| !v.is_finite()) {
        bail!(
            "{}: row {}, column `{name}`: {} is not a finite number; calibration data must be finite (fix or drop the row)",
            path.display(),
            row + 1,
            c[row]
        );
    }
    Ok(c)
}

/// Reads the inputs into experiments: one per file, or one per value of `--experiment-column`.
fn load(a: &Args, need_speed: bool, mounting: Option<&str>) -> Result<Vec<ExperimentRows>> {
    let mut out = Vec::new();
    for path in &a.inputs {
        let t = strainwave_io::read_all(path).with_context(|| format!("reading --in {}", path.display()))?;
        if t.rows() == 0 {
            bail!("{}: no data rows", path.display());
        }
        let reference = column(&t, path, &a.reference, "--reference")?;
        let sensor = column(&t, path, &a.sensor, "--sensor")?;
        let speed = match (&a.speed, need_speed) {
            (Some(s), _) => Some(column(&t, path, s, "--speed")?),
            (None, true) => bail!("--model {} needs --speed COL", a.model.name()),
            (None, false) => None,
        };
        let time = match a.held {
            Some(_) => Some(column(&t, path, &a.time, "--time (needed by --held)")?),
            None => None,
        };
        let mount = match mounting {
            Some(m) if t.column(m).is_some() || a.mounting_column.is_some() => {
                Some(column(&t, path, m, "--mounting-column")?)
            }
            _ => None,
        };
        let name = path.file_name().map_or_else(|| path.display().to_string(), |n| n.to_string_lossy().into_owned());
        // Rows per experiment, experiments in order of first appearance.
        let mut groups: Vec<(String, Vec<usize>)> = Vec::new();
        match &a.experiment_column {
            Some(col) => {
                let e = column(&t, path, col, "--experiment-column")?;
                let mut keys: Vec<f64> = Vec::new();
                for (row, &k) in e.iter().enumerate() {
                    match keys.iter().position(|&q| q == k) {
                        Some(g) => groups[g].1.push(row),
                        None => {
                            keys.push(k);
                            let label = if a.inputs.len() > 1 { format!("{name} exp {k}") } else { format!("exp {k}") };
                            groups.push((label, vec![row]));
                        }
                    }
                }
            }
            None => groups.push((name, (0..t.rows()).collect())),
        }
        for (label, rows) in groups {
            let pick = |c: Option<&[f64]>| c.map_or_else(Vec::new, |c| rows.iter().map(|&i| c[i]).collect());
            out.push(ExperimentRows {
                label,
                reference: pick(Some(reference)),
                sensor: pick(Some(sensor)),
                speed: pick(speed),
                time: pick(time),
                mounting: pick(mount),
            });
        }
    }
    Ok(out)
}

/// Keeps the held rows of each experiment (library: `held_rows`).
fn keep_held(exps: &mut [ExperimentRows], hold_s: f64, band: Option<f64>) -> Result<String> {
    let all: Vec<f64> = exps.iter().flat_map(|e| e.reference.iter().copied()).collect();
    let span =
        all.iter().copied().fold(f64::NEG_INFINITY, f64::max) - all.iter().copied().fold(f64::INFINITY, f64::min);
    let band = band.unwrap_or(0.02 * span);
    let (mut kept, mut total) = (0, 0);
    for e in exps.iter_mut() {
        let h = held_rows(&e.time, &e.reference, hold_s, band).with_context(|| format!("--held on `{}`", e.label))?;
        let keep = |v: &mut Vec<f64>| {
            if !v.is_empty() {
                *v = v.iter().zip(&h).filter(|(_, &k)| k).map(|(x, _)| *x).collect();
            }
        };
        total += h.len();
        for v in [&mut e.reference, &mut e.sensor, &mut e.speed, &mut e.time, &mut e.mounting] {
            keep(v);
        }
        kept += e.reference.len();
    }
    Ok(format!("held rows: {kept} of {total} (reference steady within {band:.3} N·m peak to peak for {hold_s} s)\n"))
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

fn pooled(exps: &[ExperimentRows]) -> ExperimentRows {
    let mut p = ExperimentRows { label: "all".into(), ..Default::default() };
    for e in exps {
        p.reference.extend_from_slice(&e.reference);
        p.sensor.extend_from_slice(&e.sensor);
        p.speed.extend_from_slice(&e.speed);
    }
    p
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

/// Loading series of every experiment (library: `split_load_series`), with labels.
pub fn din_series(exps: &[ExperimentRows]) -> Result<(Vec<LoadSeries>, Vec<String>)> {
    let (mut series, mut labels) = (Vec::new(), Vec::new());
    for e in exps {
        let m = (!e.mounting.is_empty()).then_some(e.mounting.as_slice());
        let s = split_load_series(&e.reference, &e.sensor, m).with_context(|| format!("--din on `{}`", e.label))?;
        for (k, x) in s.into_iter().enumerate() {
            labels.push(format!("{} series {}", e.label, k + 1));
            series.push(x);
        }
    }
    Ok((series, labels))
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

/// Runs `calibrate`.
pub fn run(a: &Args) -> Result<()> {
    let speed_model = matches!(a.model, Model::SpeedTable | Model::SpeedPoly);
    if a.model != Model::Gain && a.with_offset {
        bail!("--with-offset applies to --model gain (static and dynamic models always fit an offset)");
    }
    if (a.bins.is_some() || a.speed_edges.is_some()) && a.model != Model::SpeedTable && a.model != Model::Dynamic {
        bail!("--bins / --speed-edges apply to --model speed-table (or dynamic with --speed)");
    }
    let mounting = match (&a.mounting_column, a.din) {
        (Some(c), _) => Some(c.as_str()),
        (None, true) => Some("position_deg"),
        (None, false) => None,
    };
    let mut exps = load(a, speed_model, mounting)?;
    let mut out = String::new();
    let names: Vec<String> = a.inputs.iter().map(|p| p.display().to_string()).collect();
    let _ = writeln!(
        out,
        "calibration: model {}, reference `{}`, sensor `{}`, {} experiment(s) from {}",
        a.model.name(),
        a.reference,
        a.sensor,
        exps.len(),
        names.join(", ")
    );
    if let Some(hold) = a.held {
        out += &keep_held(&mut exps, hold, a.held_band)?;
    }
    let fs = a.full_scale;
    let all = pooled(&exps);
    let speed_col = a.speed.as_deref().unwrap_or("");
    let mut file = match a.model {
        Model::Gain => {
            let fit = if a.with_offset { GainFit::WithOffset } else { GainFit::ThroughOrigin };
            let e: Vec<Experiment> = exps.iter().map(|e| Experiment::new(&e.label, &e.reference, &e.sensor)).collect();
            let g = calibrate_gain(&e, fit, fs).context("fitting the gain")?;
            out += &gain_report(&g);
            g.to_file()
        }
        Model::Static | Model::Dynamic => {
            let name = if a.model == Model::Static { "static" } else { "dynamic" };
            let f = fit_affine(&all.sensor, &all.reference, fs).with_context(|| format!("fitting the {name} model"))?;
            out += &affine_report(name, &f);
            if a.model == Model::Dynamic && a.speed.is_some() {
                let bins = SpeedDependence::Table(speed_bins(a));
                match fit_speed_dependent(&all.sensor, &all.reference, &all.speed, &bins, a.extrapolation.into(), fs) {
                    Ok(t) => {
                        out += "  the same data per speed bin (for information; the file holds the dynamic fit):\n";
                        out += &speed_report(&t, speed_col);
                    }
                    Err(e) => {
                        let _ = writeln!(out, "  no per-speed look: {e}");
                    }
                }
            }
            if a.model == Model::Static {
                f.to_static_file()
            } else {
                f.to_dynamic_file()
            }
        }
        Model::SpeedTable | Model::SpeedPoly => {
            let dep = if a.model == Model::SpeedTable {
                SpeedDependence::Table(speed_bins(a))
            } else {
                SpeedDependence::Polynomial { degree: a.degree }
            };
            let f = fit_speed_dependent(&all.sensor, &all.reference, &all.speed, &dep, a.extrapolation.into(), fs)
                .with_context(|| format!("fitting the speed model (speed column `{speed_col}`)"))?;
            out += &speed_report(&f, speed_col);
            f.to_file()
        }
    };
    if a.din {
        let (series, labels) = din_series(&exps)?;
        let resolution = a.resolution.or_else(|| quantization_step(&all.sensor));
        let _ = writeln!(
            out,
            "DIN 51309 / EURAMET cg-14 figures ({} series; resolution {} of `{}`{}):",
            series.len(),
            resolution.map_or("unknown".into(), |r| format!("{r:.4e}")),
            a.sensor,
            if a.resolution.is_some() { "" } else { ", its quantization step" }
        );
        out += &din_report(&series, &labels, resolution)?;
    }
    file.description = Some(format!(
        "strainwave calibrate --model {}: reference `{}`, sensor `{}`, {} experiment(s) from {}",
        a.model.name(),
        a.reference,
        a.sensor,
        exps.len(),
        names.join(", ")
    ));
    if let Some(p) = &a.plot {
        let speed = (!all.speed.is_empty()).then_some(all.speed.as_slice());
        // The plot shows every row: rows a `reject` file would refuse are drawn clamped.
        let mut shown = file.clone();
        if shown.extrapolation == Some(Extrapolation::Reject) {
            shown.extrapolation = Some(Extrapolation::Clamp);
        }
        let ev = shown.apply(&all.sensor, speed).context("evaluating the calibration for --plot")?;
        let plots =
            fit_plots(&format!("{} model", a.model.name()), &all.sensor, &all.reference, &ev.torque_nm, &a.sensor);
        std::fs::write(p, stacked_svg(&plots)).with_context(|| format!("--plot {}", p.display()))?;
        let _ = writeln!(out, "wrote {}", p.display());
    }
    if let Some(p) = &a.out {
        file.save(p).with_context(|| format!("--out {}", p.display()))?;
        let _ = writeln!(out, "wrote {}", p.display());
    }
    if !a.quiet {
        crate::stdout::print(&out)?;
    }
    Ok(())
}

fn speed_bins(a: &Args) -> SpeedBins {
    match &a.speed_edges {
        Some(e) => SpeedBins::Edges(e.clone()),
        None => SpeedBins::EqualWidth(a.bins.unwrap_or(3)),
    }
}
