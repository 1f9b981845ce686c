//! Interrupts and closed pipes end a run the way the shell expects, leaving nothing
//! behind: on SIGINT, SIGTERM or SIGHUP (the terminal closed) the temporary files of
//! outputs not yet in place are removed and the process exits with 128 + the signal
//! (130, 143, 129); a write to a closed
//! pipe (`strainwave … --out - | head`) ends the run quietly with 141, as SIGPIPE would.
//! A write beyond the file size limit (`ulimit -f`) fails as a full disk does, with the
//! error and the cleanup, instead of SIGXFSZ killing the process over its temporary file.

use signal_hook::consts::{SIGHUP, SIGINT, SIGTERM, SIGXFSZ};

/// Exit status of a run cut short by a closed pipe (128 + SIGPIPE).
pub const BROKEN_PIPE_EXIT: u8 = 141;

/// Starts the thread that waits for SIGINT, SIGTERM and SIGHUP. Without it (if the handler cannot
/// be installed) the default action still ends the process; only the cleanup is lost.
pub fn install() {
    // Any handler replaces SIGXFSZ's default action (terminate): the write then returns
    // EFBIG, which the run reports and cleans up after. The flag itself is not read.
    let _ = signal_hook::flag::register(SIGXFSZ, std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false)));
    let Ok(mut signals) = signal_hook::iterator::Signals::new([SIGINT, SIGTERM, SIGHUP]) else { return };
    let _ = std::thread::Builder::new().name("signals".into()).spawn(move || {
        if let Some(sig) = signals.forever().next() {
            // Held until exit: no new temporary file appears after the cleanup.
            let _registry = strainwave_io::output::remove_live_temps();
            // With the registry held, the run renames nothing over what is put back.
            strainwave_io::output::restore_all();
            std::process::exit(128 + sig);
        }
    });
}

/// Whether an error was caused by writing to a closed pipe.
pub fn is_broken_pipe(e: &anyhow::Error) -> bool {
    e.chain().any(|c| c.downcast_ref::<std::io::Error>().is_some_and(|io| io.kind() == std::io::ErrorKind::BrokenPipe))
}
