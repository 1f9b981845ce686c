//! CSV recordings: a header line of column names, then one row of numbers per sample.
//! Reading streams: a background thread splits the input and parses its cells into
//! batches of rows while the caller works on the previous batch. Writing formats rows
//! into a buffer that a second thread writes to a temporary file, renamed into place on
//! [`CsvWriter::finish`], so a failed run never leaves a half-written file behind under
//! the requested name. `-` means standard input / output. Memory stays constant: a few
//! buffers of a megabyte or less.
//!
//! Cells are parsed from the raw bytes of each record (no allocation per row or cell),
//! with the values and messages of the `csv` crate's trimmed text records; numbers are
//! written with the shortest text that parses back to the same bits, std's text.

use std::fs::File;
use std::io::{Read, Write};
use std::path::{Path, PathBuf};
use std::sync::mpsc::{self, Receiver, Sender, SyncSender};

use crate::error::IoError;
use crate::output::AtomicFile;
use crate::time_unit::TimeInSeconds;

/// Rows per chunk when streaming.
pub const DEFAULT_CHUNK_ROWS: usize = 8192;

/// Longest line (record) accepted: a recording's rows are a few hundred bytes, and a
/// longer line is almost always a file that is not a recording. It bounds the input buffer.
pub const MAX_RECORD_BYTES: usize = 64 << 20;
/// Bytes asked of the input per read.
const READ_BUFFER_BYTES: usize = 1 << 20;
/// Bytes gathered before a write to an output file.
const FILE_WRITE_BUFFER_BYTES: usize = 1 << 20;
/// Bytes gathered before a write to standard output (flushed per chunk by the commands anyway).
const STDOUT_WRITE_BUFFER_BYTES: usize = 1 << 16;
/// Cells per batch handed from the parsing thread to the reader (512 KiB of `f64`).
const BATCH_CELLS: usize = 1 << 16;
/// Batches the parsing thread may have ready ahead of the reader.
const BATCHES_AHEAD: usize = 2;

mod date_time;
mod dialect;
mod format;
mod parser;
mod writer;

pub use dialect::{delimiter_name, detect_delimiter, split_unit};

use date_time::parse_date_time;
use format::*;
pub use format::{format_f64, format_row};
use parser::*;
pub use writer::CsvWriter;

/// How a text table is read.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct TextOptions {
    /// The cell delimiter (`None`: detected from the header line, see [`detect_delimiter`]).
    pub delimiter: Option<u8>,
    /// A cell that is not a number is read as NaN (counted in one warning at the end)
    /// instead of stopping the read.
    pub unreadable_as_nan: bool,
}

/// Streaming reader of a numeric CSV recording.
///
/// The header is read by [`CsvReader::open`]; the rows are tokenized and parsed on a
/// background thread, a few batches ahead, in constant memory.
pub struct CsvReader {
    path: PathBuf,
    columns: Vec<String>,
    units: Vec<Option<String>>,
    delimiter: u8,
    /// The delimiter was detected, not set.
    detected: bool,
    rows_read: u64,
    batches: Receiver<Batch>,
    spent: Sender<Vec<f64>>,
    cells: Vec<f64>,
    next: usize,
    done: bool,
    /// The time column, read in seconds.
    time: TimeInSeconds,
    /// The text columns left out, one warning each.
    warnings: Vec<String>,
}

impl CsvReader {
    /// Opens a file (or standard input for `-`) and reads its header; the delimiter is
    /// detected.
    pub fn open(path: &Path) -> Result<Self, IoError> {
        Self::open_with(path, TextOptions::default())
    }

    /// Opens a file (or standard input for `-`) with these options and reads its header.
    pub fn open_with(path: &Path, options: TextOptions) -> Result<Self, IoError> {
        let input: Box<dyn Read + Send> = if path == Path::new("-") {
            Box::new(std::io::stdin())
        } else {
            if path.is_dir() {
                return Err(IoError::IsDirectory(path.to_path_buf()));
            }
            Box::new(File::open(path).map_err(|source| IoError::Os { path: path.to_path_buf(), source })?)
        };
        Self::from_reader_with(path, input, options)
    }

    /// Reads from any byte source; `path` is used in messages.
    pub fn from_reader(path: &Path, input: Box<dyn Read + Send>) -> Result<Self, IoError> {
        Self::from_reader_with(path, input, TextOptions::default())
    }

