//! The demo's calibration section: the Taghirad gain calibration on the simulated
//! locked-wave-generator procedure (gain per experiment against the simulator's truth,
//! consistency, DIN 51309 figures), then the embedded-sensor article's static and dynamic models on the
//! simulated flexspline-fixed rig with their error table beside the paper's.

use std::fmt::Write as _;

use anyhow::{Context, Result};
use strainwave_analysis::calibration::{
    calibrate_gain, fit_affine, fit_speed_dependent, held_rows, quantization_step, Experiment, Extrapolation, GainFit,
    SpeedBins, SpeedDependence,
};
use strainwave_sim::calibration_rig::{LockedWgProcedure, COLUMNS};
use strainwave_sim::{presets, simulate};

use crate::report::calibration::{din_groups, din_series, fit_plots, ExperimentRows};
use crate::report::html::table;
use crate::report::plot::LinePlot;
use crate::report::text::text_table;

/// Taghirad and Bélanger (1999)'s gain, N·m/V, and consistency, %.
const TAGHIRAD_GAIN_NM_PER_V: f64 = 6.60;
const TAGHIRAD_CONSISTENCY_PERCENT: f64 = 2.0;
/// The embedded-sensor article's full scale (its % FS figures imply about 20 N·m).
const EMBEDDED_FULL_SCALE_NM: f64 = 20.0;
/// The embedded-sensor article's table: model, α, β N·m, max |e| N·m, RMS N·m, RMS % FS.
const EMBEDDED_ROWS: [(&str, f64, f64, f64, f64, f64); 2] =
    [("static", 1.284, -0.0812, 0.39, 0.21, 1.04), ("dynamic", 1.572, -0.0928, 0.64, 0.265, 1.27)];
/// Quasi-static rows: the reference steady for this long, s.
const HOLD_S: f64 = 0.6;

