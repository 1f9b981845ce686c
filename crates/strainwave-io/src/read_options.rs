//! How recordings are read: topics, clock and alignment of logs, the delimiter of text.
//! The command line sets one [`ReadOptions`] for the process
//! ([`set_default_read_options`]); every reader opened with
//! [`crate::RecordingReader::open`] uses it.

use std::sync::OnceLock;

pub use crate::ros2::align::Align;

/// Which time a log message is placed at.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum TimeSource {
    /// `header.stamp` where the message has a header (and it is set), else the log time.
    #[default]
    Header,
    /// The time the recorder received the message.
    Log,
}

/// Options of every reader.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ReadOptions {
    /// Log topics to read (empty: all).
    pub topics: Vec<String>,
    /// Message time.
    pub time: TimeSource,
    /// How columns of different topics meet on one clock.
    pub align: Align,
    /// Beyond this gap between a column's samples its value is NaN, s (default: 4 mean
    /// periods of its topic, at most 10 s).
    pub max_gap_s: Option<f64>,
    /// A uniform clock at this rate, Hz (default: the fastest topic's message times;
    /// for tables: rows are interpolated linearly onto it).
    pub resample_hz: Option<f64>,
    /// Delimiter of text tables (default: detected from the header line).
    pub delimiter: Option<u8>,
    /// A table's time column (default: `time`): read in seconds, and the clock of
    /// `resample_hz`.
    pub time_column: Option<String>,
    /// [`crate::RecordingReader::open`] prints the reader's warnings to standard error.
    pub print_warnings: bool,
    /// A text table's cells that are not numbers are read as NaN, counted in one warning
    /// at the end, instead of stopping the read (`filter --lenient`).
    pub unreadable_as_nan: bool,
}

static DEFAULT: OnceLock<ReadOptions> = OnceLock::new();

/// Sets the options [`crate::RecordingReader::open`] uses; only the first call counts.
pub fn set_default_read_options(options: ReadOptions) -> bool {
    DEFAULT.set(options).is_ok()
}

/// The options set by [`set_default_read_options`], or the defaults.
pub fn default_read_options() -> ReadOptions {
    DEFAULT.get().cloned().unwrap_or_default()
}
