//! `strainwave calibrate` end to end: the Taghirad loop against the simulator's truth,
//! the embedded-sensor article's static and dynamic models, and bad input (one line, exit code 1, the
//! file/row/column named, never a NaN in a calibration file).

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use strainwave_analysis::calibration::{fit_affine, held_rows};

/// Recovered gain against the simulator's true mean gain, relative: at most 0.5 %.
const GAIN_TOL: f64 = 0.005;
/// Printed consistency against the true spread, percentage points.
const CONSISTENCY_TOL_PT: f64 = 0.1;

fn run(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_strainwave")).args(args).output().expect("run strainwave")
}

fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("sw-cal-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// Runs and expects success; returns stdout.
fn ok(args: &[&str]) -> String {
    let o = run(args);
    assert!(o.status.success(), "{args:?}\n{}", stderr(&o));
    stdout(&o)
}

/// Runs and expects a user error: exit code 1 and one line on stderr.
fn user_error(args: &[&str]) -> String {
    let o = run(args);
    assert_eq!(o.status.code(), Some(1), "{args:?}\nstdout: {}\nstderr: {}", stdout(&o), stderr(&o));
    let e = stderr(&o);
    assert_eq!(e.trim_end().lines().count(), 1, "not one line: {e}");
    assert!(e.starts_with("error: "), "{e}");
    e
}

/// A number from a calibration file's `key = value` line (top level or `[metrics]`).
fn toml_number(text: &str, key: &str) -> f64 {
    let line = text.lines().find(|l| l.starts_with(&format!("{key} = "))).unwrap_or_else(|| panic!("{key}: {text}"));
    line.split(" = ").nth(1).unwrap().trim().parse().unwrap()
}

/// A calibration file, checked for non-finite numbers.
fn read_calibration(p: &Path) -> String {
    let text = std::fs::read_to_string(p).unwrap();
    let lower = text.to_lowercase();
    for bad in ["nan", "inf"] {
        let numbers = lower.lines().filter(|l| l.contains(" = ") && !l.starts_with("description"));
        assert!(!numbers.clone().any(|l| l.contains(bad)), "{bad} in {text}");
    }
    text
}

fn write_csv(p: &Path, header: &str, rows: &[Vec<f64>]) {
    let mut t = format!("{header}\n");
    for r in rows {
        t += &r.iter().map(|v| v.to_string()).collect::<Vec<_>>().join(",");
        t.push('\n');
    }
    std::fs::write(p, t).unwrap();
}

#[test]
fn taghirad_loop_recovers_the_true_gain_and_spread() {
    let d = tmp("taghirad-gain");
    let (rec, cal) = (d.join("locked.csv"), d.join("cal.toml"));
    ok(&["simulate", "--preset", "taghirad", "--procedure", "locked-wg", "--out", s(&rec), "--quiet"]);
    let out = ok(&[
        "calibrate",
        "--in",
        s(&rec),
        "--experiment-column",
        "experiment",
        "--reference",
        "reference_torque",
        "--sensor",
        "bridge_voltage",
        "--model",
        "gain",
        "--din",
        "--out",
        s(&cal),
    ]);
    // The truth: one true gain per experiment in the recording.
    let t = strainwave_io::read_all(&rec).unwrap();
    let (exp, truth) = (t.column("experiment").unwrap(), t.column("true_gain").unwrap());
    let mut gains: Vec<(f64, f64)> = Vec::new();
    for (e, g) in exp.iter().zip(truth) {
        if !gains.iter().any(|(k, _)| k == e) {
            gains.push((*e, *g));
        }
    }
    let n = gains.len() as f64;
    assert_eq!(n, 8.0);
    let mean = gains.iter().map(|g| g.1).sum::<f64>() / n;
    let sd = (gains.iter().map(|g| (g.1 - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
    let true_consistency_pct = 100.0 * sd / mean;

    let text = read_calibration(&cal);
    assert!(text.contains("model = \"gain\""), "{text}");
    let gain = toml_number(&text, "gain_nm_per_v");
    let printed: f64 = out
        .lines()
        .find_map(|l| l.split("experiments) ").nth(1))
        .and_then(|v| v.trim_end_matches(" %").parse().ok())
        .unwrap_or_else(|| panic!("no consistency line in\n{out}"));
    assert!(out.contains("DIN 51309") && out.contains("h %"), "{out}");
    // The reference is the nominal torque and the rig's arm is off by `arm` per mounting,
    // so each experiment's recoverable gain is nominal torque per volt = 1 / (arm · s).
    // A `true_gain` column holding arm / s instead fails here by about twice the mean
    // arm error (and the consistency below by the flipped arm/temperature correlation).
    assert!(
        (gain / mean - 1.0).abs() < GAIN_TOL,
        "gain {gain} vs true {mean} ({:+.3} %); consistency {printed} % vs true {true_consistency_pct:.3} %",
        100.0 * (gain / mean - 1.0)
    );
    assert!(
        (printed - true_consistency_pct).abs() < CONSISTENCY_TOL_PT,
        "consistency {printed} % vs true {true_consistency_pct:.3} %"
    );
}

#[test]
fn embedded_sensor_static_and_dynamic_through_the_cli() {
    let d = tmp("embedded-sensor");
    let (st, dy) = (d.join("static.csv"), d.join("dynamic.csv"));
    ok(&["simulate", "--preset", "flexspline-fixed-static", "--out", s(&st), "--quiet"]);
    ok(&["simulate", "--preset", "flexspline-fixed-dynamic", "--out", s(&dy), "--quiet"]);
    let common = ["--reference", "reference_torque", "--sensor", "measured_torque", "--full-scale", "20"];
    let (st_cal, dy_cal, tab_cal) = (d.join("static.toml"), d.join("dynamic.toml"), d.join("table.toml"));
    let plot = d.join("fit.svg");
    let mut args = vec!["calibrate", "--in", s(&st), "--model", "static", "--held", "0.6", "--out", s(&st_cal)];
    args.extend(["--plot", s(&plot)]);
    args.extend(common);
    let out = ok(&args);
    assert!(out.contains("held rows:") && out.contains("RMS % FS"), "{out}");
    assert!(std::fs::read_to_string(&plot).unwrap().matches("<svg").count() == 3);
    let mut args = vec!["calibrate", "--in", s(&dy), "--model", "dynamic", "--speed", "motor_velocity"];
    args.extend(["--out", s(&dy_cal)]);
    args.extend(common);
    let out = ok(&args);
    assert!(out.contains("per speed bin"), "{out}");
    let mut args = vec!["calibrate", "--in", s(&dy), "--model", "speed-table", "--speed", "motor_velocity"];
    args.extend(["--bins", "3", "--out", s(&tab_cal)]);
    args.extend(common);
    let out = ok(&args);
    assert!(out.contains("extrapolation `clamp`"), "{out}");
    // `--out -`: standard output holds the calibration file alone (the report goes to
    // standard error), the same text as the file written above.
    let mut args = vec!["calibrate", "--in", s(&dy), "--model", "speed-table", "--speed", "motor_velocity"];
    args.extend(["--bins", "3", "--out", "-"]);
    args.extend(common);
    let o = Command::new(env!("CARGO_BIN_EXE_strainwave")).args(&args).output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(String::from_utf8_lossy(&o.stdout), std::fs::read_to_string(&tab_cal).unwrap());
    assert!(String::from_utf8_lossy(&o.stderr).contains("extrapolation `clamp`"));

    // The CLI's numbers are the library's on the same rows.
    let t = strainwave_io::read_all(&st).unwrap();
    let (time, r, m) =
        (t.column("time").unwrap(), t.column("reference_torque").unwrap(), t.column("measured_torque").unwrap());
    let span = r.iter().copied().fold(f64::MIN, f64::max) - r.iter().copied().fold(f64::MAX, f64::min);
    let held = held_rows(time, r, 0.6, 0.02 * span).unwrap();
    let pick = |x: &[f64]| x.iter().zip(&held).filter(|(_, &h)| h).map(|(v, _)| *v).collect::<Vec<f64>>();
    let lib = fit_affine(&pick(m), &pick(r), Some(20.0)).unwrap();
    let st_text = read_calibration(&st_cal);
    assert!(st_text.contains("model = \"static\""));
    assert!((toml_number(&st_text, "alpha") - lib.alpha).abs() < 1e-12);
    assert!((toml_number(&st_text, "beta_nm") - lib.beta_nm).abs() < 1e-12);
    assert_eq!(toml_number(&st_text, "rows") as usize, lib.metrics.rows);

    // the embedded-sensor article's shape: a slope near the sensor's own scale, errors of a few tenths of a
    // N·m, the dynamic fit worse than the static one.
    let dy_text = read_calibration(&dy_cal);
    assert!(dy_text.contains("model = \"dynamic\""));
    let (st_rms, dy_rms) = (toml_number(&st_text, "rms_error_nm"), toml_number(&dy_text, "rms_error_nm"));
    for (name, text) in [("static", &st_text), ("dynamic", &dy_text)] {
        let a = toml_number(text, "alpha");
        assert!((0.9..1.1).contains(&a), "{name} α {a}");
    }
    assert!((0.1..0.5).contains(&st_rms) && (0.1..0.6).contains(&dy_rms) && dy_rms > st_rms, "{st_rms} {dy_rms}");
    assert!(toml_number(&dy_text, "rms_percent_fs") > toml_number(&st_text, "rms_percent_fs"));
    let tab = read_calibration(&tab_cal);
    assert!(tab.contains("model = \"speed-table\"") && tab.contains("extrapolation = \"clamp\""), "{tab}");
}

#[test]
fn one_load_is_singular() {
    let d = tmp("singular");
    let p = d.join("one-load.csv");
    // One applied load, the sensor reading it with a little scatter.
    let rows: Vec<Vec<f64>> = (0..20).map(|k| vec![k as f64, 5.0, 0.75 + 0.001 * (k % 3) as f64]).collect();
    write_csv(&p, "time,torque,volts", &rows);
    let e =
        user_error(&["calibrate", "--in", s(&p), "--reference", "torque", "--sensor", "volts", "--model", "static"]);
    assert!(e.contains("singular") && e.contains("reference"), "{e}");
    // Through the origin one load is solvable; a sensor stuck at zero is not.
    let rows: Vec<Vec<f64>> = (0..20).map(|k| vec![k as f64, k as f64, 0.0]).collect();
    write_csv(&p, "time,torque,volts", &rows);
    let e = user_error(&["calibrate", "--in", s(&p), "--reference", "torque", "--sensor", "volts"]);
    assert!(e.contains("singular") && e.contains("one-load.csv"), "{e}");
}

#[test]
fn fewer_rows_than_unknowns() {
    let d = tmp("few");
    let p = d.join("one-row.csv");
    write_csv(&p, "torque,volts", &[vec![5.0, 0.75]]);
    let e =
        user_error(&["calibrate", "--in", s(&p), "--reference", "torque", "--sensor", "volts", "--model", "static"]);
    assert!(e.contains("1 rows, needs at least 2"), "{e}");
    // α(ω), β(ω) quadratic in speed: 6 unknowns, 4 rows.
    let rows = vec![vec![1.0, 1.0, 1.0], vec![2.0, 2.0, 1.0], vec![1.1, 1.0, 2.0], vec![2.2, 2.0, 2.0]];
    write_csv(&p, "torque,volts,speed", &rows);
    let e = user_error(&[
        "calibrate",
        "--in",
        s(&p),
        "--reference",
        "torque",
        "--sensor",
        "volts",
        "--speed",
        "speed",
        "--model",
        "speed-poly",
        "--degree",
        "2",
    ]);
    assert!(e.contains("4 rows for 6 unknowns"), "{e}");
}

#[test]
fn nan_row_and_missing_column_are_named() {
    let d = tmp("nan");
    let p = d.join("with-nan.csv");
    std::fs::write(&p, "torque,volts\n0,0\n5,0.75\n10,NaN\n15,2.25\n").unwrap();
    let cal = d.join("cal.toml");
    let e = user_error(&["calibrate", "--in", s(&p), "--reference", "torque", "--sensor", "volts", "--out", s(&cal)]);
    assert!(e.contains("with-nan.csv") && e.contains("row 3") && e.contains("`volts`") && e.contains("NaN"), "{e}");
    assert!(!cal.exists(), "no file is written on error");
    let e = user_error(&["calibrate", "--in", s(&p), "--reference", "torque_ref", "--sensor", "volts"]);
    assert!(e.contains("no column `torque_ref`") && e.contains("--reference") && e.contains("with-nan.csv"), "{e}");
}

#[test]
fn a_finite_value_too_large_to_square_is_named_by_its_input_row() {
    let d = tmp("huge");
    let p = d.join("huge.csv");
    let mut text = String::from("torque,volts\n");
    for k in 0..100 {
        let torque = if k == 49 { "1e308".to_string() } else { k.to_string() };
        text += &format!("{torque},{}\n", 0.15 * k as f64);
    }
    std::fs::write(&p, text).unwrap();
    let cal = d.join("cal.toml");
    let e = user_error(&["calibrate", "--in", s(&p), "--reference", "torque", "--sensor", "volts", "--out", s(&cal)]);
    assert!(e.contains("huge.csv: row 50") && e.contains("`torque` = 1e308") && !e.contains("cal.toml"), "{e}");
    assert!(!cal.exists());
}

#[test]
fn one_glitch_row_is_refused_not_fitted() {
    // Before: one reference row of 4e9 N·m was fitted like any other (exit 0).
    let d = tmp("glitch");
    let cal = d.join("cal.toml");
    for (column, row, glitch) in [("torque", 37, "4e9"), ("volts", 12, "-1500")] {
        let p = d.join("glitch.csv");
        let mut text = String::from("torque,volts\n");
        for k in 0..100 {
            let (torque, volts) = (k.to_string(), format!("{}", 0.15 * k as f64));
            let (torque, volts) = match (k + 1 == row, column) {
                (true, "torque") => (glitch.to_string(), volts),
                (true, _) => (torque, glitch.to_string()),
                _ => (torque, volts),
            };
            text += &format!("{torque},{volts}\n");
        }
        std::fs::write(&p, text).unwrap();
        let e =
            user_error(&["calibrate", "--in", s(&p), "--reference", "torque", "--sensor", "volts", "--out", s(&cal)]);
        let at = format!("glitch.csv: row {row}: `{column}` = {glitch}");
        assert!(e.contains(&at.replace("4e9", "4000000000.0")) && e.contains("over 100 times"), "{e}");
        assert!(!cal.exists());
    }
    // Long tare stretches with noise near zero and a few loaded rows are one range, not
    // glitches; nor is a short calibration of a few points far apart.
    let p = d.join("mostly-idle.csv");
    let rows: Vec<Vec<f64>> = (0..1000)
        .map(|k| {
            let torque = if k % 20 == 19 { 50.0 } else { 0.05 * ((k % 7) as f64 - 3.0) / 3.0 };
            vec![torque, 0.15 * torque + 1e-4 * ((k % 5) as f64 - 2.0)]
        })
        .collect();
    write_csv(&p, "torque,volts", &rows);
    ok(&["calibrate", "--in", s(&p), "--reference", "torque", "--sensor", "volts", "--quiet"]);
    let p = d.join("two-points.csv");
    write_csv(&p, "torque,volts", &[vec![0.1, 0.015], vec![50.0, 7.5]]);
    ok(&["calibrate", "--in", s(&p), "--reference", "torque", "--sensor", "volts", "--quiet"]);
}

/// A fit over every experiment that fails names their files. Before: `fitting the gain:
/// gain: the mean gain is zero …`, with no file.
#[test]
fn a_failed_fit_over_the_experiments_names_their_files() {
    let d = tmp("files");
    let (a, b) = (d.join("plus.csv"), d.join("minus.csv"));
    write_csv(&a, "torque,volts", &[vec![1.0, 1.0], vec![2.0, 2.0]]);
    write_csv(&b, "torque,volts", &[vec![1.0, -1.0], vec![2.0, -2.0]]);
    let e = user_error(&["calibrate", "--in", s(&a), "--in", s(&b), "--reference", "torque", "--sensor", "volts"]);
    assert!(
        e.contains("plus.csv, ") && e.contains("minus.csv: fitting the gain: ") && e.contains("mean gain is zero"),
        "{e}"
    );
}

#[test]
fn a_hold_no_row_meets_is_named_with_what_to_change() {
    // Before: `fitting the gain: experiment `ramp.csv`: 0 rows, needs at least 1`.
    let d = tmp("held");
    let p = d.join("ramp.csv");
    let rows: Vec<Vec<f64>> = (0..100).map(|k| vec![0.01 * k as f64, k as f64, 0.15 * k as f64]).collect();
    write_csv(&p, "time,torque,volts", &rows);
    let args = ["calibrate", "--in", s(&p), "--reference", "torque", "--sensor", "volts"];
    let e = user_error(&[&args[..], &["--held", "1e308"]].concat());
    assert!(e.contains("--held 1e308: no row of `ramp.csv` has its reference steady within 1.980 N·m"), "{e}");
    assert!(e.contains("shorten --held or widen --held-band"), "{e}");
    // A band of 1e308 holds every row after the first 0.05 s, and prints short.
    let out = ok(&[&args[..], &["--held", "0.05", "--held-band", "1e308"]].concat());
    assert!(out.contains("held rows: 95 of 100 (reference steady within 1.000e308 N·m"), "{out}");
}

#[test]
fn speeds_outside_the_table_reject_or_clamp() {
    let d = tmp("speed");
    let p = d.join("speeds.csv");
    // α = 1.5 + 0.01 ω, β = −0.1 at speeds 0..=10 rad/s, loads 0..=5.
    let mut rows = Vec::new();
    for w in 0..=10 {
        for l in 0..=5 {
            let (w, l) = (w as f64, l as f64);
            rows.push(vec![(1.5 + 0.01 * w) * l - 0.1, l, w]);
        }
    }
    write_csv(&p, "torque,sensor,speed", &rows);
    let base = [
        "calibrate",
        "--in",
        s(&p),
        "--reference",
        "torque",
        "--sensor",
        "sensor",
        "--speed",
        "speed",
        "--model",
        "speed-table",
    ];
    let cal = d.join("table.toml");
    let mut args = base.to_vec();
    args.extend(["--speed-edges", "2,5,8", "--extrapolation", "reject", "--out", s(&cal)]);
    let e = user_error(&args);
    assert!(e.contains("outside") && e.contains("reject") && e.contains("speed"), "{e}");
    assert!(!cal.exists());
    let mut args = base.to_vec();
    args.extend(["--speed-edges", "2,5,8", "--extrapolation", "clamp", "--out", s(&cal)]);
    let out = ok(&args);
    assert!(out.contains("extrapolation `clamp`") && out.contains("outside the bin edges: not fitted"), "{out}");
    // 0, 1 and 9, 10 rad/s lie outside [2, 8]: 4 speeds × 6 loads.
    assert!(out.contains("24 rows lie outside the bin edges"), "{out}");
    let text = read_calibration(&cal);
    assert!(text.contains("extrapolation = \"clamp\"") && text.contains("speed_rad_s = ["), "{text}");
}

/// `--summary-json` read back: coefficients and standard errors against the closed-form
/// least-squares values, R² and rows, for a static fit with `--held`, a gain over two
/// experiments and a speed table; the file replaces an old one whole and never an input.
#[test]
fn summary_json_reads_back() {
    let d = tmp("summary");
    let p = d.join("ramp.csv");
    // A held staircase of loads with a deterministic scatter, ramps between the steps.
    let (alpha, beta) = (1.25, -0.4);
    let mut rows = Vec::new();
    let mut t = 0.0;
    for step in 0..8 {
        let load = -20.0 + 5.0 * step as f64;
        for k in 0..40 {
            let ramp = if k < 10 { (10 - k) as f64 * 0.4 } else { 0.0 };
            let x = (load - ramp - beta) / alpha + 0.02 * (((k * 7 + step * 3) % 11) as f64 - 5.0) / 5.0;
            rows.push(vec![t, load - ramp, x, 0.5 * step as f64]);
            t += 0.01;
        }
    }
    write_csv(&p, "time,reference_torque,sensor,speed", &rows);
    let json = d.join("summary.json");
    std::fs::write(&json, "old contents, longer than nothing at all").unwrap();
    let args = ["calibrate", "--in", s(&p), "--reference", "reference_torque", "--sensor", "sensor"];
    let out = ok(&[&args[..], &["--model", "static", "--held", "0.2", "--summary-json", s(&json)]].concat());
    assert!(out.contains("wrote") && out.contains("summary.json"), "{out}");
    let v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert_eq!(v["model"], "static");
    // The rows the library's --held filter keeps (band: 2 % of the reference's span).
    let (time, reference): (Vec<f64>, Vec<f64>) = rows.iter().map(|r| (r[0], r[1])).unzip();
    let span = reference.iter().copied().fold(f64::MIN, f64::max) - reference.iter().copied().fold(f64::MAX, f64::min);
    let held = held_rows(&time, &reference, 0.2, 0.02 * span).unwrap();
    let (read, used) = (v["rows"]["read"].as_u64().unwrap(), v["rows"]["used"].as_u64().unwrap());
    assert_eq!(read, 320);
    assert_eq!(v["rows"]["skipped_not_held"].as_u64().unwrap(), read - used);
    let used_rows: Vec<&Vec<f64>> = rows.iter().zip(&held).filter(|(_, &h)| h).map(|(r, _)| r).collect();
    assert_eq!(used_rows.len() as u64, used);
    assert!(used > 40 && used < 320, "{used}");
    let n = used as f64;
    let (mx, my) = (used_rows.iter().map(|r| r[2]).sum::<f64>() / n, used_rows.iter().map(|r| r[1]).sum::<f64>() / n);
    let sxx: f64 = used_rows.iter().map(|r| (r[2] - mx).powi(2)).sum();
    let sxy: f64 = used_rows.iter().map(|r| (r[2] - mx) * (r[1] - my)).sum();
    let syy: f64 = used_rows.iter().map(|r| (r[1] - my).powi(2)).sum();
    let a = sxy / sxx;
    let b = my - a * mx;
    let sse: f64 = used_rows.iter().map(|r| (r[1] - a * r[2] - b).powi(2)).sum();
    let s2 = sse / (n - 2.0);
    let (se_a, se_b) = ((s2 / sxx).sqrt(), (s2 * (1.0 / n + mx * mx / sxx)).sqrt());
    let c = v["coefficients"].as_array().unwrap();
    let get = |i: usize, k: &str| c[i][k].as_f64().unwrap();
    assert_eq!((c[0]["name"].as_str(), c[1]["name"].as_str()), (Some("alpha"), Some("beta_nm")));
    assert!((get(0, "value") - a).abs() < 1e-9 && (get(1, "value") - b).abs() < 1e-9, "{c:?} {a} {b}");
    assert!((get(0, "std_error") / se_a - 1.0).abs() < 1e-6, "{} {se_a}", get(0, "std_error"));
    assert!((get(1, "std_error") / se_b - 1.0).abs() < 1e-6, "{} {se_b}", get(1, "std_error"));
    assert!((a - alpha).abs() < 5.0 * se_a + 1e-3, "{a} ± {se_a}");
    let fit = &v["fit"];
    assert_eq!(fit["rows"].as_u64(), Some(used));
    assert!((fit["r_squared"].as_f64().unwrap() - (1.0 - sse / syy)).abs() < 1e-9, "{fit}");
    assert!((fit["rms_error_nm"].as_f64().unwrap() - (sse / n).sqrt()).abs() < 1e-9, "{fit}");
    // The largest error named by the file's own data row (1-based), not by the held rows.
    let file_rows: Vec<usize> = held.iter().enumerate().filter(|(_, &h)| h).map(|(i, _)| i + 1).collect();
    let err = |r: &Vec<f64>| (a * r[2] + b - r[1]).abs();
    let worst = (0..used_rows.len()).max_by(|&i, &j| err(used_rows[i]).total_cmp(&err(used_rows[j]))).unwrap();
    assert_eq!(fit["max_abs_file_row"].as_u64(), Some(file_rows[worst] as u64), "{fit}");
    assert_eq!(fit["max_abs_used_row"].as_u64(), Some(worst as u64 + 1), "{fit}");
    assert_ne!(file_rows[worst], worst + 1, "the held rows must differ from the file's for this check");
    assert_eq!(fit["max_abs_file"].as_str(), Some(s(&p)), "{fit}");
    assert!(!std::fs::read_dir(&d).unwrap().any(|e| e.unwrap().file_name().to_string_lossy().contains("tmp")));

    // Two experiments by a column: the gain's standard error is the spread over √2.
    let g = d.join("gain.json");
    let exp_rows: Vec<Vec<f64>> = (0..40)
        .map(|k| {
            let e = (k / 20) as f64;
            let x = 0.1 + 0.05 * (k % 20) as f64;
            vec![k as f64 * 0.01, (6.0 + 0.2 * e) * x, x, e]
        })
        .collect();
    let pg = d.join("gain.csv");
    write_csv(&pg, "time,reference_torque,sensor,exp", &exp_rows);
    let gargs = ["calibrate", "--in", s(&pg), "--reference", "reference_torque", "--sensor", "sensor"];
    ok(&[&gargs[..], &["--experiment-column", "exp", "--summary-json", s(&g), "--quiet"]].concat());
    let v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&g).unwrap()).unwrap();
    assert_eq!(v["per_experiment"].as_array().map(|a| a.len()), Some(2));
    let gain = &v["coefficients"][0];
    assert!((gain["value"].as_f64().unwrap() - 6.1).abs() < 1e-9, "{gain}");
    // Sample std of {6.0, 6.2} is 0.1·√2; over √2 experiments: 0.1.
    assert!((gain["std_error"].as_f64().unwrap() - 0.1).abs() < 1e-9, "{gain}");
    assert_eq!(v["rows"]["used"].as_u64(), Some(40));

    // A speed table: per-bin coefficients with standard errors.
    let tj = d.join("table.json");
    let targs = ["--model", "speed-table", "--speed", "speed", "--bins", "2", "--summary-json", s(&tj), "--quiet"];
    ok(&[&args[..], &targs[..]].concat());
    let v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&tj).unwrap()).unwrap();
    let bins = v["coefficients"].as_array().unwrap();
    assert_eq!(bins.len(), 2);
    let rows_in_bins: u64 = bins.iter().map(|b| b["rows"].as_u64().unwrap()).sum();
    assert_eq!(rows_in_bins, 320);
    assert!(bins.iter().all(|b| b["alpha_std_error"].as_f64().is_some_and(|e| e > 0.0)), "{bins:?}");

    // The summary may not overwrite an input.
    let e = user_error(&[&args[..], &["--model", "static", "--summary-json", s(&p)]].concat());
    assert!(e.contains("ramp.csv"), "{e}");
    assert!(std::fs::read_to_string(&p).unwrap().starts_with("time,reference_torque"));
}

