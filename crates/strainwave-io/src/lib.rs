//! Recordings for strainwave: CSV reading (streamed in chunks) and writing (atomic),
//! with errors that name the file, row and column.
//!
//! A recording is a table with a header: a `time` column in seconds and one column per
//! signal in SI units. Simulated recordings add `true_*` columns.

pub mod channels;
pub mod csv_io;
pub mod error;
pub mod guard;
#[cfg(feature = "mcap")]
pub mod mcap_in;
#[cfg(feature = "mcap")]
pub mod mcap_out;
pub mod output;
#[cfg(feature = "parquet")]
pub mod parquet_io;
pub mod read_options;
pub mod recording;
pub mod resample;
pub mod ros2;
pub mod time_axis;
mod time_unit;

pub use channels::{BoundChannel, Channel, ChannelTable};
pub use csv_io::{read_table, CsvReader, CsvWriter, Table, TextOptions, DEFAULT_CHUNK_ROWS};
pub use error::IoError;
pub use read_options::{default_read_options, set_default_read_options, ReadOptions, TimeSource};
pub use recording::{
    format_of, interpolated_by, read_all, read_all_with_time, row_label, row_name, Format, RecordingReader,
    RecordingWriter, MAX_TABLE_VALUES,
};
pub use time_axis::{TimeEvent, TimeMonitor};
