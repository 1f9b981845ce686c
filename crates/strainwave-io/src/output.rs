//! The one way every command writes a file: a temporary file of its own next to the
//! target, written, synced to disk, then renamed over the target. A reader of the target
//! sees the old content or the new, never a mix; a failed or interrupted run leaves the
//! old content in place.
//!
//! Temporary names are unique per process and per file (`.NAME.PID-N.strainwave-tmp`),
//! so two runs writing one target never share a temporary file. They are hidden and end
//! in [`TEMP_SUFFIX`], an extension no reader accepts, so one left behind by a killed run
//! is never taken for output. Live temporary files are registered, so that a signal
//! handler can remove them ([`remove_live_temps`]) before the process exits. One left by
//! a killed run is removed by a later run writing the same target, once certainly stale
//! (see [`STALE_TEMP_AGE`]).
//!
//! `-` is standard output for every writer here.

use std::fs::{File, OpenOptions};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Mutex;

use crate::error::IoError;

mod rollback;
mod stale;
pub use rollback::{restore_all, Rollback, MAX_ROLLBACK_BYTES};
pub use stale::STALE_TEMP_AGE;

/// The ending of every temporary file name.
pub const TEMP_SUFFIX: &str = ".strainwave-tmp";

/// Temporary files not yet renamed into place or removed.
static LIVE: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());
/// Distinguishes the temporary files of one process.
static COUNTER: AtomicU64 = AtomicU64::new(0);

fn live() -> std::sync::MutexGuard<'static, Vec<PathBuf>> {
    LIVE.lock().unwrap_or_else(|e| e.into_inner())
}

/// Whether `path` means standard output.
pub fn is_stdout(path: &Path) -> bool {
    path == Path::new("-")
}

/// Removes every live temporary file and returns with the registry locked, so that no
/// new one appears before the caller exits. For signal handlers.
pub fn remove_live_temps() -> std::sync::MutexGuard<'static, Vec<PathBuf>> {
    let mut files = live();
    for p in files.drain(..) {
        let _ = std::fs::remove_file(p);
    }
    files
}

/// A file being written under a temporary name; it replaces its target only on
/// [`AtomicFile::commit`], and is removed when dropped uncommitted.
pub struct AtomicFile {
    path: PathBuf,
    tmp: PathBuf,
    file: Option<File>,
}

impl AtomicFile {
    /// Creates the temporary file (mode 0600 until committed) in the target's directory.
    pub fn create(path: &Path) -> Result<Self, IoError> {
        let os = |source| IoError::Os { path: path.to_path_buf(), source };
        if path.is_dir() {
            return Err(IoError::IsDirectory(path.to_path_buf()));
        }
        let name = match path.file_name() {
            Some(n) => n.to_string_lossy().into_owned(),
            None => return Err(IoError::IsDirectory(path.to_path_buf())),
        };
        let dir = match path.parent() {
            Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
            _ => PathBuf::from("."),
        };
        let mut options = OpenOptions::new();
        options.write(true).create_new(true);
        #[cfg(unix)]
        std::os::unix::fs::OpenOptionsExt::mode(&mut options, 0o600);
        let pid = std::process::id();
        // The registry stays locked from creation to registration: a signal handler
        // never misses a file.
        let mut files = live();
        let mut last = None;
        for _ in 0..64 {
            let n = COUNTER.fetch_add(1, Ordering::Relaxed);
            let tmp = dir.join(format!(".{}.{pid}-{n}{TEMP_SUFFIX}", stale::temp_stem(&name)));
            match options.open(&tmp) {
                Ok(file) => {
                    files.push(tmp.clone());
                    return Ok(Self { path: path.to_path_buf(), tmp, file: Some(file) });
                }
                // A stale file of an earlier process with our pid: take the next number.
                Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => last = Some(e),
                Err(e) => return Err(os(e)),
            }
        }
        Err(os(last.unwrap_or_else(|| std::io::Error::other("no free temporary name"))))
    }

    /// The target path.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The temporary path.
    pub fn temp_path(&self) -> &Path {
        &self.tmp
    }

