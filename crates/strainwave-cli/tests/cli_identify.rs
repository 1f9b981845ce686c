//! `identify` on a real arm's ordinary log (LARA8, data/lara8): the loaded log alone, the
//! current-torque reference, the blocked holdout against the plain linear fit, the
//! summary, `estimate`'s `current_torque`, and the errors a user meets on the way.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_strainwave"))
}

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("strainwave-cli-identify-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn run(args: &[&str], extra: &[&Path]) -> Output {
    let mut c = bin();
    c.args(args);
    for p in extra {
        c.arg(p);
    }
    c.output().unwrap()
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// `identify` with a config, a loaded log and extra flags; returns the output and the model path.
fn identify(d: &Path, config: &Path, log: &Path, flags: &[&str]) -> (Output, PathBuf, PathBuf) {
    let (model, summary) = (d.join("model.toml"), d.join("summary.json"));
    let mut c = bin();
    c.arg("identify").arg("--config").arg(config).arg("--loaded").arg(log).arg("--out").arg(&model);
    c.arg("--summary-json").arg(&summary).args(flags);
    (c.output().unwrap(), model, summary)
}

fn json(p: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(p).unwrap()).unwrap()
}

fn example(j: u32) -> PathBuf {
    root().join(format!("examples/lara8-joint{j}.toml"))
}

fn log(name: &str) -> PathBuf {
    root().join(format!("data/lara8/{name}.csv"))
}

/// A config derived from an example by text replacements.
fn config_with(d: &Path, j: u32, edits: &[(&str, &str)]) -> PathBuf {
    let mut text = std::fs::read_to_string(example(j)).unwrap();
    for (from, to) in edits {
        assert!(text.contains(from), "{from}");
        text = text.replacen(from, to, 1);
    }
    let p = d.join(format!("joint{j}-edited.toml"));
    std::fs::write(&p, text).unwrap();
    p
}

fn r2(pred: &[f64], reference: &[f64]) -> f64 {
    let m = reference.iter().sum::<f64>() / reference.len() as f64;
    let sse: f64 = pred.iter().zip(reference).map(|(p, r)| (p - r).powi(2)).sum();
    let sst: f64 = reference.iter().map(|r| (r - m).powi(2)).sum();
    1.0 - sse / sst
}

fn columns(path: &Path, names: &[&str]) -> Vec<Vec<f64>> {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let idx: Vec<usize> = names.iter().map(|n| header.iter().position(|h| h == n).unwrap()).collect();
    let mut out = vec![Vec::new(); names.len()];
    for l in lines {
        let f: Vec<&str> = l.split(',').collect();
        for (o, &i) in out.iter_mut().zip(&idx) {
            o.push(f[i].parse().unwrap());
        }
    }
    out
}

