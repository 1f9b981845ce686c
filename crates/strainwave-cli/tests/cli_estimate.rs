//! `simulate` (arm twin) → `identify` → `estimate` end to end, and bad input.

use std::path::{Path, PathBuf};
use std::process::Command;

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_strainwave"))
}

fn dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("strainwave-cli-estimate-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn ok(cmd: &mut Command) -> String {
    let out = cmd.output().unwrap();
    assert!(out.status.success(), "{:?}: {}", cmd, String::from_utf8_lossy(&out.stderr));
    String::from_utf8_lossy(&out.stdout).into_owned()
}

fn simulate(preset: &str, out: &Path) {
    ok(bin().args(["simulate", "--preset", preset, "--quiet", "--out"]).arg(out));
}

/// `estimate` of `input` with the model file `model`, written to `out`.
fn estimate(model: &Path, input: &Path, out: &Path) -> std::process::Output {
    bin().args(["estimate", "--config"]).arg(model).arg("--in").arg(input).arg("--out").arg(out).output().unwrap()
}

fn examples() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples/arm-hda.toml")
}

/// Largest RMS error of the estimate against the true link torque, N·m (measured 0.089 on step-hold).
const RMS_BOUND_NM: f64 = 0.15;

#[test]
fn identify_then_estimate_tracks_true_link_torque() {
    let d = dir("pipeline");
    let (nl, ld, step, model, est) =
        (d.join("nl.csv"), d.join("ld.csv"), d.join("step.csv"), d.join("model.toml"), d.join("est.csv"));
    simulate("hda-arm-no-load", &nl);
    simulate("hda-arm-loaded-hold", &ld);
    simulate("hda-arm", &step);
    let table = ok(bin()
        .args(["identify", "--config"])
        .arg(examples())
        .arg("--no-load")
        .arg(&nl)
        .arg("--loaded")
        .arg(&ld)
        .arg("--out")
        .arg(&model));
    println!("{table}");
    assert!(table.contains("compliance"), "{table}");
    ok(bin().args(["estimate", "--quiet", "--config"]).arg(&model).arg("--in").arg(&step).arg("--out").arg(&est));
    let text = std::fs::read_to_string(&est).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let ti = header.iter().position(|c| *c == "true_link_torque").unwrap();
    let ei = header.iter().position(|c| *c == "torque").unwrap();
    assert!(header.contains(&"estimate_flags") && header.contains(&"kinematic_error") && header.contains(&"torsion"));
    let (mut sse, mut n) = (0.0, 0usize);
    for l in lines {
        let v: Vec<f64> = l.split(',').map(|x| x.parse().unwrap()).collect();
        sse += (v[ei] - v[ti]).powi(2);
        n += 1;
    }
    let rms = (sse / n as f64).sqrt();
    println!("step-hold via the CLI: rms {rms:.4} N·m over {n} rows");
    assert!(n == 6000, "{n} rows");
    assert!(rms < RMS_BOUND_NM, "rms {rms} N·m ≥ {RMS_BOUND_NM}");
}

/// A model file as `identify` writes it, linear spring, no encoders section.
const MODEL: &str = r#"sample_rate_hz = 1000.0
torque_range_nm = 50.0
[gear]
ratio = 100.0
rated_torque_nm = 40.0
[channels]
motor = "motor_angle"
link = "link_angle"
[kinematic]
basis = "fourier"
order = 1
mesh_harmonics = 0
coefficients = [0.0, 0.0, 0.0]
[compliance]
damping_nm_s_per_rad = 0.0
windup_offset_rad = 0.0
rated_torque_nm = 40.0
spring = { form = "linear", k_nm_per_rad = 1.0e4 }
hysteresis = { kind = "none" }
"#;

/// [`MODEL`]'s hysteresis line.
const HYSTERESIS: &str = r#"hysteresis = { kind = "none" }"#;