    /// A second handle on the temporary file (for a writer that owns its file).
    pub fn try_clone_file(&self) -> Result<File, IoError> {
        let r = match &self.file {
            Some(f) => f.try_clone(),
            None => Err(std::io::Error::other("already committed")),
        };
        r.map_err(|source| IoError::Os { path: self.path.clone(), source })
    }

    /// Syncs what was written to disk, so that a full disk shows here, before any
    /// output is replaced.
    pub fn sync(&mut self) -> Result<(), IoError> {
        let r = match &mut self.file {
            Some(f) => f.flush().and_then(|()| f.sync_all()),
            None => Ok(()),
        };
        r.map_err(|source| IoError::Os { path: self.path.clone(), source })
    }

    /// Syncs the data to disk, gives the file the target's permissions (or 0644 for a
    /// new one) and renames it over the target.
    pub fn commit(mut self) -> Result<(), IoError> {
        let os = |source| IoError::Os { path: self.path.clone(), source };
        let Some(mut file) = self.file.take() else { return Ok(()) };
        let synced = file.flush().and_then(|()| file.sync_all());
        if let Err(e) = synced {
            self.file = Some(file);
            return Err(os(e));
        }
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            let mode = std::fs::metadata(&self.path).map(|m| m.permissions().mode() & 0o7777).unwrap_or(0o644);
            let _ = file.set_permissions(std::fs::Permissions::from_mode(mode));
        }
        drop(file);
        let mut files = live();
        let renamed = std::fs::rename(&self.tmp, &self.path);
        files.retain(|p| p != &self.tmp);
        drop(files);
        if let Err(e) = renamed {
            let _ = std::fs::remove_file(&self.tmp);
            return Err(os(e));
        }
        // The rename itself reaches the disk with the directory (best effort).
        let dir = self.path.parent().filter(|d| !d.as_os_str().is_empty()).unwrap_or(Path::new("."));
        if let Ok(d) = File::open(dir) {
            let _ = d.sync_all();
        }
        if let Some(name) = self.path.file_name().and_then(|n| n.to_str()) {
            stale::remove_stale_temps(dir, name);
        }
        Ok(())
    }
}

impl Write for AtomicFile {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        match &mut self.file {
            Some(f) => f.write(buf),
            None => Err(std::io::Error::other("already committed")),
        }
    }

    fn flush(&mut self) -> std::io::Result<()> {
        match &mut self.file {
            Some(f) => f.flush(),
            None => Ok(()),
        }
    }
}

impl Drop for AtomicFile {
    fn drop(&mut self) {
        if self.file.take().is_some() {
            let mut files = live();
            let _ = std::fs::remove_file(&self.tmp);
            files.retain(|p| p != &self.tmp);
        }
    }
}

/// A text output: standard output for `-`, else an [`AtomicFile`].
pub enum Output {
    /// Standard output.
    Stdout(std::io::Stdout),
    /// A file, in place on [`Output::finish`].
    File(AtomicFile),
}

impl Output {
    /// Opens `path` for writing (`-`: standard output).
    pub fn create(path: &Path) -> Result<Self, IoError> {
        if is_stdout(path) {
            Ok(Self::Stdout(std::io::stdout()))
        } else {
            AtomicFile::create(path).map(Self::File)
        }
    }

    /// Flushes standard output, or commits the file.
    pub fn finish(self, path: &Path) -> Result<(), IoError> {
        match self {
            Self::Stdout(mut out) => out.flush().map_err(|source| IoError::Os { path: path.to_path_buf(), source }),
            Self::File(f) => f.commit(),
        }
    }
}

impl Write for Output {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        match self {
            Self::Stdout(o) => o.write(buf),
            Self::File(f) => f.write(buf),
        }
    }

    fn flush(&mut self) -> std::io::Result<()> {
        match self {
            Self::Stdout(o) => o.flush(),
            Self::File(f) => f.flush(),
        }
    }
}

/// Writes `bytes` to `path` (`-`: standard output) through a temporary file.
pub fn write_file(path: &Path, bytes: impl AsRef<[u8]>) -> Result<(), IoError> {
    let mut out = Output::create(path)?;
    out.write_all(bytes.as_ref()).map_err(|source| IoError::Os { path: path.to_path_buf(), source })?;
    out.finish(path)
}