/// Joint 3 sweeps 0.83 rev; measured: holdout R² 0.895 (model, Stribeck speed chosen
/// per block on its training rows) against 0.720 (plain).
#[test]
fn joint3_from_the_loaded_log_alone_beats_the_plain_linear_fit() {
    let d = dir("j3");
    let (o, model, summary) = identify(&d, &example(3), &log("validate"), &["--holdout", "5"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let table = String::from_utf8_lossy(&o.stdout);
    println!("{table}");
    assert!(table.contains("not identifiable"), "{table}");
    // Signs no physical reading has are said so where they are printed.
    assert!(table.contains("note: inertia_kg_m2 -1.") && table.contains("is negative"), "{table}");
    let s = json(&summary);
    let h = &s["holdout"];
    let (model_r2, plain_r2) =
        (h["model"]["r_squared"].as_f64().unwrap(), h["plain_linear"]["r_squared"].as_f64().unwrap());
    assert!(model_r2 > 0.87 && plain_r2 < 0.75 && model_r2 > plain_r2 + 0.15, "{h}");
    assert!(h["model"]["nrmse_fit_percent"].as_f64().unwrap() > 60.0, "{h}");
    let c = &s["compliance"];
    assert_eq!(c["converged"], true);
    let params = c["parameters"].as_array().unwrap();
    let names: Vec<&str> = params.iter().map(|p| p["name"].as_str().unwrap()).collect();
    assert_eq!(
        names,
        ["k_nm_per_rad", "windup_offset_rad", "coulomb_nm", "viscous_nm_s_per_rad", "stribeck_nm", "inertia_kg_m2"]
    );
    for p in params {
        let (v, se) = (p["value"].as_f64().unwrap(), p["std_error"].as_f64().unwrap());
        assert!(se > 0.0 && se.is_finite() && v.is_finite(), "{p}");
    }
    // The stiffness is well determined (near the 32e3 N·m/rad a plain fit gives on this log).
    let k = params[0]["value"].as_f64().unwrap();
    assert!((25e3..45e3).contains(&k) && params[0]["std_error"].as_f64().unwrap() < 0.02 * k, "{k}");
    // estimate: link torque and the current torque the model predicts, from the raw counts.
    let est = d.join("est.csv");
    let o = run(&["estimate", "--quiet", "--config"], &[&model]);
    assert!(!o.status.success(), "needs --in and --out");
    let mut c = bin();
    c.args(["estimate", "--quiet", "--config"]).arg(&model).arg("--in").arg(log("validate")).arg("--out").arg(&est);
    let o = c.output().unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    let cols = columns(&est, &["current_torque", "torque", "joint_torque_current_3"]);
    let in_sample = r2(&cols[0], &cols[2]);
    // The fit reported R² 0.9615 on the same log; the streaming path must agree.
    assert!(in_sample > 0.955, "{in_sample}");
    assert!(r2(&cols[1], &cols[2]) < in_sample, "friction must explain part of the current torque");
    // The same log with every other row dropped is at half the model's rate: refused, as
    // the model's damping and friction rates would be wrong (before: exit 0 and an RMS
    // error of `current_torque` of 110 N·m instead of 12.5).
    let text = std::fs::read_to_string(log("validate")).unwrap();
    let half: String = text.lines().enumerate().filter(|(k, _)| k % 2 == 0).map(|(_, l)| format!("{l}\n")).collect();
    let half_log = d.join("half.csv");
    std::fs::write(&half_log, half).unwrap();
    let mut c = bin();
    c.args(["estimate", "--config"]).arg(&model).arg("--in").arg(&half_log).arg("--out").arg(d.join("half-est.csv"));
    let o = c.output().unwrap();
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(
        err.contains("half.csv: the time column `Timestamp` steps at about 125 Hz") && err.contains("249.1 Hz"),
        "{err}"
    );
}

/// Joint 1 jogs 0.02 rev: the current torque is mostly friction. Measured: holdout R²
/// 0.849 (model) against −0.517 (plain).
#[test]
fn joint1_friction_dominated_jog() {
    let d = dir("j1");
    let (o, _, summary) = identify(&d, &example(1), &log("jogging_final"), &["--holdout", "5", "--quiet"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let h = &json(&summary)["holdout"];
    let (model_r2, plain_r2) =
        (h["model"]["r_squared"].as_f64().unwrap(), h["plain_linear"]["r_squared"].as_f64().unwrap());
    assert!(model_r2 > 0.8 && plain_r2 < 0.0, "{h}");
}

/// The Stribeck speed is chosen among candidates on training rows only: each holdout
/// block picks its own, and the pick must not make the holdout worse than the model
/// without the term (measured on joints 1 and 3: +0.010 and +0.004 R²).
#[test]
fn stribeck_speed_chosen_per_block_lifts_the_holdout() {
    for (j, name) in [(1, "jogging_final"), (3, "validate")] {
        let d = dir(&format!("strib{j}"));
        let (o, _, summary) = identify(&d, &example(j), &log(name), &["--holdout", "5", "--quiet"]);
        assert!(o.status.success(), "{}", stderr(&o));
        let s = json(&summary);
        let chosen: Vec<f64> =
            s["holdout"]["stribeck_speeds_rad_s"].as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).collect();
        assert_eq!(chosen.len(), 5, "{s}");
        assert!(chosen.iter().all(|v| [0.02, 0.05, 0.1, 0.2, 0.4].contains(v)), "{chosen:?}");
        let notes = s["kinematic"]["notes"].to_string();
        assert!(notes.contains("stribeck_speed_rad_s = ") && notes.contains("cross-validation"), "{notes}");
        let with = s["holdout"]["model"]["r_squared"].as_f64().unwrap();
        let without_cfg = config_with(&d, j, &[("stribeck_speed_rad_s = [0.02, 0.05, 0.1, 0.2, 0.4]", "")]);
        let d2 = dir(&format!("strib{j}-none"));
        let (o, _, summary) = identify(&d2, &without_cfg, &log(name), &["--holdout", "5", "--quiet"]);
        assert!(o.status.success(), "{}", stderr(&o));
        let without = json(&summary)["holdout"]["model"]["r_squared"].as_f64().unwrap();
        assert!(with > without, "joint {j}: {with} with the Stribeck term, {without} without");
    }
    // A bad candidate list is one line naming the key.
    let d = dir("strib-bad");
    for bad in ["[]", "[0.1, -0.2]"] {
        let cfg = config_with(&d, 3, &[("[0.02, 0.05, 0.1, 0.2, 0.4]", bad)]);
        let (o, _, _) = identify(&d, &cfg, &log("validate"), &["--quiet"]);
        let e = stderr(&o);
        assert_eq!(o.status.code(), Some(1), "{e}");
        assert!(e.trim_end().lines().count() == 1 && e.contains("friction.stribeck_speed_rad_s"), "{e}");
    }
}

/// A copy of the validate log with one field replaced (data row `row`, 1-based).
fn log_with(d: &Path, row: usize, column: &str, value: &str) -> PathBuf {
    let text = std::fs::read_to_string(log("validate")).unwrap();
    let mut lines: Vec<String> = text.lines().map(String::from).collect();
    let c = lines[0].split(',').position(|h| h == column).unwrap();
    let mut f: Vec<String> = lines[row].split(',').map(String::from).collect();
    f[c] = value.into();
    lines[row] = f.join(",");
    let p = d.join("edited.csv");
    std::fs::write(&p, lines.join("\n") + "\n").unwrap();
    p
}

/// Before: ``edited.csv: edited.csv: column …`` (the file named twice), and a fit on too
/// short a run named no file.
#[test]
fn errors_name_the_run_once() {
    let d = dir("named");
    let p = log_with(&d, 0, "State", "Timestamp");
    let (o, model, _) = identify(&d, &example(3), &p, &["--quiet"]);
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "{e}");
    assert!(e.contains("edited.csv: column `Timestamp` appears twice") && !e.contains("edited.csv: edited.csv"), "{e}");
    let text = std::fs::read_to_string(log("validate")).unwrap();
    let short = d.join("short.csv");
    std::fs::write(&short, text.lines().take(31).collect::<Vec<_>>().join("\n") + "\n").unwrap();
    let (o, _, _) = identify(&d, &example(3), &short, &["--quiet"]);
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "{e}");
    assert!(e.contains("short.csv: compliance fit: "), "{e}");
    assert!(!model.exists());
}

/// Joint 3 holds still in the jog log: its friction cannot be identified, and the error
/// says how to fit without it (it said "fit the link torque alone", not how).
#[test]
fn friction_of_a_joint_that_holds_still_is_refused_saying_what_to_do() {
    let d = dir("still");
    let (o, model, _) = identify(&d, &example(3), &log("jogging_final"), &["--quiet"]);
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "{e}");
    assert!(e.contains("friction: not identifiable: the joint moves faster than"), "{e}");
    assert!(e.contains("(a joint config without a [friction] table)"), "{e}");
    assert!(!model.exists());
}