#[test]
fn a_bad_model_value_is_an_error_naming_the_file_and_key_before_any_row() {
    let d = dir("bad-model");
    let input = d.join("in.csv");
    std::fs::write(&input, "time,motor_angle,link_angle\n0,0,0\n0.001,0,0\n").unwrap();
    let cases = [
        ("torque_range_nm = 50.0", "torque_range_nm = 0.0", "`torque_range_nm`"),
        ("windup_offset_rad = 0.0", "windup_offset_rad = nan", "`compliance.windup_offset_rad`"),
        ("ratio = 100.0", "ratio = -1.0", "gear.ratio"),
        ("sample_rate_hz = 1000.0", "sample_rate_hz = 0.0", "`sample_rate_hz`"),
        ("coefficients = [0.0, 0.0, 0.0]", "coefficients = [0.0, nan, 0.0]", "`kinematic.coefficients` value 2"),
        ("k_nm_per_rad = 1.0e4", "k_nm_per_rad = -1.0e4", "compliance.spring: `k_nm_per_rad`"),
        (
            HYSTERESIS,
            "hysteresis = { kind = \"dahl\", half_width_rad = -1e-4, memory_rad = 1e-4, deadband_rad = 0.0 }",
            "compliance.hysteresis: `half_width_rad`",
        ),
        (
            HYSTERESIS,
            "hysteresis = { kind = \"plays\", half_widths_rad = [-1e-4], weights_rad = [1e-4] }",
            "compliance.hysteresis: `half_widths_rad`",
        ),
        (
            HYSTERESIS,
            "hysteresis = { kind = \"plays\", half_widths_rad = [1e-4], weights_rad = [] }",
            "`compliance.hysteresis.weights_rad`: 0 values",
        ),
        (
            HYSTERESIS,
            "hysteresis = { kind = \"plays\", half_widths_rad = [], weights_rad = [] }",
            "`compliance.hysteresis.half_widths_rad`: 0 plays, 1 to 8",
        ),
    ];
    for (from, to, key) in cases {
        let model = d.join("model.toml");
        std::fs::write(&model, MODEL.replacen(from, to, 1)).unwrap();
        let out = estimate(&model, &input, &d.join("out.csv"));
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{to}: {err}");
        assert_eq!(err.trim_end().lines().count(), 1, "{err}");
        assert!(err.contains("model.toml") && err.contains(key), "{to}: {err}");
        assert!(!err.contains("in.csv"), "{to}: blames the data: {err}");
    }
}

#[test]
fn missing_encoder_column_is_a_one_line_error() {
    let d = dir("missing");
    let model = d.join("model.toml");
    std::fs::write(&model, MODEL).unwrap();
    let input = d.join("in.csv");
    std::fs::write(&input, "time,motor_angle,other\n0,0,0\n0.001,0,0\n").unwrap();
    let out = estimate(&model, &input, &d.join("out.csv"));
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(err.trim_end().lines().count(), 1, "{err}");
    assert!(err.contains("link_angle"), "{err}");
}

#[test]
fn a_config_of_another_command_is_named_as_such() {
    // `identify` and `filter` take `--config` too; their configs fail as models at a
    // missing key (before: "line 25, column 1: missing field `coefficients`").
    let d = dir("other-config");
    let input = d.join("in.csv");
    std::fs::write(&input, "time,motor_angle,link_angle\n0,0,0\n0.001,0,0\n").unwrap();
    let joint = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples/joint-taghirad.toml");
    for (config, kind) in [(examples(), "an `identify` config"), (joint, "a joint config (for `filter`)")] {
        let out = estimate(&config, &input, &d.join("out.csv"));
        assert_eq!(out.status.code(), Some(1));
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            err.contains(&format!("{kind}, not a model: pass the model file that `identify --out` writes")),
            "{err}"
        );
        assert_eq!(err.matches(config.file_name().unwrap().to_str().unwrap()).count(), 1, "{err}");
    }
}

#[test]
fn an_unreadable_recording_is_named_once() {
    let d = dir("unreadable");
    let model = d.join("model.toml");
    std::fs::write(&model, MODEL).unwrap();
    let empty = d.join("empty.csv");
    std::fs::write(&empty, "").unwrap();
    for input in [empty, d.join("missing.csv")] {
        let out = estimate(&model, &input, &d.join("out.csv"));
        assert_eq!(out.status.code(), Some(1));
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(err.matches(input.to_str().unwrap()).count(), 1, "{err}");
    }
}