/// Text for the terminal, HTML for the report, plots.
pub fn section() -> Result<(String, String, Vec<LinePlot>)> {
    let mut text =
        String::from("\nsensor calibration (Taghirad and Bélanger 1999: gain and consistency; the embedded-sensor article: static and dynamic models):\n");
    let mut html = String::new();
    let mut plots = Vec::new();

    // Taghirad and Bélanger (1999): the locked-wave-generator procedure on the taghirad sensor.
    let scenario = presets::preset("taghirad")?;
    let run = LockedWgProcedure::default().run(&scenario)?;
    let col = |name: &str| COLUMNS.iter().position(|c| *c == name).with_context(|| format!("no `{name}` column"));
    let (ie, ipos, itemp, irange) = (col("experiment")?, col("position_deg")?, col("temperature_c")?, col("range")?);
    let (iref, iv) = (col("reference_torque")?, col("bridge_voltage")?);
    let mut exps: Vec<ExperimentRows> = Vec::new();
    let mut info: Vec<(f64, f64, f64)> = Vec::new();
    for (k, _) in run.true_gains.iter().enumerate() {
        let rows: Vec<&Vec<f64>> = run.rows.iter().filter(|r| r[ie] == k as f64).collect();
        let first = rows.first().with_context(|| format!("experiment {k} has no rows"))?;
        info.push((first[ipos], first[irange], first[itemp]));
        exps.push(ExperimentRows {
            label: format!("exp {k}"),
            reference: rows.iter().map(|r| r[iref]).collect(),
            sensor: rows.iter().map(|r| r[iv]).collect(),
            mounting: rows.iter().map(|r| r[ipos]).collect(),
            ..Default::default()
        });
    }
    let e: Vec<Experiment> = exps.iter().map(|x| Experiment::new(&x.label, &x.reference, &x.sensor)).collect();
    let g = calibrate_gain(&e, GainFit::ThroughOrigin, None)?;
    let (true_mean, true_consistency) = run.true_gain_and_consistency();
    let err = |fit: f64, truth: f64| format!("{:+.3}", 100.0 * (fit / truth - 1.0));
    let mut rows: Vec<Vec<String>> = g
        .experiments
        .iter()
        .zip(&run.true_gains)
        .zip(&info)
        .map(|((x, truth), (pos, range, temp))| {
            vec![
                x.label.clone(),
                format!("{pos:.0}° {}, {temp:.1} °C", if *range == 0.0 { "low" } else { "full" }),
                format!("{:.4}", x.gain_nm_per_v),
                format!("{truth:.4}"),
                err(x.gain_nm_per_v, *truth),
                "".into(),
            ]
        })
        .collect();
    let consistency = g.consistency_percent().context("one experiment: no consistency")?;
    rows.push(vec![
        "final gain (mean)".into(),
        format!("{} experiments", g.experiments.len()),
        format!("{:.4}", g.gain_nm_per_v),
        format!("{true_mean:.4}"),
        err(g.gain_nm_per_v, true_mean),
        format!("{TAGHIRAD_GAIN_NM_PER_V:.2}"),
    ]);
    rows.push(vec![
        "consistency std/mean %".into(),
        "sample std".into(),
        format!("{consistency:.3}"),
        format!("{:.3}", 100.0 * true_consistency),
        format!("{:+.3} pt", consistency - 100.0 * true_consistency),
        format!("{TAGHIRAD_CONSISTENCY_PERCENT:.0}"),
    ]);
    let header =
        ["locked WG (Taghirad 1999)", "position, range, temperature", "fitted N·m/V", "true N·m/V", "error %", "paper"];
    let _ = writeln!(text, "  gain per experiment (T = g V through the origin) against the simulator's truth:");
    text += &text_table(&header, &rows);
    html += "<p>Taghirad 1999: gain per experiment on the simulated locked-wave-generator procedure \
             (loading and unloading both ways, four flexspline positions × low/full range, 5–35 °C).</p>";
    html += &table(&header, &rows);

    // DIN 51309 figures of the loading/unloading series.
    let (series, labels) = din_series(&exps)?;
    let all_v: Vec<f64> = exps.iter().flat_map(|x| x.sensor.iter().copied()).collect();
    let resolution = quantization_step(&all_v);
    let mut din_rows = Vec::new();
    for (members, r) in din_groups(&series, resolution)? {
        let max_of = |f: &dyn Fn(&strainwave_analysis::calibration::DinStep) -> Option<f64>| {
            r.steps.iter().filter_map(f).map(f64::abs).fold(None, |a: Option<f64>, v| Some(a.map_or(v, |a| a.max(v))))
        };
        let pct = |v: Option<f64>| v.map_or("-".to_string(), |x| format!("{:.3}", 100.0 * x));
        let top = r.steps.last().map_or(0.0, |s| s.torque_nm);
        din_rows.push(vec![
            format!("{} … {} ({} series)", labels[members[0]], labels[members[members.len() - 1]], members.len()),
            format!("{top:+.0}"),
            pct(max_of(&|s| s.repeatability)),
            pct(max_of(&|s| s.reproducibility)),
            pct(max_of(&|s| s.reversibility)),
            pct(max_of(&|s| Some(s.interpolation))),
            pct(r.max_zero_error),
            pct(r.steps.first().and_then(|s| s.resolution)),
        ]);
    }
    let din_header =
        ["series (one per position)", "top N·m", "b' %", "b %", "h %", "|f_c| %", "f0 %", "r % (1st step)"];
    let _ = writeln!(
        text,
        "  DIN 51309 / EURAMET cg-14, worst step per group (b' needs repeated series in one position; resolution = ADC step {}):",
        resolution.map_or("unknown".into(), |r| format!("{r:.3e} V"))
    );
    text += &text_table(&din_header, &din_rows);
    html += "<p>DIN 51309 / EURAMET cg-14 figures of the same procedure, worst step per group of series that \
             share their torque steps (b: reproducibility across flexspline positions, h: reversibility, \
             f_c: interpolation deviation of a line through zero, f0: zero error, r: resolution).</p>";
    html += &table(&din_header, &din_rows);

    // Fit and residuals of the final gain.
    let refs: Vec<f64> = exps.iter().flat_map(|x| x.reference.iter().copied()).collect();
    let cal: Vec<f64> = all_v.iter().map(|v| g.gain_nm_per_v * v).collect();
    plots.extend(fit_plots("Taghirad gain calibration", &all_v, &refs, &cal, "bridge voltage (V)"));

    // the embedded-sensor article: static (held loads) and dynamic (sinusoidal load) on the flexspline-fixed rig.
    let mut err_rows: Vec<Vec<String>> = Vec::new();
    for (name, preset) in [("static", "flexspline-fixed-static"), ("dynamic", "flexspline-fixed-dynamic")] {
        let (rec, _) = simulate(&presets::preset(preset)?)?;
        let c = |n: &str| rec.column(n).with_context(|| format!("`{preset}` has no `{n}` column"));
        let (t, r, m) = (c("time")?, c("reference_torque")?, c("measured_torque")?);
        let keep: Vec<bool> = if name == "static" {
            let span =
                r.iter().copied().fold(f64::NEG_INFINITY, f64::max) - r.iter().copied().fold(f64::INFINITY, f64::min);
            held_rows(t, r, HOLD_S, 0.02 * span)?
        } else {
            vec![true; r.len()]
        };
        let pick = |x: &[f64]| x.iter().zip(&keep).filter(|(_, &k)| k).map(|(v, _)| *v).collect::<Vec<f64>>();
        let (rs, ms) = (pick(r), pick(m));
        let f = fit_affine(&ms, &rs, Some(EMBEDDED_FULL_SCALE_NM))?;
        let paper = EMBEDDED_ROWS.iter().find(|s| s.0 == name).context("paper row")?;
        let what = if name == "static" { format!("static, held {HOLD_S} s") } else { "dynamic, all rows".into() };
        err_rows.push(affine_row(&what, rs.len(), f.alpha, f.beta_nm, &f.metrics));
        err_rows.push(paper_row(paper));
        if name == "dynamic" {
            let w = c("motor_velocity")?;
            let dep = SpeedDependence::Table(SpeedBins::EqualWidth(3));
            let tab = fit_speed_dependent(m, r, w, &dep, Extrapolation::Clamp, Some(EMBEDDED_FULL_SCALE_NM))?;
            let coeffs: Vec<String> = tab
                .speed_rad_s
                .iter()
                .zip(tab.alpha.iter().zip(&tab.beta_nm))
                .map(|(s, (a, b))| format!("{s:.0} rad/s: {a:.3}/{b:+.3}"))
                .collect();
            let m = &tab.metrics;
            err_rows.push(vec![
                "speed table (3 bins, clamp)".into(),
                m.rows.to_string(),
                coeffs.join("; "),
                format!("{:.3}", m.max_abs_error_nm),
                format!("{:.3}", m.rms_error_nm),
                m.rms_percent_fs.map_or("-".into(), |p| format!("{p:.2}")),
            ]);
        }
    }
    let err_header = ["embedded-sensor model", "rows", "T_ref = α T_sens + β", "max |e| N·m", "RMS N·m", "RMS % FS"];
    let _ = writeln!(
        text,
        "  embedded-sensor rig (presets flexspline-fixed-static / -dynamic), sensor = measured_torque, FS {EMBEDDED_FULL_SCALE_NM} N·m:"
    );
    text += &text_table(&err_header, &err_rows);
    html += &format!(
        "<p>Embedded sensor: static model on held loads (reference steady for {HOLD_S} s), dynamic model on the \
         sinusoidal-load run, and a speed table; error figures over the fitted rows, % of a {EMBEDDED_FULL_SCALE_NM} N·m \
         full scale, beside the paper's table.</p>"
    );
    html += &table(&err_header, &err_rows);
    Ok((text, html, plots))
}

