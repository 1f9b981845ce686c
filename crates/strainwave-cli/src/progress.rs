//! A progress line on stderr for work longer than about a second: rows, rate and time
//! left (when the total is known). Hidden when stderr is not a terminal or with --quiet.

use std::io::IsTerminal;
use std::time::{Duration, Instant};

/// Progress of one command.
pub struct Progress {
    bar: Option<indicatif::ProgressBar>,
    start: Instant,
}

impl Progress {
    /// A progress display for `what`; `total` rows when known.
    pub fn new(what: &str, quiet: bool, total: Option<u64>) -> Self {
        let show = !quiet && std::io::stderr().is_terminal();
        let bar = show.then(|| {
            let b = match total {
                Some(n) => indicatif::ProgressBar::new(n),
                None => indicatif::ProgressBar::new_spinner(),
            };
            let style = match total {
                Some(_) => "{msg} [{bar:30}] {pos}/{len} rows, {per_sec}, {eta} left",
                None => "{msg} {pos} rows, {per_sec}",
            };
            b.set_style(
                indicatif::ProgressStyle::with_template(style)
                    .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
            );
            b.set_message(what.to_string());
            // Appear only after a second of work.
            b.set_draw_target(indicatif::ProgressDrawTarget::hidden());
            b
        });
        Self { bar, start: Instant::now() }
    }

    /// Rows done so far.
    pub fn set(&self, rows: u64) {
        if let Some(b) = &self.bar {
            if b.is_hidden() && self.start.elapsed() > Duration::from_secs(1) {
                b.set_draw_target(indicatif::ProgressDrawTarget::stderr());
            }
            b.set_position(rows);
        }
    }

    /// Clears the line.
    pub fn finish(&self) {
        if let Some(b) = &self.bar {
            b.finish_and_clear();
        }
    }
}
