//! A full disk while writing an output: the run ends with a one-line error naming the
//! file (exit 1), the previous file at the target is left as it was, and no temporary
//! file stays behind.
//!
//! The full disk is a file-size limit on the child (`ulimit -f`, with SIGXFSZ ignored
//! as the shell's `trap` leaves it across `exec`): a write beyond the limit then fails
//! with `EFBIG`, the error a full file system gives as `ENOSPC`, on the same path
//! through the writers. Standard output to a pipe is not limited, so `--out -` lets the
//! `--learn` file alone meet the full disk. Under a plain `ulimit -f` the binary takes
//! SIGXFSZ itself, with the same result.
#![cfg(unix)]

use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};

fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("sw-diskfull-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

fn names(d: &Path) -> Vec<String> {
    let mut v: Vec<String> =
        std::fs::read_dir(d).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect();
    v.sort();
    v
}

fn run(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_strainwave")).args(args).output().expect("run strainwave")
}

/// Runs the binary with files limited to `blocks` blocks of the shell's `ulimit -f`
/// (512 or 1024 bytes); standard output is discarded.
fn run_on_full_disk(blocks: u32, args: &[&str]) -> Output {
    run_limited("trap '' XFSZ; ", blocks, args)
}

/// [`run_on_full_disk`] after `prelude` (shell commands) instead of ignoring SIGXFSZ.
fn run_limited(prelude: &str, blocks: u32, args: &[&str]) -> Output {
    Command::new("sh")
        .arg("-c")
        .arg(format!("{prelude}ulimit -f {blocks} && exec \"$0\" \"$@\""))
        .arg(env!("CARGO_BIN_EXE_strainwave"))
        .args(args)
        .stdout(Stdio::null())
        .output()
        .expect("run sh")
}

const PREVIOUS: &str = "previous content\n";

/// Exit 1, one line naming `file`; `target` still holds [`PREVIOUS`]; the directory
/// holds exactly `expected`.
fn check(o: &Output, file: &Path, target: &Path, dir: &Path, expected: &[&str], what: &str) {
    let e = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{what}: {e}");
    assert_eq!(e.trim_end().lines().count(), 1, "{what}: not one line: {e}");
    let name = file.file_name().unwrap().to_str().unwrap();
    assert!(e.contains(name), "{what}: `{name}` not named: {e}");
    assert!(!e.contains("panicked"), "{what}: {e}");
    assert!(e.contains("(os error"), "{what}: the system's reason is not given: {e}");
    assert_eq!(std::fs::read_to_string(target).unwrap(), PREVIOUS, "{what}: the previous file changed");
    let mut expected: Vec<&str> = expected.to_vec();
    expected.sort();
    assert_eq!(names(dir), expected, "{what}: files left behind");
    eprintln!("{what}: {}", e.trim_end());
}

/// A recording of 4 s at 1 kHz (about 600 kB of CSV).
fn recording(d: &Path) -> PathBuf {
    let rec = d.join("rec.csv");
    let o = run(&["simulate", "--preset", "taghirad", "--duration", "4", "--out", s(&rec), "--quiet"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    rec
}

#[test]
fn every_output_on_a_full_disk_is_an_error_and_the_previous_file_stays() {
    let d = tmp("outputs");
    let rec = recording(&d);
    // Sizes beyond the first block: the writer gets some bytes out, then meets the limit.
    for (ext, blocks) in [("csv", 64), ("parquet", 64), ("mcap", 64), ("tsv", 0)] {
        let out = d.join(format!("out.{ext}"));
        std::fs::write(&out, PREVIOUS).unwrap();
        let o = run_on_full_disk(blocks, &["convert", "--in", s(&rec), "--out", s(&out), "--quiet"]);
        check(&o, &out, &out, &d, &[&format!("out.{ext}"), "rec.csv"], &format!("convert -> .{ext}"));
        std::fs::remove_file(&out).unwrap();
    }
    let cases: Vec<(&str, u32, Vec<&str>)> = vec![
        ("sim.csv", 64, vec!["simulate", "--preset", "taghirad", "--duration", "4", "--quiet", "--out"]),
        ("report.html", 16, vec!["report", "--in", s(&rec), "--out"]),
        (
            "spectrum.svg",
            0,
            vec!["spectrogram", "--in", s(&rec), "--signal", "bridge_voltage", "--nperseg", "512", "--out"],
        ),
        (
            "filtered.csv",
            64,
            vec!["filter", "--config", "../../examples/joint-taghirad.toml", "--in", s(&rec), "--quiet", "--out"],
        ),
    ];
    for (name, blocks, mut args) in cases {
        let out = d.join(name);
        std::fs::write(&out, PREVIOUS).unwrap();
        args.push(s(&out));
        let o = run_on_full_disk(blocks, &args);
        check(&o, &out, &out, &d, &[name, "rec.csv"], args[0]);
        std::fs::remove_file(&out).unwrap();
    }
    // A calibration file (small: nothing can be written at all).
    let cal = d.join("cal.toml");
    std::fs::write(&cal, PREVIOUS).unwrap();
    let args =
        ["calibrate", "--in", s(&rec), "--reference", "true_torque", "--sensor", "bridge_voltage", "--out", s(&cal)];
    let o = run_on_full_disk(0, &args);
    check(&o, &cal, &cal, &d, &["cal.toml", "rec.csv"], "calibrate");
}

#[test]
fn a_learned_file_on_a_full_disk_is_an_error_and_the_previous_one_stays() {
    let d = tmp("learn");
    let rec = recording(&d);
    let learned = d.join("learned.toml");
    let mut args = [
        "filter",
        "--config",
        "../../examples/joint-taghirad.toml",
        "--in",
        s(&rec),
        "--out",
        "-",
        "--learn",
        s(&learned),
        "--quiet",
    ];
    // A learned file from an earlier run: `--learn` merges into it, so it must be one.
    let o = run(&args);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let previous = std::fs::read(&learned).unwrap();
    let o = run_on_full_disk(0, &args);
    let e = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{e}");
    assert_eq!(e.trim_end().lines().count(), 1, "not one line: {e}");
    assert!(e.contains("learned.toml") && e.contains("(os error"), "{e}");
    assert_eq!(std::fs::read(&learned).unwrap(), previous, "the previous learned file changed");
    assert_eq!(names(&d), ["learned.toml", "rec.csv"], "files left behind");

    // With both on the full disk, neither file is replaced.
    let out = d.join("out.csv");
    std::fs::write(&out, PREVIOUS).unwrap();
    args[6] = s(&out);
    let o = run_on_full_disk(64, &args);
    let e = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{e}");
    assert_eq!(e.trim_end().lines().count(), 1, "{e}");
    assert_eq!(std::fs::read_to_string(&out).unwrap(), PREVIOUS);
    assert_eq!(std::fs::read(&learned).unwrap(), previous);
    assert_eq!(names(&d), ["learned.toml", "out.csv", "rec.csv"]);
}

/// A plain `ulimit -f` (SIGXFSZ at its default, terminate): the binary takes the signal
/// itself, so the write fails as on a full disk. Before, SIGXFSZ killed the run (exit 153)
/// and left its temporary file beside the target.
#[test]
fn a_plain_file_size_limit_is_a_full_disk_not_a_kill() {
    let d = tmp("plain-ulimit");
    let rec = recording(&d);
    let out = d.join("out.csv");
    for args in [
        vec!["simulate", "--preset", "taghirad", "--duration", "4", "--quiet", "--out", s(&out)],
        vec!["filter", "--config", "../../examples/joint-taghirad.toml", "--in", s(&rec), "--quiet", "--out", s(&out)],
    ] {
        std::fs::write(&out, PREVIOUS).unwrap();
        let o = run_limited("", 64, &args);
        check(&o, &out, &out, &d, &["out.csv", "rec.csv"], args[0]);
    }
}

#[test]
fn the_limit_is_real_a_run_within_it_succeeds() {
    // The same command with room to write replaces the previous file: the failures
    // above come from the full disk, not from the arguments.
    let d = tmp("room");
    let rec = recording(&d);
    let out = d.join("out.csv");
    std::fs::write(&out, PREVIOUS).unwrap();
    let o = run_on_full_disk(1 << 20, &["convert", "--in", s(&rec), "--out", s(&out), "--quiet"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(std::fs::read(&out).unwrap(), std::fs::read(&rec).unwrap());
    assert_eq!(names(&d), ["out.csv", "rec.csv"]);
}