#[test]
fn a_non_finite_count_names_its_row_or_is_skipped_with_lenient() {
    let d = dir("nan");
    let bad = log_with(&d, 100, "encoder_motorinc_3", "NaN");
    let (o, _, _) = identify(&d, &example(3), &bad, &["--quiet"]);
    let e = stderr(&o);
    assert!(!o.status.success() && e.contains("data row 100") && e.contains("encoder_motorinc_3"), "{e}");
    let bad = log_with(&d, 7, "joint_torque_current_3", "inf");
    let (o, _, _) = identify(&d, &example(3), &bad, &["--quiet"]);
    let e = stderr(&o);
    assert!(!o.status.success() && e.contains("data row 7") && e.contains("joint_torque_current_3"), "{e}");
    let (o, _, summary) = identify(&d, &example(3), &bad, &["--quiet", "--lenient"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let s = json(&summary);
    assert_eq!(s["rows_skipped"], 1);
    assert_eq!(s["first_skipped_data_row"], 7);
    assert_eq!(s["rows"], 1831);
}

/// One corrupt reference reading (finite, but no gear carries it) would take over the
/// least-squares fit and give a model of absurd numbers: refused by row, or skipped.
#[test]
fn an_impossible_reference_torque_names_its_row_or_is_skipped_with_lenient() {
    let d = dir("huge");
    let bad = log_with(&d, 50, "joint_torque_current_3", "1e308");
    let (o, model, _) = identify(&d, &example(3), &bad, &["--quiet"]);
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "{e}");
    assert!(e.contains("edited.csv: data row 50: column `joint_torque_current_3`"), "{e}");
    assert!(e.contains("1e308 N·m, beyond 100 × gear.rated_torque_nm"), "{e}");
    assert!(!model.exists());
    let (o, model, summary) = identify(&d, &example(3), &bad, &["--quiet", "--lenient"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let s = json(&summary);
    assert_eq!((s["rows_skipped"].as_u64(), s["first_skipped_data_row"].as_u64()), (Some(1), Some(50)));
    let k = s["compliance"]["parameters"][0]["value"].as_f64().unwrap();
    assert!(k > 1e3 && k < 1e7, "stiffness {k} N·m/rad");
    assert!(std::fs::read_to_string(model).unwrap().contains("k_nm_per_rad"));
}

#[test]
fn an_impossible_gear_ratio_is_refused_by_its_key() {
    let d = dir("ratio");
    for ratio in ["1e308", "0.5"] {
        let cfg = config_with(&d, 3, &[("ratio = 101.0", &format!("ratio = {ratio}"))]);
        let (o, model, _) = identify(&d, &cfg, &log("validate"), &["--quiet"]);
        let e = stderr(&o);
        assert_eq!(o.status.code(), Some(1), "{e}");
        assert!(
            e.contains(&format!("joint3-edited.toml: gear.ratio: must be between 1 and 10000, got {ratio}")),
            "{e}"
        );
        assert!(!model.exists());
    }
}

/// Before: a huge `--holdout` or basis size panicked (capacity overflow).
#[test]
fn sizes_beyond_reason_are_refused_by_their_option_or_key() {
    let d = dir("sizes");
    for k in ["922337203685477581", "18446744073709551615"] {
        let (o, model, _) = identify(&d, &example(3), &log("validate"), &["--holdout", k, "--quiet"]);
        let e = stderr(&o);
        assert_eq!(o.status.code(), Some(1), "{e}");
        assert!(e.contains("holdout blocks (20 samples each)") && !e.contains("panicked"), "{e}");
        assert!(!model.exists());
    }
    for (from, to, want) in [
        ("mesh_harmonics = 4", "mesh_harmonics = 4611686018427387904", "kinematic.mesh_harmonics: at most 64"),
        ("order = 0", "order = 65", "kinematic.order: at most 64, got 65"),
    ] {
        let cfg = config_with(&d, 3, &[(from, to)]);
        let (o, model, _) = identify(&d, &cfg, &log("validate"), &["--quiet"]);
        let e = stderr(&o);
        assert_eq!(o.status.code(), Some(1), "{e}");
        assert!(e.contains(&format!("joint3-edited.toml: {want}")), "{e}");
        assert!(!model.exists());
    }
}

#[test]
fn encoder_directions_are_checked_and_the_fix_proposed() {
    let d = dir("dir");
    // One encoder the wrong way: the torsion is as large as the motion.
    let cfg = config_with(&d, 3, &[("motor_direction = -1", "motor_direction = 1")]);
    let (o, _, _) = identify(&d, &cfg, &log("validate"), &["--quiet"]);
    let e = stderr(&o);
    assert!(!o.status.success() && e.contains("encoders.motor_direction = -1"), "{e}");
    // Both the wrong way: the torsion changes sign, the stiffness is negative.
    let cfg = config_with(
        &d,
        3,
        &[("motor_direction = -1", "motor_direction = 1"), ("link_direction = 1", "link_direction = -1")],
    );
    let (o, _, _) = identify(&d, &cfg, &log("validate"), &["--quiet"]);
    let e = stderr(&o);
    assert!(!o.status.success() && e.contains("negative stiffness") && e.contains("flip both"), "{e}");
    // Not ±1.
    let cfg = config_with(&d, 3, &[("motor_direction = -1", "motor_direction = 2")]);
    let (o, _, _) = identify(&d, &cfg, &log("validate"), &["--quiet"]);
    let e = stderr(&o);
    assert!(!o.status.success() && e.contains("encoders.motor_direction: must be 1 or -1"), "{e}");
}

#[test]
fn settings_that_would_be_ignored_are_refused() {
    let d = dir("unused");
    for (edit, expect) in [
        (
            ("motor = \"encoder_motorinc_3\"", "motor = { column = \"encoder_motorinc_3\", scale = -1.0 }"),
            "channels.motor: scale/offset are not applied to encoder counts",
        ),
        (("damping = false", "damping = false\nt1_nm = 14.0"), "compliance.t1_nm / t2_nm: unused"),
        (("damping = false", "damping = false\ndecimation = 3"), "compliance.decimation: unused"),
        (("[gear]", "sample_rate_hz = 250.0\n[gear]"), "channels.time: unused"),
    ] {
        let cfg = config_with(&d, 3, &[edit]);
        let (o, _, _) = identify(&d, &cfg, &log("validate"), &["--quiet"]);
        let e = stderr(&o);
        assert!(!o.status.success() && e.contains(expect), "{edit:?}: {e}");
    }
}

#[test]
fn a_bad_gear_value_is_an_error_naming_the_config_and_key_before_the_fit() {
    let d = dir("bad-gear");
    for (edit, expect) in [
        (("rated_torque_nm = 100.0", "rated_torque_nm = -1.0"), "gear.rated_torque_nm: must be positive"),
        (("rated_torque_nm = 100.0", "rated_torque_nm = nan"), "gear.rated_torque_nm: must be positive"),
    ] {
        let cfg = config_with(&d, 3, &[edit]);
        let (o, model, _) = identify(&d, &cfg, &log("validate"), &["--quiet"]);
        let e = stderr(&o);
        assert_eq!(o.status.code(), Some(1), "{e}");
        assert!(e.contains("joint3-edited.toml") && e.contains(expect), "{edit:?}: {e}");
        assert!(!model.exists());
    }
    let plays = ("hysteresis = \"none\"", "hysteresis = \"plays\"");
    let cfg = config_with(&d, 3, &[plays, ("[encoders]", "[encoders]\nnoise_counts = nan")]);
    let (o, _, _) = identify(&d, &cfg, &log("validate"), &["--quiet"]);
    let e = stderr(&o);
    assert!(e.contains("joint3-edited.toml") && e.contains("encoders.noise_counts: must be positive"), "{e}");
    // Before: reported as fit failures, without file or key.
    let stribeck = "stribeck_speed_rad_s = [0.02, 0.05, 0.1, 0.2, 0.4]";
    let cfg = config_with(&d, 3, &[(stribeck, "stribeck_speed_rad_s = 1e-300")]);
    let (o, _, _) = identify(&d, &cfg, &log("validate"), &["--quiet"]);
    let e = stderr(&o);
    assert!(e.contains("joint3-edited.toml: friction.stribeck_speed_rad_s: 1e-300 rad/s is outside"), "{e}");
    let cfg = config_with(&d, 3, &[("rated_torque_nm = 100.0", "rated_torque_nm = 1e9")]);
    let (o, _, _) = identify(&d, &cfg, &log("validate"), &["--quiet"]);
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "{e}");
    assert!(e.contains("validate.csv: the reference torque varies by 6.705e1 N·m rms"), "{e}");
    assert!(e.contains("under 0.1 % of `gear.rated_torque_nm` = 1e9 N·m"), "{e}");
}

#[test]
fn an_unconverged_fit_exits_1_unless_allowed() {
    let d = dir("lm");
    let cfg = config_with(&d, 3, &[("hysteresis = \"none\"", "hysteresis = \"plays\"\nmax_iterations = 1")]);
    let (o, model, summary) = identify(&d, &cfg, &log("validate"), &["--quiet"]);
    let e = stderr(&o);
    assert!(!o.status.success() && e.contains("iteration limit") && !model.exists(), "{e}");
    assert_eq!(json(&summary)["compliance"]["converged"], false);
    let (o, model, _) = identify(&d, &cfg, &log("validate"), &["--quiet", "--allow-unconverged"]);
    assert!(o.status.success() && model.exists(), "{}", stderr(&o));
}

/// A no-load run in which the link turns less than a revolution: the output harmonics
/// are reported as not identifiable and the mesh harmonics of the motor angle are fitted.
#[test]
fn a_no_load_run_under_one_revolution_fits_mesh_harmonics_only() {
    let d = dir("short-no-load");
    let cfg = config_with(&d, 1, &[("order = 0", "order = 2")]);
    let mut c = bin();
    c.args(["identify", "--quiet", "--config"]).arg(&cfg).arg("--no-load").arg(log("jogging_final"));
    c.arg("--loaded").arg(log("jogging_final")).arg("--out").arg(d.join("m.toml"));
    c.arg("--summary-json").arg(d.join("s.json"));
    let o = c.output().unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    let s = json(&d.join("s.json"));
    let notes = s["kinematic"]["notes"].to_string();
    assert!(notes.contains("output harmonics not identifiable: the link turns 0.14 rad"), "{notes}");
    assert!(s["kinematic"]["basis"].as_str().unwrap().starts_with("Fourier, 0 output + 4 mesh"), "{s}");
    let model = std::fs::read_to_string(d.join("m.toml")).unwrap();
    assert!(model.contains("mesh_angle = \"motor\""), "{model}");
}

/// A time channel over a column in ms (`Timestamp [ms]`) is read in seconds: the
/// identified model is the one from the log in seconds.
#[test]
fn a_time_channel_in_ms_is_read_in_seconds() {
    let d = dir("time-ms");
    let text = std::fs::read_to_string(log("validate")).unwrap();
    let mut lines = text.lines();
    let mut ms = lines.next().unwrap().replacen("Timestamp", "Timestamp [ms]", 1) + "\n";
    for line in lines {
        let (t, rest) = line.split_once(',').unwrap();
        ms += &format!("{},{rest}\n", t.parse::<f64>().unwrap() * 1000.0);
    }
    let ms_log = d.join("validate-ms.csv");
    std::fs::write(&ms_log, ms).unwrap();
    let (o, model_s, _) = identify(&d, &example(3), &log("validate"), &["--quiet"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let seconds = std::fs::read_to_string(model_s).unwrap();
    let (o, model_ms, _) = identify(&d, &example(3), &ms_log, &["--quiet"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let from_ms = std::fs::read_to_string(model_ms).unwrap();
    let rate = |m: &str| m.lines().find(|l| l.starts_with("sample_rate_hz")).map(String::from);
    assert!(rate(&seconds).is_some(), "{seconds}");
    assert_eq!(rate(&from_ms), rate(&seconds));
}