#[test]
fn din_errors_name_the_file_row_counted_from_one() {
    let d = tmp("din-rows");
    let p = d.join("din.csv");
    // Experiment 1 (data rows 1–5) is fine; experiment 2 (data rows 6–12) is remounted
    // from 0° to 120° at data row 9, inside a loaded series.
    let mut rows = Vec::new();
    for (tq, v) in [(0.0, 0.0), (5.0, 0.5), (10.0, 1.0), (5.0, 0.5), (0.0, 0.0)] {
        rows.push(vec![1.0, tq, v, 0.0]);
    }
    for (k, (tq, v)) in
        [(0.0, 0.0), (5.0, 0.5), (10.0, 1.0), (10.0, 1.0), (5.0, 0.5), (0.0, 0.0), (0.0, 0.0)].into_iter().enumerate()
    {
        rows.push(vec![2.0, tq, v, if k >= 3 { 120.0 } else { 0.0 }]);
    }
    write_csv(&p, "experiment,torque,volts,position_deg", &rows);
    let args = [
        "calibrate",
        "--in",
        s(&p),
        "--experiment-column",
        "experiment",
        "--reference",
        "torque",
        "--sensor",
        "volts",
        "--din",
    ];
    let e = user_error(&args);
    assert!(e.contains("din.csv: data row 9 (--din on `exp 2`): the mounting position changes from 0° to 120°"), "{e}");

    // The same rows after --held: the rows kept still count as in the file. A torque
    // changing sign inside a series is named by the series and its step (from 1).
    let mut rows = Vec::new();
    for (k, (tq, v)) in [(0.0, 0.0), (5.0, 0.5), (-10.0, -1.0), (0.0, 0.0)].into_iter().enumerate() {
        for j in 0..3 {
            rows.push(vec![(3 * k + j) as f64, tq, v, 0.0]);
        }
    }
    let p2 = d.join("sign.csv");
    write_csv(&p2, "time,torque,volts,position_deg", &rows);
    let e = user_error(&["calibrate", "--in", s(&p2), "--reference", "torque", "--sensor", "volts", "--din"]);
    assert!(e.contains("sign.csv: --din on `sign.csv series 1`: step 3: torque changes sign"), "{e}");
}

