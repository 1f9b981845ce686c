//! Do no harm: with the guard on (the default), the cleaned torque is never worse than the
//! raw one in any 1 s window after the first second, against the twin's truth: on the
//! twin's presets, on joints drawn at random, cold (no learned file) and commissioned,
//! and with deliberately wrong configs. Cold free-motion runs in which the output turns
//! come within 1.6× of the noise floor after 10 s, commissioned ones within 1.1×.
//!
//! Every run goes through `filter_recording`, the pipeline of `strainwave filter`.

use std::cell::RefCell;
use std::path::{Path, PathBuf};
use std::rc::Rc;
use std::sync::atomic::{AtomicU64, Ordering};

use strainwave_io::IoError;
use strainwave_joint::run::{RowSink, RowSource};
use strainwave_joint::{filter_recording, FilterOptions, FilterSummary, JointConfig};
use strainwave_sim::scenario::{ExternalTorque, FixedElementName, MotionSegment, Scenario};
use strainwave_sim::{presets, simulate, Recording};

/// A fresh folder for one case's files.
fn case_dir() -> PathBuf {
    static N: AtomicU64 = AtomicU64::new(0);
    let d = std::env::temp_dir()
        .join(format!("sw-harm-{}", std::process::id()))
        .join(N.fetch_add(1, Ordering::Relaxed).to_string());
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn examples() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples")
}

/// A simulated run and what the filter needs to know of its joint.
struct Run {
    rec: Recording,
    noise_nm: f64,
    fs: f64,
}

fn run(scenario: &Scenario) -> Run {
    let (rec, sim) = simulate(scenario).unwrap();
    Run { rec, noise_nm: sim.sensor().noise_floor_nm(), fs: scenario.sample_rate_hz }
}

/// The recording's rows, for the filter.
struct Rows<'a> {
    rec: &'a Recording,
    columns: Vec<String>,
    k: usize,
}

