//! MCAP output: each column but `time` becomes a topic of `std_msgs/msg/Float64` (CDR,
//! `ros2msg` schema), so Foxglove and PlotJuggler overlay it on the original bag.
//!
//! A column `j1.torque_filtered` is the topic `/strainwave/j1/torque_filtered`: `.` becomes
//! `/` and any character outside `[A-Za-z0-9_/]` becomes `_`, under `/strainwave`. Each
//! row gives one message per column at log and publish time `round(time · 10⁹)` ns; a NaN
//! gives no message. The file is chunked (zstd) and indexed; it is written to a
//! temporary file of its own ([`crate::output::AtomicFile`]) and appears under its name,
//! synced, only on [`McapWriter::finish`].

use std::collections::BTreeMap;
use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};

use crate::error::IoError;
use crate::output::AtomicFile;

/// The message type of every column topic.
pub const COLUMN_SCHEMA: &str = "std_msgs/msg/Float64";
/// Its `ros2msg` definition.
const COLUMN_DEFINITION: &[u8] = b"float64 data\n";

/// The topic a column is written on.
pub fn column_topic(column: &str) -> String {
    let mut topic = String::from("/strainwave/");
    for c in column.chars() {
        topic.push(match c {
            '.' | '/' => '/',
            c if c.is_ascii_alphanumeric() || c == '_' => c,
            _ => '_',
        });
    }
    // No empty segments (`a..b`, a leading `/` in the column).
    while topic.contains("//") {
        topic = topic.replace("//", "/");
    }
    topic.trim_end_matches('/').to_string()
}

/// An error of the `mcap` writer; an I/O error (a full disk) says what the system said.
fn mcap_err(path: &Path, e: mcap::McapError) -> IoError {
    match e {
        mcap::McapError::Io(source) => IoError::Os { path: path.to_path_buf(), source },
        e => IoError::Csv { path: path.to_path_buf(), msg: format!("MCAP: {e}") },
    }
}

/// MCAP writer of a recording.
pub struct McapWriter {
    path: PathBuf,
    writer: Option<mcap::Writer<BufWriter<File>>>,
    /// The temporary file the writer writes through a second handle (declared after
    /// `writer`, so dropped after it: an unfinished file is removed last).
    tmp: Option<AtomicFile>,
    time_index: usize,
    /// Channel of each column (`None` for `time`).
    channels: Vec<Option<u16>>,
    sequence: u32,
    rows: u64,
}

impl McapWriter {
    /// Creates the file; `columns` must hold `time`.
    pub fn create(path: &Path, columns: &[&str]) -> Result<Self, IoError> {
        let Some(time_index) = columns.iter().position(|c| *c == "time") else {
            return Err(IoError::MissingColumn {
                path: path.to_path_buf(),
                column: "time".into(),
                available: format!("{} (MCAP output needs a `time` column, s)", columns.join(", ")),
            });
        };
        let tmp = AtomicFile::create(path)?;
        let file = tmp.try_clone_file()?;
        let mut w = mcap::WriteOptions::new()
            .compression(Some(mcap::Compression::Zstd))
            .profile("ros2")
            .create(BufWriter::new(file))
            .map_err(|e| mcap_err(path, e))?;
        let schema = w.add_schema(COLUMN_SCHEMA, "ros2msg", COLUMN_DEFINITION).map_err(|e| mcap_err(path, e))?;
        let mut channels = Vec::with_capacity(columns.len());
        let mut topics: Vec<String> = Vec::new();
        for (i, c) in columns.iter().enumerate() {
            if i == time_index {
                channels.push(None);
                continue;
            }
            let mut topic = column_topic(c);
            if topics.contains(&topic) {
                topic = format!("{topic}_{i}");
            }
            let id = w.add_channel(schema, &topic, "cdr", &BTreeMap::new()).map_err(|e| mcap_err(path, e))?;
            topics.push(topic);
            channels.push(Some(id));
        }
        Ok(Self {
            path: path.to_path_buf(),
            writer: Some(w),
            tmp: Some(tmp),
            time_index,
            channels,
            sequence: 0,
            rows: 0,
        })
    }

    /// Writes one row.
    pub fn write_row(&mut self, row: &[f64]) -> Result<(), IoError> {
        if row.len() != self.channels.len() {
            return Err(IoError::RowLength {
                path: self.path.clone(),
                row: self.rows + 1,
                got: row.len(),
                want: self.channels.len(),
            });
        }
        self.rows += 1;
        let t = row[self.time_index];
        let ns = t * 1e9;
        if !(ns.is_finite() && ns >= 0.0 && ns < u64::MAX as f64) {
            return Err(IoError::NotANumber {
                path: self.path.clone(),
                row: self.rows,
                column: "time".into(),
                value: format!("{t} (MCAP times are s since the epoch, zero or positive)"),
            });
        }
        let ns = ns.round() as u64;
        let Some(w) = self.writer.as_mut() else { return Ok(()) };
        // CDR little endian: the encapsulation header, then the float64 at offset 0.
        let mut data = [0u8; 12];
        data[1] = 1;
        for (ch, v) in self.channels.iter().zip(row) {
            let (Some(id), false) = (ch, v.is_nan()) else { continue };
            data[4..].copy_from_slice(&v.to_le_bytes());
            let header = mcap::records::MessageHeader {
                channel_id: *id,
                sequence: self.sequence,
                log_time: ns,
                publish_time: ns,
            };
            self.sequence = self.sequence.wrapping_add(1);
            w.write_to_known_channel(&header, &data).map_err(|e| mcap_err(&self.path, e))?;
        }
        Ok(())
    }

    /// Rows written.
    pub fn rows(&self) -> u64 {
        self.rows
    }

    /// Writes the summary, syncs the file and moves it into place.
    pub fn finish(mut self) -> Result<u64, IoError> {
        if let Some(mut w) = self.writer.take() {
            w.finish().map_err(|e| mcap_err(&self.path, e))?;
            let mut file = w.into_inner();
            std::io::Write::flush(&mut file).map_err(|source| IoError::Os { path: self.path.clone(), source })?;
        }
        if let Some(tmp) = self.tmp.take() {
            tmp.commit()?;
        }
        Ok(self.rows)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn topics_from_column_names() {
        assert_eq!(column_topic("j1.torque_filtered"), "/strainwave/j1/torque_filtered");
        assert_eq!(column_topic("/wrench/wrench.force.x"), "/strainwave/wrench/wrench/force/x");
        assert_eq!(column_topic("torque (N·m)"), "/strainwave/torque__N_m_");
    }
}
