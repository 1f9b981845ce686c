//! Nothing lost, nothing crashes: each failure case (partial outputs, overwritten inputs,
//! bounds, glitches, interrupts, closed pipes) as a run of the binary.
//! Outputs appear whole or not at all, an output naming an input is refused, bounds and
//! glitches are one-line errors (exit 1, never a panic's 101), interrupts leave no
//! temporary files and closed pipes end quietly.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};

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
    let d = std::env::temp_dir().join(format!("sw-safety-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// The names in a directory, sorted.
fn names(d: &Path) -> Vec<String> {
    let mut v: Vec<String> =
        std::fs::read_dir(d).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect();
    v.sort();
    v
}

/// Exit 1 with one line on stderr that contains every needle.
fn assert_error(o: &Output, needles: &[&str]) {
    let e = stderr(o);
    assert_eq!(o.status.code(), Some(1), "{e}");
    assert_eq!(e.trim_end().lines().count(), 1, "not one line: {e}");
    for n in needles {
        assert!(e.contains(n), "`{n}` not in: {e}");
    }
}

/// A CSV of `n` rows at 1 kHz: time, a sine signal and a speed of 600 rpm; `edit` changes
/// row `k` (0-based) before it is written.
fn recording(path: &Path, n: usize, edit: impl Fn(usize, &mut [f64; 3])) {
    let mut text = String::from("time,signal,speed\n");
    for k in 0..n {
        let t = k as f64 * 1e-3;
        let mut r = [t, (std::f64::consts::TAU * 60.0 * t).sin(), 600.0];
        edit(k, &mut r);
        text += &format!("{},{},{}\n", r[0], r[1], r[2]);
    }
    std::fs::write(path, text).unwrap();
}

fn simulate(out: &Path, duration: &str) -> Output {
    run(&["simulate", "--preset", "taghirad", "--duration", duration, "--out", s(out), "--quiet"])
}

#[test]
fn two_runs_writing_one_output_leave_one_whole_file() {
    let d = tmp("race");
    let out = d.join("run.csv");
    let spawn = |seed: &str| {
        bin()
            .args(["simulate", "--preset", "taghirad", "--duration", "3", "--seed", seed, "--out", s(&out), "--quiet"])
            .stderr(Stdio::piped())
            .spawn()
            .unwrap()
    };
    let (a, b) = (spawn("1"), spawn("2"));
    for c in [a, b] {
        let o = c.wait_with_output().unwrap();
        assert!(o.status.success(), "{}", stderr(&o));
    }
    // Whole: every row has the header's cells, and it converts without error.
    let text = std::fs::read_to_string(&out).unwrap();
    let cells = text.lines().next().unwrap().split(',').count();
    assert!(text.lines().all(|l| l.split(',').count() == cells));
    assert_eq!(text.lines().count(), 3001);
    assert_eq!(names(&d), ["run.csv"]);
}

#[test]
fn an_output_naming_an_input_is_refused_and_the_input_kept() {
    let d = tmp("same");
    let rec = d.join("rec.csv");
    recording(&rec, 4096, |_, _| {});
    let before = std::fs::read(&rec).unwrap();
    let other_spelling = format!("{}/./rec.csv", s(&d));
    let cases: Vec<Vec<&str>> = vec![
        vec!["convert", "--in", s(&rec), "--out", &other_spelling],
        vec!["report", "--in", s(&rec), "--out", s(&rec)],
        vec!["spectrogram", "--in", s(&rec), "--signal", "signal", "--out", s(&rec)],
        vec!["campbell", "--in", s(&rec), "--signal", "signal", "--speed", "speed", "--out", s(&rec)],
        vec!["orders", "--in", s(&rec), "--signal", "signal", "--speed", "speed", "--order", "6", "--out", s(&rec)],
        vec!["filter", "--config", "../../examples/joint-taghirad.toml", "--in", s(&rec), "--out", s(&rec)],
    ];
    for args in cases {
        let o = run(&args);
        assert_error(&o, &["is also an input"]);
        assert_eq!(std::fs::read(&rec).unwrap(), before, "{args:?}");
    }
    #[cfg(unix)]
    {
        let link = d.join("link.csv");
        std::os::unix::fs::symlink(&rec, &link).unwrap();
        assert_error(&run(&["convert", "--in", s(&rec), "--out", s(&link)]), &["is also an input"]);
    }
    assert_eq!(std::fs::read(&rec).unwrap(), before);
    // A bag folder is read whole: an output inside it would replace or join its files.
    // Before: `--out bag/bag_0.mcap` overwrote the recording with exit 0.
    let bag = d.join("bag");
    std::fs::create_dir_all(&bag).unwrap();
    let log = bag.join("bag_0.mcap");
    assert!(run(&["convert", "--in", s(&rec), "--out", s(&log), "--quiet"]).status.success());
    let recorded = std::fs::read(&log).unwrap();
    for out in [log.clone(), bag.join("bag_0.csv")] {
        let o = run(&["convert", "--in", s(&bag), "--out", s(&out)]);
        assert_error(&o, &["is inside the input folder"]);
        assert_eq!(std::fs::read(&log).unwrap(), recorded);
        assert!(!bag.join("bag_0.csv").exists());
    }
}

#[test]
fn filter_and_report_refuse_to_write_over_a_file_their_config_names() {
    let d = tmp("config-reads");
    let rec = d.join("rec.csv");
    recording(&rec, 64, |_, _| {});
    // The config's calibration and learned files, under names an output could take.
    let (cal, learned) = (d.join("cal.csv"), d.join("learned.csv"));
    std::fs::copy("../../examples/calibration.toml", &cal).unwrap();
    std::fs::copy("../../examples/joint-taghirad-learned.toml", &learned).unwrap();
    let config = std::fs::read_to_string("../../examples/joint-taghirad.toml")
        .unwrap()
        .replace("gain_nm_per_v = 6.611", "file = \"cal.csv\"")
        .replace("learned = \"joint-taghirad-learned.toml\"", "learned = \"learned.csv\"");
    let joint = d.join("joint.toml");
    std::fs::write(&joint, config).unwrap();
    let before = [&cal, &learned].map(|p| std::fs::read(p).unwrap());
    let filter = ["filter", "--config", s(&joint), "--in", s(&rec)];
    for (flag, target) in [("--out", &cal), ("--out", &learned), ("--learn", &cal)] {
        let o = run(&[&filter[..], &[flag, s(target)]].concat());
        assert_error(&o, &["is also an input", s(target)]);
    }
    // `report` does not read them, but writing over them would lose them.
    for target in [&cal, &learned] {
        let o = run(&["report", "--config", s(&joint), "--in", s(&rec), "--out", s(target)]);
        assert_error(&o, &["is also an input", s(target)]);
    }
    assert_eq!([&cal, &learned].map(|p| std::fs::read(p).unwrap()), before);
}

#[test]
fn a_second_output_naming_an_input_or_the_first_output_is_refused() {
    let d = tmp("second");
    let rec = d.join("rec.csv");
    recording(&rec, 64, |_, _| {});
    let before = std::fs::read(&rec).unwrap();
    let (model, cal) = (d.join("m.toml"), d.join("cal.toml"));
    let identify = |summary: &Path| {
        let arm = "../../examples/arm-hda.toml";
        run(&["identify", "--config", arm, "--loaded", s(&rec), "--out", s(&model), "--summary-json", s(summary)])
    };
    assert_error(&identify(&rec), &["is also an input", "rec.csv"]);
    assert_error(&identify(&d.join(".").join("m.toml")), &["named by both --out and --summary-json"]);
    let calibrate = ["calibrate", "--in", s(&rec), "--reference", "signal", "--sensor", "signal", "--out", s(&cal)];
    assert_error(&run(&[&calibrate[..], &["--plot", s(&cal)]].concat()), &["named by both --out and --plot"]);
    let filter = ["filter", "--config", "../../examples/joint-taghirad.toml", "--in", s(&rec)];
    assert_error(&run(&[&filter[..], &["--out", s(&cal), "--learn", s(&cal)]].concat()), &["--out and --learn"]);
    assert_eq!(std::fs::read(&rec).unwrap(), before);
    assert_eq!(names(&d), ["rec.csv"]);
}

#[test]
fn report_to_standard_output_creates_no_file_named_dash() {
    let d = tmp("dash");
    let rec = d.join("rec.csv");
    recording(&rec, 2048, |_, _| {});
    let o = bin().current_dir(&d).args(["report", "--in", "rec.csv", "--out", "-"]).output().unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(String::from_utf8_lossy(&o.stdout).to_lowercase().contains("<html"));
    assert_eq!(names(&d), ["rec.csv"]);
}

/// An SVG written to standard output is the whole of it: `design --svg -` printed its
/// report there too, before the SVG.
#[test]
fn an_svg_on_standard_output_is_not_mixed_with_the_report() {
    let d = tmp("design-svg");
    let config = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples/sensor-taghirad.toml");
    let o = bin().current_dir(&d).args(["design", "--config", s(&config), "--svg", "-"]).output().unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    let svg = String::from_utf8_lossy(&o.stdout);
    assert!(svg.starts_with("<svg") && svg.trim_end().ends_with("</svg>"), "{svg}");
    assert!(stderr(&o).starts_with("sensor design"), "{}", stderr(&o));
    assert!(names(&d).is_empty());
}

/// Before: one sample of 1e308 overflowed the column's sum of squares, and the table said
/// `inf` (and printed the mean in 300 digits).
#[test]
fn report_writes_no_infinity_it_created() {
    let d = tmp("huge");
    let rec = d.join("rec.csv");
    recording(&rec, 2048, |k, r| r[2] = if k == 100 { 1e308 } else { 600.0 });
    let o = bin().current_dir(&d).args(["report", "--in", "rec.csv", "--out", "-"]).output().unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    let html = String::from_utf8_lossy(&o.stdout).into_owned();
    let row = html.split("<tr>").find(|r| r.contains("<td>speed</td>")).expect("the speed row");
    assert!(row.contains("<td>4.88281e304</td><td>2.20971e306</td><td>1.00000e308</td>"), "{row}");
    assert!(!row.contains("inf") && row.len() < 400, "{row}");
}

#[test]
fn a_learn_file_that_cannot_be_written_leaves_the_output_as_it_was() {
    let d = tmp("learn");
    let rec = d.join("rec.csv");
    assert!(simulate(&rec, "2").status.success());
    let out = d.join("out.csv");
    std::fs::write(&out, "previous content\n").unwrap();
    let learn = d.join("no-such-dir").join("learned.toml");
    let o = run(&[
        "filter",
        "--config",
        "../../examples/joint-taghirad.toml",
        "--in",
        s(&rec),
        "--out",
        s(&out),
        "--learn",
        s(&learn),
        "--quiet",
    ]);
    assert_error(&o, &["learned.toml"]);
    assert_eq!(std::fs::read_to_string(&out).unwrap(), "previous content\n");
    assert_eq!(names(&d), ["out.csv", "rec.csv"]);
}

#[test]
fn sigterm_sigint_and_sighup_remove_the_temporary_file_and_exit_128_plus_the_signal() {
    for (sig, code) in [("TERM", 143), ("INT", 130), ("HUP", 129)] {
        let d = tmp(&format!("sig{sig}"));
        let out = d.join("long.csv");
        let mut child = bin()
            .args(["simulate", "--preset", "taghirad", "--duration", "3000", "--out", s(&out), "--quiet"])
            .spawn()
            .unwrap();
        // Wait until the temporary file exists, then interrupt.
        let t0 = std::time::Instant::now();
        while names(&d).is_empty() && t0.elapsed().as_secs() < 60 {
            std::thread::sleep(std::time::Duration::from_millis(20));
        }
        assert_eq!(names(&d).len(), 1);
        assert!(names(&d)[0].starts_with(".long.csv."), "{:?}", names(&d));
        let kill = Command::new("kill").args([&format!("-{sig}"), &child.id().to_string()]).status().unwrap();
        assert!(kill.success());
        let status = child.wait().unwrap();
        assert_eq!(status.code(), Some(code), "SIG{sig}");
        assert!(names(&d).is_empty(), "SIG{sig} left {:?}", names(&d));
    }
}

/// `filter --learn` over two inputs, interrupted while it waits for the second (a named
/// pipe nobody writes): the learned file, merged with the first run by then, is put back
/// as it was, and the process exits 130 (it does not hang).
#[cfg(unix)]
#[test]
fn an_interrupted_learning_over_several_inputs_puts_the_learned_file_back() {
    let d = tmp("learn-interrupted");
    let rec = d.join("rec.csv");
    assert!(simulate(&rec, "2").status.success());
    let learned = d.join("learned.toml");
    std::fs::copy("../../examples/joint-taghirad-learned.toml", &learned).unwrap();
    let before = std::fs::read(&learned).unwrap();
    let fifo = d.join("second.csv");
    assert!(Command::new("mkfifo").arg(&fifo).status().unwrap().success());
    let config = "../../examples/joint-taghirad.toml";
    let mut child = bin()
        .args(["filter", "--config", config, "--in", s(&rec), s(&fifo), "--learn", s(&learned), "--quiet"])
        .spawn()
        .unwrap();
    // The first run has merged into the file: then interrupt.
    let t0 = std::time::Instant::now();
    while std::fs::read(&learned).unwrap() == before && t0.elapsed().as_secs() < 60 {
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    assert_ne!(std::fs::read(&learned).unwrap(), before, "the first run merged nothing");
    assert!(Command::new("kill").args(["-INT", &child.id().to_string()]).status().unwrap().success());
    assert_eq!(child.wait().unwrap().code(), Some(130));
    assert_eq!(std::fs::read(&learned).unwrap(), before);
    assert_eq!(names(&d), ["learned.toml", "rec.csv", "second.csv"]);
}

#[test]
fn after_sigkill_the_left_temporary_is_hidden_and_taken_for_no_recording() {
    let d = tmp("kill");
    let out = d.join("long.csv");
    let mut child = bin()
        .args(["simulate", "--preset", "taghirad", "--duration", "3000", "--out", s(&out), "--quiet"])
        .spawn()
        .unwrap();
    let t0 = std::time::Instant::now();
    while names(&d).is_empty() && t0.elapsed().as_secs() < 60 {
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    child.kill().unwrap();
    child.wait().unwrap();
    let left = names(&d);
    assert_eq!(left.len(), 1);
    assert!(left[0].starts_with('.') && left[0].ends_with(".strainwave-tmp"), "{left:?}");
    assert!(!out.exists());
    // No reader takes it for a recording, and the next run writes its own file.
    let stale = d.join(&left[0]);
    assert_error(&run(&["convert", "--in", s(&stale), "--out", s(&d.join("x.csv"))]), &["unknown format"]);
    assert!(simulate(&out, "0.2").status.success());
    assert!(out.exists());
}

#[test]
fn a_closed_output_pipe_ends_quietly_with_141() {
    let d = tmp("pipe");
    let rec = d.join("rec.csv");
    recording(&rec, 200_000, |_, _| {});
    let mut child = bin()
        .args(["convert", "--in", s(&rec), "--out", "-", "--quiet"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    drop(child.stdout.take());
    let o = child.wait_with_output().unwrap();
    assert_eq!(o.status.code(), Some(141), "{}", stderr(&o));
    assert_eq!(stderr(&o), "");
}

/// With standard error closed, a run still writes its outputs and succeeds (its
/// messages are lost); an error still exits 1.
#[test]
fn a_closed_error_pipe_loses_messages_not_outputs() {
    let d = tmp("stderr-pipe");
    let rec = d.join("rec.csv");
    recording(&rec, 2_000, |_, _| {});
    let closed = |args: &[&str]| {
        let mut child = bin().args(args).stdout(Stdio::null()).stderr(Stdio::piped()).spawn().unwrap();
        drop(child.stderr.take());
        child.wait().unwrap()
    };
    let out = d.join("out.csv");
    assert_eq!(closed(&["convert", "--in", s(&rec), "--out", s(&out)]).code(), Some(0));
    assert_eq!(std::fs::read_to_string(&out).unwrap().lines().count(), 2_001);
    let missing = d.join("missing.csv");
    assert_eq!(closed(&["convert", "--in", s(&missing), "--out", s(&out)]).code(), Some(1));
}

/// An output name near the file system's limit of 255 bytes is written (its temporary
/// file's name is cut to fit).
#[test]
fn an_output_name_of_250_bytes_is_written() {
    let d = tmp("long-name");
    let rec = d.join("rec.csv");
    recording(&rec, 100, |_, _| {});
    let out = d.join(format!("{}.csv", "a".repeat(246)));
    let o = run(&["convert", "--in", s(&rec), "--out", s(&out), "--quiet"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(std::fs::read_to_string(&out).unwrap().lines().count(), 101);
    assert_eq!(names(&d).len(), 2, "no temporary file left: {:?}", names(&d));
}

#[test]
fn csv_headers_with_commas_and_line_breaks_survive_a_round_trip() {
    let d = tmp("quote");
    let rec = d.join("q.csv");
    std::fs::write(&rec, "time,\"a,b\",\"two\nlines\"\n0,1,2\n0.001,3,4\n").unwrap();
    let out = d.join("out.csv");
    let o = run(&["convert", "--in", s(&rec), "--out", s(&out), "--quiet"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let back = d.join("back.csv");
    let o = run(&["convert", "--in", s(&out), "--out", s(&back), "--quiet"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(std::fs::read(&out).unwrap(), std::fs::read(&back).unwrap());
    assert!(std::fs::read_to_string(&out).unwrap().starts_with("time,\"a,b\",\"two\nlines\"\n"));
}

#[test]
fn a_crafted_mcap_record_length_is_an_error_not_a_panic() {
    let d = tmp("mcap");
    let p = d.join("evil.mcap");
    let mut bytes = b"\x89MCAP0\r\n".to_vec();
    // A header record claiming u64::MAX - 3 bytes, then padding to 38 bytes.
    bytes.push(0x01);
    bytes.extend_from_slice(&(u64::MAX - 3).to_le_bytes());
    bytes.resize(38, 0);
    std::fs::write(&p, &bytes).unwrap();
    assert_error(
        &run(&["convert", "--in", s(&p), "--out", s(&d.join("o.csv"))]),
        &["evil.mcap", "length exceeds limit"],
    );
    // A chunk whose uncompressed size is absurd.
    let mut bytes = b"\x89MCAP0\r\n".to_vec();
    let mut chunk = Vec::new();
    chunk.extend_from_slice(&[0; 16]);
    chunk.extend_from_slice(&(1u64 << 60).to_le_bytes());
    chunk.extend_from_slice(&[0; 4]);
    chunk.extend_from_slice(&4u32.to_le_bytes());
    chunk.extend_from_slice(b"zstd");
    chunk.extend_from_slice(&0u64.to_le_bytes());
    bytes.push(0x06);
    bytes.extend_from_slice(&(chunk.len() as u64).to_le_bytes());
    bytes.extend_from_slice(&chunk);
    std::fs::write(&p, &bytes).unwrap();
    // It ends as the mcap crate's decompression error: one line, the file named.
    assert_error(
        &run(&["convert", "--in", s(&p), "--out", s(&d.join("o.csv"))]),
        &["evil.mcap", "MCAP", "decompression"],
    );
    assert!(!d.join("o.csv").exists());
}

#[test]
fn a_signal_sample_that_is_not_finite_is_an_error_naming_file_row_and_column() {
    let d = tmp("signal");
    let rec = d.join("inf.csv");
    recording(&rec, 8192, |k, r| {
        if k == 389 {
            r[1] = f64::INFINITY;
        }
    });
    let out = d.join("o.svg");
    let base = ["--in", s(&rec), "--signal", "signal", "--out", s(&out)];
    let speed = ["--speed", "speed"];
    for args in [
        [&["spectrogram", "--nperseg", "256"][..], &base].concat(),
        [&["campbell", "--nperseg", "512"][..], &base, &speed].concat(),
        [&["orders", "--order", "6"][..], &base, &speed].concat(),
    ] {
        assert_error(&run(&args), &["inf.csv: row 390, column `signal`", "not finite"]);
    }
    assert!(!out.exists());
}

#[test]
fn one_glitched_speed_sample_or_a_tiny_speed_bin_is_an_error_naming_it() {
    let d = tmp("campbell");
    let rec = d.join("glitch.csv");
    recording(&rec, 8192, |k, r| {
        if k == 4000 {
            r[2] = 1e20;
        }
    });
    let out = d.join("c.svg");
    let base = ["--in", s(&rec), "--signal", "signal", "--speed", "speed", "--out", s(&out)];
    let campbell = |extra: &[&str]| run(&[&["campbell", "--nperseg", "512"][..], &base, extra].concat());
    assert_error(&campbell(&[]), &["row 4001", "`speed`", "beyond ±1e7 rpm"]);
    let orders = run(&[&["orders", "--order", "6"][..], &base].concat());
    assert_error(&orders, &["row 4001", "`speed`"]);
    // An order that aliases at every speed (600 rpm, 1 kHz: above order 50).
    let clean600 = d.join("clean600.csv");
    recording(&clean600, 8192, |_, _| {});
    let alias = ["orders", "--in", s(&clean600), "--signal", "signal", "--speed", "speed", "--out", s(&out)];
    assert_error(&run(&[&alias[..], &["--order", "1e300"]].concat()), &["--order 1e300", "Nyquist"]);
    let clean = d.join("clean.csv");
    recording(&clean, 8192, |_, _| {});
    let o = run(&[
        "campbell",
        "--in",
        s(&clean),
        "--signal",
        "signal",
        "--speed",
        "speed",
        "--nperseg",
        "512",
        "--speed-bin",
        "1e-20",
        "--out",
        s(&out),
    ]);
    // In the shortest form: before, 1e-20 was written out in 24 digits.
    assert_error(&o, &["--speed-bin 1e-20 rpm"]);
    assert!(!out.exists());
    // Before: `campbell --max-hz -100` (or 0, or NaN) drew an empty plot and exited 0.
    for max_hz in ["-100", "0", "NaN"] {
        let flag = format!("--max-hz={max_hz}");
        let args = [&["campbell", "--nperseg", "512", flag.as_str()][..], &base].concat();
        assert_error(&run(&args), &["--max-hz: must be positive"]);
    }
    assert!(!out.exists());
}

#[test]
fn a_huge_time_step_or_backwards_time_is_an_error_naming_the_row() {
    let d = tmp("time");
    let step = d.join("step.csv");
    recording(&step, 8192, |k, r| r[0] += if k >= 5000 { 1e6 } else { 0.0 });
    let back = d.join("back.csv");
    recording(&back, 8192, |k, r| {
        if k == 300 {
            r[0] = 0.0;
        }
    });
    let out = d.join("o.svg");
    let orders = |p: &Path| {
        run(&["orders", "--in", s(p), "--signal", "signal", "--speed", "speed", "--order", "6", "--out", s(&out)])
    };
    assert_error(&orders(&step), &["row 5001", "`time`"]);
    assert_error(&orders(&back), &["row 301", "`time`"]);
    let spectrogram = run(&["spectrogram", "--in", s(&back), "--signal", "signal", "--out", s(&out)]);
    assert_error(&spectrogram, &["row 301", "`time`"]);
    assert!(!out.exists());
}

#[test]
fn resampling_one_absurd_time_stamp_is_an_error_before_writing() {
    let d = tmp("resample");
    let rec = d.join("rec.csv");
    recording(&rec, 1000, |k, r| {
        if k == 500 {
            r[0] = 1e308;
        }
    });
    let out = d.join("out.csv");
    let o = run(&["convert", "--in", s(&rec), "--out", s(&out), "--resample-hz", "1000", "--quiet"]);
    assert_error(&o, &["rec.csv", "row 501", "--resample-hz"]);
    assert_eq!(names(&d), ["rec.csv"]);
}

#[test]
fn option_values_beyond_the_limits_are_one_line_errors() {
    let d = tmp("limits");
    let o = run(&["simulate", "--preset", "taghirad", "--duration", "1e12", "--out", s(&d.join("x.csv"))]);
    assert_error(&o, &["--duration", "duration_s"]);
    // A calibration table of u64::MAX bins.
    let rec = d.join("speed.csv");
    let mut text = String::from("reference,sensor,w\n");
    for k in 0..200 {
        let w = k as f64 * 0.5;
        text += &format!("{},{},{w}\n", k as f64 * 0.1, k as f64 * 0.05 + 1e-3 * w);
    }
    std::fs::write(&rec, text).unwrap();
    let o = run(&[
        "calibrate",
        "--in",
        s(&rec),
        "--reference",
        "reference",
        "--sensor",
        "sensor",
        "--speed",
        "w",
        "--model",
        "speed-table",
        "--bins",
        "18446744073709551615",
        "--quiet",
    ]);
    assert_error(&o, &["speed bins"]);
    // FIR taps of a bench config: too many, or too few for a filter (named by the key,
    // not by the library's parameter).
    let bench = d.join("bench.csv");
    let o = run(&["simulate", "--preset", "kit-bench", "--duration", "2", "--out", s(&bench), "--quiet"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let original = std::fs::read_to_string("../../examples/bench-kit.toml").unwrap();
    for taps in ["fir_taps = 100000001", "fir_taps = 1"] {
        let cfg = if original.contains("fir_taps") {
            original
                .lines()
                .map(|l| if l.trim_start().starts_with("fir_taps") { taps } else { l })
                .collect::<Vec<_>>()
                .join("\n")
        } else {
            original.replace("[model]\n", &format!("[model]\n{taps}\n"))
        };
        let cfg_path = d.join("bench.toml");
        std::fs::write(&cfg_path, cfg).unwrap();
        let o = run(&[
            "fuse",
            "--config",
            s(&cfg_path),
            "--in",
            s(&bench),
            "--method",
            "corrected",
            "--out",
            s(&d.join("f.csv")),
        ]);
        assert_error(&o, &[taps]);
    }
    // Bench keys no bench has. Before: accepted (NaN response figures with exit 0), or a
    // crossover of 1e-300 Hz blamed on the input's data row 1.
    let cases = [
        (
            "stator_inertia_kg_m2 = 1.305e-3",
            "stator_inertia_kg_m2 = 1e308",
            "`stator_inertia_kg_m2` = 1e308 kg·m²: at most 1e4 kg·m²",
        ),
        ("radius_m = 0.6727", "radius_m = 1e308", "`radius_m` = 1e308 m: at most 1e1 m"),
        ("crossover_hz = 250.0", "crossover_hz = 1e-300", "`crossover_hz` = 1e-300 Hz is below a millionth"),
    ];
    for (from, to, needle) in cases {
        assert!(original.contains(from), "{from}");
        let cfg_path = d.join("bench.toml");
        std::fs::write(&cfg_path, original.replacen(from, to, 1)).unwrap();
        let fused = d.join("f.csv");
        let args = ["fuse", "--config", s(&cfg_path), "--in", s(&bench), "--out", s(&fused)];
        for method in ["complementary", "online-corrected"] {
            let o = run(&[&args[..], &["--method", method]].concat());
            if method == "online-corrected" && to.starts_with("crossover_hz") {
                continue; // its own crossover is `[model] online_crossover_hz`
            }
            assert_error(&o, &["bench.toml", needle]);
            assert!(!stderr(&o).contains("bench.csv"), "blames the data: {}", stderr(&o));
        }
    }
}

#[test]
fn fuse_refuses_accelerometer_values_that_overflow_and_backwards_time() {
    let d = tmp("fuse");
    let bench = d.join("bench.csv");
    let o = run(&["simulate", "--preset", "kit-bench", "--duration", "1", "--out", s(&bench), "--quiet"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = std::fs::read_to_string(&bench).unwrap();
    let header: Vec<&str> = text.lines().next().unwrap().split(',').collect();
    let at = |name: &str| header.iter().position(|c| *c == name).unwrap();
    let (a1, a2) = (at("accel_1"), at("accel_2"));
    let edit = |row: usize, cols: &[usize], v: &str| -> String {
        let mut lines: Vec<String> = text.lines().map(str::to_string).collect();
        let mut cells: Vec<String> = lines[row].split(',').map(str::to_string).collect();
        for &c in cols {
            cells[c] = v.to_string();
        }
        lines[row] = cells.join(",");
        lines.join("\n") + "\n"
    };
    let bad = d.join("bad.csv");
    std::fs::write(&bad, edit(101, &[a1, a2], "1.7e308")).unwrap();
    let out = d.join("f.csv");
    let cfg_path = "../../examples/bench-kit.toml";
    let o = run(&["fuse", "--config", cfg_path, "--in", s(&bad), "--out", s(&out)]);
    assert_error(&o, &["row 101"]);
    std::fs::write(&bad, edit(201, &[0], "0")).unwrap();
    let o = run(&["fuse", "--config", cfg_path, "--in", s(&bad), "--out", s(&out)]);
    assert_error(&o, &["row 201", "time"]);
    assert!(!out.exists());
    // One finite glitch no sensor gives. Before: every method wrote fused torques near
    // 1e297 N·m with exit 0 (the spectral ones over the whole recording).
    let torsion = at("torsion_torque");
    let glitches = [
        (a2, "1e300", "column `accel_2`: 1e300 m/s² is beyond any accelerometer (limit ±1e6 m/s²"),
        (torsion, "-2e7", "column `torsion_torque`: -2e7 N·m is beyond any torque transducer (limit ±1e7 N·m)"),
    ];
    for (col, v, needle) in glitches {
        std::fs::write(&bad, edit(301, &[col], v)).unwrap();
        for method in ["online-corrected", "complementary", "spectral", "corrected"] {
            let o = run(&["fuse", "--config", cfg_path, "--in", s(&bad), "--out", s(&out), "--method", method]);
            assert_error(&o, &["bad.csv: data row 301, ", needle]);
            assert!(!out.exists(), "{method}");
        }
    }
}

#[test]
fn standard_input_is_never_taken_for_the_same_file_as_the_output() {
    let d = tmp("stdin");
    let rec = d.join("rec.csv");
    recording(&rec, 100, |_, _| {});
    let mut child = bin()
        .args(["convert", "--in", "-", "--out", "-", "--quiet"])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .spawn()
        .unwrap();
    child.stdin.take().unwrap().write_all(&std::fs::read(&rec).unwrap()).unwrap();
    let o = child.wait_with_output().unwrap();
    assert!(o.status.success());
    assert_eq!(String::from_utf8_lossy(&o.stdout).lines().count(), 101);
}

#[test]
fn a_reading_the_calibration_makes_infinite_stops_filter_or_is_skipped_with_lenient() {
    let d = tmp("calinf");
    let rec = d.join("rec.csv");
    assert!(simulate(&rec, "1").status.success());
    let text = std::fs::read_to_string(&rec).unwrap();
    let header: Vec<&str> = text.lines().next().unwrap().split(',').collect();
    let v = header.iter().position(|c| *c == "bridge_voltage").unwrap();
    let mut lines: Vec<String> = text.lines().map(str::to_string).collect();
    let mut cells: Vec<String> = lines[400].split(',').map(str::to_string).collect();
    cells[v] = "1e308".into();
    lines[400] = cells.join(",");
    let bad = d.join("bad.csv");
    std::fs::write(&bad, lines.join("\n") + "\n").unwrap();
    let out = d.join("out.csv");
    let cfg = "../../examples/joint-taghirad.toml";
    let o = run(&["filter", "--config", cfg, "--in", s(&bad), "--out", s(&out), "--quiet"]);
    assert_error(
        &o,
        &["bad.csv", "data row 400", "(`channels.torque`) is 1e308,", "calibration makes infinite", "--lenient"],
    );
    assert!(!out.exists());
    let o = run(&["filter", "--config", cfg, "--in", s(&bad), "--out", s(&out), "--lenient"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stderr(&o).contains("skipped, the first at data row 400"), "{}", stderr(&o));
    let written = std::fs::read_to_string(&out).unwrap();
    assert!(!written.contains("inf"), "an infinity was written");
    // A finite reading beyond ±1e12 N·m (an overrange code) is skipped as a NaN is, even
    // without --lenient: before, its filtering overflowed and stopped the run.
    lines[400] = lines[400].replace("1e308", "1e300");
    std::fs::write(&bad, lines.join("\n") + "\n").unwrap();
    let o = run(&["filter", "--config", cfg, "--in", s(&bad), "--out", s(&out)]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stderr(&o).contains("beyond ±1e12 N·m (an overrange code), were skipped, the first at data row 400"));
    assert!(!std::fs::read_to_string(&out).unwrap().contains("inf"), "an infinity was written");
}

/// Runs `args` alone; its output file's bytes.
fn output_of(args: &[&str], out: &Path) -> Vec<u8> {
    let o = run(args);
    assert!(o.status.success(), "{args:?}: {}", stderr(&o));
    std::fs::read(out).unwrap()
}

/// Two `convert` runs of different recordings (different lengths) into one `--out`,
/// started together, several rounds, for CSV, Parquet and MCAP: each run succeeds or
/// fails with a one-line error, at least one succeeds, and the file is byte for byte
/// what one of the runs writes alone (no rows of the other, no mix of two files),
/// readable again, with no temporary file left.
#[test]
fn concurrent_runs_into_one_output_leave_one_whole_file_of_one_run() {
    let d = tmp("race-convert");
    let (a, b) = (d.join("a.csv"), d.join("b.csv"));
    for (p, seed, seconds) in [(&a, "1", "8"), (&b, "2", "5")] {
        let o = run(&["simulate", "--preset", "taghirad", "--duration", seconds, "--seed", seed, "--out", s(p), "-q"]);
        assert!(o.status.success(), "{}", stderr(&o));
    }
    for ext in ["csv", "parquet", "mcap"] {
        let out = d.join(format!("race.{ext}"));
        let alone = d.join(format!("alone.{ext}"));
        let want_a = output_of(&["convert", "--in", s(&a), "--out", s(&alone), "-q"], &alone);
        let want_b = output_of(&["convert", "--in", s(&b), "--out", s(&alone), "-q"], &alone);
        assert_ne!(want_a, want_b);
        let spawn = |input: &Path| {
            bin().args(["convert", "--in", s(input), "--out", s(&out), "-q"]).stderr(Stdio::piped()).spawn().unwrap()
        };
        for round in 0..3 {
            let _ = std::fs::remove_file(&out);
            let (ca, cb) = (spawn(&a), spawn(&b));
            let mut ok = 0;
            for c in [ca, cb] {
                let o = c.wait_with_output().unwrap();
                if o.status.success() {
                    ok += 1;
                } else {
                    assert_error(&o, &[s(&out)]);
                }
            }
            assert!(ok >= 1, "{ext} round {round}: both runs failed");
            let got = std::fs::read(&out).unwrap();
            assert!(got == want_a || got == want_b, "{ext} round {round}: the output is neither run's file");
            let back = d.join("back.csv");
            let o = run(&["convert", "--in", s(&out), "--out", s(&back), "-q"]);
            assert!(o.status.success(), "{ext} round {round}: {}", stderr(&o));
        }
        let stray: Vec<String> = names(&d).into_iter().filter(|n| n.starts_with('.')).collect();
        assert!(stray.is_empty(), "{ext}: left {stray:?}");
    }
}

/// SIGKILL in the middle of writing over an earlier output: the earlier file is left
/// byte for byte. The killed run's temporary file stays (nothing runs at SIGKILL); it is
/// hidden, names the target and the dead process, ends in `.strainwave-tmp`, and a later
/// run that writes the same target removes it once unchanged for ten minutes
/// (`strainwave_io::output::STALE_TEMP_AGE`; its process gone).
#[test]
fn sigkill_mid_write_leaves_the_previous_file_and_a_later_run_cleans_up() {
    let d = tmp("kill-previous");
    let out = d.join("run.csv");
    assert!(simulate(&out, "0.5").status.success());
    let before = std::fs::read(&out).unwrap();
    let mut child = bin()
        .args(["simulate", "--preset", "taghirad", "--duration", "3000", "--out", s(&out), "--quiet"])
        .spawn()
        .unwrap();
    // Mid-write: the temporary file has grown past the first megabyte.
    let temp = || names(&d).into_iter().find(|n| n.ends_with(".strainwave-tmp")).map(|n| d.join(n));
    let t0 = std::time::Instant::now();
    while temp().and_then(|p| std::fs::metadata(p).ok()).is_none_or(|m| m.len() < 1 << 20) {
        assert!(t0.elapsed().as_secs() < 120, "no temporary file grew: {:?}", names(&d));
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    child.kill().unwrap();
    child.wait().unwrap();
    assert!(std::fs::read(&out).unwrap() == before, "the previous output changed");
    let left = temp().unwrap();
    let name = left.file_name().unwrap().to_string_lossy().into_owned();
    assert!(name.starts_with(&format!(".run.csv.{}-", child.id())), "{name}");
    assert_eq!(names(&d), [name.clone(), "run.csv".to_string()]);

    // A later run soon after leaves it (its writer might still be alive elsewhere) ...
    assert!(simulate(&out, "0.2").status.success());
    assert!(left.exists(), "removed a fresh temporary file");
    // ... and removes it once it is old.
    let old = std::time::SystemTime::now() - std::time::Duration::from_secs(3600);
    std::fs::File::options().write(true).open(&left).unwrap().set_modified(old).unwrap();
    assert!(simulate(&out, "0.2").status.success());
    assert_eq!(names(&d), ["run.csv"]);
}