impl RowSource for Rows<'_> {
    fn columns(&self) -> &[String] {
        &self.columns
    }
    fn read_row(&mut self, row: &mut Vec<f64>) -> Result<bool, IoError> {
        if self.k >= self.rec.data[0].len() {
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

/// Keeps the `torque`, `ripple` and `misalignment` columns where the test can read them
/// after the run; with `smoothed`, also `torque_smoothed`.
struct Torque {
    index: usize,
    values: Rc<RefCell<Vec<[f64; 3]>>>,
    smoothed: Option<(usize, Rc<RefCell<Vec<f64>>>)>,
}

impl RowSink for Torque {
    fn write_row(&mut self, row: &[f64]) -> Result<(), IoError> {
        let i = self.index;
        self.values.borrow_mut().push([row[i], row[i + 1], row[i + 2]]);
        if let Some((j, v)) = &self.smoothed {
            v.borrow_mut().push(row[*j]);
        }
        Ok(())
    }
    fn flush(&mut self) -> Result<(), IoError> {
        Ok(())
    }
    fn finish(self) -> Result<u64, IoError> {
        Ok(self.values.borrow().len() as u64)
    }
}

/// Runs the config at `cfg` over `r`: per sample the cleaned torque, ripple and
/// misalignment columns, and the summary. With `learn`, writes the learned file there.
fn filter(cfg: &Path, r: &Run, learn: Option<PathBuf>) -> (Vec<[f64; 3]>, FilterSummary) {
    try_filter(cfg, r, learn).unwrap()
}

/// [`filter`], or its error.
fn try_filter(cfg: &Path, r: &Run, learn: Option<PathBuf>) -> anyhow::Result<(Vec<[f64; 3]>, FilterSummary)> {
    let cfg = JointConfig::load(cfg)?;
    let mut rows = Rows { rec: &r.rec, columns: r.rec.columns.iter().map(|c| c.to_string()).collect(), k: 0 };
    let values = Rc::new(RefCell::new(Vec::new()));
    let opts = FilterOptions { input_name: "run".into(), learn, ..Default::default() };
    let create = |cols: &[&str]| {
        let index = cols.iter().position(|c| *c == "torque").unwrap();
        Ok(Torque { index, values: values.clone(), smoothed: None })
    };
    let summary = filter_recording(&cfg, &mut rows, create, &opts, &mut |_| {})?;
    let torque = values.borrow().clone();
    Ok((torque, summary))
}

/// The worst 1 s window after the first second of `|clean − true|` RMS over
/// `|raw − true|` RMS, where raw is the filter's own input (`torque + ripple +
/// misalignment`: exactly what it subtracted from).
fn worst_window(out: &[[f64; 3]], r: &Run) -> f64 {
    let truth = r.rec.column("true_torque").unwrap();
    let n = r.fs as usize;
    let mut worst = 0.0f64;
    for w in 1..truth.len() / n {
        let (mut clean, mut raw) = (0.0, 0.0);
        for k in w * n..(w + 1) * n {
            let [t, rip, mis] = out[k];
            clean += (t - truth[k]).powi(2);
            raw += (t + rip + mis - truth[k]).powi(2);
        }
        worst = worst.max((clean / raw).sqrt());
    }
    worst
}

/// RMS of `clean − true` from `from_s` on, over the noise floor.
fn over_floor(out: &[[f64; 3]], r: &Run, from_s: f64) -> f64 {
    let truth = r.rec.column("true_torque").unwrap();
    let k0 = (from_s * r.fs) as usize;
    let sum: f64 = (k0..truth.len()).map(|k| (out[k][0] - truth[k]).powi(2)).sum();
    (sum / (truth.len() - k0) as f64).sqrt() / r.noise_nm
}

/// Never worse than raw: the worst window at most 1 (rounding aside); a case that is
/// worse goes into `harm` (each test reports all its cases, then fails).
fn no_harm(what: &str, out: &[[f64; 3]], r: &Run, harm: &mut Vec<String>) -> f64 {
    let w = worst_window(out, r);
    if w > 1.0 + 1e-9 {
        harm.push(format!("{what}: worst 1 s window {w:.3}× raw"));
    }
    w
}

/// A joint config for a simulated joint (torque channel in N·m), written to `dir`.
struct Cfg<'a> {
    ratio: f64,
    fixed: &'a str,
    fs: f64,
    noise_nm: f64,
    model: &'a str,
    learned: Option<&'a Path>,
}

impl Cfg<'_> {
    fn write(&self, dir: &Path, name: &str) -> PathBuf {
        let learned = self.learned.map_or(String::new(), |p| format!("learned = {:?}\n", p.display().to_string()));
        let text = format!(
            "[gear]\nratio = {}\nfixed = \"{}\"\n\n[channels]\ntime = \"time\"\ntorque = \"measured_torque\"\n\
             motor_angle = \"motor_angle\"\noutput_angle = \"output_angle\"\nmotor_velocity = \"motor_velocity\"\n\n\
             [calibration]\ngain_nm_per_v = 1.0\n\n[filter]\nsample_rate_hz = {}\nnoise_nm = {}\n{}\n{learned}",
            self.ratio, self.fixed, self.fs, self.noise_nm, self.model
        );
        let path = dir.join(name);
        std::fs::write(&path, text).unwrap();
        path
    }
}

fn fixed_name(s: &Scenario) -> &'static str {
    match s.gear.fixed {
        FixedElementName::CircularSpline => "circular_spline",
        FixedElementName::Flexspline => "flexspline",
    }
}

/// A small seeded generator (xorshift64*), uniform in `[lo, hi)`.
struct Draw(u64);

impl Draw {
    fn next(&mut self, lo: f64, hi: f64) -> f64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        let u = (self.0.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 11) as f64 / (1u64 << 53) as f64;
        lo + (hi - lo) * u
    }
}

