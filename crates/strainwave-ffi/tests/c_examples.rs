//! The C and C++ examples, built with the system compilers (`cc`, `c++` from PATH) against
//! `include/strainwave.h` and the static library, on a simulated recording:
//!
//! - `examples/c/filter_csv.c` with a model from `strainwave export-c` gives the numbers
//!   of `strainwave filter` on the same recording and config, to 1e-9 N·m (f64) and the
//!   same `filter_flags`: under the do-no-harm guard (the default) for the learned full
//!   model and the paper's 6th-order model, and bare (`filter.guard = false`);
//! - an f32 export compiles and passes `sw32_init`;
//! - `examples/c/stack_use.c` measures the stack of each call, within bounds;
//! - `examples/ros2_control` compiles with `c++ -std=c++17` and runs.
//!
//! Skipped with a message when a compiler is missing. The library and the command line
//! come from a nested `cargo test --workspace --no-run`: the very units `cargo test
//! --workspace` builds, so a no-op under it. (`cargo build` would resolve the features
//! without the dev-dependencies, and selecting only some crates other features again:
//! either rebuilds much of the workspace.)

use std::path::{Path, PathBuf};
use std::process::Command;

use strainwave_ffi::{sw32_state, sw_state};

fn workspace() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..").canonicalize().unwrap()
}

fn have(compiler: &str) -> bool {
    Command::new(compiler).arg("--version").output().is_ok_and(|o| o.status.success())
}

