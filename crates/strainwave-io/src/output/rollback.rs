//! A file that several steps of one run replace in turn (`filter --learn` over several
//! recordings merges each into its learned file) is put back as it was when a later step
//! fails or the run is interrupted: the run changes it as a whole or not at all.

use std::path::{Path, PathBuf};
use std::sync::Mutex;

use crate::error::IoError;

/// Largest file kept for putting back, bytes (a learned file is a few kilobytes).
pub const MAX_ROLLBACK_BYTES: u64 = 64 << 20;

/// The files to put back, with what they held (`None`: they did not exist).
static ARMED: Mutex<Vec<(PathBuf, Option<Vec<u8>>)>> = Mutex::new(Vec::new());

fn armed() -> std::sync::MutexGuard<'static, Vec<(PathBuf, Option<Vec<u8>>)>> {
    ARMED.lock().unwrap_or_else(|e| e.into_inner())
}

/// `path` as it was when armed; put back when dropped before [`Rollback::keep`], or by
/// [`restore_all`] on an interrupt.
pub struct Rollback {
    path: PathBuf,
}

impl Rollback {
    /// Remembers what `path` holds now (or that it does not exist).
    pub fn arm(path: &Path) -> Result<Self, IoError> {
        let os = |source| IoError::Os { path: path.to_path_buf(), source };
        let before = match std::fs::metadata(path) {
            Ok(m) if m.len() > MAX_ROLLBACK_BYTES => {
                let why = format!("larger than {MAX_ROLLBACK_BYTES} bytes: not a file this run can keep a copy of");
                return Err(os(std::io::Error::other(why)));
            }
            Ok(_) => Some(std::fs::read(path).map_err(os)?),
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => None,
            Err(e) => return Err(os(e)),
        };
        armed().push((path.to_path_buf(), before));
        Ok(Self { path: path.to_path_buf() })
    }

    /// The run succeeded: the file stays as the run left it.
    pub fn keep(self) {
        armed().retain(|(p, _)| p != &self.path);
        std::mem::forget(self);
    }
}

impl Drop for Rollback {
    fn drop(&mut self) {
        let mut files = armed();
        if let Some(at) = files.iter().position(|(p, _)| p == &self.path) {
            let (path, before) = files.remove(at);
            put_back(&path, before.as_deref());
        }
    }
}

/// Puts every armed file back (best effort). For signal handlers.
pub fn restore_all() {
    for (path, before) in armed().drain(..) {
        put_back(&path, before.as_deref());
    }
}

/// Puts `path` back (best effort): the old bytes written beside it and renamed over it, or
/// the file removed. Not through [`super::AtomicFile`]: a signal handler calls this with
/// the registry of temporary files locked, which also holds back the run's own renames.
fn put_back(path: &Path, before: Option<&[u8]>) {
    let Some(bytes) = before else {
        let _ = std::fs::remove_file(path);
        return;
    };
    let name = path.file_name().map(|n| super::stale::temp_stem(&n.to_string_lossy()).to_string());
    let tmp = path.with_file_name(format!(
        ".{}.{}-rollback{}",
        name.unwrap_or_default(),
        std::process::id(),
        super::TEMP_SUFFIX
    ));
    if std::fs::write(&tmp, bytes).and_then(|()| std::fs::rename(&tmp, path)).is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_file_is_put_back_unless_kept() {
        let d = std::env::temp_dir().join(format!("sw-rollback-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        let (old, new) = (d.join("old.toml"), d.join("new.toml"));
        std::fs::write(&old, "a = 1\n").unwrap();
        let (r_old, r_new) = (Rollback::arm(&old).unwrap(), Rollback::arm(&new).unwrap());
        std::fs::write(&old, "a = 2\n").unwrap();
        std::fs::write(&new, "b = 1\n").unwrap();
        drop((r_old, r_new));
        assert_eq!(std::fs::read_to_string(&old).unwrap(), "a = 1\n");
        assert!(!new.exists(), "created by the run: removed");
        let kept = Rollback::arm(&old).unwrap();
        std::fs::write(&old, "a = 3\n").unwrap();
        kept.keep();
        assert_eq!(std::fs::read_to_string(&old).unwrap(), "a = 3\n");
        std::fs::remove_dir_all(&d).unwrap();
    }
}