/// A joint drawn at random from the taghirad preset: ratio, fixed element, ripple
/// amplitudes and phases, misalignment; `run` draws its motion (speeds, reversals,
/// standstills) and load (a sinusoid and a step).
fn random_joint(d: &mut Draw) -> Scenario {
    let mut s = presets::preset("taghirad").unwrap();
    s.gear.ratio = d.next(50.0, 160.0).round();
    if d.next(0.0, 1.0) < 0.3 {
        s.gear.fixed = FixedElementName::Flexspline;
    }
    let tau = std::f64::consts::TAU;
    s.ripple.amplitude_2x_nm = d.next(0.05, 0.5);
    s.ripple.amplitude_2x_per_nm = d.next(0.0, 0.03);
    s.ripple.phase_2x_rad = d.next(0.0, tau);
    s.ripple.amplitude_4x_nm = d.next(0.02, 0.2);
    s.ripple.amplitude_4x_per_nm = d.next(0.0, 0.015);
    s.ripple.phase_4x_rad = d.next(0.0, tau);
    s.misalignment.amplitude_nm = d.next(0.1, 1.2);
    s.misalignment.phase_rad = d.next(0.0, tau);
    s.seed = d.next(0.0, 1e9) as u64;
    s
}

/// An ordinary run of `joint`: two speeds with a standstill and a reversal between,
/// an unknown sinusoidal load and a load step.
fn ordinary_run(joint: &Scenario, d: &mut Draw) -> Scenario {
    let mut s = joint.clone();
    let (v1, v2) = (d.next(60.0, 250.0), -d.next(60.0, 250.0));
    s.motion = vec![
        MotionSegment::Ramp { to_rad_s: v1, duration_s: 0.4 },
        MotionSegment::Hold { duration_s: d.next(2.0, 3.0) },
        MotionSegment::Ramp { to_rad_s: 0.0, duration_s: 0.3 },
        MotionSegment::Hold { duration_s: d.next(0.8, 1.5) },
        MotionSegment::Ramp { to_rad_s: v2, duration_s: 0.5 },
        MotionSegment::Hold { duration_s: 3.0 },
    ];
    s.external_torque = vec![
        ExternalTorque::Sine {
            amplitude_nm: d.next(0.0, 4.0),
            frequency_hz: d.next(0.2, 2.0),
            phase_rad: 0.0,
            start_s: d.next(0.5, 2.0),
        },
        ExternalTorque::Step { at_s: d.next(1.0, 7.0), torque_nm: d.next(-5.0, 5.0) },
    ];
    s.duration_s = 8.0;
    s.noise_seed = Some(d.next(0.0, 1e9) as u64);
    s
}

/// The commissioning run of `joint`: steady speed, several output turns, load levels.
fn commissioning_run(joint: &Scenario) -> Scenario {
    let mut s = joint.clone();
    s.motion = vec![MotionSegment::Ramp { to_rad_s: 200.0, duration_s: 0.4 }, MotionSegment::Hold { duration_s: 30.0 }];
    s.external_torque = vec![
        ExternalTorque::Step { at_s: 8.0, torque_nm: 6.0 },
        ExternalTorque::Step { at_s: 16.0, torque_nm: -12.0 },
        ExternalTorque::Step { at_s: 24.0, torque_nm: 6.0 },
    ];
    s.duration_s = 30.0;
    s.noise_seed = Some(s.seed ^ 0x5eed);
    s
}

/// An example config without its learned file, in `dir`.
fn cold_copy(example: &str, dir: &Path) -> PathBuf {
    let text = std::fs::read_to_string(examples().join(example)).unwrap();
    let cold: String =
        text.lines().filter(|l| !l.trim_start().starts_with("learned")).map(|l| format!("{l}\n")).collect();
    let path = dir.join(example);
    std::fs::write(&path, cold).unwrap();
    path
}

