//! Property tests of the joint's files with hostile text: the joint config (loaded and
//! run over a short recording), the learned file and the calibration file it names.
//! Every case ends in a result or a one-line error naming the file, never a panic.
//!
//! The short pass (256 cases per file) runs with the other tests. The long pass (see
//! docs/safety.md; each test prints its count every 100 000 cases):
//!
//! ```text
//! ulimit -v 6000000   # after building: the limit binds the compiler too
//! PROPTEST_CASES=1000000 cargo test --release -p strainwave-joint --test fuzz_files -- --nocapture
//! ```

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use proptest::prelude::*;
use proptest::test_runner::Config;
use strainwave_io::IoError;
use strainwave_joint::{filter_recording, FilterOptions, JointConfig, LearnedFile};

fn dir() -> PathBuf {
    let d = std::env::temp_dir().join(format!("sw-fuzz-joint-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn case_dir() -> PathBuf {
    static N: AtomicU64 = AtomicU64::new(0);
    let d = dir().join(format!("case-{}", N.fetch_add(1, Ordering::Relaxed)));
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// A recording of 64 rows in memory, with the example config's columns.
struct Rows {
    columns: Vec<String>,
    k: u64,
}

impl strainwave_joint::run::RowSource for Rows {
    fn columns(&self) -> &[String] {
        &self.columns
    }
    fn read_row(&mut self, row: &mut Vec<f64>) -> Result<bool, IoError> {
        if self.k == 64 {
            return Ok(false);
        }
        let t = self.k as f64 * 1e-3;
        row.clear();
        row.extend_from_slice(&[t, 0.1 * (50.0 * t).sin(), 20.0 * t, 0.2 * t, 20.0]);
        self.k += 1;
        Ok(true)
    }
    fn rows_read(&self) -> u64 {
        self.k
    }
}

struct Discard(u64);

impl strainwave_joint::run::RowSink for Discard {
    fn write_row(&mut self, row: &[f64]) -> Result<(), IoError> {
        assert!(row.iter().all(|v| !v.is_infinite()), "an infinite value written: {row:?}");
        self.0 += 1;
        Ok(())
    }
    fn flush(&mut self) -> Result<(), IoError> {
        Ok(())
    }
    fn finish(self) -> Result<u64, IoError> {
        Ok(self.0)
    }
}

/// `seed` with edits: characters overwritten or inserted (favouring those that change
/// numbers and structure), then a cut.
fn mutated(seed: &'static str) -> impl Strategy<Value = String> {
    let ch = prop_oneof![
        4 => prop::sample::select(vec!['0', '9', '-', '.', 'e', '"', '=', '[', ']', '\n', '#', ',', ' ']),
        1 => any::<char>(),
    ];
    let number = prop_oneof![
        any::<f64>().prop_map(|v| format!("{v:e}")),
        Just("1e308".to_string()),
        Just("-0.0".to_string()),
        Just("nan".to_string()),
        Just("inf".to_string()),
        Just("18446744073709551615".to_string()),
        Just("0".to_string()),
    ];
    (
        prop::collection::vec((any::<prop::sample::Index>(), ch), 0..4),
        prop::collection::vec((any::<prop::sample::Index>(), number), 0..3),
        any::<prop::sample::Index>(),
        prop::bool::weighted(0.1),
    )
        .prop_map(move |(edits, numbers, cut, do_cut)| {
            let mut s: Vec<char> = seed.chars().collect();
            for (i, c) in edits {
                let i = i.index(s.len());
                s[i] = c;
            }
            // A number replaces the value after an `=`.
            for (i, v) in numbers {
                let eqs: Vec<usize> = s.iter().enumerate().filter(|(_, c)| **c == '=').map(|(k, _)| k).collect();
                if eqs.is_empty() {
                    break;
                }
                let at = eqs[i.index(eqs.len())] + 1;
                let end = s[at..].iter().position(|c| *c == '\n').map_or(s.len(), |e| at + e);
                s.splice(at..end, format!(" {v}").chars());
            }
            if do_cut {
                s.truncate(cut.index(s.len() + 1));
            }
            s.into_iter().collect()
        })
}

static CONFIG: &str = r#"[gear]
ratio = 100.0
fixed = "circular_spline"
[channels]
time = "time"
torque = "bridge_voltage"
motor_angle = "motor_angle"
output_angle = "output_angle"
motor_velocity = "motor_velocity"
[calibration]
gain_nm_per_v = 6.611
[filter]
model = "full"
sample_rate_hz = 1000.0
noise_nm = 0.0162
phase = "angle"
learned = "learned.toml"
"#;

static LEARNED: &str = include_str!("../../../examples/joint-taghirad-learned.toml");

static CALIBRATION: &str = r#"model = "speed_table"
extrapolation = "clamp"
speed_rad_s = [0.5, 2.0, 4.0]
alpha = [1.55, 1.57, 1.60]
beta_nm = [-0.090, -0.093, -0.100]
"#;

fn config() -> Config {
    Config { failure_persistence: None, ..Config::default() }
}

fn one_line(e: &anyhow::Error) -> String {
    e.chain().map(|c| c.to_string()).collect::<Vec<_>>().join(": ")
}

/// Loads the config in `d` and runs it over the in-memory recording.
fn run_config(d: &Path) -> Result<u64, String> {
    let path = d.join("joint.toml");
    let cfg = JointConfig::load(&path).map_err(|e| one_line(&e))?;
    let mut rows = Rows {
        columns: ["time", "bridge_voltage", "motor_angle", "output_angle", "motor_velocity"].map(String::from).to_vec(),
        k: 0,
    };
    let opts = FilterOptions { input_name: "rec.csv".into(), lenient: true, ..Default::default() };
    filter_recording(&cfg, &mut rows, |_| Ok(Discard(0)), &opts, &mut |_| {}).map(|s| s.rows).map_err(|e| one_line(&e))
}

/// Whether TOML text has an escape that can put a line break into a string (a path
/// then carries it into messages; the command line prints it escaped).
fn escapes(text: &str) -> bool {
    ["\\n", "\\r", "\\u", "\\U", "\\b", "\\f"].iter().any(|e| text.contains(e))
}

fn check_error(e: &str, file: &Path) -> Result<(), TestCaseError> {
    let named = e.contains(file.file_name().unwrap().to_str().unwrap());
    prop_assert!(named, "the file is not named: {}", e);
    Ok(())
}

/// Counts the cases of one test and prints the count every 100 000 (seen with
/// `--nocapture`), so a long pass shows how far it got.
fn tick(counter: &AtomicU64, name: &str) {
    let n = counter.fetch_add(1, Ordering::Relaxed) + 1;
    if n.is_multiple_of(100_000) {
        eprintln!("{name}: {n} cases");
    }
}

proptest! {
    #![proptest_config(config())]

    #[test]
    fn joint_config_never_panics(text in mutated(CONFIG)) {
        static CASES: AtomicU64 = AtomicU64::new(0);
        tick(&CASES, "joint_config_never_panics");
        let d = case_dir();
        std::fs::write(d.join("joint.toml"), &text).unwrap();
        std::fs::write(d.join("learned.toml"), LEARNED).unwrap();
        if let Err(e) = run_config(&d) {
            prop_assert!(escapes(&text) || !e.contains('\n'), "more than one line: {}", e);
            // Errors of the learned file or of a column name those instead.
            if !e.contains("learned.toml") && !e.starts_with("rec.csv: ") {
                check_error(&e, &d.join("joint.toml"))?;
            }
        }
        std::fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn learned_file_never_panics(text in mutated(LEARNED)) {
        static CASES: AtomicU64 = AtomicU64::new(0);
        tick(&CASES, "learned_file_never_panics");
        let d = case_dir();
        std::fs::write(d.join("joint.toml"), CONFIG).unwrap();
        std::fs::write(d.join("learned.toml"), &text).unwrap();
        if let Err(e) = LearnedFile::load(&d.join("learned.toml")) {
            let e = one_line(&e);
            prop_assert!(!e.contains('\n'), "more than one line: {}", e);
            check_error(&e, &d.join("learned.toml"))?;
        }
        let _ = run_config(&d);
        std::fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn calibration_file_never_panics(text in mutated(CALIBRATION)) {
        static CASES: AtomicU64 = AtomicU64::new(0);
        tick(&CASES, "calibration_file_never_panics");
        let d = case_dir();
        let cfg = CONFIG.replace("gain_nm_per_v = 6.611", "file = \"cal.toml\"").replace("learned = \"learned.toml\"\n", "");
        std::fs::write(d.join("joint.toml"), cfg).unwrap();
        std::fs::write(d.join("cal.toml"), &text).unwrap();
        if let Err(e) = run_config(&d) {
            prop_assert!(escapes(&text) || !e.contains('\n'), "more than one line: {}", e);
            prop_assert!(e.contains("cal.toml") || e.contains("joint.toml"), "no file named: {}", e);
        }
        std::fs::remove_dir_all(&d).unwrap();
    }
}
