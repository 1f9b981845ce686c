//! Property tests of the commands' numeric options: any value (huge, tiny, negative,
//! NaN, infinite, integer extremes) ends in a result or a one-line error (exit 0, 1 or
//! 2), never a panic (101), an abort or a run that does not end. Each case runs the
//! binary, so the pass is short (48 cases per option set; more with `PROPTEST_CASES`).

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;
use std::time::Duration;

use proptest::prelude::*;
use proptest::test_runner::Config;

fn dir() -> &'static Path {
    static D: OnceLock<PathBuf> = OnceLock::new();
    D.get_or_init(|| {
        let d = std::env::temp_dir().join(format!("sw-fuzz-opt-{}", std::process::id()));
        std::fs::create_dir_all(&d).unwrap();
        // A short recording with a speed column.
        let mut text = String::from("time,signal,speed\n");
        for k in 0..4096 {
            let t = k as f64 * 1e-3;
            text += &format!("{t},{},{}\n", (300.0 * t).sin(), 600.0 + 10.0 * t);
        }
        std::fs::write(d.join("rec.csv"), text).unwrap();
        d
    })
}

/// Numbers as a user might type them, hostile ones favoured.
fn number() -> impl Strategy<Value = String> {
    prop_oneof![
        any::<f64>().prop_map(|v| format!("{v:e}")),
        any::<i64>().prop_map(|v| v.to_string()),
        (0.0f64..1e4).prop_map(|v| v.to_string()),
        prop::sample::select(vec!["0", "-0", "1e-300", "1e300", "nan", "inf", "-inf", "18446744073709551615", "1"])
            .prop_map(String::from),
    ]
}

/// Runs the binary (at most 60 s) and checks how it ended.
fn check(args: &[&str]) -> Result<(), TestCaseError> {
    let mut child = Command::new(env!("CARGO_BIN_EXE_strainwave"))
        .args(args)
        .current_dir(dir())
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let t0 = std::time::Instant::now();
    let status = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break s;
        }
        if t0.elapsed() > Duration::from_secs(60) {
            let _ = child.kill();
            return Err(TestCaseError::fail(format!("{args:?} still running after 60 s")));
        }
        std::thread::sleep(Duration::from_millis(5));
    };
    let mut err = String::new();
    std::io::Read::read_to_string(&mut child.stderr.take().unwrap(), &mut err).unwrap();
    let code = status.code();
    prop_assert!(matches!(code, Some(0..=2)), "{:?}: exit {:?}: {}", args, code, err);
    if code == Some(1) {
        prop_assert_eq!(err.trim_end().lines().count(), 1, "{:?}: {}", args, err);
    }
    Ok(())
}

fn config() -> Config {
    Config { cases: 48, failure_persistence: None, ..Config::default() }
}

const REC: &[&str] = &["--in", "rec.csv", "--signal", "signal"];

proptest! {
    #![proptest_config(config())]

    #[test]
    fn campbell_options(bin in number(), nperseg in number(), max_hz in number()) {
        let a = [&["campbell", "--speed", "speed", "--out", "c.svg"], REC, &["--speed-bin", &bin, "--nperseg", &nperseg, "--max-hz", &max_hz]].concat();
        check(&a)?;
    }

    #[test]
    fn orders_options(order in number(), revs in number(), bin in number()) {
        let a = [&["orders", "--speed", "speed", "--out", "o.svg"], REC, &["--order", &order, "--revs-per-block", &revs, "--speed-bin", &bin]].concat();
        check(&a)?;
    }

    #[test]
    fn spectrogram_options(nperseg in number()) {
        check(&[&["spectrogram", "--out", "s.svg"], REC, &["--nperseg", &nperseg]].concat())?;
    }

    #[test]
    fn convert_resample_option(hz in number()) {
        check(&["convert", "--in", "rec.csv", "--out", "r.csv", "--quiet", "--resample-hz", &hz])?;
    }

    #[test]
    fn simulate_options(duration in number(), seed in number()) {
        // Valid long durations are cut by the time limit of `check`; keep them short.
        let d = match duration.parse::<f64>() { Ok(v) if v.is_finite() && v > 2.0 && v < 1e9 => "2".to_string(), _ => duration };
        check(&["simulate", "--preset", "taghirad", "--duration", &d, "--seed", &seed, "--out", "sim.csv", "--quiet"])?;
    }

    #[test]
    fn calibrate_bins_option(bins in number(), degree in number()) {
        check(&["calibrate", "--in", "rec.csv", "--reference", "signal", "--sensor", "signal", "--speed", "speed",
            "--model", "speed-table", "--bins", &bins, "--quiet"])?;
        check(&["calibrate", "--in", "rec.csv", "--reference", "signal", "--sensor", "signal", "--speed", "speed",
            "--model", "speed-poly", "--degree", &degree, "--quiet"])?;
    }
}