/// The twin's presets with the shipped configs: cold and commissioned (their learned
/// files), never worse than raw; commissioned far better.
#[test]
fn presets_never_worse_than_raw_cold_and_commissioned() {
    let mut harm = Vec::new();
    let dir = case_dir();
    let cases = [
        ("taghirad", "joint-taghirad.toml"),
        ("taghirad-standstill", "joint-taghirad.toml"),
        ("taghirad-loaded", "joint-taghirad.toml"),
        ("flexspline-fixed", "joint-flexspline-fixed.toml"),
    ];
    for (preset, config) in cases {
        let r = run(&presets::preset(preset).unwrap());
        let (cold, summary) = filter(&cold_copy(config, &dir), &r, None);
        let w_cold = no_harm(&format!("{preset} cold"), &cold, &r, &mut harm);
        let health = summary.health.expect("the guard is on by default");
        assert_eq!(health.orders.len(), 5);
        let (comm, summary) = filter(&examples().join(config), &r, None);
        let w_comm = no_harm(&format!("{preset} commissioned"), &comm, &r, &mut harm);
        assert!(w_comm < 0.15, "{preset} commissioned: worst window {w_comm:.3}");
        let health = summary.health.unwrap();
        assert!(health.orders.iter().all(|o| o.applied_share > 0.9), "{preset}: {health:?}");
        eprintln!("{preset}: worst 1 s window cold {w_cold:.2}×, commissioned {w_comm:.2}×");
    }
    assert!(harm.is_empty(), "made worse than raw:\n{}", harm.join("\n"));
}

/// The paper's filters as the shipped configs give them (no bias state, so their
/// oscillators take load the model does not know) on the joint presets, three seeds:
/// never worse than raw. Before, the 6th-order filter on `taghirad` admitted its 2× line
/// at a load transient, 14 samples after which the health test stepped it back: its
/// worst 1 s window was 1.006× raw (1.002× on `taghirad-loaded`).
#[test]
fn the_papers_filters_never_worse_than_raw() {
    let mut harm = Vec::new();
    for config in ["joint-taghirad-4th-order.toml", "joint-taghirad-6th-order.toml"] {
        for preset in ["taghirad", "taghirad-standstill", "taghirad-loaded"] {
            for seed in 1..=3 {
                let mut scenario = presets::preset(preset).unwrap();
                scenario.seed = seed;
                let r = run(&scenario);
                let (out, _) = filter(&examples().join(config), &r, None);
                let w = no_harm(&format!("{preset} seed {seed}, {config}"), &out, &r, &mut harm);
                eprintln!("{preset} seed {seed}, {config}: worst 1 s window {w:.4}×");
            }
        }
    }
    assert!(harm.is_empty(), "made worse than raw:\n{}", harm.join("\n"));
}

/// The offline smoother (`--smooth`) on the same presets and configs: its `torque` and
/// `torque_smoothed` never worse than raw. Before, the smoother ran without the guard:
/// cold on `taghirad-loaded`, some 1 s windows were 1.1–1.2× raw.
#[test]
fn the_smoother_never_worse_than_raw_cold_and_commissioned() {
    let mut harm = Vec::new();
    let dir = case_dir();
    let cases = [("taghirad-loaded", "joint-taghirad.toml"), ("flexspline-fixed", "joint-flexspline-fixed.toml")];
    for (preset, config) in cases {
        let r = run(&presets::preset(preset).unwrap());
        for (what, cfg) in [("cold", cold_copy(config, &dir)), ("commissioned", examples().join(config))] {
            let cfg = JointConfig::load(&cfg).unwrap();
            let mut rows = Rows { rec: &r.rec, columns: r.rec.columns.iter().map(|c| c.to_string()).collect(), k: 0 };
            let (values, smoothed) = (Rc::new(RefCell::new(Vec::new())), Rc::new(RefCell::new(Vec::new())));
            let opts = FilterOptions { input_name: "run".into(), smooth: true, ..Default::default() };
            let create = |cols: &[&str]| {
                let index = cols.iter().position(|c| *c == "torque").unwrap();
                let j = cols.iter().position(|c| *c == "torque_smoothed").unwrap();
                Ok(Torque { index, values: values.clone(), smoothed: Some((j, smoothed.clone())) })
            };
            let summary = filter_recording(&cfg, &mut rows, create, &opts, &mut |_| {}).unwrap();
            assert!(summary.health.is_some(), "the guard's figures");
            let out = values.borrow().clone();
            let w = no_harm(&format!("{preset} {what}, torque"), &out, &r, &mut harm);
            // The smoothed torque against the same raw input.
            let as_clean: Vec<[f64; 3]> =
                out.iter().zip(smoothed.borrow().iter()).map(|(o, s)| [*s, o[0] + o[1] + o[2] - s, 0.0]).collect();
            let ws = no_harm(&format!("{preset} {what}, torque_smoothed"), &as_clean, &r, &mut harm);
            eprintln!("{preset} {what} --smooth: worst 1 s window torque {w:.2}×, torque_smoothed {ws:.2}×");
            if what == "commissioned" {
                assert!(ws < 0.15, "{preset}: the smoother still works where the guard trusts the model: {ws:.3}");
            }
        }
    }
    assert!(harm.is_empty(), "made worse than raw:\n{}", harm.join("\n"));
}

