//! The canceller's files import only downwards (see `docs/design.md`): a file may use
//! the ones listed before it, never one after it, so there is no cycle to untangle.

use std::path::Path;

/// `ripple/`'s files, lowest layer first.
const LAYERS: [&str; 9] = ["io", "trig", "trace", "model", "presets", "bank", "kernel", "filter", "snapshot"];

/// The sibling modules a file names through `super::`, outside its tests.
fn siblings_used(source: &str) -> Vec<String> {
    let code = source.split("#[cfg(test)]").next().unwrap_or("");
    let mut used = Vec::new();
    for (at, _) in code.match_indices("super::") {
        let rest = &code[at + "super::".len()..];
        let name: String = rest.chars().take_while(|c| c.is_ascii_alphanumeric() || *c == '_').collect();
        if !name.is_empty() && !used.contains(&name) {
            used.push(name);
        }
    }
    used
}

#[test]
fn ripple_files_import_only_downwards() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("src/ripple");
    let mut files: Vec<String> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().trim_end_matches(".rs").to_string())
        .filter(|n| n != "mod")
        .collect();
    files.sort();
    let mut listed: Vec<String> = LAYERS.iter().map(|s| s.to_string()).collect();
    listed.sort();
    assert_eq!(files, listed, "every file of ripple/ has its place in LAYERS");
    for (level, name) in LAYERS.iter().enumerate() {
        let source = std::fs::read_to_string(dir.join(format!("{name}.rs"))).unwrap();
        for used in siblings_used(&source) {
            let Some(other) = LAYERS.iter().position(|l| *l == used) else { continue };
            assert!(other < level, "ripple/{name}.rs uses {used}, a layer at or above its own");
        }
    }
}

#[test]
fn the_layer_check_sees_an_upward_import() {
    let source = "use super::io::StepFlags;\nuse super::kernel::run;\n#[cfg(test)]\nmod tests { use super::snapshot; }";
    assert_eq!(siblings_used(source), ["io", "kernel"]);
}