/// Whether two paths name one existing file (same device and inode on Unix, same
/// canonical path elsewhere).
pub fn same_file(a: &Path, b: &Path) -> bool {
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        match (std::fs::metadata(a), std::fs::metadata(b)) {
            (Ok(x), Ok(y)) => x.dev() == y.dev() && x.ino() == y.ino(),
            _ => false,
        }
    }
    #[cfg(not(unix))]
    {
        match (std::fs::canonicalize(a), std::fs::canonicalize(b)) {
            (Ok(x), Ok(y)) => x == y,
            _ => false,
        }
    }
}

/// Refuses an output that is one of the inputs (through any spelling or link), or that
/// lies inside an input folder (a rosbag2 bag: its files are the input).
pub fn refuse_input_as_output<'a>(output: &Path, inputs: impl IntoIterator<Item = &'a Path>) -> Result<(), IoError> {
    if is_stdout(output) {
        return Ok(());
    }
    // The output's folder as the file system resolves it (the output may not exist yet).
    let folder = output.parent().map(|p| if p.as_os_str().is_empty() { Path::new(".") } else { p });
    let folder = folder.and_then(|p| std::fs::canonicalize(p).ok());
    for input in inputs {
        if is_stdout(input) {
            continue;
        }
        if same_file(output, input) {
            return Err(IoError::OutputIsInput { output: output.to_path_buf(), input: input.to_path_buf() });
        }
        let inside = |f: &PathBuf| is_bag_folder(input) && std::fs::canonicalize(input).is_ok_and(|d| f.starts_with(d));
        if folder.as_ref().is_some_and(inside) {
            return Err(IoError::OutputInInputFolder { output: output.to_path_buf(), input: input.to_path_buf() });
        }
    }
    Ok(())
}

/// Whether `path` is a folder a reader takes as a rosbag2 bag: it holds `metadata.yaml`
/// or `.mcap` / `.db3` files.
fn is_bag_folder(path: &Path) -> bool {
    let bag_file = |p: &Path| {
        p.file_name().is_some_and(|n| n == "metadata.yaml")
            || p.extension().is_some_and(|e| e.eq_ignore_ascii_case("mcap") || e.eq_ignore_ascii_case("db3"))
    };
    std::fs::read_dir(path).is_ok_and(|entries| entries.flatten().any(|e| bag_file(&e.path())))
}