/// With several inputs the fit pools their rows; an error names the file and its own
/// data row, not the row of the pooled data. The same with `--experiment-column` and
/// `--held`, where an experiment's rows are not the file's.
#[test]
fn errors_with_several_inputs_name_the_file_and_its_row() {
    let d = tmp("pooled");
    let loads = |w: f64| (0..=5).map(move |l| vec![(1.5 + 0.01 * w) * l as f64 - 0.1, l as f64, w]);
    let (a, b) = (d.join("first.csv"), d.join("second.csv"));
    // first.csv: 42 rows inside [2, 8] rad/s; second.csv: data rows 13–18 at 9 rad/s.
    write_csv(
        &a,
        "torque,sensor,speed",
        &[2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0].into_iter().flat_map(loads).collect::<Vec<_>>(),
    );
    write_csv(&b, "torque,sensor,speed", &[2.0, 3.0, 9.0, 4.0].into_iter().flat_map(loads).collect::<Vec<_>>());
    let e = user_error(&[
        "calibrate",
        "--in",
        s(&a),
        "--in",
        s(&b),
        "--reference",
        "torque",
        "--sensor",
        "sensor",
        "--speed",
        "speed",
        "--model",
        "speed-table",
        "--speed-edges",
        "2,5,8",
        "--extrapolation",
        "reject",
    ]);
    let want = format!("{}: row 13, column `speed`: speed 9 rad/s is outside", b.display());
    assert!(e.contains(&want), "{e}");
    assert!(!e.contains("row 55"), "a pooled row: {e}");
    // The file given first: its own row.
    let e = user_error(&[
        "calibrate",
        "--in",
        s(&b),
        "--in",
        s(&a),
        "--reference",
        "torque",
        "--sensor",
        "sensor",
        "--speed",
        "speed",
        "--model",
        "speed-table",
        "--speed-edges",
        "2,8",
        "--extrapolation",
        "reject",
    ]);
    assert!(e.contains(&want), "{e}");

    // Two experiments interleaved in one file; time goes backwards at the second
    // experiment's 10th row, which is the file's data row 20.
    let mut rows = Vec::new();
    for k in 0..20 {
        for exp in [1.0, 2.0] {
            let tq = if k > 3 { 5.0 } else { 0.0 };
            rows.push(vec![exp, k as f64 * 0.1, tq, tq / 10.0]);
        }
    }
    rows[19][1] = 0.05;
    let h = d.join("held.csv");
    write_csv(&h, "exp,time,torque,volts", &rows);
    let e = user_error(&[
        "calibrate",
        "--in",
        s(&h),
        "--experiment-column",
        "exp",
        "--reference",
        "torque",
        "--sensor",
        "volts",
        "--held",
        "0.2",
    ]);
    assert!(e.contains(&format!("{}: row 20: --held: time goes backwards (0.05 s after 0.8 s)", h.display())), "{e}");
}
