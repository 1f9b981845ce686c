//! Messages on standard error that never stop a run: with stderr closed (`2>&1 | head`)
//! or full, a message is lost, not the run's outputs (`eprintln!` would panic there).

use std::io::Write;

/// `eprintln!` that ignores a failed write.
macro_rules! note {
    ($($arg:tt)*) => {
        $crate::stderr::write(format_args!("{}\n", format_args!($($arg)*)))
    };
}

/// Writes `text` to standard error; a failure is ignored (there is nowhere to report it).
pub fn write(text: std::fmt::Arguments<'_>) {
    let _ = std::io::stderr().lock().write_fmt(text);
}
