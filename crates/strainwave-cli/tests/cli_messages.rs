//! User-facing errors of `fuse`, `identify`, `design` and `filter`: one line, naming the file the problem is
//! in (the config for its keys, the recording for its rows, counted from 1) and the key
//! or column as the user wrote it.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn run(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_strainwave")).args(args).output().expect("run strainwave")
}

fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("sw-messages-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// Exit 1, one line, every needle in it.
fn error(args: &[&str], needles: &[&str]) -> String {
    let o = run(args);
    let e = String::from_utf8_lossy(&o.stderr).into_owned();
    assert_eq!(o.status.code(), Some(1), "{args:?}: {e}");
    assert_eq!(e.trim_end().lines().count(), 1, "not one line: {e}");
    for n in needles {
        assert!(e.contains(n), "`{n}` not in: {e}");
    }
    e
}

/// The bench example config with `edit` applied, and a 0.5 s twin recording.
fn bench(d: &Path, edit: impl Fn(String) -> String) -> (PathBuf, PathBuf) {
    let cfg = d.join("bench.toml");
    std::fs::write(&cfg, edit(std::fs::read_to_string("../../examples/bench-kit.toml").unwrap())).unwrap();
    let rec = d.join("bench.csv");
    let o = run(&["simulate", "--preset", "kit-bench", "--duration", "0.5", "--out", s(&rec), "--quiet"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    (cfg, rec)
}

/// `rec` with `f` applied to each line (0: the header).
fn edit_lines(rec: &Path, out: &Path, f: impl Fn(usize, &str) -> String) {
    let text = std::fs::read_to_string(rec).unwrap();
    let lines: Vec<String> = text.lines().enumerate().map(|(k, l)| f(k, l)).collect();
    std::fs::write(out, lines.join("\n") + "\n").unwrap();
}

#[test]
fn fuse_names_the_config_for_its_keys() {
    let d = tmp("fuse-config");
    let (cfg, rec) = bench(&d, |t| t.replace("crossover_hz = 250.0", "crossover_hz = 1e9"));
    let out = d.join("f.csv");
    for method in ["complementary", "spectral", "corrected"] {
        error(
            &["fuse", "--config", s(&cfg), "--in", s(&rec), "--method", method, "--out", s(&out)],
            &["bench.toml: ", "`crossover_hz`", "Nyquist"],
        );
    }
    // A steady-torque corner too small for the section to be computed.
    let (tiny, _) = bench(&d, |t| t.replace("static_corner_hz = 0.05", "static_corner_hz = 1e-320"));
    let needles = ["bench.toml: [model]: `static_corner_hz` is out of range"];
    error(&["fuse", "--config", s(&tiny), "--in", s(&rec), "--out", s(&out)], &needles);
    // A damping no bench has: the fusion inverted from it is far off on its own model.
    let damping = "bearing_damping_nm_s_per_rad = 424e-6";
    let (absurd, _) = bench(&d, |t| t.replace(damping, "bearing_damping_nm_s_per_rad = 1e10"));
    let needles = ["bench.toml: the online fusion designed from `[model]` is off by ", "--method complementary"];
    error(&["fuse", "--config", s(&absurd), "--in", s(&rec), "--out", s(&out)], &needles);
    // A hundred times the example's is still a model: written, with its flatness.
    let (large, _) = bench(&d, |t| t.replace(damping, "bearing_damping_nm_s_per_rad = 424e-4"));
    let o = run(&["fuse", "--config", s(&large), "--in", s(&rec), "--out", s(&out)]);
    assert!(o.status.success() && out.exists(), "{}", String::from_utf8_lossy(&o.stderr));
    std::fs::remove_file(&out).unwrap();
    // TOML syntax: file, line and column on one line.
    std::fs::write(&cfg, "radius_m = [\n").unwrap();
    error(&["fuse", "--config", s(&cfg), "--in", s(&rec), "--out", s(&out)], &["bench.toml: line 2, column"]);
    assert!(!out.exists());
}

#[test]
fn fuse_names_the_recording_and_its_row_from_one() {
    let d = tmp("fuse-rows");
    let (cfg, rec) = bench(&d, |t| t);
    let out = d.join("f.csv");
    let header = std::fs::read_to_string(&rec).unwrap().lines().next().unwrap().to_string();
    let torsion = header.split(',').position(|c| c == "torsion_torque").unwrap();
    // A NaN torsion at data row 7 (line 8), read whole by the offline methods.
    let nan = d.join("nan.csv");
    edit_lines(&rec, &nan, |k, l| {
        if k != 7 {
            return l.to_string();
        }
        let mut cells: Vec<&str> = l.split(',').collect();
        cells[torsion] = "NaN";
        cells.join(",")
    });
    for method in ["spectral", "complementary"] {
        error(
            &["fuse", "--config", s(&cfg), "--in", s(&nan), "--method", method, "--out", s(&out)],
            &["nan.csv: ", "row 7", "`torsion_torque`"],
        );
        // Resampled (20 → 40 kHz), the rows are not the file's: named by their time.
        let resampled = ["--resample-hz", "40000"];
        let args = ["fuse", "--config", s(&cfg), "--in", s(&nan), "--method", method, "--out", s(&out)];
        error(&[&args[..], &resampled].concat(), &["nan.csv: resampled row 12 (time 0.000275 s): `torsion_torque`"]);
    }
    let args = ["orders", "--in", s(&nan), "--signal", "torsion_torque", "--speed", "speed_rpm", "--order", "18"];
    error(
        &[&args[..], &["--out", s(&d.join("o.svg")), "--resample-hz", "40000"]].concat(),
        &["nan.csv: resampled row 12 (time 0.000275 s), column `torsion_torque`: NaN is not finite"],
    );
    // The second time equal to the first: the sample rate cannot come from them.
    let same = d.join("same.csv");
    edit_lines(&rec, &same, |k, l| if k == 2 { l.replacen(l.split(',').next().unwrap(), "0", 1) } else { l.into() });
    error(
        &["fuse", "--config", s(&cfg), "--in", s(&same), "--method", "complementary", "--out", s(&out)],
        &["same.csv: row 2, column `time`"],
    );
    // A second time stamp 1e15 s on: the third row's time goes back, named by its row.
    let jump = d.join("jump.csv");
    edit_lines(&rec, &jump, |k, l| if k == 2 { l.replacen(l.split(',').next().unwrap(), "1e15", 1) } else { l.into() });
    error(&["fuse", "--config", s(&cfg), "--in", s(&jump), "--out", s(&out)], &["jump.csv: row 3, column `time`"]);
    // Times in another unit (1e15 times too large): the online fusion's design fails at
    // that rate, and the message says where the rate came from.
    let slow = d.join("slow.csv");
    edit_lines(&rec, &slow, |k, l| {
        let t = l.split(',').next().unwrap();
        match (k, t.parse::<f64>()) {
            (1.., Ok(v)) => l.replacen(t, &format!("{:?}", v * 1e15), 1),
            _ => l.into(),
        }
    });
    error(
        &["fuse", "--config", s(&cfg), "--in", s(&slow), "--out", s(&out)],
        &[" Hz sampling, from ", "slow.csv: the median step of rows 1–65, column `time`"],
    );
    // An input that already has the output's column.
    let fused = d.join("fused.csv");
    edit_lines(&rec, &fused, |k, l| if k == 0 { l.replacen("torsion_torque", "fused_torque", 1) } else { l.into() });
    let cfg2 = d.join("bench2.toml");
    std::fs::write(&cfg2, std::fs::read_to_string(&cfg).unwrap().replace("\"torsion_torque\"", "\"fused_torque\""))
        .unwrap();
    error(
        &["fuse", "--config", s(&cfg2), "--in", s(&fused), "--method", "complementary", "--out", s(&out)],
        &["fused.csv: already has a `fused_torque` column"],
    );
    assert!(!out.exists());
}

/// Resampled rows are not the file's: `filter --resample-hz` names a bad value by the
/// resampled row's time and the data rows of the file it lies between (it said "data row
/// 998" of a file whose bad row is 500), with or without `--smooth`, and so does
/// `--lenient`'s warning.
#[test]
fn filter_names_a_resampled_row_by_its_time_and_the_file_rows() {
    let d = tmp("resampled-rows");
    let rec = d.join("rec.csv");
    let o = run(&["simulate", "--preset", "taghirad", "--duration", "1", "--out", s(&rec), "--quiet"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let header = std::fs::read_to_string(&rec).unwrap().lines().next().unwrap().to_string();
    let torque = header.split(',').position(|c| c == "bridge_voltage").unwrap();
    let bad = d.join("inf.csv");
    edit_lines(&rec, &bad, |k, l| {
        let mut cells: Vec<String> = l.split(',').map(String::from).collect();
        if k == 500 {
            cells[torque] = "inf".into();
        }
        cells.join(",")
    });
    let config = "../../examples/joint-taghirad.toml";
    let out = d.join("out.csv");
    let filter = ["filter", "--config", config, "--in", s(&bad), "--out", s(&out)];
    error(&filter, &["inf.csv: data row 500: column `bridge_voltage`"]);
    let at = "resampled row 998 (time 0.4985 s, between data rows 499 and 500 of the file): column `bridge_voltage`";
    error(&[&filter[..], &["--resample-hz", "2000"]].concat(), &[at]);
    error(&[&filter[..], &["--resample-hz", "2000", "--smooth"]].concat(), &[at]);
    let o = run(&[&filter[..], &["--resample-hz", "2000", "--lenient"]].concat());
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(
        o.status.success() && e.contains("the first at resampled row 998 (time 0.4985 s, between data rows 499"),
        "{e}"
    );
}

#[test]
fn identify_names_the_config_for_its_keys() {
    let d = tmp("identify");
    let rec = d.join("arm.csv");
    let o = run(&["simulate", "--preset", "hda-arm", "--duration", "1", "--out", s(&rec), "--quiet"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let base = std::fs::read_to_string("../../examples/arm-hda.toml").unwrap();
    let cfg = d.join("arm.toml");
    let out = d.join("model.toml");
    // A TOML error: one line with file, line and column.
    std::fs::write(&cfg, base.replace("ratio = 100.0", "ratio = [")).unwrap();
    error(&["identify", "--config", s(&cfg), "--loaded", s(&rec), "--out", s(&out)], &["arm.toml: line ", ", column "]);
    // A key's value the library refuses: the config file and the key.
    std::fs::write(&cfg, base.replace("ratio = 100.0", "ratio = 0.0")).unwrap();
    error(&["identify", "--config", s(&cfg), "--loaded", s(&rec), "--out", s(&out)], &["arm.toml: ", "gear"]);
    std::fs::write(&cfg, base.replace("motor_counts_per_rev = 131072", "motor_counts_per_rev = 0")).unwrap();
    error(
        &["identify", "--config", s(&cfg), "--loaded", s(&rec), "--out", s(&out)],
        &["arm.toml: ", "encoders.motor_counts_per_rev"],
    );
    std::fs::write(&cfg, base.replace("time = \"time\"", "")).unwrap();
    error(
        &["identify", "--config", s(&cfg), "--loaded", s(&rec), "--out", s(&out)],
        &["arm.toml: give sample_rate_hz or channels.time"],
    );
    assert!(!out.exists());
}

#[test]
fn a_scenario_toml_error_is_one_plain_line() {
    let d = tmp("scenario");
    let cfg = d.join("twin.toml");
    std::fs::write(&cfg, "[gear\nratio = 1\n").unwrap();
    let e = error(
        &["simulate", "--scenario", s(&cfg), "--out", s(&d.join("x.csv"))],
        &["twin.toml", "invalid table header; expected", "(at line 1, column 6)"],
    );
    assert!(!e.contains('\\'), "an escaped line break: {e}");
}

/// A command-line choice is an enum: any other value is a usage error (exit 2) that lists
/// the accepted ones; the older snake spelling of `--speed-unit` still parses.
#[test]
fn an_unknown_choice_lists_the_accepted_ones() {
    for (args, accepted) in [
        (
            &["fuse", "--config", "b.toml", "--in", "x.csv", "--out", "y.csv", "--method", "hoka"][..],
            "online-corrected",
        ),
        (&["export-c", "--config", "j.toml", "--out", "-", "--precision", "f16"], "f64, f32"),
        (&["orders", "--in", "x.csv", "--signal", "s", "--speed", "v", "--speed-unit", "rps"], "rpm, rad-s"),
        (
            &["orders", "--in", "x.csv", "--signal", "s", "--speed", "v", "--align", "spline"],
            "linear, hold, nearest, none",
        ),
        (&["orders", "--in", "x.csv", "--signal", "s", "--speed", "v", "--time", "wall"], "header, log"),
    ] {
        let o = run(args);
        let e = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {e}");
        assert!(e.contains("possible values") && e.contains(accepted), "{args:?}: {e}");
    }
    let d = tmp("speed-unit");
    let out = d.join("o.csv");
    let none = d.join("none.csv");
    let o = run(&[
        "orders",
        "--in",
        s(&none),
        "--signal",
        "s",
        "--speed",
        "v",
        "--speed-unit",
        "rad_s",
        "--order",
        "2",
        "--out",
        s(&out),
    ]);
    let e = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "parsed, then the missing file: {e}");
    // calibrate's --time-column and the global --time are two options.
    let o = run(&["calibrate", "--in", s(&none), "--reference", "r", "--sensor", "v", "--time", "log"]);
    let e = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{e}");
    assert!(!e.contains("panicked"), "{e}");
}

#[test]
fn design_names_the_file_line_and_key_of_a_wrong_type() {
    let d = tmp("design");
    let text = std::fs::read_to_string("../../examples/sensor-taghirad.toml").unwrap();
    for (prefix, to, key) in
        [("seed = ", "seed = nan", "`monte_carlo.seed`"), ("layout = ", "layout = 0", "`sensor.layout`")]
    {
        assert!(text.lines().any(|l| l.starts_with(prefix)), "{prefix}");
        let edited: Vec<&str> = text.lines().map(|l| if l.starts_with(prefix) { to } else { l }).collect();
        let cfg = d.join("sensor.toml");
        std::fs::write(&cfg, edited.join("\n")).unwrap();
        error(&["design", "--config", s(&cfg)], &["sensor.toml: line ", key]);
    }
}

#[test]
fn report_lists_the_columns_when_the_time_column_is_missing() {
    let d = tmp("report");
    // A device line above the header is read as a header of one column.
    let rec = d.join("daq.csv");
    std::fs::write(&rec, "NI 9237 rev B\ntime,torque\n0,1\n").unwrap();
    let out = d.join("r.html");
    error(&["report", "--in", s(&rec), "--out", s(&out)], &["daq.csv: no column `time` (columns: NI 9237 rev B)"]);
    assert!(!out.exists());
}

#[test]
fn options_that_cannot_work_together_are_refused() {
    let d = tmp("combinations");
    let cfg = "../../examples/joint-taghirad.toml";
    let rec = d.join("rec.csv");
    let o = run(&["simulate", "--preset", "taghirad", "--duration", "0.2", "--out", s(&rec), "--quiet"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    // `--learn -` would write a file named `-`.
    error(&["filter", "--config", cfg, "--in", s(&rec), "--learn", "-"], &["--learn -: the learned file is a file"]);
    assert!(!Path::new("-").exists() && !d.join("-").exists());
    // Resampled encoder counts are not counts.
    let out = d.join("e.csv");
    let model = "../../examples/lara8-joint3.toml";
    error(
        &["estimate", "--config", model, "--in", s(&rec), "--out", s(&out), "--resample-hz", "500"],
        &["--resample-hz interpolates the encoder counts"],
    );
    assert!(!out.exists());
}

#[test]
fn identify_says_why_two_holdout_blocks_are_too_few_for_several_stribeck_speeds() {
    let d = tmp("holdout2");
    let out = d.join("m.toml");
    let args =
        ["identify", "--config", "../../examples/lara8-joint3.toml", "--loaded", "../../data/lara8/validate.csv"];
    let mut with = args.to_vec();
    with.extend(["--holdout", "2", "--out", s(&out)]);
    error(&with, &["--holdout 2: choosing among the 5 candidates of `friction.stribeck_speed_rad_s`", "--holdout 3"]);
    assert!(!out.exists());
}

/// `calibrate` and `identify` name a resampled row by its time too (they said "row 1000"
/// and "data row 41" of files whose bad rows are 500 and 50).
#[test]
fn calibrate_and_identify_name_a_resampled_row_by_its_time() {
    let d = tmp("resampled-fits");
    let locked = d.join("locked.csv");
    let o = run(&["simulate", "--preset", "taghirad", "--procedure", "locked-wg", "--out", s(&locked), "--quiet"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let bad = d.join("glitch.csv");
    let reference = 6; // reference_torque
    edit_lines(&locked, &bad, |k, l| {
        let mut cells: Vec<String> = l.split(',').map(String::from).collect();
        if k == 501 {
            cells[reference] = "4e9".into();
        }
        cells.join(",")
    });
    let calibrate = ["calibrate", "--in", s(&bad), "--experiment-column", "experiment"];
    let calibrate = [&calibrate[..], &["--reference", "reference_torque", "--sensor", "bridge_voltage"]].concat();
    error(&calibrate, &["glitch.csv: row 501: `reference_torque` = 4000000000.0 is over 100 times"]);
    let resampled = [&calibrate[..], &["--resample-hz", "2000"]].concat();
    error(&resampled, &["glitch.csv: resampled row 1000 (time 0.4995 s): `reference_torque` = 2000000008.0"]);

    let text = std::fs::read_to_string("../../data/lara8/validate.csv").unwrap();
    let mut lines: Vec<String> = text.lines().map(String::from).collect();
    let c = lines[0].split(',').position(|h| h == "joint_torque_current_3").unwrap();
    let mut cells: Vec<String> = lines[50].split(',').map(String::from).collect();
    cells[c] = "1e308".into();
    lines[50] = cells.join(",");
    let log = d.join("edited.csv");
    std::fs::write(&log, lines.join("\n") + "\n").unwrap();
    let out = d.join("model.toml");
    let identify = ["identify", "--config", "../../examples/lara8-joint3.toml", "--loaded", s(&log), "--out", s(&out)];
    error(&identify, &["edited.csv: data row 50: column `joint_torque_current_3`"]);
    // The log's time column is `Timestamp` (channels.time): --resample-hz reads it there.
    let at = "edited.csv: resampled row 41 (time 92125.577816271 s): column `joint_torque_current_3`";
    error(&[&identify[..], &["--resample-hz", "200"]].concat(), &[at]);
    // Resampled encoder counts are not whole: the message says why.
    error(
        &[&identify[..], &["--resample-hz", "200", "--lenient"]].concat(),
        &["resampled row 2 (time ", "are not whole numbers (--resample-hz interpolates between rows"],
    );
}

/// `--resample-hz` resamples on the config's time channel: a recording whose time column
/// is not `time` failed with "no column `time` … set --time-column", an option `filter`
/// does not have.
#[test]
fn resampling_uses_the_configs_time_channel() {
    let d = tmp("resample-time-channel");
    let rec = d.join("rec.csv");
    let o = run(&["simulate", "--preset", "taghirad", "--duration", "1", "--out", s(&rec), "--quiet"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let renamed = d.join("t_s.csv");
    edit_lines(&rec, &renamed, |k, l| if k == 0 { l.replacen("time,", "t_s,", 1) } else { l.to_string() });
    let base = std::fs::read_to_string("../../examples/joint-taghirad.toml").unwrap();
    let cfg = d.join("joint.toml");
    let edited: Vec<&str> = base.lines().filter(|l| !l.starts_with("learned")).collect();
    std::fs::write(&cfg, edited.join("\n").replace("time = \"time\"", "time = \"t_s\"")).unwrap();
    let out = d.join("out.csv");
    let o = run(&["filter", "--config", s(&cfg), "--in", s(&renamed), "--out", s(&out), "--resample-hz", "2000", "-q"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let rows = std::fs::read_to_string(&out).unwrap().lines().count() - 1;
    assert_eq!(rows, 1999, "1000 rows at 1 kHz resampled at 2 kHz");
    // A time channel with a scale is not seconds: refused, saying what to do.
    let scaled = d.join("scaled.toml");
    std::fs::write(&scaled, edited.join("\n").replace("time = \"time\"", "time = { column = \"t_s\", scale = 0.001 }"))
        .unwrap();
    let args = ["filter", "--config", s(&scaled), "--in", s(&renamed), "--out", s(&out), "--resample-hz", "2000"];
    error(&args, &["t_s.csv: --resample-hz needs the time in seconds", "`t_s [ms]`"]);
}

/// Extreme values in an arm or bench scenario: refused by key, or by the first value of the
/// recording that stops being finite, with no output left (before: a panic in the arm
/// twin, and NaN rows written with exit 0 by the bench twin).
#[test]
fn simulate_refuses_scenarios_that_overflow() {
    let d = tmp("simulate-extreme");
    let scenario = |preset: &str, key: &str, value: &str| {
        let o = run(&["simulate", "--preset", preset, "--print-scenario"]);
        let text = String::from_utf8(o.stdout).unwrap();
        let line = text.lines().find(|l| l.starts_with(&format!("{key} ="))).unwrap_or_else(|| panic!("{key}"));
        let p = d.join(format!("{preset}-{key}.toml"));
        std::fs::write(&p, text.replacen(line, &format!("{key} = {value}"), 1)).unwrap();
        p
    };
    let out = d.join("out.csv");
    let cases = [
        (scenario("hda-arm", "ratio", "1e-300"), "`gear.ratio` must be between 1 and 10000, got 1e-300"),
        (scenario("hda-arm", "offset_rad", "1e308"), "column `reference_torque` is not finite at t = 0 s"),
        (scenario("kit-bench", "brake_inertia_kg_m2", "1e-12"), "is not finite at t = "),
        (scenario("taghirad", "adc_range_v", "1e308"), "column `bridge_voltage` is not finite at t = 0 s"),
    ];
    for (p, needle) in cases {
        error(&["simulate", "--scenario", s(&p), "--duration", "0.05", "--out", s(&out)], &[needle]);
        assert!(!out.exists());
    }
    for preset in ["hda-arm", "kit-bench"] {
        error(&["simulate", "--preset", preset, "--duration", "1e-300", "--out", s(&out)], &["not one sample"]);
    }
    assert_eq!(
        std::fs::read_dir(&d)
            .unwrap()
            .filter(|e| e.as_ref().unwrap().path().extension() != Some("toml".as_ref()))
            .count(),
        0
    );
}

/// A signal whose spectrum would overflow is named by its row (before: an empty plot, or
/// a table of NaN, with exit 0).
#[test]
fn spectral_commands_name_a_value_their_spectrum_would_overflow() {
    let d = tmp("spectral-overflow");
    let rec = d.join("big.csv");
    let mut text = String::from("time,x,speed_rpm\n");
    for k in 0..4096 {
        let x = if k == 700 { 1e200 } else { (k as f64 * 0.3).sin() };
        text += &format!("{},{x},{}\n", k as f64 * 1e-3, 1000.0 + k as f64);
    }
    std::fs::write(&rec, text).unwrap();
    let svg = d.join("out.svg");
    let needle = "row 701, column `x`: 1e200 is beyond ±1e100, where its spectrum would overflow";
    error(&["spectrogram", "--in", s(&rec), "--signal", "x", "--out", s(&svg)], &[needle]);
    error(&["campbell", "--in", s(&rec), "--signal", "x", "--speed", "speed_rpm", "--out", s(&svg)], &[needle]);
    error(
        &["orders", "--in", s(&rec), "--signal", "x", "--speed", "speed_rpm", "--order", "2", "--out", s(&svg)],
        &[needle],
    );
    assert!(!svg.exists());
}

/// The spectral commands' speed and options named as the user gave them (before: a mean
/// speed of 300 digits with no file, `--order 6: revs_per_block` for `--revs-per-block`,
/// and "`#` is not one ASCII character").
#[test]
fn spectral_commands_name_their_file_speed_row_and_option() {
    let d = tmp("spectral-speed");
    let rec = d.join("run.csv");
    let mut text = String::from("time,x,speed_rpm\n");
    for k in 0..4096 {
        let speed = if k == 100 { -1.7e308 } else { 1000.0 };
        text += &format!("{},{},{speed}\n", k as f64 * 1e-3, (k as f64 * 0.3).sin());
    }
    std::fs::write(&rec, text).unwrap();
    let svg = d.join("out.svg");
    let needle = "run.csv: row 101, column `speed_rpm`: speed -1.7e308 rpm is beyond ±1e7 rpm";
    error(&["campbell", "--in", s(&rec), "--signal", "x", "--speed", "speed_rpm", "--out", s(&svg)], &[needle]);
    std::fs::write(&rec, "time,x,speed_rpm\n0,1,-5\n0.001,2,-5\n").unwrap();
    error(
        &["orders", "--in", s(&rec), "--signal", "x", "--speed", "speed_rpm", "--order", "2", "--out", s(&svg)],
        &["run.csv: --speed: column `speed_rpm` is zero or negative"],
    );
    let mut text = String::from("time,x,speed_rpm\n");
    for k in 0..4096 {
        text += &format!("{},{},1000\n", k as f64 * 1e-3, (k as f64 * 0.3).sin());
    }
    std::fs::write(&rec, text).unwrap();
    for bad in ["0", "inf"] {
        let args = ["orders", "--in", s(&rec), "--signal", "x", "--speed", "speed_rpm", "--order", "2"];
        error(
            &[&args[..], &["--revs-per-block", bad, "--out", s(&svg)]].concat(),
            &["--revs-per-block: must be at least 1"],
        );
    }
    let o = run(&["convert", "--in", s(&rec), "--delimiter", "#", "--out", s(&d.join("o.csv"))]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("`#` starts a comment line"));
    assert!(!svg.exists());
}
