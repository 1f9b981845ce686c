//! The bench commands end to end: simulate kit-bench, fuse, campbell, orders, spectrogram,
//! and their one-line errors.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn run(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_strainwave")).args(args).output().expect("run strainwave")
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("sw-bench-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn config() -> String {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples/bench-kit.toml").to_str().unwrap().to_string()
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

fn assert_user_error(o: &Output, needle: &str) {
    let e = stderr(o);
    assert_eq!(o.status.code(), Some(1), "{e}");
    assert!(e.contains(needle), "`{needle}` not in: {e}");
    assert_eq!(e.trim_end().lines().count(), 1, "one line: {e}");
}

fn simulate(d: &Path) -> PathBuf {
    let f = d.join("bench.csv");
    let o = run(&["simulate", "--preset", "kit-bench", "--duration", "4", "--seed", "5", "--out", s(&f), "-q"]);
    assert!(o.status.success(), "{}", stderr(&o));
    f
}

fn read(path: &Path) -> (Vec<String>, Vec<Vec<f64>>) {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    let header = lines.next().unwrap().split(',').map(String::from).collect();
    (header, lines.map(|l| l.split(',').map(|v| v.parse().unwrap()).collect()).collect())
}

/// Rewrites a recording with one column transformed.
fn rewrite(src: &Path, dst: &Path, column: &str, f: impl Fn(f64) -> f64, rows: usize) {
    let (h, data) = read(src);
    let i = h.iter().position(|c| c == column).unwrap();
    let mut out = h.join(",") + "\n";
    for r in data.iter().take(rows) {
        let cells: Vec<String> =
            r.iter().enumerate().map(|(k, v)| if k == i { f(*v).to_string() } else { v.to_string() }).collect();
        out += &(cells.join(",") + "\n");
    }
    std::fs::write(dst, out).unwrap();
}