/// Deliberately wrong configs on the taghirad joint: an order missing, the noise 10×
/// too large or too small, the wrong fixed element, the learned file of another joint.
/// A learned file whose joint differs from the config's is refused (its identity); every
/// other case runs and is never worse than raw.
#[test]
fn wrong_configs_never_worse_than_raw() {
    let mut harm = Vec::new();
    let dir = case_dir();
    let noise = 0.0162;
    let good = |model: &'static str| Cfg {
        ratio: 100.0,
        fixed: "circular_spline",
        fs: 1000.0,
        noise_nm: noise,
        model,
        learned: None,
    };
    // This joint's learned file, commissioned with this test's channel names.
    let comm_file = dir.join("taghirad-learned.toml");
    let commissioning = run(&presets::preset("taghirad-commissioning").unwrap());
    filter(&good("model = \"full\"").write(&dir, "commissioning.toml"), &commissioning, Some(comm_file.clone()));
    let other_file = examples().join("joint-flexspline-fixed-learned.toml");
    let missing = "model = \"orders\"\nbias_q_nm2 = 1e-3\norders = [{ reference = \"relative\", multiple = 2.0, q_per_rad_nm2 = 1e-4 }]";
    let mut cases: Vec<(String, PathBuf)> = Vec::new();
    let mut add = |name: &str, cfg: Cfg| {
        let path = cfg.write(&dir, &format!("{name}.toml"));
        cases.push((name.to_string(), path));
    };
    add("missing orders", good(missing));
    for (what, learned) in [("cold", None), ("commissioned", Some(comm_file.as_path()))] {
        add(
            &format!("noise 10x too large, {what}"),
            Cfg { noise_nm: 10.0 * noise, learned, ..good("model = \"full\"") },
        );
        add(
            &format!("noise 10x too small, {what}"),
            Cfg { noise_nm: noise / 10.0, learned, ..good("model = \"full\"") },
        );
    }
    add("wrong fixed element, cold", Cfg { fixed: "flexspline", ..good("model = \"full\"") });
    for preset in ["taghirad", "taghirad-standstill", "taghirad-loaded"] {
        let r = run(&presets::preset(preset).unwrap());
        for (name, path) in &cases {
            let (out, summary) = filter(path, &r, None);
            let w = no_harm(&format!("{preset}, {name}"), &out, &r, &mut harm);
            let nis = summary.health.as_ref().map_or(f64::NAN, |h| h.mean_nis);
            eprintln!("{preset}, {name}: worst 1 s window {w:.2}×, mean NIS {nis:.2}");
        }
    }
    assert!(harm.is_empty(), "made worse than raw:\n{}", harm.join("\n"));
    // A learned file of another joint, or of this joint under the wrong fixed element,
    // never reaches the canceller.
    for (name, cfg, differs) in [
        (
            "learned file of another joint",
            Cfg { learned: Some(other_file.as_path()), ..good("model = \"full\"") },
            "fixed",
        ),
        (
            "wrong fixed element, commissioned",
            Cfg { fixed: "flexspline", learned: Some(comm_file.as_path()), ..good("model = \"full\"") },
            "fixed",
        ),
    ] {
        let path = cfg.write(&dir, &format!("{name}.toml"));
        let r = run(&presets::preset("taghirad").unwrap());
        let e = format!("{:#}", try_filter(&path, &r, None).err().unwrap_or_else(|| panic!("{name}: accepted")));
        assert!(e.contains("learned on another joint") && e.contains(differs), "{name}: {e}");
    }
}