fn run(cmd: &mut Command) -> String {
    let out = cmd.output().unwrap_or_else(|e| panic!("{cmd:?}: {e}"));
    assert!(
        out.status.success(),
        "{cmd:?} failed:\n{}\n{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// Builds the static library and the command line with the workspace's tests; their
/// paths, as cargo reports them.
fn build() -> (PathBuf, PathBuf) {
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let mut cmd = Command::new(cargo);
    cmd.current_dir(workspace()).args(["test", "--quiet", "--workspace", "--no-run", "--message-format", "json"]);
    // The profile of this test's own build (`target/<profile>/deps/<this test>`).
    let exe = std::env::current_exe().unwrap();
    if exe.ancestors().nth(2).and_then(Path::file_name).is_some_and(|n| n == "release") {
        cmd.arg("--release");
    }
    let (mut lib, mut cli) = (None, None);
    for line in run(&mut cmd).lines() {
        let Ok(msg) = serde_json::from_str::<serde_json::Value>(line) else { continue };
        let target = &msg["target"];
        if msg["reason"] != "compiler-artifact" {
            continue;
        }
        // The command line itself, not its unit-test harness (also a `bin` target).
        if target["name"] == "strainwave" && target["kind"][0] == "bin" && msg["profile"]["test"] == false {
            cli = msg["executable"].as_str().map(PathBuf::from);
        }
        if target["name"] == "strainwave_ffi" && msg["profile"]["test"] == false {
            let files = msg["filenames"].as_array().into_iter().flatten().filter_map(|f| f.as_str());
            lib = files.map(PathBuf::from).find(|f| f.extension().is_some_and(|e| e == "a")).or(lib);
        }
    }
    (lib.expect("cargo built no libstrainwave_ffi.a"), cli.expect("cargo built no strainwave binary"))
}

/// Columns of a CSV file (no quoting) by name.
fn read_csv(path: &Path) -> (Vec<String>, Vec<Vec<String>>) {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    let header = lines.next().unwrap().split(',').map(str::to_string).collect();
    let rows = lines.filter(|l| !l.is_empty()).map(|l| l.split(',').map(str::to_string).collect()).collect();
    (header, rows)
}

/// Rows, the largest difference of the values, and whether any row has guard bits (8 and
/// up) in `filter_flags`; the flags must be equal row by row.
fn compare(reference: &Path, ours: &Path) -> (usize, f64, bool) {
    let (h1, r1) = read_csv(reference);
    let (h2, r2) = read_csv(ours);
    assert_eq!(h1, h2, "columns differ");
    assert_eq!(r1.len(), r2.len(), "row counts differ");
    let col = |name: &str| h1.iter().rposition(|c| c == name).unwrap();
    let mut worst = 0.0f64;
    let mut guard_bits = false;
    for (i, (a, b)) in r1.iter().zip(&r2).enumerate() {
        for name in ["torque", "ripple", "misalignment", "innovation", "nis"] {
            let j = col(name);
            let (x, y): (f64, f64) = (a[j].parse().unwrap(), b[j].parse().unwrap());
            assert!(x.is_finite() && y.is_finite(), "row {}: {name} {x} vs {y}", i + 1);
            worst = worst.max((x - y).abs());
        }
        let j = col("filter_flags");
        assert_eq!(a[j], b[j], "row {}: flags", i + 1);
        guard_bits |= a[j].parse::<u32>().unwrap() >> 8 != 0;
    }
    (r1.len(), worst, guard_bits)
}

#[test]
fn c_example_matches_filter_and_cpp_example_builds() {
    if !have("cc") || !have("c++") {
        eprintln!("skipped: no `cc` or `c++` on PATH (install gcc and g++ to run the C examples)");
        return;
    }
    let root = workspace();
    let (lib, cli) = build();
    let tmp = std::env::temp_dir().join(format!("strainwave-ffi-c-{}", std::process::id()));
    std::fs::create_dir_all(&tmp).unwrap();
    let recording = tmp.join("taghirad.csv");
    run(Command::new(&cli).args(["simulate", "--preset", "taghirad", "--duration", "5", "--out"]).arg(&recording));
    let include = root.join("include");
    // No contraction into fused multiply-adds: the channel scaling stays as Rust does it.
    let cc_flags = ["-std=c99", "-O2", "-Wall", "-Wextra", "-Werror", "-ffp-contract=off"];
    let libs = ["-lm", "-lpthread", "-ldl"];

    // The guard on (the default, as firmware runs it) for the learned full model, the full
    // model learning from zero (its cold start) and the paper's 6th-order model, and off
    // (`filter.guard = false`, the bare canceller).
    for (config, guard, learned) in [
        ("joint-taghirad.toml", true, true),
        ("joint-taghirad.toml", true, false),
        ("joint-taghirad.toml", false, true),
        ("joint-taghirad-6th-order.toml", true, false),
    ] {
        let kind = match (guard, learned) {
            (true, true) => "guarded",
            (true, false) => "guarded_cold",
            (false, _) => "bare",
        };
        let stem = format!("{}_{kind}", config.trim_end_matches(".toml"));
        // A copy of the config with its learned file named from the examples, for both
        // `export-c` and the reference `filter` run.
        let examples = root.join("examples");
        let mut text = std::fs::read_to_string(examples.join(config)).unwrap();
        if !learned {
            text = text.lines().filter(|l| !l.starts_with("learned =")).map(|l| format!("{l}\n")).collect();
        }
        let mut copy = text.replace("learned = \"", &format!("learned = \"{}/", examples.display()));
        if !guard {
            copy = copy.replace("[filter]\n", "[filter]\nguard = false\n");
        }
        let copy_config = tmp.join(format!("{stem}.toml"));
        std::fs::write(&copy_config, copy).unwrap();
        let model = tmp.join(format!("{stem}_model.h"));
        run(Command::new(&cli).arg("export-c").arg("--config").arg(&copy_config).arg("--out").arg(&model));
        let exported = std::fs::read_to_string(&model).unwrap();
        assert!(exported.contains(&format!(".off = {}", u8::from(!guard))), "{stem}: {exported}");
        let reference = tmp.join(format!("{stem}_filter.csv"));
        run(Command::new(&cli)
            .arg("filter")
            .arg("--config")
            .arg(&copy_config)
            .arg("--in")
            .arg(&recording)
            .arg("--out")
            .arg(&reference));
        let exe = tmp.join(format!("{stem}_filter_csv"));
        run(Command::new("cc")
            .args(cc_flags)
            .arg("-I")
            .arg(&include)
            .arg(format!("-DSW_MODEL_HEADER=\"{}\"", model.display()))
            .arg(root.join("examples/c/filter_csv.c"))
            .arg(&lib)
            .args(libs)
            .arg("-o")
            .arg(&exe));
        let ours = tmp.join(format!("{stem}_c.csv"));
        run(Command::new(&exe).arg(&recording).arg(&ours));
        let (rows, worst, guard_bits) = compare(&reference, &ours);
        eprintln!("{stem}: {rows} rows, largest difference C vs filter {worst:e} N·m");
        assert_eq!(rows, 5000);
        assert!(worst <= 1e-9, "{stem}: C example differs from filter by {worst:e} N·m");
        // The cold guarded run (no learned file) withholds its orders at first; the learned
        // one may apply them from the first sample; the bare runs have no guard bits.
        let cold = !text.lines().any(|l| l.trim_start().starts_with("learned ="));
        assert_eq!(guard_bits, guard && cold, "{stem}: guard bits in filter_flags");
    }

    // Single precision: the export compiles and its model passes sw32_init.
    let model32 = tmp.join("model32.h");
    run(Command::new(&cli)
        .args(["export-c", "--precision", "f32", "--name", "SW32_MODEL", "--config"])
        .arg(root.join("examples/joint-taghirad.toml"))
        .arg("--out")
        .arg(&model32));
    let check32 = tmp.join("check32.c");
    std::fs::write(
        &check32,
        "#include \"model32.h\"\nint main(void) {\n    static sw32_state s;\n    return sw32_init(&s, &SW32_MODEL);\n}\n",
    )
    .unwrap();
    // A C program against the header, the exported models in `tmp` and the library.
    let compile = |source: &Path, name: &str| {
        let exe = tmp.join(name);
        let mut cc = Command::new("cc");
        cc.args(cc_flags).arg("-I").arg(&include).arg("-I").arg(&tmp).arg(source).arg(&lib).args(libs);
        run(cc.arg("-o").arg(&exe));
        exe
    };
    run(&mut Command::new(compile(&check32, "check32")));

    // The instruction-count workload (docs/performance.md) builds and runs.
    std::fs::copy(tmp.join("joint-taghirad_guarded_model.h"), tmp.join("model.h")).unwrap();
    let out = run(Command::new(compile(&root.join("examples/c/step_loop.c"), "step_loop")).arg("2000"));
    assert!(out.contains("mean clean torque over 2000 steps"), "{out}");

    // The stack each call takes (the full model, guarded): `sw_init` builds the instance
    // in the caller's state, not beside it (a copy per order count took 90 kB before).
    let exe_stack = compile(&root.join("examples/c/stack_use.c"), "stack_use");
    let out = run(&mut Command::new(&exe_stack));
    eprintln!("{out}");
    let bytes = |call: &str| -> usize {
        let line = out.lines().find(|l| l.split_whitespace().next() == Some(call)).unwrap_or_else(|| panic!("{out}"));
        line.split_whitespace().nth(1).and_then(|b| b.parse().ok()).unwrap_or_else(|| panic!("{line}"))
    };
    let (state64, state32) = (std::mem::size_of::<sw_state>(), std::mem::size_of::<sw32_state>());
    for (call, limit) in [
        ("sw_init", 3 * state64),
        ("sw32_init", 3 * state32),
        ("sw_reset", state64),
        ("sw32_reset", state32),
        ("sw_step", state64),
        ("sw32_step", state32),
    ] {
        assert!(bytes(call) <= limit, "{call} takes {} bytes of stack (limit {limit}):\n{out}", bytes(call));
    }

    // The ros2_control wrapper, C++17, against the header and an exported model.
    let exe_cpp = tmp.join("hardware_interface_example");
    run(Command::new("c++")
        .args(["-std=c++17", "-O2", "-Wall", "-Wextra", "-Werror", "-I"])
        .arg(&include)
        .arg(format!("-DSW_MODEL_HEADER=\"{}\"", tmp.join("joint-taghirad_guarded_model.h").display()))
        .arg(root.join("examples/ros2_control/hardware_interface_example.cpp"))
        .arg(&lib)
        .args(["-lpthread", "-ldl"])
        .arg("-o")
        .arg(&exe_cpp));
    let out = run(&mut Command::new(&exe_cpp));
    assert!(out.contains("effort") && out.contains("after a NaN torque sample: level 1"), "{out}");
    std::fs::remove_dir_all(&tmp).unwrap();
}
