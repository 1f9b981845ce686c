//! `strainwave export-c`: what it writes and its one-line errors. (That the exported
//! model gives `filter`'s numbers is tested by compiling it: crates/strainwave-ffi's
//! `c_examples` test.)

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn run(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_strainwave")).args(args).output().expect("run strainwave")
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("sw-export-c-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn example(name: &str) -> String {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples").join(name).to_str().unwrap().to_string()
}

fn assert_user_error(o: &Output, needle: &str) {
    let e = stderr(o);
    assert_eq!(o.status.code(), Some(1), "{e}");
    assert!(e.contains(needle), "`{needle}` not in: {e}");
    assert_eq!(e.trim_end().lines().count(), 1, "one line: {e}");
}

#[test]
fn writes_the_learned_model_and_its_channels() {
    let d = tmp("ok");
    let out = d.join("model.h");
    let o = run(&["export-c", "--config", &example("joint-taghirad.toml"), "--out", out.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = std::fs::read_to_string(&out).unwrap();
    assert!(text.contains("static const sw_model SW_MODEL = {"), "{text}");
    assert!(text.contains(".order_count = 5,") && text.contains(".has_bias_state = 1,"), "{text}");
    assert!(text.contains(".alpha = { 6.611 },"), "{text}");
    // The learned coefficients of the config's `filter.learned` file, as it wrote them.
    let learned = std::fs::read_to_string(example("joint-taghirad-learned.toml")).unwrap();
    let first_cos = learned.lines().find_map(|l| l.strip_prefix("cos_nm = ")).unwrap().trim();
    assert!(text.contains(&format!(".prior_nm = {{ {first_cos}, ")), "{first_cos} not in {text}");
    assert!(text.contains(".torque = { \"bridge_voltage\", 1.0, 0.0 },"), "{text}");
    assert!(text.contains(".expected_torque = { 0, 1.0, 0.0 },"), "{text}");

    // Single precision, another name, to standard output.
    let o = run(&[
        "export-c",
        "--config",
        &example("joint-taghirad.toml"),
        "--out",
        "-",
        "--name",
        "JOINT3",
        "--precision",
        "f32",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = String::from_utf8(o.stdout).unwrap();
    assert!(text.contains("static const sw32_model JOINT3 = {") && text.contains("JOINT3_CHANNELS"), "{text}");
    assert!(text.contains(".sample_rate_hz = 1000.0f,"), "{text}");
    std::fs::remove_dir_all(d).unwrap();
}

#[test]
fn errors_are_one_line() {
    let d = tmp("errors");
    let out = d.join("model.h");
    let out = out.to_str().unwrap();
    let cfg = example("joint-taghirad.toml");
    assert_user_error(&run(&["export-c", "--config", &cfg, "--out", out, "--name", "3joint"]), "--name `3joint`");
    assert_user_error(&run(&["export-c", "--config", &cfg, "--out", out, "--name", "static"]), "--name `static`");
    // A learned file for another model: its identity lists five orders against the paper's three.
    let sixth = example("joint-taghirad-6th-order.toml");
    let learned = example("joint-taghirad-learned.toml");
    assert_user_error(
        &run(&["export-c", "--config", &sixth, "--learned", &learned, "--out", out]),
        "joint-taghirad-learned.toml: learned on another joint than",
    );
    assert_user_error(
        &run(&["export-c", "--config", &d.join("none.toml").to_string_lossy(), "--out", out]),
        "none.toml",
    );
    // The velocity phase without a tachometer channel.
    let text = std::fs::read_to_string(&sixth)
        .unwrap()
        .replace("phase = \"angle\"", "phase = \"velocity\"")
        .replace("motor_velocity = \"motor_velocity\"", "# no tachometer");
    let bad = d.join("velocity.toml");
    std::fs::write(&bad, text).unwrap();
    assert_user_error(
        &run(&["export-c", "--config", bad.to_str().unwrap(), "--out", out]),
        "needs `channels.motor_velocity`",
    );
    // A value float cannot hold names where it comes from, in the shortest form. Before:
    // the config and the C field (`alpha`, `prior_nm`), with the value in 301 digits.
    let text = std::fs::read_to_string(&cfg).unwrap();
    let gain = d.join("gain.toml");
    let text = text.replace("\"joint-taghirad-learned.toml\"", &format!("{learned:?}"));
    std::fs::write(&gain, text.replace("gain_nm_per_v = 6.611", "gain_nm_per_v = 1e300")).unwrap();
    let f32 = ["--precision", "f32", "--out", out];
    assert_user_error(
        &run(&[&["export-c", "--config", gain.to_str().unwrap()][..], &f32].concat()),
        "gain.toml: `calibration` (its gain and offset): `alpha` = 1e300 does not fit a float",
    );
    let learned_text = std::fs::read_to_string(&learned).unwrap();
    let at = learned_text.find("cos_nm = ").unwrap();
    let end = at + learned_text[at..].find('\n').unwrap();
    let huge = d.join("huge.toml");
    std::fs::write(&huge, format!("{}cos_nm = 1e308{}", &learned_text[..at], &learned_text[end..])).unwrap();
    assert_user_error(
        &run(&[&["export-c", "--config", &cfg, "--learned", huge.to_str().unwrap()][..], &f32].concat()),
        "huge.toml: `orders[0]`: `prior_nm` = 1e308 does not fit a float",
    );
    // An output folder that does not exist: the path is named.
    let missing = d.join("no/such/dir/model.h");
    assert_user_error(&run(&["export-c", "--config", &cfg, "--out", missing.to_str().unwrap()]), "no/such/dir/model.h");
    std::fs::remove_dir_all(d).unwrap();
}

/// `--out` is written through a temporary file renamed into place, and never names an
/// input: the config, `--learned`, or the learned file the config names.
#[test]
fn the_output_never_replaces_an_input() {
    let d = tmp("inputs");
    let cfg = d.join("joint.toml");
    let learned = d.join("learned.toml");
    let text = std::fs::read_to_string(example("joint-taghirad.toml")).unwrap();
    std::fs::write(&cfg, text.replace("\"joint-taghirad-learned.toml\"", "\"learned.toml\"")).unwrap();
    std::fs::copy(example("joint-taghirad-learned.toml"), &learned).unwrap();
    let before = [std::fs::read(&cfg).unwrap(), std::fs::read(&learned).unwrap()];
    let c = cfg.to_str().unwrap();
    for out in [&cfg, &learned] {
        let o = run(&["export-c", "--config", c, "--out", out.to_str().unwrap()]);
        assert_user_error(&o, "is also an input");
        let o =
            run(&["export-c", "--config", c, "--learned", learned.to_str().unwrap(), "--out", out.to_str().unwrap()]);
        assert_user_error(&o, "is also an input");
    }
    assert!(std::fs::read(&cfg).unwrap() == before[0] && std::fs::read(&learned).unwrap() == before[1]);
    let out = d.join("model.h");
    std::fs::write(&out, "old").unwrap();
    let o = run(&["export-c", "--config", c, "--out", out.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(std::fs::read_to_string(&out).unwrap().contains("SW_MODEL"));
    let mut names: Vec<String> =
        std::fs::read_dir(&d).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect();
    names.sort();
    assert_eq!(names, ["joint.toml", "learned.toml", "model.h"]);
}