#[test]
fn simulate_fuse_and_analyse() {
    let d = tmp("flow");
    let sim = simulate(&d);
    let (h, rows) = read(&sim);
    assert_eq!(rows.len(), 80_000);
    for c in ["time", "speed_rpm", "torsion_torque", "accel_1", "accel_2", "accel_torque", "true_dut_torque"] {
        assert!(h.iter().any(|x| x == c), "{c}");
    }

    for method in ["online-corrected", "complementary", "spectral", "corrected"] {
        let out = d.join(format!("fused-{method}.csv"));
        let o = run(&["fuse", "--config", &config(), "--in", s(&sim), "--out", s(&out), "--method", method]);
        assert!(o.status.success(), "{method}: {}", stderr(&o));
        let (fh, frows) = read(&out);
        assert_eq!(fh.len(), h.len() + 1);
        assert_eq!(fh.last().unwrap(), "fused_torque");
        assert_eq!(frows.len(), rows.len());
        // The fused torque follows the true torque at low frequency: compare means over the
        // last half second.
        let (fi, ti) = (fh.len() - 1, fh.iter().position(|c| c == "true_shaft_torque").unwrap());
        let tail = &frows[frows.len() - 10_000..];
        let mf = tail.iter().map(|r| r[fi]).sum::<f64>() / tail.len() as f64;
        let mt = tail.iter().map(|r| r[ti]).sum::<f64>() / tail.len() as f64;
        assert!((mf - mt).abs() < 0.02, "{method}: {mf} vs {mt}");
    }

    let svg = d.join("campbell.svg");
    let o = run(&[
        "campbell",
        "--in",
        s(&sim),
        "--signal",
        "accel_torque",
        "--speed",
        "speed_rpm",
        "--orders",
        "18,36",
        "--out",
        s(&svg),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = std::fs::read_to_string(&svg).unwrap();
    assert!(text.starts_with("<svg") && text.matches("<rect").count() > 100);
    assert_eq!(text.matches("class=\"order-line\"").count(), 2);
    assert!(text.contains("speed (rpm)") && text.contains("frequency (Hz)") && text.contains("18×"));
    // An order too large for the plot ends at its top (before: `-inf` in the SVG).
    let huge = d.join("campbell-huge.svg");
    let args = ["campbell", "--in", s(&sim), "--signal", "accel_torque", "--speed", "speed_rpm"];
    let o = run(&[&args[..], &["--orders", "18,1e308", "--out", s(&huge)]].concat());
    assert!(o.status.success(), "{}", stderr(&o));
    let text = std::fs::read_to_string(&huge).unwrap();
    let lines: Vec<&str> = text.split("points=\"").skip(1).map(|p| p.split('"').next().unwrap()).collect();
    assert_eq!(lines.len(), 2);
    let mut ends = Vec::new();
    for p in &lines {
        let v: Vec<f64> = p.split([',', ' ']).map(|v| v.parse().unwrap_or(f64::NAN)).collect();
        assert!(v.len() == 4 && v.iter().all(|v| v.is_finite() && v.abs() < 1e5), "{p}");
        ends.push(v);
    }
    // The 1e308× line rises straight up from the origin (x within a pixel) and ends
    // higher than the 18× line, which leaves by the top too but further right.
    let (o18, huge) = (&ends[0], &ends[1]);
    assert!((huge[2] - huge[0]).abs() < 1.0 && huge[3] < huge[1], "{huge:?}");
    assert!(huge[3] <= o18[3] + 0.01 && o18[2] > huge[2], "{o18:?} {huge:?}");

    let svg = d.join("orders.svg");
    let o = run(&[
        "orders",
        "--in",
        s(&sim),
        "--signal",
        "accel_torque",
        "--speed",
        "speed_rpm",
        "--order",
        "18",
        "--order",
        "36",
        "--speed-bin",
        "100",
        "--revs-per-block",
        "2",
        "--out",
        s(&svg),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let table = String::from_utf8_lossy(&o.stdout);
    assert!(table.contains("speed rpm") && table.contains("18× amplitude") && table.contains("36× phase °"), "{table}");
    assert!(table.lines().count() > 4, "{table}");
    assert!(std::fs::read_to_string(&svg).unwrap().starts_with("<svg"));
    // `--out -`: standard output holds the SVG alone, the table goes to standard error.
    let args: Vec<&str> = ["orders", "--in", s(&sim), "--signal", "accel_torque", "--speed", "speed_rpm"]
        .into_iter()
        .chain(["--order", "18", "--order", "36", "--speed-bin", "100", "--revs-per-block", "2", "--out", "-"])
        .collect();
    let o = run(&args);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(String::from_utf8_lossy(&o.stdout), std::fs::read_to_string(&svg).unwrap());
    assert_eq!(stderr(&o), table);

    let svg = d.join("spectrogram.svg");
    let o = run(&["spectrogram", "--in", s(&sim), "--signal", "torsion_torque", "--nperseg", "1024", "--out", s(&svg)]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = std::fs::read_to_string(&svg).unwrap();
    assert!(text.matches("<rect").count() > 100 && text.contains("time (s)"));
}

#[test]
fn bad_inputs_give_one_line_errors() {
    let d = tmp("bad");
    let sim = simulate(&d);

    // Crossover above Nyquist (20 kHz sampling).
    let cfg = d.join("high.toml");
    let text = std::fs::read_to_string(config()).unwrap().replace("crossover_hz = 250.0", "crossover_hz = 12000.0");
    std::fs::write(&cfg, text).unwrap();
    for method in ["complementary", "spectral", "corrected"] {
        let o = run(&["fuse", "--config", s(&cfg), "--in", s(&sim), "--out", s(&d.join("x.csv")), "--method", method]);
        assert_user_error(&o, "crossover_hz");
    }
    // A value written `1e308` is printed so, not in 309 digits.
    let text = std::fs::read_to_string(config()).unwrap().replace("crossover_hz = 250.0", "crossover_hz = 1e308");
    std::fs::write(&cfg, text).unwrap();
    let o =
        run(&["fuse", "--config", s(&cfg), "--in", s(&sim), "--out", s(&d.join("x.csv")), "--method", "complementary"]);
    assert_user_error(&o, "`crossover_hz` = 1e308 Hz is at or above the Nyquist frequency");
    // Before: accepted, with a fused torque of 5.8e297 N·m (radius) or a 60 times larger
    // error (a rate for another recording), and exit 0.
    let every = ["online-corrected", "complementary", "spectral"];
    for (from, to, needle, methods) in [
        ("radius_m = 0.6727", "radius_m = 1e-300", "`radius_m` = 1e-300 m: at least 1e-3 m", &every[..]),
        ("stator_inertia_kg_m2 = 1.305e-3", "stator_inertia_kg_m2 = 1e-300", "`stator_inertia_kg_m2` = 1e-300", &every),
        ("# sample_rate_hz = 20000.0", "sample_rate_hz = 1000.0", "`sample_rate_hz` = 1000.0 Hz, but", &every),
        // Named as the file spells them (before: the shaft model's `damping_nm_s_per_rad`).
        (
            "bearing_damping_nm_s_per_rad = 424e-6",
            "bearing_damping_nm_s_per_rad = -1",
            "`bearing_damping_nm_s_per_rad`",
            &every[..1],
        ),
        (
            "shaft_stiffness_nm_per_rad = 258.0",
            "shaft_stiffness_nm_per_rad = 0",
            "`shaft_stiffness_nm_per_rad`",
            &every[..1],
        ),
    ] {
        let text = std::fs::read_to_string(config()).unwrap();
        assert!(text.contains(from), "{from}");
        std::fs::write(&cfg, text.replacen(from, to, 1)).unwrap();
        for method in methods {
            let o =
                run(&["fuse", "--config", s(&cfg), "--in", s(&sim), "--out", s(&d.join("x.csv")), "--method", method]);
            assert_user_error(&o, needle);
        }
    }
    assert!(!d.join("x.csv").exists());
    // One late first sample does not decide the rate (the median step of the first rows
    // does): before, a right `sample_rate_hz` was refused, and without it the rate was
    // taken as 952 Hz for a 20 kHz recording.
    let late = d.join("late.csv");
    let text = std::fs::read_to_string(&sim).unwrap();
    let mut lines: Vec<String> = text.lines().map(String::from).collect();
    let t = lines[0].split(',').position(|h| h == "time").unwrap();
    let mut cells: Vec<String> = lines[1].split(',').map(String::from).collect();
    cells[t] = (cells[t].parse::<f64>().unwrap() - 0.001).to_string();
    lines[1] = cells.join(",");
    std::fs::write(&late, lines.join("\n") + "\n").unwrap();
    let rate = d.join("rate.toml");
    std::fs::write(&rate, std::fs::read_to_string(config()).unwrap().replace("# sample_rate_hz", "sample_rate_hz"))
        .unwrap();
    for cfg in [&rate, &PathBuf::from(config())] {
        let o = run(&["fuse", "--config", s(cfg), "--in", s(&late), "--out", s(&d.join("late-out.csv"))]);
        assert!(o.status.success(), "{}", stderr(&o));
        // The design at 20 kHz (at 952 Hz its band would end at 429 Hz).
        let said = String::from_utf8_lossy(&o.stdout);
        assert!(said.contains("1–4000 Hz: worst 0.04 dB"), "{said}");
    }
    // The online corrected fusion has its own crossover, in [model].
    let text = std::fs::read_to_string(config())
        .unwrap()
        .replace("online_crossover_hz = 150.0", "online_crossover_hz = 9500.0");
    std::fs::write(&cfg, text).unwrap();
    let o = run(&["fuse", "--config", s(&cfg), "--in", s(&sim), "--out", s(&d.join("x.csv"))]);
    assert_user_error(&o, "online_crossover_hz");
    // No [model]: the default method says what it needs.
    let text = std::fs::read_to_string(config()).unwrap();
    let cut = text.find("\n[model]\n").unwrap();
    std::fs::write(&cfg, &text[..cut]).unwrap();
    let o = run(&["fuse", "--config", s(&cfg), "--in", s(&sim), "--out", s(&d.join("x.csv"))]);
    assert_user_error(&o, "[model]");
    // A missing reference column, and a non-finite torsion sample named by its data row.
    let o = run(&["fuse", "--config", &config(), "--in", s(&sim), "--out", s(&d.join("x.csv")), "--reference", "nope"]);
    assert_user_error(&o, "nope");
    let nan = d.join("nan.csv");
    let (h, data) = read(&sim);
    let ti = h.iter().position(|c| c == "torsion_torque").unwrap();
    let mut text = h.join(",") + "\n";
    for (k, r) in data.iter().take(100).enumerate() {
        let cells: Vec<String> =
            r.iter().enumerate().map(|(c, v)| if c == ti && k == 41 { "NaN".into() } else { v.to_string() }).collect();
        text += &(cells.join(",") + "\n");
    }
    std::fs::write(&nan, text).unwrap();
    let o = run(&["fuse", "--config", &config(), "--in", s(&nan), "--out", s(&d.join("x.csv"))]);
    assert_user_error(&o, "data row 42");

    // Negative speed channel.
    let neg = d.join("neg.csv");
    rewrite(&sim, &neg, "speed_rpm", |v| -v - 1.0, usize::MAX);
    let o = run(&[
        "campbell",
        "--in",
        s(&neg),
        "--signal",
        "accel_torque",
        "--speed",
        "speed_rpm",
        "--out",
        s(&d.join("c.svg")),
    ]);
    assert_user_error(&o, "speed_rpm");
    let o = run(&[
        "orders",
        "--in",
        s(&neg),
        "--signal",
        "accel_torque",
        "--speed",
        "speed_rpm",
        "--order",
        "18",
        "--out",
        s(&d.join("o.svg")),
    ]);
    assert_user_error(&o, "speed_rpm");
    let args = ["orders", "--in", s(&sim), "--signal", "accel_torque", "--speed", "speed_rpm", "--order", "18"];
    let o = run(&[&args[..], &["--revs-per-block", "1e308", "--out", s(&d.join("o.svg"))]].concat());
    assert_user_error(&o, "one block needs 1e308");

    // Fewer samples than one window.
    let short = d.join("short.csv");
    rewrite(&sim, &short, "time", |v| v, 500);
    let o = run(&["spectrogram", "--in", s(&short), "--signal", "torsion_torque", "--out", s(&d.join("s.svg"))]);
    assert_user_error(&o, "--nperseg");
    let o = run(&[
        "campbell",
        "--in",
        s(&short),
        "--signal",
        "accel_torque",
        "--speed",
        "speed_rpm",
        "--out",
        s(&d.join("c.svg")),
    ]);
    assert_user_error(&o, "--nperseg");

    // Missing column.
    let o = run(&["spectrogram", "--in", s(&sim), "--signal", "nope", "--out", s(&d.join("s.svg"))]);
    assert_user_error(&o, "nope");

    // A frequency range that shows nothing.
    for max_hz in ["0", "-0", "nan"] {
        let svg = d.join("s.svg");
        let o = run(&[
            "spectrogram",
            "--in",
            s(&sim),
            "--signal",
            "torsion_torque",
            &format!("--max-hz={max_hz}"),
            "--out",
            s(&svg),
        ]);
        assert_user_error(&o, "--max-hz: must be positive");
        assert!(!svg.exists());
    }
}

/// The fusion target, end to end: `fuse` with its defaults on the `kit-bench-sweep`
/// preset is flat against the true air-gap torque within ±1 dB and ±5° over 1 Hz–2 kHz
/// (and 4 kHz) after a constant delay of at most 1 ms, and prints those figures.
#[test]
fn default_fuse_is_flat_on_the_sweep() {
    use strainwave_sim::bench::{preset, simulate_bench};
    let d = tmp("sweep");
    let cols = ["time", "torsion_torque", "accel_1", "accel_2", "true_dut_torque"];
    let rec = simulate_bench(&preset("kit-bench-sweep").unwrap(), Some(&cols)).unwrap();
    let input = d.join("sweep.csv");
    let mut text = cols.join(",") + "\n";
    for k in 0..rec.data[0].len() {
        let row: Vec<String> = rec.data.iter().map(|c| format!("{:e}", c[k])).collect();
        text += &(row.join(",") + "\n");
    }
    std::fs::write(&input, text).unwrap();
    let out = d.join("fused.csv");
    let o =
        run(&["fuse", "--config", &config(), "--in", s(&input), "--out", s(&out), "--reference", "true_dut_torque"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let stdout = String::from_utf8_lossy(&o.stdout).into_owned();
    println!("{stdout}");
    // Two blocks: on its own model, then against the reference; check the second.
    let measured = &stdout[stdout.find("against `true_dut_torque`").expect("reference block")..];
    for band in ["1–2000 Hz", "1–4000 Hz"] {
        let line = measured.lines().find(|l| l.trim_start().starts_with(band)).unwrap_or_else(|| panic!("{band}"));
        let num = |after: &str| -> f64 {
            let rest = &line[line.find(after).unwrap() + after.len()..];
            rest.split(|c: char| !(c.is_ascii_digit() || c == '.')).next().unwrap().parse().unwrap()
        };
        let (db, deg, delay_ms) = (num("worst "), num(") / "), num("delay of "));
        assert!(db < 1.0 && deg < 5.0 && delay_ms <= 1.0, "{line}");
    }
    std::fs::remove_dir_all(&d).ok();
}

/// A bench config whose time channel names a column in ms (`t [ms]`): `fuse` reads it in
/// seconds and fuses exactly as from the recording in seconds.
#[test]
fn a_time_channel_in_ms_is_read_in_seconds() {
    let d = tmp("time-ms");
    let sim = simulate(&d);
    let ms = d.join("ms.csv");
    rewrite(&sim, &ms, "time", |t| t * 1000.0, 2000);
    let text = std::fs::read_to_string(&ms).unwrap().replacen("time", "t [ms]", 1);
    std::fs::write(&ms, text).unwrap();
    let secs = d.join("s.csv");
    rewrite(&sim, &secs, "time", |t| t, 2000);
    let cfg_text = std::fs::read_to_string(config()).unwrap();
    assert!(cfg_text.contains("time = \"time\""));
    let cfg = d.join("bench-ms.toml");
    std::fs::write(&cfg, cfg_text.replacen("time = \"time\"", "time = \"t\"", 1)).unwrap();
    let (out_ms, out_s) = (d.join("out-ms.csv"), d.join("out-s.csv"));
    for (c, i, o) in [(s(&cfg), &ms, &out_ms), (config().as_str(), &secs, &out_s)] {
        let o = run(&["fuse", "--config", c, "--in", s(i), "--out", s(o)]);
        assert!(o.status.success(), "{}", stderr(&o));
    }
    let ((h_ms, rows_ms), (h_s, rows_s)) = (read(&out_ms), read(&out_s));
    let fused = |h: &[String], rows: &[Vec<f64>]| {
        let i = h.iter().position(|c| c == "fused_torque").unwrap_or_else(|| panic!("{h:?}"));
        rows.iter().map(|r| r[i]).collect::<Vec<f64>>()
    };
    assert_eq!(fused(&h_ms, &rows_ms), fused(&h_s, &rows_s));
}
