//! `strainwave calibrate`: fit a calibration from experiments, print the report, write the file.
//!
//! Thin over `strainwave_analysis::calibration`: this file reads the recordings, checks
//! the columns, hands the rows to the library and prints what comes back.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use strainwave_analysis::calibration::{
    calibrate_gain, fit_affine, fit_speed_dependent, held_rows, quantization_step, CalibrationError, Experiment,
    Extrapolation, GainFit, SpeedBins, SpeedDependence,
};

mod rows;
mod summary;

use crate::report::calibration::{
    affine_report, din_report, din_series, fit_plots, gain_report, speed_report, stacked_svg, ExperimentRows,
};
use crate::report::text::compact;

/// The model to fit.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum Model {
    /// `T = g V` per experiment; final gain = mean, consistency = std/mean (Taghirad and Bélanger (1999)).
    Gain,
    /// `T = α x + β` on quasi-static data (the embedded-sensor article); use `--held` for held loads only.
    Static,
    /// `T = α x + β` on sinusoidal-load data (the embedded-sensor article); `--speed` adds a per-speed look.
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
    /// Input recordings (any format `convert` reads), one per experiment; repeat the option.
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
    #[arg(long = "time-column", value_name = "COL", default_value = "time")]
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
    /// Write a JSON summary here: coefficients with standard errors, fit statistics,
    /// rows used and left out (written atomically).
    #[arg(long, value_name = "FILE")]
    pub summary_json: Option<PathBuf>,
    /// Write the fit and its residuals as SVG.
    #[arg(long, value_name = "FILE.svg")]
    pub plot: Option<PathBuf>,
    /// Print nothing but errors.
    #[arg(long, short)]
    pub quiet: bool,
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

/// How many times the column's range a reference or sensor value may be: a calibration
/// spans one range, so a value far beyond it is a glitch or a unit slip that a
/// least-squares fit would follow (one row of 4e9 N·m made the gain 5000 times too large).
const OUTLIER_FACTOR: f64 = 100.0;

/// Fewest rows the check runs on (fewer: every row may matter).
const OUTLIER_MIN_ROWS: usize = 20;

/// An error naming the row of `c` (column `name` of `path`) whose magnitude is over
/// [`OUTLIER_FACTOR`] times the column's range: its largest magnitude once the largest
/// 1 % (at least 3) are set aside, so that neither a few glitches nor long idle stretches
/// near zero set it.
/// `times`: the rows' times, to name a row the reader made.
fn refuse_outlier(c: &[f64], (path, times): (&Path, Option<&[f64]>), name: &str) -> Result<()> {
    if c.len() < OUTLIER_MIN_ROWS {
        return Ok(());
    }
    let mut size: Vec<f64> = c.iter().map(|v| v.abs()).collect();
    size.sort_by(f64::total_cmp);
    let range = size[size.len() - 1 - (size.len() / 100).max(3)];
    if range == 0.0 {
        return Ok(());
    }
    if let Some(row) = c.iter().position(|v| v.abs() > OUTLIER_FACTOR * range) {
        bail!(
            "{}: {}: `{name}` = {:?} is over {OUTLIER_FACTOR} times the column's range (its largest magnitude \
             {range:?} without the top 1 %); a glitch or a unit slip? Fix or drop the row",
            path.display(),
            strainwave_io::row_label(
                &path.to_string_lossy(),
                row as u64 + 1,
                times.and_then(|t| t.get(row)).copied().unwrap_or(f64::NAN),
                "row"
            ),
            c[row]
        );
    }
    Ok(())
}

/// Reads the inputs into experiments: one per file, or one per value of `--experiment-column`.
fn load(a: &Args, need_speed: bool, mounting: Option<&str>) -> Result<Vec<ExperimentRows>> {
    let mut out = Vec::new();
    for path in &a.inputs {
        let t = strainwave_io::read_all(path)?;
        if t.rows() == 0 {
            bail!("{}: no data rows", path.display());
        }
        let reference = column(&t, path, &a.reference, "--reference")?;
        let sensor = column(&t, path, &a.sensor, "--sensor")?;
        let times = t.column(&a.time);
        refuse_outlier(reference, (path, times), &a.reference)?;
        refuse_outlier(sensor, (path, times), &a.sensor)?;
        let speed = match (&a.speed, need_speed) {
            (Some(s), _) => Some(column(&t, path, s, "--speed")?),
            (None, true) => bail!("--model {} needs --speed COL", a.model.name()),
            (None, false) => None,
        };
        let time = match a.held {
            Some(_) => Some(column(&t, path, &a.time, "--time-column (needed by --held)")?),
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
                file: path.display().to_string(),
                file_rows: rows.iter().map(|&i| i as u64 + 1).collect(),
                file_times: pick(t.column(&a.time)),
            });
        }
    }
    Ok(out)
}

