//! Writing to standard output without panicking when the reader goes away
//! (`strainwave demo | head`): a broken pipe ends the output quietly.

use std::io::Write;
use std::path::Path;

/// Writes `text` to standard output; a closed pipe is not an error.
pub fn print(text: &str) -> anyhow::Result<()> {
    let mut out = std::io::stdout().lock();
    match out.write_all(text.as_bytes()).and_then(|()| out.flush()) {
        Err(e) if e.kind() != std::io::ErrorKind::BrokenPipe => Err(anyhow::anyhow!("standard output: {e}")),
        _ => Ok(()),
    }
}

/// Prints a command's report: on standard output, or on standard error where one of the
/// command's `outputs` is standard output (`-`), so that the file written there (an SVG,
/// a TOML) is not mixed with the report.
pub fn print_report<'a>(text: &str, outputs: impl IntoIterator<Item = Option<&'a Path>>) -> anyhow::Result<()> {
    if outputs.into_iter().flatten().any(strainwave_io::output::is_stdout) {
        crate::stderr::write(format_args!("{text}"));
        return Ok(());
    }
    print(text)
}
