//! End-to-end behaviour of the `strainwave` binary.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_strainwave"))
}

fn run(args: &[&str]) -> Output {
    bin().args(args).output().expect("run strainwave")
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("sw-cli-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

#[test]
fn simulate_same_seed_same_bytes() {
    let d = tmp("seed");
    let a = d.join("a.csv");
    let b = d.join("b.csv");
    let c = d.join("c.csv");
    for (p, seed) in [(&a, "3"), (&b, "3"), (&c, "4")] {
        let o = run(&[
            "simulate",
            "--preset",
            "taghirad",
            "--duration",
            "0.5",
            "--seed",
            seed,
            "--out",
            p.to_str().unwrap(),
            "--quiet",
        ]);
        assert!(o.status.success(), "{}", stderr(&o));
    }
    let (a, b, c) = (std::fs::read(a).unwrap(), std::fs::read(b).unwrap(), std::fs::read(c).unwrap());
    assert_eq!(a, b);
    assert_ne!(a, c);
    let text = String::from_utf8(a).unwrap();
    let header = text.lines().next().unwrap();
    for col in [
        "time",
        "motor_angle",
        "output_angle",
        "motor_velocity",
        "motor_current",
        "bridge_voltage",
        "true_torque",
        "true_ripple",
        "true_misalignment",
        "true_relative_angle",
    ] {
        assert!(header.split(',').any(|h| h == col), "missing {col} in {header}");
    }
    assert_eq!(text.lines().count(), 501);
}

#[test]
fn print_scenario_round_trips_through_a_file() {
    let o = run(&["simulate", "--preset", "taghirad", "--print-scenario"]);
    assert!(o.status.success());
    let d = tmp("print");
    let f = d.join("joint.toml");
    std::fs::write(&f, &o.stdout).unwrap();
    let out = d.join("r.csv");
    let o = run(&[
        "simulate",
        "--scenario",
        f.to_str().unwrap(),
        "--duration",
        "0.2",
        "--out",
        out.to_str().unwrap(),
        "--quiet",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let p = run(&[
        "simulate",
        "--preset",
        "taghirad",
        "--duration",
        "0.2",
        "--out",
        d.join("p.csv").to_str().unwrap(),
        "--quiet",
    ]);
    assert!(p.status.success());
    assert_eq!(std::fs::read(out).unwrap(), std::fs::read(d.join("p.csv")).unwrap());
}

/// Before: the bench's and the arm's printed scenarios could not be read back (``unknown
/// field `mechanics` ``), `--procedure` was ignored for the bench, and an unknown preset's
/// list left out the bench's and the arm's.
#[test]
fn every_twin_s_printed_scenario_runs_as_its_preset() {
    let d = tmp("twins");
    for preset in ["kit-bench", "hda-arm"] {
        let o = run(&["simulate", "--preset", preset, "--print-scenario"]);
        assert!(o.status.success(), "{}", stderr(&o));
        let f = d.join(format!("{preset}.toml"));
        std::fs::write(&f, &o.stdout).unwrap();
        let (from_file, from_preset) = (d.join(format!("{preset}-file.csv")), d.join(format!("{preset}.csv")));
        for (source, out) in [(["--scenario", f.to_str().unwrap()], &from_file), (["--preset", preset], &from_preset)] {
            let o =
                run(&[&["simulate"][..], &source, &["--duration", "0.05", "--out", out.to_str().unwrap(), "-q"]]
                    .concat());
            assert!(o.status.success(), "{preset}: {}", stderr(&o));
        }
        assert_eq!(std::fs::read(&from_file).unwrap(), std::fs::read(&from_preset).unwrap(), "{preset}");
        let o = run(&[
            "simulate",
            "--preset",
            preset,
            "--procedure",
            "locked-wg",
            "--out",
            d.join("x.csv").to_str().unwrap(),
        ]);
        assert_user_error(&o, "--procedure applies to the joint twin");
    }
    let o = run(&["simulate", "--preset", "nope", "--out", d.join("x.csv").to_str().unwrap()]);
    assert_user_error(&o, "flexspline-fixed-dynamic, kit-bench, kit-bench-sweep, hda-arm, hda-arm-no-load");
    assert!(!d.join("x.csv").exists());
}

fn scenario_with(d: &Path, from: &str, to: &str) -> PathBuf {
    let text = String::from_utf8(run(&["simulate", "--preset", "taghirad", "--print-scenario"]).stdout).unwrap();
    assert!(text.contains(from), "{from}");
    let f = d.join("bad.toml");
    std::fs::write(&f, text.replacen(from, to, 1)).unwrap();
    f
}

fn assert_user_error(o: &Output, needle: &str) {
    let e = stderr(o);
    assert_eq!(o.status.code(), Some(1), "{e}");
    assert!(e.contains(needle), "`{needle}` not in: {e}");
    assert_eq!(e.trim_end().lines().count(), 1, "one line: {e}");
    assert!(!e.contains("panicked"), "{e}");
}

#[test]
fn bad_scenarios_are_one_line_errors_naming_the_key() {
    let d = tmp("bad");
    let out = d.join("never.csv");
    let cases = [
        ("ratio = 100.0", "ratio = 0.0", "gear.ratio"),
        ("ratio = 100.0", "ratio = 100.0\nratoi = 3", "ratoi"),
        ("inertia_kg_m2 = 1.0", "inertia_kg_m2 = -1.0", "load.inertia_kg_m2"),
        ("inertia_kg_m2 = 3.3e-5", "inertia_kg_m2 = 0.0", "motor.inertia_kg_m2"),
        ("sample_rate_hz = 1000.0", "sample_rate_hz = 150.0", "sample_rate_hz"),
        // Checked as the twin builds its sensor: still the file and the section named.
        ("outer_radius_m = 0.020", "outer_radius_m = 1e308", "bad.toml: `sensor` leaves the bridge with no torque"),
        // Before: NaN angles and truth in 499 of 500 rows, exit 0 (the sub-step cap was reached).
        (
            "damping_nm_s_per_rad = 5.0",
            "damping_nm_s_per_rad = 1e7",
            "`gear.damping_nm_s_per_rad` = 1e7 with `motor.inertia_kg_m2` = 3.3e-5, `load.inertia_kg_m2` = 1e0: the \
             joint's fastest mode (4.030e7 rad/s) makes RK4 unstable even at 10000 sub-steps",
        ),
        // Before: accepted.
        ("ratio = 100.0", "ratio = 1e308", "`gear.ratio` must be between 1 and 10000, got 1e308"),
        // Before: a header and no row, exit 0.
        ("duration_s = 4.0", "duration_s = 1e-300", "`duration_s` = 1e-300 s: not one sample"),
    ];
    for (from, to, needle) in cases {
        let f = scenario_with(&d, from, to);
        let o = run(&["simulate", "--scenario", f.to_str().unwrap(), "--out", out.to_str().unwrap()]);
        assert_user_error(&o, needle);
        assert!(!out.exists(), "nothing written for {needle}");
    }
}

#[test]
fn unwritable_output_and_unknown_preset_are_user_errors() {
    let o = run(&["simulate", "--preset", "taghirad", "--out", "/nonexistent-dir/x.csv"]);
    assert_user_error(&o, "/nonexistent-dir/x.csv");
    let o = run(&["simulate", "--preset", "nope", "--out", "x.csv"]);
    assert_user_error(&o, "unknown preset `nope`");
    let d = tmp("dir");
    let o = run(&["simulate", "--preset", "taghirad", "--out", d.to_str().unwrap()]);
    assert_user_error(&o, "is a directory");
}

#[test]
fn bad_usage_exits_2() {
    assert_eq!(run(&["simulate"]).status.code(), Some(2));
    assert_eq!(run(&["frobnicate"]).status.code(), Some(2));
    assert_eq!(
        run(&["simulate", "--preset", "taghirad", "--scenario", "x.toml", "--out", "y.csv"]).status.code(),
        Some(2)
    );
    let v = run(&["--version"]);
    assert!(v.status.success() && String::from_utf8_lossy(&v.stdout).starts_with("strainwave "));
}

#[test]
fn demo_prints_the_ripple_lines_and_writes_the_report() {
    let d = tmp("demo");
    let o = run(&["demo", "--out", d.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(text.contains("2× relative angle") && text.contains("4× relative angle"), "{text}");
    // Both ripple lines found as peaks within one bin.
    for l in text.lines().filter(|l| l.contains("× relative angle") && !l.contains("order")) {
        let cells: Vec<&str> = l.split_whitespace().collect();
        assert_eq!(cells.last(), Some(&"yes"), "{l}");
        let off: f64 = cells[cells.len() - 3].parse().unwrap();
        assert!(off.abs() <= 1.0, "{l}");
    }
    let html = std::fs::read_to_string(d.join("report.html")).unwrap();
    assert!(html.starts_with("<!DOCTYPE html>"));
    assert!(html.matches("<svg").count() >= 4, "plots");
    for section in ["Joint digital twin", "Ripple and misalignment cancellation", "Sensor calibration"] {
        assert!(html.contains(section), "{section}");
    }
    // Self-contained: no scripts, no address but the SVG namespace.
    assert!(!html.contains("<script"));
    assert_eq!(html.matches("http").count(), html.matches("http://www.w3.org/2000/svg").count());
    assert!(d.join("taghirad.csv").exists());
}

#[test]
fn closed_stdout_pipe_is_not_a_panic() {
    use std::process::Stdio;
    let d = tmp("pipe");
    for args in
        [vec!["demo", "--out", d.to_str().unwrap()], vec!["simulate", "--preset", "taghirad", "--print-scenario"]]
    {
        let mut child = bin().args(&args).stdout(Stdio::piped()).stderr(Stdio::piped()).spawn().unwrap();
        drop(child.stdout.take()); // the reader goes away at once
        let o = child.wait_with_output().unwrap();
        assert!(o.status.success(), "{args:?}: {}", stderr(&o));
        assert!(!stderr(&o).contains("panicked"));
    }
}

#[test]
fn design_prints_the_figures_and_rejects_bad_configs() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let d = tmp("design");
    let svg = d.join("h.svg");
    for cfg in ["examples/sensor-taghirad.toml", "examples/sensor-flexspline-fixed.toml"] {
        let o = run(&["design", "--config", root.join(cfg).to_str().unwrap(), "--svg", svg.to_str().unwrap()]);
        assert!(o.status.success(), "{cfg}: {}", stderr(&o));
        let text = String::from_utf8_lossy(&o.stdout);
        for needle in ["mV/V per N·m", "full scale", "resolution", "µε", "circumferential", "angular", "combined"] {
            assert!(text.contains(needle), "{needle} in {text}");
        }
        assert!(std::fs::read_to_string(&svg).unwrap().contains("<path"));
    }
    let text = std::fs::read_to_string(root.join("examples/sensor-taghirad.toml")).unwrap();
    let bad = d.join("bad.toml");
    std::fs::write(&bad, text.replace("thickness_m = 1.44e-3", "thickness_m = -1.0")).unwrap();
    assert_user_error(&run(&["design", "--config", bad.to_str().unwrap()]), "sensor.thickness_m");
    std::fs::write(&bad, text.replace("draws = 10000", "draws = 0")).unwrap();
    assert_user_error(&run(&["design", "--config", bad.to_str().unwrap()]), "monte_carlo.draws");
    std::fs::write(&bad, text.replace("seed = 1", "seed = 1\nsede = 2")).unwrap();
    assert_user_error(&run(&["design", "--config", bad.to_str().unwrap()]), "sede");
    // Before: accepted, with `inf` or 300-digit figures, or unchanged results for gauges
    // off the diaphragm.
    let absurd = [
        ("thickness_m = 1.44e-3", "thickness_m = 1e308", "`sensor.thickness_m` = 1e308 m: a diaphragm is thinner"),
        ("gauge_radius_m = 0.014", "gauge_radius_m = 0.5", "`sensor.gauge_radius_m` = 0.5 m: the gauges sit on"),
        ("gauge_radius_m = 0.014", "gauge_radius_m = 0.004", "between `sensor.hub_radius_m` (0.008)"),
        ("gauge_factor = 2.0", "gauge_factor = 1e308", "`sensor.gauge_factor` = 1e308: at most 1e3"),
        ("excitation_v = 10.0", "excitation_v = 1e308", "`sensor.excitation_v` = 1e308: at most 1e2"),
        ("shear_modulus_pa = 80.0e9", "shear_modulus_pa = 1e308", "`sensor.shear_modulus_pa` = 1e308: at most 1e12"),
        // Before: a sensitivity of `inf` mV/V per N·m, or a strain of `inf` µε, and exit 0.
        ("shear_modulus_pa = 80.0e9", "shear_modulus_pa = 1e-300", "`sensor.shear_modulus_pa` = 1e-300: at least 1e5"),
        (
            "rated_torque_nm = 40.0",
            "rated_torque_nm = 1e308",
            "`rated_torque_nm` gives a strain at rated torque of inf",
        ),
    ];
    for (from, to, needle) in absurd {
        assert!(text.contains(from), "{from}");
        std::fs::write(&bad, text.replacen(from, to, 1)).unwrap();
        assert_user_error(&run(&["design", "--config", bad.to_str().unwrap()]), needle);
    }
}

#[test]
fn convert_round_trips_csv_parquet_csv_bit_exact() {
    let d = tmp("convert");
    let (a, pq, b) = (d.join("a.csv"), d.join("a.parquet"), d.join("b.csv"));
    assert!(run(&[
        "simulate",
        "--preset",
        "flexspline-fixed",
        "--duration",
        "0.3",
        "--out",
        a.to_str().unwrap(),
        "-q"
    ])
    .status
    .success());
    for (i, o) in [(&a, &pq), (&pq, &b)] {
        let r = run(&["convert", "--in", i.to_str().unwrap(), "--out", o.to_str().unwrap(), "-q"]);
        assert!(r.status.success(), "{}", stderr(&r));
    }
    assert_eq!(std::fs::read(&a).unwrap(), std::fs::read(&b).unwrap());
}

#[test]
fn convert_rejects_bad_recordings_naming_file_row_and_column() {
    let d = tmp("badrec");
    let out = d.join("o.csv");
    let cases: [(&str, &str, &str); 5] = [
        ("empty.csv", "", "empty file"),
        ("header.csv", "time,x\n", "no data rows"),
        ("trunc.csv", "time,x,y\n0,1,2\n0.001,3", "row 2 has 2 cells, the header has 3"),
        ("text.csv", "time,x\n0,1\n0.001,abc\n", "row 2, column `x`: `abc` is not a number"),
        ("weird.xlsx", "time\n0\n", "unknown format"),
    ];
    for (name, text, needle) in cases {
        let f = d.join(name);
        std::fs::write(&f, text).unwrap();
        assert_user_error(&run(&["convert", "--in", f.to_str().unwrap(), "--out", out.to_str().unwrap()]), needle);
        assert!(!out.exists(), "{name}: output left behind");
    }
    assert_user_error(
        &run(&["convert", "--in", d.to_str().unwrap(), "--out", out.to_str().unwrap()]),
        "is a directory",
    );
}

#[test]
fn convert_reports_time_gaps_and_resamples_only_when_asked() {
    let d = tmp("gaps");
    let f = d.join("g.csv");
    std::fs::write(&f, "time,x\n0,0\n0.001,1\n0.002,2\n0.010,10\n0.010,10\n0.011,11\n").unwrap();
    let out = d.join("o.csv");
    let o = run(&["convert", "--in", f.to_str().unwrap(), "--out", out.to_str().unwrap()]);
    assert!(o.status.success());
    let e = stderr(&o);
    assert!(e.contains("1 gap(s)") && e.contains("1 non-monotonic"), "{e}");
    assert_eq!(std::fs::read_to_string(&out).unwrap().lines().count(), 7, "kept as is");
    let o = run(&["convert", "--in", f.to_str().unwrap(), "--out", out.to_str().unwrap(), "--resample-hz", "1000"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = std::fs::read_to_string(&out).unwrap();
    let rows: Vec<&str> = text.lines().skip(1).collect();
    assert_eq!(rows.len(), 12, "{text}");
    assert_eq!(rows[5], "0.005,5");
}

/// `convert --time-column t` names the clock of `--resample-hz` too, and a time column in
/// ms is read in seconds: 0, 2 and 4 ms resampled at 1 kHz are 5 rows, 1 ms apart.
#[test]
fn convert_resamples_on_the_named_time_column() {
    let d = tmp("time-column");
    let f = d.join("t.csv");
    std::fs::write(&f, "t [ms],x\n0,0\n2,2\n4,4\n").unwrap();
    let out = d.join("o.csv");
    let args = ["convert", "--in", f.to_str().unwrap(), "--out", out.to_str().unwrap(), "--time-column", "t"];
    let o = run(&[&args[..], &["--resample-hz", "1000"]].concat());
    assert!(o.status.success(), "{}", stderr(&o));
    let text = std::fs::read_to_string(&out).unwrap();
    assert_eq!(text, "t [s],x\n0,0\n0.001,1\n0.002,2\n0.003,3\n0.004,4\n");
    // Without it, `--resample-hz` asks for the time column by name.
    let o = run(&["convert", "--in", f.to_str().unwrap(), "--out", out.to_str().unwrap(), "--resample-hz", "1000"]);
    assert_user_error(&o, "set --time-column");
}

/// `--resample-hz` far above the recording's rate (25 MHz typed for a 1 kHz log) is
/// refused early, naming the option, instead of writing 100 million made-up rows; the
/// output is not created.
#[test]
fn convert_refuses_up_sampling_beyond_reason() {
    let d = tmp("upsample");
    let f = d.join("rec.csv");
    let text: String = std::iter::once("time,x\n".to_string())
        .chain((0..4096).map(|k| format!("{},{k}\n", k as f64 * 1e-3)))
        .collect();
    std::fs::write(&f, text).unwrap();
    let out = d.join("o.csv");
    let o = run(&["convert", "--in", f.to_str().unwrap(), "--out", out.to_str().unwrap(), "--resample-hz", "2.5e7"]);
    assert_user_error(&o, "--resample-hz 25000000 makes more than 1000 rows per input row");
    assert!(!out.exists());
    // A hundredfold is fine.
    let o = run(&["convert", "--in", f.to_str().unwrap(), "--out", out.to_str().unwrap(), "--resample-hz", "1e5"]);
    assert!(o.status.success(), "{}", stderr(&o));
}