#[test]
fn the_time_column_must_move_forward_at_the_models_rate() {
    let d = dir("time");
    let model = d.join("model.toml");
    std::fs::write(&model, MODEL.replacen("[channels]\n", "[channels]\ntime = \"time\"\n", 1)).unwrap();
    let rows = |times: &[&str]| -> String {
        let body: String = times.iter().map(|t| format!("{t},0,0\n")).collect();
        format!("time,motor_angle,link_angle\n{body}")
    };
    let every_other_row: Vec<String> = (0..50).map(|k| format!("{}", 0.002 * k as f64)).collect();
    let every_other_row: Vec<&str> = every_other_row.iter().map(String::as_str).collect();
    let cases = [
        (
            rows(&every_other_row),
            "steps at about 500 Hz (its median step), but the model was fitted at `sample_rate_hz` = 1000.0 Hz",
        ),
        (rows(&["0", "0.001", "nan", "0.003"]), "data row 3: time (column `time`) is NaN"),
        (
            rows(&["0.002", "0.001", "0"]),
            "data row 2: time 0.001 s (column `time`) is before the previous row's 0.002 s",
        ),
        (rows(&[]), "no data rows"),
    ];
    let out = d.join("out.csv");
    std::fs::write(&out, "kept").unwrap();
    for (text, message) in cases {
        let input = d.join("in.csv");
        std::fs::write(&input, &text).unwrap();
        let run = estimate(&model, &input, &out);
        let err = String::from_utf8_lossy(&run.stderr);
        assert_eq!(run.status.code(), Some(1), "{message}: {err}");
        assert_eq!(err.trim_end().lines().count(), 1, "{err}");
        assert!(err.contains("in.csv") && err.contains(message), "{message}: {err}");
        assert_eq!(std::fs::read_to_string(&out).unwrap(), "kept", "an error leaves the old output");
    }
    // Within 5 % of the model's rate is the same rate (a real arm's logs differ by 0.5 %).
    let close: Vec<String> = (0..50).map(|k| format!("{}", 0.00102 * k as f64)).collect();
    let input = d.join("in.csv");
    std::fs::write(&input, rows(&close.iter().map(String::as_str).collect::<Vec<_>>())).unwrap();
    let run = estimate(&model, &input, &out);
    assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
    // A model time channel `t` over a column in ms (`t [ms]`) is read in seconds: 1 kHz.
    let ms_model = d.join("model-ms.toml");
    std::fs::write(&ms_model, MODEL.replacen("[channels]\n", "[channels]\ntime = \"t\"\n", 1)).unwrap();
    let body: String = (0..50).map(|k| format!("{k},0,0\n")).collect();
    std::fs::write(&input, format!("t [ms],motor_angle,link_angle\n{body}")).unwrap();
    let run = estimate(&ms_model, &input, &out);
    assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
    // A repeated stamp and a pause do not change the median step.
    let paused: Vec<String> =
        (0..50).map(|k| format!("{}", 0.001 * k as f64 + if k >= 25 { 3.0 } else { 0.0 })).collect();
    let mut paused: Vec<&str> = paused.iter().map(String::as_str).collect();
    paused.insert(10, paused[9]);
    std::fs::write(&input, rows(&paused)).unwrap();
    let run = estimate(&model, &input, &out);
    assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
    // Without the model's time column the rate is not checked, and the summary says so.
    std::fs::write(&input, "motor_angle,link_angle\n0,0\n0,0\n").unwrap();
    let run = estimate(&model, &input, &out);
    let err = String::from_utf8_lossy(&run.stderr);
    assert!(run.status.success(), "{err}");
    assert!(err.contains("warning: ") && err.contains("no time column `time`") && err.contains("not checked"), "{err}");
    // A model that names no time column (its rate given as a number) checks none: a
    // column called `time` may then be in any unit.
    let plain = d.join("plain.toml");
    std::fs::write(&plain, MODEL).unwrap();
    std::fs::write(&input, rows(&every_other_row)).unwrap();
    let run = estimate(&plain, &input, &out);
    assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
}
