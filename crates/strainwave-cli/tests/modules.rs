//! No command module imports another: what two commands share lives in its own module
//! (`recording_args.rs`, `progress.rs`, `signals.rs`, `stdout.rs`, `report/`).

use std::path::{Path, PathBuf};

/// Every `.rs` file under `dir`.
fn sources(dir: &Path, into: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            sources(&path, into);
        } else if path.extension().is_some_and(|e| e == "rs") {
            into.push(path);
        }
    }
}

/// The command a source file belongs to (`cmd_filter.rs` and `cmd_filter/…` are
/// `cmd_filter`), if any.
fn command_of(src: &Path, file: &Path) -> Option<String> {
    let first = file.strip_prefix(src).ok()?.components().next()?;
    let name = first.as_os_str().to_string_lossy();
    name.starts_with("cmd_").then(|| name.trim_end_matches(".rs").to_string())
}

/// The command modules a source names through `crate::`.
fn commands_named(source: &str) -> Vec<String> {
    source
        .match_indices("crate::cmd_")
        .map(|(at, _)| {
            let rest = &source[at + "crate::".len()..];
            rest.chars().take_while(|c| c.is_ascii_alphanumeric() || *c == '_').collect()
        })
        .collect()
}

#[test]
fn no_command_module_imports_another() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files = Vec::new();
    sources(&src, &mut files);
    let mut checked = 0;
    for file in &files {
        let Some(own) = command_of(&src, file) else { continue };
        checked += 1;
        for named in commands_named(&std::fs::read_to_string(file).unwrap()) {
            assert_eq!(named, own, "{} names {named}", file.display());
        }
    }
    assert!(checked >= 14, "the command modules were found ({checked})");
}

#[test]
fn the_check_sees_a_command_naming_another() {
    assert_eq!(commands_named("use crate::cmd_filter::Args;\nuse crate::stdout;"), ["cmd_filter"]);
}
