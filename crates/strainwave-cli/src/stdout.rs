//! Writing to standard output without panicking when the reader goes away
//! (`strainwave demo | head`): a broken pipe ends the output quietly.

use std::io::Write;

/// Writes `text` to standard output; a closed pipe is not an error.
pub fn print(text: &str) -> anyhow::Result<()> {
    let mut out = std::io::stdout().lock();
    match out.write_all(text.as_bytes()).and_then(|()| out.flush()) {
        Err(e) if e.kind() != std::io::ErrorKind::BrokenPipe => Err(anyhow::anyhow!("standard output: {e}")),
        _ => Ok(()),
    }
}
