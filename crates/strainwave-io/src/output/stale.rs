//! Temporary files left by killed runs (SIGKILL, a crash, a power cut: nothing of the
//! run could remove them), removed by a later run that writes the same target.
//!
//! Only a file that is certainly stale goes: named as [`super::AtomicFile`] names the
//! target's temporary files (`.NAME.PID-N.strainwave-tmp`), of a process that no longer
//! runs, and unchanged for [`STALE_TEMP_AGE`]. The process check reads `/proc` (Linux);
//! where there is none, nothing is removed. The age covers a writer alive in another
//! PID namespace (a container sharing the directory), which `/proc` cannot see.

use std::path::Path;
use std::time::Duration;

use super::TEMP_SUFFIX;

/// How long another process's temporary file must have been left unchanged before a
/// later run removes it (its process gone).
pub const STALE_TEMP_AGE: Duration = Duration::from_secs(600);

/// Longest target name kept whole in its temporary files' names, bytes: with the rest
/// of the name (at most 48 bytes) it stays within the usual limit of 255.
const MAX_STEM_BYTES: usize = 200;

/// The target name `name` as its temporary files carry it: cut to [`MAX_STEM_BYTES`] (at a
/// character boundary), so that a target with a long valid name gets a valid one too.
pub(super) fn temp_stem(name: &str) -> &str {
    let mut end = name.len().min(MAX_STEM_BYTES);
    while !name.is_char_boundary(end) {
        end -= 1;
    }
    &name[..end]
}

/// The process id in a temporary file name of target `name`
/// (`.NAME.PID-N.strainwave-tmp`), or `None` for any other file.
fn temp_pid(file: &str, name: &str) -> Option<u32> {
    let stem = temp_stem(name);
    let mid = file.strip_prefix('.')?.strip_prefix(stem)?.strip_prefix('.')?.strip_suffix(TEMP_SUFFIX)?;
    let (pid, n) = mid.split_once('-')?;
    let digits = |s: &str| !s.is_empty() && s.bytes().all(|b| b.is_ascii_digit());
    (digits(pid) && digits(n)).then(|| pid.parse().ok()).flatten()
}

/// Removes the stale temporary files of target `name` in `dir` (best effort: a file
/// that cannot be read or removed is left).
pub fn remove_stale_temps(dir: &Path, name: &str) {
    let proc_dir = Path::new("/proc");
    if !proc_dir.join("self").exists() {
        return;
    }
    let Ok(entries) = std::fs::read_dir(dir) else { return };
    let own = std::process::id();
    for e in entries.flatten() {
        let Some(pid) = e.file_name().to_str().and_then(|f| temp_pid(f, name)) else { continue };
        if pid == own || proc_dir.join(pid.to_string()).exists() {
            continue;
        }
        let Ok(meta) = e.metadata() else { continue };
        let age = meta.modified().ok().and_then(|t| t.elapsed().ok());
        if meta.is_file() && age.is_some_and(|a| a >= STALE_TEMP_AGE) {
            let _ = std::fs::remove_file(e.path());
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_this_targets_temporary_names_are_recognised() {
        assert_eq!(temp_pid(".run.csv.123-4.strainwave-tmp", "run.csv"), Some(123));
        assert_eq!(temp_pid(".run.csv.5.123-4.strainwave-tmp", "run.csv"), None, "target run.csv.5");
        assert_eq!(temp_pid(".run.csv.123-4.strainwave-tmp", "run"), None, "target run");
        assert_eq!(temp_pid(".run.csv.123-.strainwave-tmp", "run.csv"), None);
        assert_eq!(temp_pid(".run.csv.x-4.strainwave-tmp", "run.csv"), None);
        assert_eq!(temp_pid(".run.csv.123-4.partial", "run.csv"), None);
        assert_eq!(temp_pid("run.csv", "run.csv"), None);
        // A long name is cut in its temporaries' names, at a character boundary.
        let long = "é".repeat(150);
        let stem = temp_stem(&long);
        assert_eq!((stem.len(), stem.chars().count()), (200, 100));
        assert_eq!(temp_pid(&format!(".{stem}.7-0.strainwave-tmp"), &long), Some(7));
    }

    #[cfg(target_os = "linux")]
    #[test]
    fn a_later_commit_removes_old_temporaries_of_dead_processes_only() {
        use std::io::Write;
        let d = std::env::temp_dir().join(format!("sw-out-stale-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        // No process has pid 4294967294 (above any pid_max); pid 1 always runs.
        let dead_old = d.join(".t.csv.4294967294-0.strainwave-tmp");
        let dead_new = d.join(".t.csv.4294967294-1.strainwave-tmp");
        let live_old = d.join(".t.csv.1-0.strainwave-tmp");
        let other_target = d.join(".u.csv.4294967294-0.strainwave-tmp");
        let old = std::time::SystemTime::now() - STALE_TEMP_AGE - Duration::from_secs(1);
        for p in [&dead_old, &dead_new, &live_old, &other_target] {
            let f = std::fs::File::create(p).unwrap();
            if p != &dead_new {
                f.set_modified(old).unwrap();
            }
        }
        let mut a = super::super::AtomicFile::create(&d.join("t.csv")).unwrap();
        a.write_all(b"time\n0\n").unwrap();
        a.commit().unwrap();
        assert!(!dead_old.exists());
        assert!(dead_new.exists() && live_old.exists() && other_target.exists());
        std::fs::remove_dir_all(&d).unwrap();
    }
}