fn affine_row(
    what: &str,
    rows: usize,
    alpha: f64,
    beta: f64,
    m: &strainwave_analysis::calibration::ErrorMetrics,
) -> Vec<String> {
    vec![
        what.to_string(),
        rows.to_string(),
        format!("{alpha:.4} T {beta:+.4}"),
        format!("{:.3}", m.max_abs_error_nm),
        format!("{:.3}", m.rms_error_nm),
        m.rms_percent_fs.map_or("-".into(), |p| format!("{p:.2}")),
    ]
}

fn paper_row(s: &(&str, f64, f64, f64, f64, f64)) -> Vec<String> {
    vec![
        format!("  embedded sensor {}", s.0),
        "".into(),
        format!("{:.3} T {:+.4}", s.1, s.2),
        format!("{:.2}", s.3),
        format!("{:.3}", s.4),
        format!("{:.2}", s.5),
    ]
}

#[cfg(test)]
mod tests {
    /// `cargo test --release -p strainwave-cli --bin strainwave cmd_demo::calibration -- --nocapture`
    #[test]
    fn section_prints_the_tables() {
        let (text, html, plots) = super::section().unwrap();
        println!("{text}");
        for s in [
            "final gain (mean)",
            "consistency std/mean %",
            "6.60",
            "DIN 51309",
            "embedded sensor static",
            "speed table",
        ] {
            assert!(text.contains(s), "{s}");
        }
        assert_eq!(html.matches("<table>").count(), 3);
        assert_eq!(plots.len(), 2);
        assert!(!text.contains("NaN") && !html.contains("NaN"));
    }
}