    /// Reads from any byte source with these options.
    pub fn from_reader_with(path: &Path, input: Box<dyn Read + Send>, options: TextOptions) -> Result<Self, IoError> {
        let path = path.to_path_buf();
        let detected = options.delimiter.is_none();
        let (input, delimiter) = match options.delimiter {
            Some(d) => (input, d),
            None => dialect::sniff(&path, input)?,
        };
        let (out, batches) = mpsc::sync_channel(BATCHES_AHEAD);
        let (spent, spent_rx) = mpsc::channel();
        let mut parser = Parser::new(path.clone(), input, out, spent_rx, delimiter);
        parser.unreadable_as_nan = options.unreadable_as_nan;
        let mut header = parser.header()?;
        // A delimiter at the end of the header line names no column.
        let unnamed = header.iter().rev().take_while(|h| h.trim().is_empty()).count();
        if header.len() > 1 && unnamed < header.len() {
            header.truncate(header.len() - unnamed);
            parser.unnamed_tail = unnamed;
        }
        if header.is_empty() || (header.len() == 1 && header[0].is_empty()) {
            return Err(IoError::Empty(path));
        }
        let (columns, units): (Vec<String>, Vec<Option<String>>) = header.iter().map(split_unit).unzip();
        let mut seen = std::collections::HashSet::with_capacity(columns.len());
        if let Some(c) = columns.iter().find(|c| !seen.insert(c.as_str())) {
            return Err(IoError::DuplicateColumn { path, column: c.clone() });
        }
        parser.columns = columns.clone();
        // Text columns (a DAQ's state or comment) are left out, named in a warning; dates
        // and times are seconds since 1970.
        parser.kinds = parser.column_kinds()?;
        let kind = |i: usize| parser.kinds.get(i).copied().unwrap_or(CellKind::Number);
        let warnings = (0..columns.len())
            .filter(|&i| kind(i) == CellKind::Text)
            .map(|i| format!("column `{}` holds text in data row 1: left out", crate::error::shown(&columns[i])))
            .collect();
        let (columns, mut units): (Vec<String>, Vec<Option<String>>) = columns
            .into_iter()
            .zip(units)
            .enumerate()
            .filter(|&(i, _)| kind(i) != CellKind::Text)
            .map(|(i, (c, u))| (c, if kind(i) == CellKind::DateTime { Some("s".to_string()) } else { u }))
            .unzip();
        // A time in another unit (`Time [ms]`) is read in seconds, as every command takes it.
        let time = TimeInSeconds::new(&columns, &mut units);
        std::thread::Builder::new()
            .name("csv-parse".into())
            .spawn(move || parser.run())
            .map_err(|source| IoError::Os { path: path.clone(), source })?;
        Ok(Self {
            path,
            columns,
            units,
            delimiter,
            detected,
            rows_read: 0,
            batches,
            spent,
            cells: Vec::new(),
            next: 0,
            done: false,
            time,
            warnings,
        })
    }

    /// Makes `name` the time column (it is `time` by default), read in seconds whatever
    /// time unit its header gives. No such column: nothing changes.
    pub fn set_time_column(&mut self, name: &str) {
        self.time.set_column(&self.columns, &mut self.units, name);
    }

    /// Reads the time column as the file gives it, unconverted (a config's scale
    /// converts it instead).
    pub fn keep_time_as_written(&mut self) {
        self.time.keep_as_written(&mut self.units);
    }

    /// Column names in file order (units taken off, see [`split_unit`]), but for the text
    /// columns left out: those whose first data row holds text where others hold numbers.
    pub fn columns(&self) -> &[String] {
        &self.columns
    }

    /// Each column's unit from the header, if it has one.
    pub fn units(&self) -> &[Option<String>] {
        &self.units
    }

    /// The text columns left out, one warning each.
    pub fn warnings(&self) -> &[String] {
        &self.warnings
    }

    /// The delimiter in use.
    pub fn delimiter(&self) -> u8 {
        self.delimiter
    }

    /// The file name used in messages.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Index of a column, or an error listing the columns there are.
    pub fn column_index(&self, name: &str) -> Result<usize, IoError> {
        self.columns.iter().position(|c| c == name).ok_or_else(|| IoError::MissingColumn {
            path: self.path.clone(),
            column: name.to_string(),
            available: self.columns.join(", "),
        })
    }

    /// Data rows read so far.
    pub fn rows_read(&self) -> u64 {
        self.rows_read
    }

    /// Reads the next row into `row`; `Ok(false)` at the end of the file.
    /// Cells must parse as numbers (`NaN` and `inf` are numbers and pass through).
    #[inline]
    pub fn read_row(&mut self, row: &mut Vec<f64>) -> Result<bool, IoError> {
        let n = self.columns.len();
        while self.next + n > self.cells.len() {
            if !self.next_batch()? {
                return Ok(false);
            }
        }
        row.clear();
        row.extend_from_slice(&self.cells[self.next..self.next + n]);
        self.time.apply(row, &self.path, self.rows_read + 1)?;
        self.next += n;
        self.rows_read += 1;
        Ok(true)
    }

