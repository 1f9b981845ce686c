//! Self-commissioning against the twin's truth: learning from a run
//! into a learned file, merging runs by information, order discovery of an unmodelled
//! line, and the joint identity a learned file carries.

use std::path::{Path, PathBuf};

use strainwave_io::IoError;
use strainwave_joint::run::{RowSink, RowSource};
use strainwave_joint::{filter_recording, FilterOptions, FilterSummary, JointConfig, LearnedFile};
use strainwave_sim::scenario::{ExtraLine, LineReference};
use strainwave_sim::{presets, simulate, Recording, Scenario};

/// Largest RMS error over the noise floor once the line is discovered.
const DISCOVERED_WITHIN_FLOOR: f64 = 1.1;
/// Seconds left out of the RMS figures (the filter's start).
const WARM_UP_S: f64 = 0.3;

fn dir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("sw-selfcomm-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn example(name: &str) -> String {
    std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples").join(name)).unwrap()
}

/// A recording in memory as the filter's rows.
struct Rows<'a> {
    rec: &'a Recording,
    columns: Vec<String>,
    k: usize,
}

impl<'a> Rows<'a> {
    fn new(rec: &'a Recording) -> Self {
        Self { rec, columns: rec.columns.iter().map(|c| c.to_string()).collect(), k: 0 }
    }
}

impl RowSource for Rows<'_> {
    fn columns(&self) -> &[String] {
        &self.columns
    }
    fn read_row(&mut self, row: &mut Vec<f64>) -> Result<bool, IoError> {
        if self.k == self.rec.data[0].len() {
            return Ok(false);
        }
        row.clear();
        row.extend(self.rec.data.iter().map(|c| c[self.k]));
        self.k += 1;
        Ok(true)
    }
    fn rows_read(&self) -> u64 {
        self.k as u64
    }
}

/// Keeps the squared error of `torque` against `true_torque` after the warm-up.
struct ErrorSink {
    at: (usize, usize, usize),
    sum: f64,
    n: u64,
}

impl RowSink for ErrorSink {
    fn write_row(&mut self, row: &[f64]) -> Result<(), IoError> {
        if row[self.at.0] > WARM_UP_S {
            self.sum += (row[self.at.1] - row[self.at.2]).powi(2);
            self.n += 1;
        }
        Ok(())
    }
    fn flush(&mut self) -> Result<(), IoError> {
        Ok(())
    }
    fn finish(self) -> Result<u64, IoError> {
        Ok(self.n)
    }
}

/// Runs the filter of `cfg` over `rec`; the RMS error of the clean torque and the summary.
fn filter(cfg: &Path, rec: &Recording, learn: Option<&Path>) -> anyhow::Result<(f64, FilterSummary)> {
    let cfg = JointConfig::load(cfg)?;
    let opts = FilterOptions { input_name: "run".into(), learn: learn.map(Path::to_path_buf), ..Default::default() };
    let mut rms = f64::NAN;
    let summary = filter_recording(
        &cfg,
        &mut Rows::new(rec),
        |cols| {
            let at = |n: &str| cols.iter().position(|c| *c == n).unwrap();
            Ok(Recorder {
                inner: ErrorSink { at: (at("time"), at("torque"), at("true_torque")), sum: 0.0, n: 0 },
                out: &mut rms,
            })
        },
        &opts,
        &mut |_| {},
    )?;
    Ok((rms, summary))
}

/// An [`ErrorSink`] that leaves its RMS in `out` when finished.
struct Recorder<'a> {
    inner: ErrorSink,
    out: &'a mut f64,
}

impl RowSink for Recorder<'_> {
    fn write_row(&mut self, row: &[f64]) -> Result<(), IoError> {
        self.inner.write_row(row)
    }
    fn flush(&mut self) -> Result<(), IoError> {
        Ok(())
    }
    fn finish(self) -> Result<u64, IoError> {
        *self.out = (self.inner.sum / self.inner.n as f64).sqrt();
        Ok(self.inner.n)
    }
}

/// The taghirad joint with a noisier sensor (floor about 0.15 N·m) and a 3× relative
/// line of 0.3 N·m that no model of the config lists.
fn joint_with_3x(preset: &str) -> Scenario {
    let mut s = presets::preset(preset).unwrap();
    s.sensor.noise_v_rms = 0.0227;
    s.extra_lines =
        vec![ExtraLine { reference: LineReference::Relative, multiple: 3.0, amplitude_nm: 0.3, phase_rad: 0.9 }];
    s
}