/// Refuses two outputs of one run that name one file, existing or not (`(flag, path)`
/// pairs; standard output may be named more than once).
pub fn refuse_shared_outputs<'a>(outputs: impl IntoIterator<Item = (&'a str, &'a Path)>) -> Result<(), IoError> {
    let outputs: Vec<(&str, &Path)> = outputs.into_iter().filter(|(_, p)| !is_stdout(p)).collect();
    let absolute = |p: &Path| std::path::absolute(p).ok();
    for (k, &(second, path)) in outputs.iter().enumerate() {
        for &(first, earlier) in &outputs[..k] {
            if earlier == path || same_file(earlier, path) || absolute(earlier) == absolute(path) {
                return Err(IoError::OutputsShareFile {
                    path: path.to_path_buf(),
                    first: first.to_string(),
                    second: second.to_string(),
                });
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn dir(tag: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("sw-out-{tag}-{}", std::process::id()));
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    fn names(d: &Path) -> Vec<String> {
        let mut v: Vec<String> =
            std::fs::read_dir(d).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect();
        v.sort();
        v
    }

    #[test]
    fn an_output_inside_an_input_folder_is_refused() {
        let d = dir("bag");
        let bag = d.join("bag");
        std::fs::create_dir_all(bag.join("sub")).unwrap();
        std::fs::write(bag.join("bag_0.mcap"), b"x").unwrap();
        for out in [bag.join("bag_0.mcap"), bag.join("new.csv"), bag.join("sub/new.csv"), bag.join("../bag/x.csv")] {
            let e = refuse_input_as_output(&out, [bag.as_path()]).unwrap_err().to_string();
            assert!(e.contains("is inside the input folder"), "{e}");
        }
        refuse_input_as_output(&d.join("beside.csv"), [bag.as_path()]).unwrap();
        // A file input: only that file is refused, not its folder.
        let file = d.join("rec.csv");
        std::fs::write(&file, b"x").unwrap();
        refuse_input_as_output(&d.join("other.csv"), [file.as_path()]).unwrap();
        assert!(refuse_input_as_output(&file, [file.as_path()]).is_err());
        std::fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn two_writers_of_one_target_use_two_temporary_files() {
        let d = dir("two");
        let p = d.join("a.txt");
        let mut a = AtomicFile::create(&p).unwrap();
        let mut b = AtomicFile::create(&p).unwrap();
        assert_ne!(a.temp_path(), b.temp_path());
        a.write_all(b"first\n").unwrap();
        b.write_all(b"second\n").unwrap();
        a.commit().unwrap();
        assert_eq!(std::fs::read_to_string(&p).unwrap(), "first\n");
        b.commit().unwrap();
        assert_eq!(std::fs::read_to_string(&p).unwrap(), "second\n");
        assert_eq!(names(&d), ["a.txt"]);
        std::fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn dropped_uncommitted_leaves_the_old_content_and_no_temporary() {
        let d = dir("drop");
        let p = d.join("b.txt");
        std::fs::write(&p, "old").unwrap();
        let mut a = AtomicFile::create(&p).unwrap();
        a.write_all(b"new, half written").unwrap();
        assert!(live().contains(&a.temp_path().to_path_buf()));
        let tmp = a.temp_path().to_path_buf();
        assert!(tmp.file_name().unwrap().to_string_lossy().starts_with(".b.txt."));
        drop(a);
        assert!(!live().contains(&tmp));
        assert_eq!(std::fs::read_to_string(&p).unwrap(), "old");
        assert_eq!(names(&d), ["b.txt"]);
        std::fs::remove_dir_all(&d).unwrap();
    }

    #[cfg(unix)]
    #[test]
    fn temporary_is_private_and_the_target_keeps_its_mode() {
        use std::os::unix::fs::PermissionsExt;
        let d = dir("mode");
        let p = d.join("c.txt");
        std::fs::write(&p, "old").unwrap();
        std::fs::set_permissions(&p, std::fs::Permissions::from_mode(0o640)).unwrap();
        let a = AtomicFile::create(&p).unwrap();
        assert_eq!(std::fs::metadata(a.temp_path()).unwrap().permissions().mode() & 0o777, 0o600);
        a.commit().unwrap();
        assert_eq!(std::fs::metadata(&p).unwrap().permissions().mode() & 0o777, 0o640);
        std::fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn two_outputs_naming_one_file_are_refused_existing_or_not() {
        let d = dir("shared");
        let (a, b) = (d.join("m.toml"), d.join("s.json"));
        let again = d.join(".").join("m.toml");
        let e = refuse_shared_outputs([("--out", a.as_path()), ("--summary-json", again.as_path())])
            .unwrap_err()
            .to_string();
        assert!(e.contains("named by both --out and --summary-json"), "{e}");
        assert!(refuse_shared_outputs([("--out", a.as_path()), ("--summary-json", b.as_path())]).is_ok());
        assert!(refuse_shared_outputs([("--out", Path::new("-")), ("--plot", Path::new("-"))]).is_ok());
        std::fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn an_input_under_another_name_is_refused_as_output() {
        let d = dir("same");
        let p = d.join("in.csv");
        std::fs::write(&p, "time\n0\n").unwrap();
        let other = d.join(".").join("in.csv");
        let e = refuse_input_as_output(&other, [p.as_path()]).unwrap_err().to_string();
        assert!(e.contains("is also an input"), "{e}");
        assert!(refuse_input_as_output(&d.join("out.csv"), [p.as_path()]).is_ok());
        assert!(refuse_input_as_output(Path::new("-"), [Path::new("-")]).is_ok());
        std::fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn a_missing_directory_is_an_error_naming_the_target() {
        let e = write_file(Path::new("/nonexistent-dir-sw/x.txt"), "x").unwrap_err().to_string();
        assert!(e.starts_with("/nonexistent-dir-sw/x.txt: "), "{e}");
    }
}