    /// Takes the next batch from the parsing thread; `Ok(false)` at the end.
    fn next_batch(&mut self) -> Result<bool, IoError> {
        if self.done {
            return Ok(false);
        }
        match self.batches.recv() {
            Ok(Batch::Rows(cells)) => {
                let spent = std::mem::replace(&mut self.cells, cells);
                if spent.capacity() > 0 {
                    let _ = self.spent.send(spent);
                }
                self.next = 0;
                Ok(true)
            }
            Ok(Batch::End { rows, result, unreadable }) => {
                self.done = true;
                self.rows_read = rows;
                if let Some((count, first)) = unreadable {
                    self.warnings
                        .push(format!("{count} cell(s) that are not numbers read as NaN, the first at {first}"));
                }
                result.map(|()| false).map_err(|e| self.with_dialect(e))
            }
            Err(_) => {
                self.done = true;
                Err(IoError::Csv { path: self.path.clone(), msg: "the CSV parsing thread stopped".into() })
            }
        }
    }

    /// A row error of a file read with another delimiter than a comma, or as one column,
    /// names the delimiter it was read with.
    fn with_dialect(&self, e: IoError) -> IoError {
        let row_error = matches!(
            e,
            IoError::NotANumber { .. }
                | IoError::NotATime { .. }
                | IoError::TextRow { .. }
                | IoError::RowLength { .. }
                | IoError::UnnamedCell { .. }
        );
        let one_column = self.detected && self.columns.len() == 1;
        if !row_error || (self.delimiter == b',' && !one_column) {
            return e;
        }
        let decimal = if self.delimiter == b',' { "" } else { ", decimal comma accepted" };
        // A one-column header and longer rows: the header line may be a preamble above the
        // real one (a DAQ's device line). A row of text says so itself.
        let longer = one_column && matches!(e, IoError::RowLength { .. });
        let preamble = if longer { ", or start lines above the header with `#`" } else { "" };
        IoError::Dialect {
            inner: Box::new(e),
            note: format!(
                "read as {}-delimited{decimal}, {} column(s); set --delimiter if that is wrong{preamble}",
                delimiter_name(self.delimiter),
                self.columns.len()
            ),
        }
    }

    /// Reads up to `max_rows` rows, row-major, into `out` (cleared first); returns rows read.
    pub fn read_chunk(&mut self, out: &mut Vec<f64>, max_rows: usize) -> Result<usize, IoError> {
        out.clear();
        let mut row = Vec::with_capacity(self.columns.len());
        let mut n = 0;
        while n < max_rows && self.read_row(&mut row)? {
            out.extend_from_slice(&row);
            n += 1;
        }
        Ok(n)
    }
}

/// A whole recording in memory, column-major.
#[derive(Debug, Clone, PartialEq)]
pub struct Table {
    /// Column names.
    pub columns: Vec<String>,
    /// `data[c][k]`.
    pub data: Vec<Vec<f64>>,
}

impl Table {
    /// Every row `next` gives (`false`: no more), column-major, from a reader of `path`
    /// with these columns; more than [`MAX_TABLE_VALUES`](crate::MAX_TABLE_VALUES) values
    /// is an error (found before they are allocated).
    pub fn collect(
        path: &Path,
        columns: &[String],
        next: impl FnMut(&mut Vec<f64>) -> Result<bool, IoError>,
    ) -> Result<Self, IoError> {
        Self::collect_within(path, columns, crate::MAX_TABLE_VALUES, next)
    }

    /// [`Self::collect`] with at most `max_values` values.
    fn collect_within(
        path: &Path,
        columns: &[String],
        max_values: u64,
        mut next: impl FnMut(&mut Vec<f64>) -> Result<bool, IoError>,
    ) -> Result<Self, IoError> {
        let mut data = vec![Vec::new(); columns.len()];
        let mut row = Vec::new();
        let max_rows = max_values / columns.len().max(1) as u64;
        let mut rows = 0;
        while next(&mut row)? {
            rows += 1;
            if rows > max_rows {
                return Err(IoError::TooLarge { path: path.to_path_buf(), rows: max_rows, columns: columns.len() });
            }
            for (c, v) in data.iter_mut().zip(&row) {
                c.push(*v);
            }
        }
        Ok(Self { columns: columns.to_vec(), data })
    }

    /// A column by name.
    pub fn column(&self, name: &str) -> Option<&[f64]> {
        self.columns.iter().position(|c| c == name).map(|i| self.data[i].as_slice())
    }

    /// Number of rows.
    pub fn rows(&self) -> usize {
        self.data.first().map_or(0, Vec::len)
    }
}

/// Reads a whole CSV recording into memory (for analyses that need every sample).
pub fn read_table(path: &Path) -> Result<Table, IoError> {
    let mut r = CsvReader::open(path)?;
    let columns = r.columns().to_vec();
    Table::collect(path, &columns, |row| r.read_row(row))
}

#[cfg(test)]
mod tests;