/// The example taghirad config with `noise_nm` and `learned` replaced.
fn write_config(d: &Path, name: &str, noise_nm: f64, learned: Option<&Path>) -> PathBuf {
    let text = example("joint-taghirad.toml");
    let learned_line = match learned {
        Some(p) => format!("learned = {:?}", p.to_str().unwrap()),
        None => String::new(),
    };
    let text = text
        .lines()
        .map(|l| {
            if l.starts_with("noise_nm =") {
                format!("noise_nm = {noise_nm}")
            } else if l.starts_with("learned =") {
                learned_line.clone()
            } else {
                l.to_string()
            }
        })
        .collect::<Vec<_>>()
        .join("\n");
    let p = d.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

/// Order discovery: an unmodelled 3× line of 0.3 N·m keeps the commissioned
/// canceller well above the noise floor; the order analysis of a `--learn` run finds
/// it, and with the learned file the error comes back within 1.1× of the floor.
#[test]
fn an_unmodelled_3x_line_is_discovered_and_the_error_comes_back_to_the_floor() {
    let d = dir("3x");
    let (comm, sim) = simulate(&joint_with_3x("taghirad-commissioning")).unwrap();
    let floor = sim.sensor().noise_floor_nm();
    let (loaded, _) = simulate(&joint_with_3x("taghirad-loaded")).unwrap();
    let learned = d.join("learned.toml");
    let cold_cfg = write_config(&d, "cold.toml", floor, None);
    let cfg = write_config(&d, "joint.toml", floor, Some(&learned));

    let (cold, _) = filter(&cold_cfg, &loaded, None).unwrap();
    let (_, summary) = filter(&cfg, &comm, Some(&learned)).unwrap();
    let found: Vec<&String> = summary.notes.iter().filter(|n| n.starts_with("discovered")).collect();
    assert_eq!(found.len(), 1, "{:?}", summary.notes);
    assert!(found[0].starts_with("discovered 3 relative: 0.29") || found[0].starts_with("discovered 3 relative: 0.30"));
    let file = LearnedFile::load(&learned).unwrap();
    let line = file.orders.last().unwrap();
    assert!(
        line.discovered
            && line.reference == strainwave_joint::config::ReferenceChoice::Relative
            && line.multiple == 3.0
    );
    // 0.3 sin(3φ + 0.9) = 0.3 sin 0.9 cos 3φ + 0.3 cos 0.9 sin 3φ.
    assert!((line.cos_nm - 0.3 * 0.9f64.sin()).abs() < 0.02 && (line.sin_nm - 0.3 * 0.9f64.cos()).abs() < 0.02);

    // The same learned file without the discovered order: commissioned, line unmodelled.
    let mut without = file.clone();
    without.orders.pop();
    let learned_without = d.join("without.toml");
    without.save(&learned_without, "test: the learned file without its discovered order").unwrap();
    let before_cfg = write_config(&d, "before.toml", floor, Some(&learned_without));
    let (before, _) = filter(&before_cfg, &loaded, None).unwrap();
    let (after, _) = filter(&cfg, &loaded, None).unwrap();
    eprintln!(
        "3x line: floor {floor:.4} N·m; cold {cold:.4} ({:.2}×), commissioned without the line {before:.4} \
         ({:.2}×), after discovery {after:.4} ({:.2}×)",
        cold / floor,
        before / floor,
        after / floor
    );
    assert!(before > 1.5 * floor, "before {before} floor {floor}");
    assert!(after <= DISCOVERED_WITHIN_FLOOR * floor, "after {after} floor {floor}");
    std::fs::remove_dir_all(&d).unwrap();
}

/// Two runs merge by information: learning one run twice doubles each order's
/// information (half the covariance, the same coefficients), since each run's learning
/// starts cold and its cold prior is taken out before the merge. A run without an
/// unmodelled line discovers nothing.
#[test]
fn the_same_run_learned_twice_doubles_the_information() {
    let d = dir("twice");
    let mut s = presets::preset("taghirad-commissioning").unwrap();
    s.duration_s = 12.0;
    let (rec, sim) = simulate(&s).unwrap();
    let learned = d.join("learned.toml");
    let cfg = write_config(&d, "joint.toml", sim.sensor().noise_floor_nm(), Some(&learned));
    let (_, summary) = filter(&cfg, &rec, Some(&learned)).unwrap();
    assert!(!summary.notes.iter().any(|n| n.starts_with("discovered")), "{:?}", summary.notes);
    let once = LearnedFile::load(&learned).unwrap();
    assert_eq!(once.orders.len(), 5);
    filter(&cfg, &rec, Some(&learned)).unwrap();
    let twice = LearnedFile::load(&learned).unwrap();
    for (a, b) in once.orders.iter().zip(&twice.orders) {
        assert_eq!((a.runs, b.runs), (1, 2), "{}", a.label());
        let (ga, gb) = (a.gaussian(), b.gaussian());
        for i in 0..2 {
            assert!((ga.mean_nm[i] - gb.mean_nm[i]).abs() <= 1e-9 * ga.mean_nm[i].abs().max(1e-6), "{}", a.label());
            for j in 0..2 {
                let half = 0.5 * ga.cov_nm2[i][j];
                assert!((gb.cov_nm2[i][j] - half).abs() <= 1e-9 * ga.cov_nm2[0][0], "{}", a.label());
            }
        }
    }
    std::fs::remove_dir_all(&d).unwrap();
}

/// A learned file of another joint is refused with one line naming the file and what
/// differs, for the filter and for `--learn` alike, and the file is left as it was; an
/// older file without identity is used with a warning.
#[test]
fn a_learned_file_of_another_joint_is_refused_and_kept() {
    let d = dir("identity");
    let mut s = presets::preset("taghirad-commissioning").unwrap();
    s.duration_s = 3.0;
    let (rec, _) = simulate(&s).unwrap();
    let learned = d.join("learned.toml");
    let cfg = write_config(&d, "joint.toml", 0.0162, Some(&learned));
    filter(&cfg, &rec, Some(&learned)).unwrap();
    let before = std::fs::read(&learned).unwrap();

    let edits: [(&str, &str, &str); 4] = [
        (
            "fixed = \"circular_spline\"",
            "fixed = \"flexspline\"",
            "gear.fixed circular_spline in the file, flexspline in the config",
        ),
        ("ratio = 100.0", "ratio = 160.0", "gear.ratio 100 in the file, 160 in the config"),
        (
            "output_angle = \"output_angle\"",
            "output_angle = { column = \"output_angle\", offset = 0.3 }",
            "fingerprint",
        ),
        (
            "model = \"full\"",
            "model = \"taghirad-6th-order\"",
            "orders [2 relative, 4 relative, 2 relative load-scaled",
        ),
    ];
    for (from, to, needle) in edits {
        let text = std::fs::read_to_string(&cfg).unwrap();
        assert!(text.contains(from), "{from}");
        let other = d.join("other.toml");
        std::fs::write(&other, text.replacen(from, to, 1)).unwrap();
        for learn in [None, Some(learned.as_path())] {
            let e = format!("{:#}", filter(&other, &rec, learn).unwrap_err());
            assert!(e.contains("learned.toml: learned on another joint than") && e.contains(needle), "{e}");
            assert!(!e.contains('\n'), "{e}");
        }
        assert_eq!(std::fs::read(&learned).unwrap(), before, "{to}");
    }

    // An older file: no [joint] table.
    let text = String::from_utf8(before).unwrap();
    let start = text.find("[joint]").unwrap();
    let end = text.find("[[orders]]").unwrap();
    std::fs::write(&learned, format!("{}{}", &text[..start], &text[end..])).unwrap();
    let (_, summary) = filter(&cfg, &rec, None).unwrap();
    assert!(summary.notes.iter().any(|n| n.contains("learned.toml: no joint identity")), "{:?}", summary.notes);
    std::fs::remove_dir_all(&d).unwrap();
}

/// Two channels reading one column are a one-line warning in the run's summary.
#[test]
fn two_channels_on_one_column_are_reported() {
    let d = dir("dup");
    let mut s = presets::preset("taghirad").unwrap();
    s.duration_s = 0.5;
    let (rec, _) = simulate(&s).unwrap();
    let cfg = write_config(&d, "joint.toml", 0.0162, None);
    let text = std::fs::read_to_string(&cfg)
        .unwrap()
        .replace("motor_velocity = \"motor_velocity\"", "motor_velocity = \"motor_angle\"");
    std::fs::write(&cfg, text).unwrap();
    let (_, summary) = filter(&cfg, &rec, None).unwrap();
    let w: Vec<&String> = summary.warnings.iter().filter(|w| w.contains("both read")).collect();
    assert_eq!(w.len(), 1, "{:?}", summary.warnings);
    assert!(
        w[0].contains("`channels.motor_angle` and `channels.motor_velocity` both read column `motor_angle`"),
        "{}",
        w[0]
    );
    std::fs::remove_dir_all(&d).unwrap();
}