/// Keeps the held rows of each experiment (library: `held_rows`).
fn keep_held(exps: &mut [ExperimentRows], hold_s: f64, band: Option<f64>, cols: &rows::Columns) -> Result<String> {
    let all: Vec<f64> = exps.iter().flat_map(|e| e.reference.iter().copied()).collect();
    let span =
        all.iter().copied().fold(f64::NEG_INFINITY, f64::max) - all.iter().copied().fold(f64::INFINITY, f64::min);
    let band = band.unwrap_or(0.02 * span);
    let (mut kept, mut total) = (0, 0);
    for e in exps.iter_mut() {
        // Checked here so that the row named is the file's (the library counts the experiment's rows).
        if let Some(i) = (1..e.time.len()).find(|&i| e.time[i] < e.time[i - 1]) {
            let (t, before) = (e.time[i], e.time[i - 1]);
            match rows::locate_in(e, i) {
                Some(at) => bail!("{}: {}: --held: time goes backwards ({t} s after {before} s)", at.file, at.name),
                None => bail!("--held on `{}`: row {}: time goes backwards ({t} s after {before} s)", e.label, i + 1),
            }
        }
        let h = held_rows(&e.time, &e.reference, hold_s, band)
            .map_err(|err| rows::experiment_error(e, cols, &format!("--held on `{}`", e.label), err))?;
        let keep = |v: &mut Vec<f64>| {
            if !v.is_empty() {
                *v = v.iter().zip(&h).filter(|(_, &k)| k).map(|(x, _)| *x).collect();
            }
        };
        total += h.len();
        for v in [&mut e.reference, &mut e.sensor, &mut e.speed, &mut e.time, &mut e.mounting] {
            keep(v);
        }
        if !e.file_rows.is_empty() {
            e.file_rows = e.file_rows.iter().zip(&h).filter(|(_, &k)| k).map(|(r, _)| *r).collect();
        }
        if !e.file_times.is_empty() {
            e.file_times = e.file_times.iter().zip(&h).filter(|(_, &k)| k).map(|(t, _)| *t).collect();
        }
        if e.reference.is_empty() {
            bail!(
                "--held {hold_s:?}: no row of `{}` has its reference steady within {} N·m peak to peak for that long; \
                 shorten --held or widen --held-band",
                e.label,
                compact(band, 3)
            );
        }
        kept += e.reference.len();
    }
    let band = compact(band, 3);
    Ok(format!("held rows: {kept} of {total} (reference steady within {band} N·m peak to peak for {hold_s:?} s)\n"))
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

/// Runs `calibrate`.
pub fn run(a: &Args) -> Result<()> {
    let outputs = [("--out", &a.out), ("--summary-json", &a.summary_json), ("--plot", &a.plot)];
    let outputs = outputs.into_iter().filter_map(|(flag, p)| Some((flag, p.as_deref()?)));
    for (_, out) in outputs.clone() {
        strainwave_io::output::refuse_input_as_output(out, a.inputs.iter().map(|p| p.as_path()))?;
    }
    strainwave_io::output::refuse_shared_outputs(outputs)?;
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
    let cols = rows::Columns { reference: &a.reference, sensor: &a.sensor, speed: a.speed.as_deref() };
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
    let rows_read: usize = exps.iter().map(|e| e.reference.len()).sum();
    if let Some(hold) = a.held {
        out += &keep_held(&mut exps, hold, a.held_band, &cols)?;
    }
    let rows_held: usize = exps.iter().map(|e| e.reference.len()).sum();
    let fs = a.full_scale;
    let all = pooled(&exps);
    let speed_col = a.speed.as_deref().unwrap_or("");
    // Coefficients with standard errors, where they come from, per-experiment fits,
    // and the speed model's row counts, for --summary-json.
    let coefficients;
    let se_source;
    let mut experiments = Vec::new();
    let mut speed_rows = serde_json::Value::Null;
    let mut file = match a.model {
        Model::Gain => {
            let fit = if a.with_offset { GainFit::WithOffset } else { GainFit::ThroughOrigin };
            let e: Vec<Experiment> = exps.iter().map(|e| Experiment::new(&e.label, &e.reference, &e.sensor)).collect();
            let g = calibrate_gain(&e, fit, fs).map_err(|err| gain_error(&exps, &cols, err))?;
            out += &gain_report(&g);
            let (c, source, per) = summary::gain(&g);
            (coefficients, se_source, experiments) = (c, source, per);
            g.to_file()
        }
        Model::Static | Model::Dynamic => {
            let name = if a.model == Model::Static { "static" } else { "dynamic" };
            let f = fit_affine(&all.sensor, &all.reference, fs).map_err(|err| {
                rows::pooled_error(&exps, &cols, &format!("fitting the {name} model to {}", names.join(", ")), err)
            })?;
            out += &affine_report(name, &f);
            coefficients = summary::affine(&f);
            se_source = "residuals of the least-squares fit";
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
                .map_err(|err| {
                    let doing = format!("fitting the speed model to {} (speed column `{speed_col}`)", names.join(", "));
                    rows::pooled_error(&exps, &cols, &doing, err)
                })?;
            out += &speed_report(&f, speed_col);
            let (c, source) = summary::speed(&f, &all.sensor, &all.reference, &all.speed);
            (coefficients, se_source) = (c, source);
            speed_rows = serde_json::json!({
                "unbinned": f.rows_unbinned,
                "extrapolated": f.rows_extrapolated,
                "rejected": f.rows_rejected,
            });
            f.to_file()
        }
    };
    if let Some(m) = file.metrics.as_ref().filter(|m| !(m.rms_error_nm.is_finite() && m.mean_error_nm.is_finite())) {
        // Finite values whose squares overflow: name the row of the largest one.
        let size = |k: usize| all.reference[k].abs().max(all.sensor[k].abs());
        let k = (0..all.reference.len()).max_by(|&i, &j| size(i).total_cmp(&size(j))).unwrap_or(m.max_abs_row);
        let at = rows::locate(&exps, k).map_or(format!("row {}", k + 1), |at| format!("{}: {}", at.file, at.name));
        bail!(
            "{at}: the fit's error figures are not finite with `{}` = {:?} and `{}` = {:?} (values this large overflow; \
             check the columns' scale)",
            a.reference,
            all.reference[k],
            a.sensor,
            all.sensor[k]
        );
    }
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
        let ev = shown
            .apply(&all.sensor, speed)
            .map_err(|err| rows::pooled_error(&exps, &cols, "evaluating the calibration for --plot", err))?;
        let plots =
            fit_plots(&format!("{} model", a.model.name()), &all.sensor, &all.reference, &ev.torque_nm, &a.sensor);
        strainwave_io::output::write_file(p, stacked_svg(&plots)).context("--plot")?;
        let _ = writeln!(out, "wrote {}", p.display());
    }
    if let Some(p) = &a.summary_json {
        let v = serde_json::json!({
            "model": a.model.name(),
            "inputs": names,
            "reference": a.reference,
            "sensor": a.sensor,
            "speed": a.speed,
            "experiments": exps.len(),
            "rows": {
                "read": rows_read,
                "used": rows_held,
                "skipped_not_held": rows_read - rows_held,
                "speed_model": speed_rows,
            },
            "coefficients": coefficients,
            "std_error_source": se_source,
            "per_experiment": experiments,
            "fit": file.metrics.as_ref().map(|m| {
                let mut v = summary::statistics(m, &all.reference);
                // The largest error's file and data row, when the metrics cover every row.
                if let Some(at) = (m.rows == all.reference.len()).then(|| rows::locate(&exps, m.max_abs_row)).flatten() {
                    v["max_abs_file"] = at.file.into();
                    v["max_abs_file_row"] = at.row.into();
                }
                v
            }),
        });
        strainwave_io::output::write_file(p, summary::document(v)).context("--summary-json")?;
        let _ = writeln!(out, "wrote {}", p.display());
    }
    if let Some(p) = &a.out {
        let text = file.to_toml_string().with_context(|| format!("--out {}", p.display()))?;
        strainwave_io::output::write_file(p, text).context("--out")?;
        let _ = writeln!(out, "wrote {}", p.display());
    }
    if !a.quiet {
        crate::stdout::print_report(&out, [a.out.as_deref(), a.summary_json.as_deref(), a.plot.as_deref()])?;
    }
    Ok(())
}

/// A gain fit's error; one naming a row names the experiment's file and data row.
fn gain_error(exps: &[ExperimentRows], cols: &rows::Columns, err: CalibrationError) -> anyhow::Error {
    // The library names the experiment as "experiment `LABEL`".
    let which = match &err {
        CalibrationError::NonFiniteRow { what, .. } | CalibrationError::AtRow { what, .. } => {
            exps.iter().find(|e| *what == format!("experiment `{}`", e.label))
        }
        _ => None,
    };
    match which {
        Some(e) => rows::experiment_error(e, cols, &format!("fitting the gain of `{}`", e.label), err),
        // Named by its experiment (its file) already, or else by the files of the fit.
        None if err.to_string().contains("experiment `") => anyhow::anyhow!(err).context("fitting the gain"),
        None => {
            let files: Vec<&str> = exps.iter().map(|e| e.label.as_str()).collect();
            anyhow::anyhow!(err).context(format!("{}: fitting the gain", files.join(", ")))
        }
    }
}

fn speed_bins(a: &Args) -> SpeedBins {
    match &a.speed_edges {
        Some(e) => SpeedBins::Edges(e.clone()),
        None => SpeedBins::EqualWidth(a.bins.unwrap_or(3)),
    }
}
