//! `strainwave filter --learn` end to end: several runs in one call, order discovery
//! reported, the joint identity of a learned file, and the duplicate-channel warning.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn run(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_strainwave")).args(args).output().expect("run strainwave")
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("sw-learn-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

fn assert_user_error(o: &Output, needles: &[&str]) {
    let e = stderr(o);
    assert_eq!(o.status.code(), Some(1), "{e}");
    for n in needles {
        assert!(e.contains(n), "`{n}` not in: {e}");
    }
    assert_eq!(e.trim_end().lines().count(), 1, "one line: {e}");
}

/// A copy of the example taghirad config in `d`, its learned file `learned` (absolute).
fn config(d: &Path, learned: &Path, edit: impl Fn(String) -> String) -> PathBuf {
    let text = std::fs::read_to_string(root().join("examples/joint-taghirad.toml")).unwrap();
    let text = text.replace("\"joint-taghirad-learned.toml\"", &format!("{:?}", s(learned)));
    let p = d.join("joint.toml");
    std::fs::write(&p, edit(text)).unwrap();
    p
}

fn simulate(d: &Path, preset: &str, seconds: &str) -> PathBuf {
    let f = d.join(format!("{preset}-{seconds}.csv"));
    let o = run(&["simulate", "--preset", preset, "--duration", seconds, "--out", s(&f), "-q"]);
    assert!(o.status.success(), "{}", stderr(&o));
    f
}

/// Two recordings in one call, learning only: each is merged into the file in turn
/// (runs = 2) and each run's order analysis is reported.
#[test]
fn several_runs_in_one_call_merge_into_the_file() {
    let d = tmp("several");
    let (a, b) = (simulate(&d, "taghirad-commissioning", "8"), simulate(&d, "taghirad", "4"));
    let learned = d.join("learned.toml");
    let cfg = config(&d, &learned, |t| t);
    let o = run(&["filter", "--config", s(&cfg), "--learn", s(&learned), "--in", s(&a), s(&b)]);
    let e = stderr(&o);
    assert!(o.status.success(), "{e}");
    assert_eq!(e.matches("note: order analysis of the innovation:").count(), 2, "{e}");
    assert_eq!(e.matches("-> nowhere (learning only)").count(), 2, "{e}");
    let text = std::fs::read_to_string(&learned).unwrap();
    assert!(text.contains("[joint]") && text.contains("fingerprint = "), "{text}");
    // The 2× ripple line turns in both runs: both added to it.
    let first = text.split("[[orders]]").nth(1).unwrap();
    assert!(first.contains("multiple = 2.0") && first.contains("runs = 2"), "{first}");

    // Several inputs without --learn, and --out naming the learned file, are refused.
    let out = d.join("f.csv");
    let o = run(&["filter", "--config", s(&cfg), "--in", s(&a), s(&b), "--out", s(&out)]);
    assert_user_error(&o, &["several --in recordings need --learn"]);
    let o = run(&["filter", "--config", s(&cfg), "--in", s(&a), "--out", s(&learned), "--learn", s(&learned)]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(std::fs::read_to_string(&learned).unwrap() == text, "the learned file changed");

    // A run that fails part way (a torque cell that is not a number) leaves the file as it was.
    let good = std::fs::read_to_string(&a).unwrap();
    let mut lines: Vec<String> = good.lines().take(3000).map(String::from).collect();
    let broken = lines[2000].splitn(7, ',').enumerate().map(|(i, c)| if i == 5 { "x" } else { c }).collect::<Vec<_>>();
    lines[2000] = broken.join(",");
    let bad = d.join("bad.csv");
    std::fs::write(&bad, lines.join("\n") + "\n").unwrap();
    let o = run(&["filter", "--config", s(&cfg), "--learn", s(&learned), "--in", s(&bad)]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(stderr(&o).contains("bad.csv"), "{}", stderr(&o));
    assert!(std::fs::read_to_string(&learned).unwrap() == text, "the learned file changed");
    // Several runs, the last failing: the file is as it was, not merged with the first.
    let o = run(&["filter", "--config", s(&cfg), "--learn", s(&learned), "--in", s(&b), s(&bad)]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(std::fs::read_to_string(&learned).unwrap() == text, "the learned file changed");
    // ... and a file the first run created is gone again.
    let fresh = d.join("fresh.toml");
    let o = run(&["filter", "--config", s(&cfg), "--learn", s(&fresh), "--in", s(&b), s(&bad)]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(!fresh.exists());
    std::fs::remove_dir_all(&d).unwrap();
}

/// A learned file of another joint: the flexspline-fixed joint's learned file with the taghirad config
/// is refused, naming the file and the fixed element.
#[test]
fn a_learned_file_of_another_joint_is_refused() {
    let d = tmp("identity");
    let rec = simulate(&d, "taghirad", "1");
    let other = root().join("examples/joint-flexspline-fixed-learned.toml");
    let cfg = config(&d, &other, |t| t);
    let o = run(&["filter", "--config", s(&cfg), "--in", s(&rec), "--out", s(&d.join("f.csv"))]);
    assert_user_error(
        &o,
        &[
            "joint-flexspline-fixed-learned.toml: learned on another joint",
            "gear.fixed flexspline in the file, circular_spline",
        ],
    );
    std::fs::remove_dir_all(&d).unwrap();
}

/// Two channels on one column: a warning naming both keys and the column.
#[test]
fn two_channels_on_one_column_are_a_warning() {
    let d = tmp("dup");
    let rec = simulate(&d, "taghirad", "1");
    let learned = root().join("examples/joint-taghirad-learned.toml");
    let cfg =
        config(&d, &learned, |t| t.replace("motor_velocity = \"motor_velocity\"", "motor_velocity = \"output_angle\""));
    let o = run(&["filter", "--config", s(&cfg), "--in", s(&rec), "--out", s(&d.join("f.csv"))]);
    let e = stderr(&o);
    assert!(o.status.success(), "{e}");
    let w: Vec<&str> = e.lines().filter(|l| l.contains("both read")).collect();
    assert_eq!(w.len(), 1, "{e}");
    assert!(
        w[0].starts_with("warning: ")
            && w[0].contains(
                "joint.toml: `channels.output_angle` and `channels.motor_velocity` both read column `output_angle`"
            ),
        "{}",
        w[0]
    );
    std::fs::remove_dir_all(&d).unwrap();
}

/// A joint with a 3× relative line no model lists: the order analysis reports it and
/// the learned file holds it as a sixth order.
#[test]
fn an_unmodelled_line_is_discovered_and_reported() {
    let d = tmp("discover");
    let preset =
        std::fs::read_to_string(root().join("crates/strainwave-sim/presets/taghirad-commissioning.toml")).unwrap();
    let scenario = format!(
        "{}\n[[extra_lines]]\nreference = \"relative\"\nmultiple = 3.0\namplitude_nm = 0.3\nphase_rad = 0.9\n",
        preset.replace("noise_v_rms = 0.002", "noise_v_rms = 0.0227")
    );
    let sc = d.join("joint-3x.toml");
    std::fs::write(&sc, scenario).unwrap();
    let rec = d.join("comm.csv");
    let o = run(&["simulate", "--scenario", s(&sc), "--duration", "10", "--out", s(&rec), "-q"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let learned = d.join("learned.toml");
    let cfg = config(&d, &learned, |t| t.replace("noise_nm = 0.0162", "noise_nm = 0.150"));
    let o = run(&["filter", "--config", s(&cfg), "--in", s(&rec), "--learn", s(&learned)]);
    let e = stderr(&o);
    assert!(o.status.success(), "{e}");
    let found: Vec<&str> = e.lines().filter(|l| l.starts_with("note: discovered")).collect();
    assert_eq!(found.len(), 1, "{e}");
    assert!(
        found[0].starts_with("note: discovered 3 relative: 0.") && found[0].contains("; added to "),
        "{}",
        found[0]
    );
    let text = std::fs::read_to_string(&learned).unwrap();
    assert_eq!(text.matches("[[orders]]").count(), 6, "{text}");
    assert!(text.contains("discovered = true"), "{text}");
    std::fs::remove_dir_all(&d).unwrap();
}

/// Exit status 1 and, after the first run's summary, one error line holding `needle`.
fn last_line_error(o: &Output, needle: &str) {
    let e = stderr(o);
    assert_eq!(o.status.code(), Some(1), "{e}");
    let last = e.trim_end().lines().last().unwrap_or("");
    assert!(last.starts_with("error: ") && last.contains(needle), "`{needle}` not in the last line of: {e}");
    assert_eq!(e.matches("error").count(), 1, "one error: {e}");
}

/// Several runs in one call are read one after the other, never pooled: a bad row in
/// the second names that file and its own data row (1-based), not a row counted from
/// the start of the first.
#[test]
fn a_bad_row_in_a_later_run_names_its_file_and_row() {
    let d = tmp("later-row");
    let a = simulate(&d, "taghirad", "1");
    let text = std::fs::read_to_string(&a).unwrap();
    let header = text.lines().next().unwrap();
    let col = |name: &str| header.split(',').position(|c| c == name).unwrap();
    let (time, torque) = (col("time"), col("bridge_voltage"));
    // A copy of `a` with cell `c` of data row `row` (1-based) replaced.
    let edited = |name: &str, row: usize, c: usize, value: &str| {
        let mut lines: Vec<String> = text.lines().map(String::from).collect();
        let mut cells: Vec<&str> = lines[row].split(',').collect();
        cells[c] = value;
        lines[row] = cells.join(",");
        let p = d.join(name);
        std::fs::write(&p, lines.join("\n") + "\n").unwrap();
        p
    };
    let nan = edited("nan.csv", 5, torque, "NaN");
    let back = edited("back.csv", 7, time, "0.0001");
    let learned = d.join("learned.toml");
    let cfg = config(&d, &d.join("none.toml"), |t| t);
    let o = run(&["filter", "--config", s(&cfg), "--learn", s(&learned), "--in", s(&a), s(&nan)]);
    last_line_error(&o, &format!("{}: data row 5: column `bridge_voltage`", nan.display()));
    let o = run(&["filter", "--config", s(&cfg), "--learn", s(&learned), "--in", s(&a), s(&back)]);
    last_line_error(&o, &format!("{}: data row 7: time 0.0001 s is not after", back.display()));
    std::fs::remove_dir_all(&d).unwrap();
}

/// A learned file damaged to a coefficient a million times too large: the guard passes the
/// raw torque through from the first sample, and no sample is made worse than raw. Before:
/// the first 40 rows were about 1e6 N·m off, until the running mean NIS stepped back.
#[test]
fn a_damaged_learned_coefficient_makes_no_sample_worse_than_raw() {
    let d = tmp("damaged");
    let rec = simulate(&d, "taghirad", "2");
    let text = std::fs::read_to_string(root().join("examples/joint-taghirad-learned.toml")).unwrap();
    let at = text.find("cos_nm = ").unwrap();
    let end = at + text[at..].find('\n').unwrap();
    let learned = d.join("learned.toml");
    std::fs::write(&learned, format!("{}cos_nm = 1e6{}", &text[..at], &text[end..])).unwrap();
    let out = d.join("out.csv");
    let o = run(&["filter", "--config", s(&config(&d, &learned, |t| t)), "--in", s(&rec), "--out", s(&out)]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stderr(&o).contains("passed the raw torque through for 100.0 %"), "{}", stderr(&o));
    let table = std::fs::read_to_string(&out).unwrap();
    let mut lines = table.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = |name: &str| header.iter().position(|h| *h == name).unwrap();
    let (clean, raw, truth) = (col("torque"), col("measured_torque"), col("true_torque"));
    for (k, line) in lines.enumerate() {
        let v: Vec<f64> = line.split(',').map(|x| x.parse().unwrap()).collect();
        let (cleaned, raw) = ((v[clean] - v[truth]).abs(), (v[raw] - v[truth]).abs());
        assert!(cleaned <= raw + 0.05, "row {}: {cleaned} N·m against raw {raw}", k + 1);
    }
}

/// A bad key of the config is named as the config's, not under `filter.learned` (before:
/// ``joint.toml: `filter.learned`: joint.toml: `filter.noise_nm` must be positive``), and
/// an output that overflows from a learned coefficient names the learned file.
#[test]
fn errors_name_the_file_that_holds_the_value() {
    let d = tmp("which-file");
    let rec = simulate(&d, "taghirad", "1");
    let learned = root().join("examples/joint-taghirad-learned.toml");
    let cfg = config(&d, &learned, |t| t.replace("noise_nm = 0.0162", "noise_nm = -1.0"));
    for args in [
        vec!["filter", "--config", s(&cfg), "--in", s(&rec), "--out", s(&d.join("x.csv"))],
        vec!["export-c", "--config", s(&cfg), "--out", s(&d.join("x.c"))],
    ] {
        let o = run(&args);
        assert_user_error(&o, &["joint.toml: `filter.noise_nm` must be positive"]);
        assert!(!stderr(&o).contains("filter.learned"), "{}", stderr(&o));
    }
    let text = std::fs::read_to_string(&learned).unwrap();
    let at = text.find("cos_nm = ").unwrap();
    let end = at + text[at..].find('\n').unwrap();
    let huge = d.join("huge.toml");
    std::fs::write(&huge, format!("{}cos_nm = 1e300{}", &text[..at], &text[end..])).unwrap();
    let o = run(&["filter", "--config", s(&config(&d, &huge, |t| t)), "--in", s(&rec), "--out", s(&d.join("x.csv"))]);
    assert_user_error(&o, &["overflows", "and the coefficients in", "huge.toml"]);
    assert!(!d.join("x.csv").exists() && !d.join("x.c").exists());
}

/// One glitched sample (10 V on the bridge) in the first 0.25 s of a warm run costs its
/// own samples only. Before the glitch rule of the gross-misfit test: the whole model
/// passed the raw torque through for 0.64 s, 0.43 N·m RMS over the next second against
/// 0.016 N·m without the glitch.
#[test]
fn an_early_glitch_costs_its_samples_only() {
    let d = tmp("early-glitch");
    let rec = simulate(&d, "taghirad", "2");
    let text = std::fs::read_to_string(&rec).unwrap();
    let mut lines: Vec<String> = text.lines().map(String::from).collect();
    let header: Vec<&str> = lines[0].split(',').collect();
    let v = header.iter().position(|h| *h == "bridge_voltage").unwrap();
    let mut cells: Vec<String> = lines[101].split(',').map(String::from).collect();
    cells[v] = (cells[v].parse::<f64>().unwrap() + 10.0).to_string();
    lines[101] = cells.join(",");
    let glitched = d.join("glitched.csv");
    std::fs::write(&glitched, lines.join("\n") + "\n").unwrap();
    let learned = root().join("examples/joint-taghirad-learned.toml");
    let out = d.join("out.csv");
    let o = run(&["filter", "--config", s(&config(&d, &learned, |t| t)), "--in", s(&glitched), "--out", s(&out)]);
    assert!(o.status.success(), "{}", stderr(&o));
    let table = std::fs::read_to_string(&out).unwrap();
    let header: Vec<String> = table.lines().next().unwrap().split(',').map(String::from).collect();
    let col = |name: &str| header.iter().position(|h| h == name).unwrap();
    let (clean, truth) = (col("torque"), col("true_torque"));
    let err: Vec<f64> = table
        .lines()
        .skip(1)
        .map(|l| {
            let v: Vec<f64> = l.split(',').map(|x| x.parse().unwrap()).collect();
            v[clean] - v[truth]
        })
        .collect();
    let rms = (err[102..1102].iter().map(|e| e * e).sum::<f64>() / 1000.0).sqrt();
    assert!(rms < 0.03, "RMS over the second after the glitch: {rms} N·m");
}
