//! `strainwave filter` and `strainwave report` end to end.

use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};

fn run(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_strainwave")).args(args).output().expect("run strainwave")
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("sw-filter-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn config() -> String {
    root().join("examples/joint-taghirad.toml").to_str().unwrap().to_string()
}

fn assert_user_error(o: &Output, needle: &str) {
    let e = stderr(o);
    assert_eq!(o.status.code(), Some(1), "{e}");
    assert!(e.contains(needle), "`{needle}` not in: {e}");
    assert_eq!(e.trim_end().lines().count(), 1, "one line: {e}");
}

/// The example config's text with its learned file as an absolute path (for copies
/// written elsewhere).
fn absolute_learned(cfg: &str) -> String {
    let learned = root().join("examples/joint-taghirad-learned.toml");
    cfg.replace("\"joint-taghirad-learned.toml\"", &format!("{:?}", learned.to_str().unwrap()))
}

fn simulate(d: &Path, seconds: &str) -> PathBuf {
    let f = d.join("sim.csv");
    let o = run(&["simulate", "--preset", "taghirad", "--duration", seconds, "--out", f.to_str().unwrap(), "-q"]);
    assert!(o.status.success(), "{}", stderr(&o));
    f
}

fn read(path: &Path) -> (Vec<String>, Vec<Vec<f64>>) {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    let header = lines.next().unwrap().split(',').map(String::from).collect();
    (header, lines.map(|l| l.split(',').map(|v| v.parse().unwrap()).collect()).collect())
}

fn col(h: &[String], rows: &[Vec<f64>], name: &str) -> Vec<f64> {
    let i = h.iter().position(|c| c == name).unwrap_or_else(|| panic!("no {name}"));
    rows.iter().map(|r| r[i]).collect()
}

#[test]
fn filter_adds_its_columns_and_removes_ripple_at_constant_speed() {
    let d = tmp("basic");
    let sim = simulate(&d, "4");
    let out = d.join("f.csv");
    let o = run(&["filter", "--config", &config(), "--in", sim.to_str().unwrap(), "--out", out.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let (h, rows) = read(&out);
    for c in ["torque", "ripple", "misalignment", "innovation", "nis", "filter_flags", "true_torque"] {
        assert!(h.iter().any(|x| x == c), "{c}");
    }
    // The clean torque equals the calibrated input minus the predictions (no added delay).
    let (meas, tq, rip, mis) = (
        col(&h, &rows, "measured_torque"),
        col(&h, &rows, "torque"),
        col(&h, &rows, "ripple"),
        col(&h, &rows, "misalignment"),
    );
    for k in 0..rows.len() {
        // bridge_voltage × the config's gain (6.611) vs the simulator's exact gain: 1e-4 relative.
        assert!((tq[k] + rip[k] + mis[k] - meas[k]).abs() < 1e-3 * meas[k].abs().max(1.0), "row {k}");
    }
    // The predicted ripple follows the true ripple once converged (1.5–2.0 s, constant speed).
    let tr = col(&h, &rows, "true_ripple");
    let (mut e0, mut e1) = (0.0, 0.0);
    for k in 1500..2000 {
        e0 += tr[k] * tr[k];
        e1 += (tr[k] - rip[k]).powi(2);
    }
    let db = 10.0 * (e0 / e1).log10();
    assert!(db > 20.0, "ripple suppression at constant speed {db:.1} dB");
}

#[test]
fn filter_streams_through_a_pipe() {
    let d = tmp("pipe");
    let sim = simulate(&d, "0.5");
    let mut child = Command::new(env!("CARGO_BIN_EXE_strainwave"))
        .args(["filter", "--config", &config(), "--in", "-", "--out", "-", "-q"])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let data = std::fs::read(&sim).unwrap();
    let mut stdin = child.stdin.take().unwrap();
    let writer = std::thread::spawn(move || {
        use std::io::Write;
        stdin.write_all(&data).unwrap();
    });
    let o = child.wait_with_output().unwrap();
    writer.join().unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    let text = String::from_utf8(o.stdout).unwrap();
    assert_eq!(text.lines().count(), 501);
    assert!(text.lines().next().unwrap().ends_with("torque,ripple,misalignment,innovation,nis,filter_flags"));
}

/// A copy of the simulated recording with one cell of data row `row` replaced.
fn with_cell(sim: &Path, row: usize, column: &str, value: &str, name: &str) -> PathBuf {
    let text = std::fs::read_to_string(sim).unwrap();
    let mut lines: Vec<String> = text.lines().map(String::from).collect();
    let i = lines[0].split(',').position(|c| c == column).unwrap();
    let mut cells: Vec<String> = lines[row].split(',').map(String::from).collect();
    cells[i] = value.into();
    lines[row] = cells.join(",");
    let bad = sim.with_file_name(name);
    std::fs::write(&bad, lines.join("\n") + "\n").unwrap();
    bad
}

/// A non-finite sample stops the filter with the row, column and channel named (exit 1,
/// nothing written); with `--lenient` it is skipped with a flag and counted, by the
/// filter and by the smoother.
#[test]
fn nan_samples_are_errors_or_with_lenient_skipped_with_a_flag() {
    let d = tmp("nan");
    let sim = simulate(&d, "0.5");
    let bad = with_cell(&sim, 100, "bridge_voltage", "NaN", "nan.csv");
    let out = d.join("f.csv");
    let args = ["filter", "--config", &config(), "--in", bad.to_str().unwrap(), "--out", out.to_str().unwrap()];
    assert_user_error(&run(&args), "data row 100: column `bridge_voltage` (`channels.torque`) is NaN");
    assert!(!out.exists());
    let angle = with_cell(&sim, 7, "motor_angle", "inf", "inf.csv");
    let o = run(&["filter", "--config", &config(), "--in", angle.to_str().unwrap(), "--out", out.to_str().unwrap()]);
    assert_user_error(&o, "data row 7: column `motor_angle` (`channels.motor_angle`) is inf");
    let back = with_cell(&sim, 50, "time", "0.01", "back.csv");
    let o = run(&["filter", "--config", &config(), "--in", back.to_str().unwrap(), "--out", out.to_str().unwrap()]);
    assert_user_error(&o, "data row 50: time 0.01 s is not after the previous row's");
    // On standard output the rows already written are counted in the message.
    let o = run(&["filter", "--config", &config(), "--in", bad.to_str().unwrap(), "--out", "-"]);
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("(99 rows were already written to standard output)"), "{}", stderr(&o));

    for extra in [None, Some("--smooth")] {
        let mut lenient = args.to_vec();
        lenient.push("--lenient");
        lenient.extend(extra);
        let o = run(&lenient);
        assert!(o.status.success(), "{}", stderr(&o));
        let e = stderr(&o);
        assert!(e.contains("1 samples with a non-finite angle, or a torque not finite or beyond ±1e12 N·m"), "{e}");
        assert!(e.contains("were skipped, the first at data row 100"), "{e}");
        let (h, rows) = read(&out);
        let flags = col(&h, &rows, "filter_flags");
        assert_eq!(flags[99] as u32 & 1, 1, "row 100 flagged");
        assert!(col(&h, &rows, "torque")[101].is_finite());
        std::fs::remove_file(&out).unwrap();
    }
    // A DAQ's overrange code (9.9e37 V) is skipped as a NaN is, even without --lenient: its
    // square would overflow the filter. The run goes on, the row passes its value through.
    let over = with_cell(&sim, 100, "bridge_voltage", "9.9e37", "over.csv");
    let o = run(&["filter", "--config", &config(), "--in", over.to_str().unwrap(), "--out", out.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stderr(&o).contains("were skipped, the first at data row 100"), "{}", stderr(&o));
    let (h, rows) = read(&out);
    assert_eq!(col(&h, &rows, "filter_flags")[99] as u32 & 1, 1, "row 100 flagged");
    assert!(col(&h, &rows, "nis")[99].is_nan());
    assert!(col(&h, &rows, "torque")[100..].iter().all(|t| t.abs() < 100.0));
}

/// Each shipped joint config runs on the preset it was written for. The full
/// configurations (with their learned files) remove at least 20 dB of the raw error
/// against `true_torque` and come within 1.1× the config's noise floor (a stale learned
/// file fails this); the paper's own models only have to run.
#[test]
fn every_shipped_joint_config_runs_on_its_preset() {
    let d = tmp("examples");
    let cases = [
        ("joint-taghirad.toml", "taghirad-loaded", Some(20.0)),
        ("joint-flexspline-fixed.toml", "flexspline-fixed", Some(20.0)),
        ("joint-taghirad-4th-order.toml", "taghirad", None),
        ("joint-taghirad-6th-order.toml", "taghirad", None),
    ];
    for (cfg, preset, floor_db) in cases {
        let sim = d.join(format!("{preset}.csv"));
        if !sim.exists() {
            simulate_preset(&d, preset);
        }
        let out = d.join(format!("{cfg}.csv"));
        let cfg_path = root().join("examples").join(cfg);
        let o = run(&["filter", "--config", cfg_path.to_str().unwrap(), "--in", sim.to_str().unwrap(), "--out"]
            .into_iter()
            .chain([out.to_str().unwrap(), "-q"])
            .collect::<Vec<_>>());
        assert!(o.status.success(), "{cfg}: {}", stderr(&o));
        let (raw, filtered) = (rms_error(&out, "measured_torque", 0.3), rms_error(&out, "torque", 0.3));
        assert!(filtered.is_finite(), "{cfg}");
        if let Some(floor) = floor_db {
            let db = 20.0 * (raw / filtered).log10();
            assert!(db >= floor, "{cfg} on {preset}: {db:.1} dB");
            let noise_nm = noise_nm(&cfg_path);
            assert!(filtered <= 1.1 * noise_nm, "{cfg} on {preset}: {:.2}× the noise floor", filtered / noise_nm);
        }
    }
}

#[test]
fn bad_inputs_are_one_line_errors_and_write_nothing() {
    let d = tmp("bad");
    let sim = simulate(&d, "0.2");
    let out = d.join("never.csv");
    let cfg_text = std::fs::read_to_string(config()).unwrap();
    let counter = std::cell::Cell::new(0);
    let with = |from: &str, to: &str| {
        assert!(cfg_text.contains(from), "{from}");
        counter.set(counter.get() + 1);
        let p = d.join(format!("cfg-{}.toml", counter.get()));
        std::fs::write(&p, absolute_learned(&cfg_text.replacen(from, to, 1))).unwrap();
        p
    };
    let cases = [
        (with("ratio = 100.0", "ratio = 0.0"), "gear.ratio"),
        (with("motor_velocity = \"motor_velocity\"", "motor_velocity = \"tacho\""), "no column `tacho`"),
        // A column the recording lacks, named as such (not as a learned file of another
        // joint, the channel being part of the joint's identity).
        (with("output_angle = \"output_angle\"", "output_angle = \"link_angle\""), "no column `link_angle`"),
        (with("noise_nm = 0.0162", "noise_nm = -1.0"), "noise_nm"),
        // Positive, but its variance overflows: named once, by its key and value.
        (with("noise_nm = 0.0162", "noise_nm = 1e300"), "toml: `filter.noise_nm` = 1e300 N·m: its square"),
        (with("noise_nm = 0.0162", "noise_nm = 1e-300"), "toml: `filter.noise_nm` = 1e-300 N·m: its square"),
        // The process noise the full model's tuning makes of it: named by `noise_nm` too
        // (before: `q_per_rad_nm2` and `q_per_sample_nm2`, keys this config has not).
        (with("noise_nm = 0.0162", "noise_nm = 1e10"), "`filter.noise_nm` is out of range"),
        (with("noise_nm = 0.0162", "noise_nm = 1e100"), "`filter.noise_nm` must be finite"),
        (with("model = \"full\"", "model = \"magic\""), "filter.model"),
        (with("model = \"full\"", "model = \"product\""), "orders [2 relative, 4 relative, 2 relative load-scaled"),
        (with("learned = \"joint-taghirad-learned.toml\"", "learned = \"missing.toml\""), "`filter.learned`: "),
        (with("gain_nm_per_v = 6.611", "file = \"nope.toml\""), "`calibration.file`: "),
        (with("[filter]", "[filter]\ncutoff = 3"), "cutoff"),
        (with("torque = \"bridge_voltage\"", "torque = { column = \"bridge_voltage\", sclae = 2 }"), "`sclae`"),
        (with("[channels]", "[channels"), "line 12, column 36: invalid table header"),
    ];
    for (cfg, needle) in cases {
        let o = run(&[
            "filter",
            "--config",
            cfg.to_str().unwrap(),
            "--in",
            sim.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ]);
        assert_user_error(&o, needle);
        assert!(!out.exists());
    }
    // An angle the scale makes infinite, as a NaN in the file (before: skipped with a
    // warning, the run going on). Cold: a learned file knows the channel's scale.
    let cold: String = cfg_text.lines().filter(|l| !l.starts_with("learned")).map(|l| format!("{l}\n")).collect();
    let scaled = d.join("scaled.toml");
    let to = "motor_angle = { column = \"motor_angle\", scale = 1e308 }";
    std::fs::write(&scaled, cold.replacen("motor_angle = \"motor_angle\"", to, 1)).unwrap();
    let o = run(&[
        "filter",
        "--config",
        scaled.to_str().unwrap(),
        "--in",
        sim.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_user_error(&o, "column `motor_angle` (`channels.motor_angle`) is");
    assert!(stderr(&o).contains("which its scale and offset make infinite"));
    assert!(!out.exists());
    let empty = d.join("empty.csv");
    std::fs::write(&empty, "").unwrap();
    assert_user_error(
        &run(&["filter", "--config", &config(), "--in", empty.to_str().unwrap(), "--out", out.to_str().unwrap()]),
        "empty file",
    );
    let header_only = d.join("header.csv");
    std::fs::write(&header_only, std::fs::read_to_string(&sim).unwrap().lines().next().unwrap().to_string() + "\n")
        .unwrap();
    assert_user_error(
        &run(&["filter", "--config", &config(), "--in", header_only.to_str().unwrap(), "--out", out.to_str().unwrap()]),
        "no data rows",
    );
    assert!(!out.exists());
}

#[test]
fn report_renders_sections_for_a_filtered_recording() {
    let d = tmp("report");
    let sim = simulate(&d, "2");
    let f = d.join("f.csv");
    assert!(run(&["filter", "--config", &config(), "--in", sim.to_str().unwrap(), "--out", f.to_str().unwrap(), "-q"])
        .status
        .success());
    let html = d.join("r.html");
    let o = run(&["report", "--in", f.to_str().unwrap(), "--config", &config(), "--out", html.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = std::fs::read_to_string(&html).unwrap();
    for s in ["Torque over time", "Amplitude spectrum", "Errors against true_torque", "(speed held)"] {
        assert!(text.contains(s), "{s}");
    }
    assert!(!text.contains("<script"));
    // The config's torque channel is a bridge voltage: not a torque to plot or to score in
    // N·m (before: listed with an "RMS error" of 2.26 V against true_torque).
    let errors = text.split("Errors against true_torque").nth(1).unwrap();
    let errors = errors.split("<h2").next().unwrap();
    assert!(errors.contains("measured_torque") && !errors.contains("bridge_voltage"), "{errors}");
    let over_time = text.split("Torque over time").nth(1).unwrap().split("<h2").next().unwrap();
    assert!(!over_time.contains("bridge_voltage"));
}

/// An empty cell is a missing value; a text cell (a DAQ's `OVL`) stops the run with a
/// hint, and `--lenient` reads it as missing: its sample is skipped with a flag.
#[test]
fn empty_and_text_cells_are_missing_values() {
    let d = tmp("cells");
    let sim = std::fs::read_to_string(simulate(&d, "0.2")).unwrap();
    let header: Vec<&str> = sim.lines().next().unwrap().split(',').collect();
    let at = |name: &str| header.iter().position(|c| *c == name).unwrap();
    // Data row 101 (line 102) with `cell` in column `column`.
    let with = |column: &str, cell: &str| {
        let mut lines: Vec<String> = sim.lines().map(String::from).collect();
        let mut cells: Vec<String> = lines[101].split(',').map(String::from).collect();
        cells[at(column)] = cell.to_string();
        lines[101] = cells.join(",");
        let f = d.join(format!("{column}-{}.csv", cell.len()));
        std::fs::write(&f, lines.join("\n") + "\n").unwrap();
        f
    };
    let (out, config) = (d.join("out.csv"), config());
    let filter = |input: &Path, lenient: bool| {
        let mut args =
            vec!["filter", "--config", &config, "--in", input.to_str().unwrap(), "--out", out.to_str().unwrap()];
        args.extend(lenient.then_some("--lenient"));
        run(&args)
    };
    // Empty in a column the filter does not use: passes through as NaN.
    let o = filter(&with("true_ripple", ""), false);
    assert!(o.status.success(), "{}", stderr(&o));
    let (columns, rows) = read(&out);
    let ripple = columns.iter().position(|c| c == "true_ripple").unwrap();
    assert!(rows[100][ripple].is_nan() && rows.len() == 200);
    // Empty in the torque channel: a NaN, with its hint.
    assert_user_error(
        &filter(&with("bridge_voltage", " "), false),
        "data row 101: column `bridge_voltage` (`channels.torque`) is NaN",
    );
    // Text: the cell named, with the option that goes on.
    let text = with("bridge_voltage", "OVL");
    assert_user_error(
        &filter(&text, false),
        "row 101, column `bridge_voltage`: `OVL` is not a number; pass --lenient to read such cells as missing (NaN)",
    );
    let o = filter(&text, true);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stderr(&o)
        .contains("1 cell(s) that are not numbers read as NaN, the first at row 101, column `bridge_voltage`: `OVL`"));
    let (columns, rows) = read(&out);
    let (flags, torque) = (col(&columns, &rows, "filter_flags"), col(&columns, &rows, "torque"));
    assert_eq!(rows.len(), 200);
    assert_eq!(flags[100] as u32 & 1, 1, "measurement skipped");
    assert!(torque[99].is_finite() && torque[101].is_finite());
}

#[test]
fn report_marks_the_order_lines_of_a_run_that_reverses() {
    // The taghirad run holds 156 rad/s one way, then the other: its net angle is small
    // and its ramps take the mean speed below the plateau, but its 2× line is at
    // 2 × 156 / 2π ≈ 50 Hz (drawn at 7.5 Hz before).
    let d = tmp("report-reverse");
    let sim = simulate_preset(&d, "taghirad");
    let html = d.join("r.html");
    let o = run(&["report", "--in", sim.to_str().unwrap(), "--config", &config(), "--out", html.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = std::fs::read_to_string(&html).unwrap();
    let hz = |label: &str| -> f64 {
        let after = text.split(label).nth(1).unwrap_or_else(|| panic!("no {label}"));
        after.trim_start().split(' ').next().unwrap().parse().unwrap()
    };
    let (two, four) = (hz("2×"), hz("4×"));
    assert!((48.5..51.0).contains(&two), "2× marked at {two} Hz");
    assert!((2.0 * two - four).abs() < 0.2, "4× at {four} Hz");
}

fn simulate_preset(d: &Path, preset: &str) -> PathBuf {
    let f = d.join(format!("{preset}.csv"));
    let o = run(&["simulate", "--preset", preset, "--out", f.to_str().unwrap(), "-q"]);
    assert!(o.status.success(), "{}", stderr(&o));
    f
}

/// `filter.noise_nm` of a joint config.
fn noise_nm(config: &Path) -> f64 {
    let text = std::fs::read_to_string(config).unwrap();
    let line = text.lines().find(|l| l.trim_start().starts_with("noise_nm")).expect("noise_nm");
    line.split('=').nth(1).unwrap().split('#').next().unwrap().trim().parse().unwrap()
}

fn rms_error(path: &Path, column: &str, after_s: f64) -> f64 {
    let (h, rows) = read(path);
    let (t, x, truth) = (col(&h, &rows, "time"), col(&h, &rows, column), col(&h, &rows, "true_torque"));
    let e: Vec<f64> = (0..t.len()).filter(|&k| t[k] > after_s).map(|k| x[k] - truth[k]).collect();
    (e.iter().map(|v| v * v).sum::<f64>() / e.len() as f64).sqrt()
}

/// Commissioning with `--learn`, then operation from the learned file: the loaded run's
/// torque comes out within 1.5× the white-noise floor (0.0162 N·m), and `--smooth` too.
#[test]
fn learn_on_commissioning_then_filter_and_smooth_a_loaded_run() {
    let d = tmp("learn");
    let comm = simulate_preset(&d, "taghirad-commissioning");
    let learned = d.join("learned.toml");
    let o = run(&[
        "filter",
        "--config",
        &config(),
        "--in",
        comm.to_str().unwrap(),
        "--out",
        d.join("comm-f.csv").to_str().unwrap(),
        "--learn",
        learned.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = std::fs::read_to_string(&learned).unwrap();
    // Misalignment 0.8 sin(θ + 0.7): cos coefficient 0.8 sin 0.7, sin coefficient 0.8 cos 0.7.
    let last = text.rsplit("[[orders]]").next().unwrap();
    let value = |key: &str| -> f64 {
        let line = last.lines().find(|l| l.starts_with(key)).unwrap();
        line.split('=').nth(1).unwrap().trim().parse().unwrap()
    };
    assert!(last.contains("reference = \"output\""), "{last}");
    assert!((value("cos_nm") - 0.8 * 0.7f64.sin()).abs() < 0.02, "{last}");
    assert!((value("sin_nm") - 0.8 * 0.7f64.cos()).abs() < 0.02, "{last}");

    let cfg = d.join("joint.toml");
    let cfg_text = std::fs::read_to_string(config()).unwrap();
    let learned_line = format!("learned = {:?}\ntorque_bandwidth_hz = 20.0", learned.to_str().unwrap());
    std::fs::write(&cfg, cfg_text.replace("learned = \"joint-taghirad-learned.toml\"", &learned_line)).unwrap();
    let loaded = simulate_preset(&d, "taghirad-loaded");
    let (out, smooth) = (d.join("loaded-f.csv"), d.join("loaded-s.csv"));
    for (path, extra) in [(&out, None), (&smooth, Some("--smooth"))] {
        let mut args = vec!["filter", "--config", cfg.to_str().unwrap(), "--in", loaded.to_str().unwrap(), "--out"];
        args.push(path.to_str().unwrap());
        args.extend(extra);
        let o = run(&args);
        assert!(o.status.success(), "{}", stderr(&o));
        // 20 Hz: α = 1 − exp(−2π 20/1000) = 0.1181, (1 − α)/(α fs) = 7.47 ms.
        assert!(stderr(&o).contains("torque_denoised: 20 Hz, group delay at DC 7.47 ms"), "{}", stderr(&o));
    }
    let raw = rms_error(&out, "measured_torque", 0.3);
    let filtered = rms_error(&out, "torque", 0.3);
    let smoothed = rms_error(&smooth, "torque", 0.3);
    assert!(raw > 0.5, "raw {raw}");
    assert!(filtered < 1.5 * 0.0162, "filtered {filtered}");
    assert!(smoothed < 1.5 * 0.0162, "smoothed {smoothed}");
    // The smoothed torque: below half the floor, its 1σ band covering the truth
    // 68 % ± 5 % of the time (the target; see docs/smoothing.md).
    let torque_smoothed = rms_error(&smooth, "torque_smoothed", 0.3);
    assert!(torque_smoothed < 0.5 * 0.0162, "torque_smoothed {torque_smoothed}");
    let (h, rows) = read(&smooth);
    let (t, x, sd, truth) = (
        col(&h, &rows, "time"),
        col(&h, &rows, "torque_smoothed"),
        col(&h, &rows, "torque_smoothed_sd"),
        col(&h, &rows, "true_torque"),
    );
    let after: Vec<usize> = (0..t.len()).filter(|&k| t[k] > 0.3).collect();
    let covered = after.iter().filter(|&&k| (x[k] - truth[k]).abs() <= sd[k]).count() as f64 / after.len() as f64;
    assert!((0.63..=0.73).contains(&covered), "coverage {covered}");
    // The causal denoised torque is the same with and without --smooth (the same forward
    // filter, up to the streaming kernel's rounding), and the streaming output has no
    // smoothed columns.
    let (hf, rows_f) = read(&out);
    let (a, b) = (col(&hf, &rows_f, "torque_denoised"), col(&h, &rows, "torque_denoised"));
    let most = a.iter().zip(&b).map(|(x, y)| (x - y).abs()).fold(0.0, f64::max);
    assert!(a.len() == b.len() && most < 1e-6, "torque_denoised differs by {most} N·m");
    assert!(!hf.iter().any(|c| c.starts_with("torque_smoothed")), "{hf:?}");
    let denoised = rms_error(&out, "torque_denoised", 0.3);
    // The report plots the smoothed torque and its band, gives its coverage, and states
    // the denoised torque's group delay.
    let html = d.join("loaded-s.html");
    let o = run(&["report", "--in", smooth.to_str().unwrap(), "--config", cfg.to_str().unwrap(), "--out"]
        .into_iter()
        .chain([html.to_str().unwrap()])
        .collect::<Vec<_>>());
    assert!(o.status.success(), "{}", stderr(&o));
    let text = std::fs::read_to_string(&html).unwrap();
    for s in ["Smoothed torque (offline)", "torque_smoothed", "+1σ", "400 rows at full rate", "group delay at DC"] {
        assert!(text.contains(s), "{s}");
    }
    // Over every row with a band (no warm-up left out), as the report counts, in its order
    // of operations (a share of exactly x.x5 % rounds alike).
    let banded: Vec<usize> = (0..t.len()).filter(|&k| x[k].is_finite() && sd[k].is_finite()).collect();
    let all = 100.0 * banded.iter().filter(|&&k| (x[k] - truth[k]).abs() <= sd[k]).count() as f64 / banded.len() as f64;
    assert!(text.contains(&format!("{all:.1} %")), "the report's coverage is the one measured here: {all}");
    assert!(text.contains("<b>7.47 ms</b>"));
    eprintln!(
        "taghirad-loaded: torque {filtered:.4}, torque_denoised (20 Hz) {denoised:.4}, torque_smoothed \
         {torque_smoothed:.4} N·m RMS, coverage {covered:.3}"
    );

    // A bandwidth the sample rate cannot carry is refused, naming the key.
    let bad_cfg = d.join("bad.toml");
    std::fs::write(&bad_cfg, std::fs::read_to_string(&cfg).unwrap().replace("= 20.0", "= 600.0")).unwrap();
    let args = ["filter", "--config", bad_cfg.to_str().unwrap(), "--in", loaded.to_str().unwrap(), "--out"];
    let o = run(&[&args[..], &[d.join("bad.csv").to_str().unwrap()]].concat());
    assert_user_error(&o, "`filter.torque_bandwidth_hz` must be positive and below 0.45");

    // Learning and smoothing together is a usage error (exit 2).
    let o = run(&[
        "filter",
        "--config",
        cfg.to_str().unwrap(),
        "--in",
        loaded.to_str().unwrap(),
        "--out",
        d.join("x.csv").to_str().unwrap(),
        "--smooth",
        "--learn",
        d.join("x.toml").to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
}

fn scratch_files(d: &Path) -> Vec<String> {
    std::fs::read_dir(d)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.starts_with(".strainwave-smooth"))
        .collect()
}

/// `--smooth` over a recording of several backward blocks (4096 rows each): every row
/// out, at the noise floor, to a file or to standard output, and its scratch files
/// removed after a run and after an error.
#[test]
fn smooth_spans_blocks_and_leaves_no_scratch_files() {
    let d = tmp("smooth-blocks");
    let sim = simulate(&d, "10");
    let out = d.join("s.csv");
    let args = ["filter", "--config", &config(), "--in", sim.to_str().unwrap(), "--smooth", "-q"];
    let o = run(&[&args[..], &["--out", out.to_str().unwrap()]].concat());
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(scratch_files(&d), Vec::<String>::new());
    let (h, rows) = read(&out);
    assert_eq!(rows.len(), 10_000);
    let (t, truth) = (col(&h, &rows, "torque"), col(&h, &rows, "true_torque"));
    let err = (300..10_000).map(|k| (t[k] - truth[k]).powi(2)).sum::<f64>() / 9_700.0;
    assert!(err.sqrt() < 1.5 * 0.0162, "smoothed RMS error {}", err.sqrt());
    // The smoothed torque's two filters cross the block boundaries (4096, 8192) unbroken.
    let (x, sd) = (col(&h, &rows, "torque_smoothed"), col(&h, &rows, "torque_smoothed_sd"));
    let err = (300..10_000).map(|k| (x[k] - truth[k]).powi(2)).sum::<f64>() / 9_700.0;
    assert!(err.sqrt() < 0.5 * 0.0162, "torque_smoothed RMS error {}", err.sqrt());
    for k in (4086..4106).chain(8182..8202) {
        assert!((x[k] - truth[k]).abs() < 4.0 * sd[k], "row {k}: {} ± {} vs {}", x[k], sd[k], truth[k]);
    }

    let o = run(&[&args[..], &["--out", "-"]].concat());
    assert!(o.status.success(), "{}", stderr(&o));
    let text = String::from_utf8(o.stdout).unwrap();
    assert_eq!(text.lines().count(), 10_001);
    assert_eq!(text.lines().nth(5000), std::fs::read_to_string(&out).unwrap().lines().nth(5000));

    let bad = with_cell(&sim, 9_000, "bridge_voltage", "NaN", "nan.csv");
    std::fs::remove_file(&out).unwrap();
    let o = run(&[
        "filter",
        "--config",
        &config(),
        "--in",
        bad.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--smooth",
    ]);
    assert_user_error(&o, "data row 9000: column `bridge_voltage`");
    assert!(!out.exists());
    assert_eq!(scratch_files(&d), Vec::<String>::new());
}

/// `--smooth` under the guard still fills in skipped samples: a dropout of the bridge
/// (NaN, `--lenient`) gets a finite `torque_smoothed` and band, close to the truth.
#[test]
fn the_smoother_fills_a_dropout_under_the_guard() {
    let d = tmp("dropout");
    let sim = simulate(&d, "4");
    let text = std::fs::read_to_string(&sim).unwrap();
    let header: Vec<&str> = text.lines().next().unwrap().split(',').collect();
    let v = header.iter().position(|c| *c == "bridge_voltage").unwrap();
    let lines: Vec<String> = text
        .lines()
        .enumerate()
        .map(|(k, l)| {
            if !(3000..3020).contains(&k) {
                return l.to_string();
            }
            let mut cells: Vec<&str> = l.split(',').collect();
            cells[v] = "NaN";
            cells.join(",")
        })
        .collect();
    let holed = d.join("holed.csv");
    std::fs::write(&holed, lines.join("\n") + "\n").unwrap();
    let out = d.join("s.csv");
    let args = ["filter", "--config", &config(), "--in", holed.to_str().unwrap(), "--out", out.to_str().unwrap()];
    let o = run(&[&args[..], &["--smooth", "--lenient", "-q"]].concat());
    assert!(o.status.success(), "{}", stderr(&o));
    let (h, rows) = read(&out);
    let (s, sd, truth) =
        (col(&h, &rows, "torque_smoothed"), col(&h, &rows, "torque_smoothed_sd"), col(&h, &rows, "true_torque"));
    for k in 2999..3019 {
        assert!(s[k].is_finite() && sd[k].is_finite(), "data row {}: {} ± {}", k + 1, s[k], sd[k]);
        assert!((s[k] - truth[k]).abs() < 0.1, "data row {}: {} against {}", k + 1, s[k], truth[k]);
    }
}

/// A config whose time channel names a column in ms (`Timestamp [ms]`): `filter` reads it
/// in seconds, and cleans the torque exactly as from the same recording in seconds.
#[test]
fn a_time_channel_in_ms_is_read_in_seconds() {
    let d = tmp("time-ms");
    let sim = simulate_preset(&d, "taghirad");
    let text = std::fs::read_to_string(&sim).unwrap();
    let mut lines = text.lines();
    let header = lines.next().unwrap().replacen("time", "Timestamp [ms]", 1);
    let mut ms = header + "\n";
    for line in lines.take(2000) {
        let (t, rest) = line.split_once(',').unwrap();
        ms += &format!("{},{rest}\n", t.parse::<f64>().unwrap() * 1000.0);
    }
    let ms_path = d.join("ms.csv");
    std::fs::write(&ms_path, ms).unwrap();
    let cfg_text = std::fs::read_to_string(root().join("examples/joint-taghirad.toml")).unwrap();
    assert!(cfg_text.contains("time = \"time\""));
    let cfg = d.join("joint-ms.toml");
    std::fs::copy(root().join("examples/joint-taghirad-learned.toml"), d.join("joint-taghirad-learned.toml")).unwrap();
    std::fs::write(&cfg, cfg_text.replacen("time = \"time\"", "time = \"Timestamp\"", 1)).unwrap();
    let (out_ms, out_s) = (d.join("out-ms.csv"), d.join("out-s.csv"));
    let cfg_s = root().join("examples/joint-taghirad.toml");
    for (c, i, o) in [(&cfg, &ms_path, &out_ms), (&cfg_s, &sim, &out_s)] {
        let o = run(&[
            "filter",
            "--config",
            c.to_str().unwrap(),
            "--in",
            i.to_str().unwrap(),
            "--out",
            o.to_str().unwrap(),
            "-q",
        ]);
        assert!(o.status.success(), "{}", stderr(&o));
    }
    let (h_ms, rows_ms) = read(&out_ms);
    let (h_s, rows_s) = read(&out_s);
    let torque_s = col(&h_s, &rows_s, "torque");
    assert_eq!(col(&h_ms, &rows_ms, "torque"), torque_s[..2000].to_vec());
    // A channel that scales ms to s itself is not converted twice.
    let scaled = cfg_text.replacen("time = \"time\"", "time = { column = \"Timestamp\", scale = 0.001 }", 1);
    std::fs::write(&cfg, scaled).unwrap();
    let o = run(&["filter", "--config", cfg.to_str().unwrap(), "--in", ms_path.to_str().unwrap(), "--out"]
        .into_iter()
        .chain([out_ms.to_str().unwrap(), "-q"])
        .collect::<Vec<_>>());
    assert!(o.status.success(), "{}", stderr(&o));
    let (h_ms, rows_ms) = read(&out_ms);
    assert_eq!(col(&h_ms, &rows_ms, "torque"), torque_s[..2000].to_vec());
}

/// A calibration that rejects speeds outside its table: the skipped samples are named by
/// that reason, with and without `--smooth` (before: "a non-finite angle, or a torque not
/// finite or beyond ±1e12 N·m").
#[test]
fn samples_the_calibration_rejects_are_named_as_such() {
    let d = tmp("reject");
    let sim = simulate(&d, "0.5");
    std::fs::write(
        d.join("cal.toml"),
        "model = \"speed_table\"\nspeed_rad_s = [-5.0, 5.0]\nalpha = [6.611, 6.611]\nbeta_nm = [0.0, 0.0]\nextrapolation = \"reject\"\n",
    )
    .unwrap();
    let text = std::fs::read_to_string(config()).unwrap();
    let cold: String = text.lines().filter(|l| !l.starts_with("learned")).map(|l| format!("{l}\n")).collect();
    let cfg = d.join("joint.toml");
    std::fs::write(&cfg, cold.replacen("gain_nm_per_v = 6.611", "file = \"cal.toml\"", 1)).unwrap();
    let out = d.join("out.csv");
    for smooth in [false, true] {
        let mut args = vec!["filter", "--config", cfg.to_str().unwrap(), "--in", sim.to_str().unwrap()];
        args.extend(["--out", out.to_str().unwrap()]);
        args.extend(smooth.then_some("--smooth"));
        let o = run(&args);
        assert!(o.status.success(), "{}", stderr(&o));
        let e = stderr(&o);
        assert!(e.contains("samples with a speed outside the calibration's range were skipped"), "{e}");
        assert!(!e.contains("a non-finite angle"), "{e}");
    }
}