/// Joints drawn at random (seeded), each commissioned on its own steady run and then
/// filtering an ordinary run with standstills, a reversal and unknown loads: never
/// worse than raw, cold or commissioned.
#[test]
fn random_joints_never_worse_than_raw() {
    let mut harm = Vec::new();
    let dir = case_dir();
    let mut d = Draw(0x00C0_FFEE_D15C_0B0E);
    for j in 0..4 {
        let joint = random_joint(&mut d);
        let what = format!("joint {j} (ratio {}, {})", joint.gear.ratio, fixed_name(&joint));
        let r = run(&ordinary_run(&joint, &mut d));
        let cfg = |learned| Cfg {
            ratio: joint.gear.ratio,
            fixed: fixed_name(&joint),
            fs: r.fs,
            noise_nm: r.noise_nm,
            model: "model = \"full\"",
            learned,
        };
        let cold = cfg(None).write(&dir, &format!("cold-{j}.toml"));
        let learned = dir.join(format!("learned-{j}.toml"));
        filter(&cold, &run(&commissioning_run(&joint)), Some(learned.clone()));
        let comm = cfg(Some(&learned)).write(&dir, &format!("comm-{j}.toml"));
        let (out, _) = filter(&cold, &r, None);
        let w_cold = no_harm(&format!("{what} cold"), &out, &r, &mut harm);
        let (out, _) = filter(&comm, &r, None);
        let w_comm = no_harm(&format!("{what} commissioned"), &out, &r, &mut harm);
        eprintln!("{what}: worst 1 s window cold {w_cold:.2}×, commissioned {w_comm:.2}×");
    }
    assert!(harm.is_empty(), "made worse than raw:\n{}", harm.join("\n"));
}

/// Free motion with the output turning (the taghirad joint at 300 rad/s, about one
/// output turn every two seconds): commissioned (its shipped learned file), the error is
/// within 1.1× of the noise floor after the first second.
#[test]
fn commissioned_free_motion_is_at_the_noise_floor() {
    let mut harm = Vec::new();
    let r = run(&free_motion(100.0, 300.0));
    let (out, _) = filter(&examples().join("joint-taghirad.toml"), &r, None);
    no_harm("free motion commissioned", &out, &r, &mut harm);
    let ratio = over_floor(&out, &r, 1.0);
    eprintln!("free motion commissioned: RMS error {ratio:.2}× the noise floor after 1 s");
    assert!(harm.is_empty(), "made worse than raw:\n{}", harm.join("\n"));
    assert!(ratio <= 1.1, "commissioned: {ratio:.2}× the noise floor");
}

/// A 50:1 joint at 156 rad/s (one output turn every two seconds), cold: the error comes
/// within 1.6× of the noise floor after 10 s (the guard admits the misalignment after
/// three output turns).
#[test]
fn cold_free_motion_reaches_the_noise_floor_after_10_s() {
    let mut harm = Vec::new();
    let r = run(&free_motion(50.0, 156.0));
    let dir = case_dir();
    let cfg = Cfg {
        ratio: 50.0,
        fixed: "circular_spline",
        fs: r.fs,
        noise_nm: r.noise_nm,
        model: "model = \"full\"",
        learned: None,
    };
    let (out, _) = filter(&cfg.write(&dir, "cold.toml"), &r, None);
    no_harm("free motion cold", &out, &r, &mut harm);
    let ratio = over_floor(&out, &r, 10.0);
    eprintln!("free motion cold: RMS error {ratio:.2}× the noise floor after 10 s");
    assert!(harm.is_empty(), "made worse than raw:\n{}", harm.join("\n"));
    assert!(ratio <= 1.6, "cold: {ratio:.2}× the noise floor after 10 s");
}

/// The taghirad joint at `ratio`, accelerating to `speed_rad_s` and holding it for 20 s,
/// no external load.
fn free_motion(ratio: f64, speed_rad_s: f64) -> Scenario {
    let mut s = presets::preset("taghirad").unwrap();
    s.gear.ratio = ratio;
    s.motion =
        vec![MotionSegment::Ramp { to_rad_s: speed_rad_s, duration_s: 0.5 }, MotionSegment::Hold { duration_s: 20.0 }];
    s.external_torque = Vec::new();
    s.duration_s = 20.0;
    s
}
