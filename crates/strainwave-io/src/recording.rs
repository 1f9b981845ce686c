//! Recordings in any supported format, chosen by the path: delimited text (`.csv`,
//! `.txt`, `.tsv`, `.dat`; `-` for standard input/output), `.parquet` (with the `parquet`
//! feature), ROS 2 logs in (`.mcap`, `.db3`, a rosbag2 folder) and MCAP out (with the
//! `mcap` feature; `.db3` with `sqlite`). Commands read and write through these types,
//! row by row, in bounded memory; [`RecordingReader::open`] takes the process's
//! [`ReadOptions`] so every command reads every format the same way.

use std::collections::VecDeque;
use std::io::Write as _;
use std::path::Path;

use crate::csv_io::{CsvReader, CsvWriter};
use crate::error::IoError;
use crate::read_options::{default_read_options, ReadOptions};
use crate::resample::LinearResampler;

/// File formats.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    /// Comma-separated values with a header line.
    Csv,
    /// Apache Parquet.
    Parquet,
    /// MCAP.
    Mcap,
    /// rosbag2 SQLite storage (input only).
    Db3,
    /// A rosbag2 folder (input only).
    RosbagFolder,
}

/// The format of a path by its extension (`-` is CSV on standard input/output); a
/// directory is an error.
pub fn format_of(path: &Path) -> Result<Format, IoError> {
    if path == Path::new("-") {
        return Ok(Format::Csv);
    }
    if path.is_dir() {
        let bag = path.join("metadata.yaml").is_file()
            || std::fs::read_dir(path).is_ok_and(|d| {
                d.flatten().any(|e| matches!(log_extension(&e.path()).as_deref(), Some("mcap" | "db3")))
            });
        return if bag { Ok(Format::RosbagFolder) } else { Err(IoError::IsDirectory(path.to_path_buf())) };
    }
    match log_extension(path).as_deref() {
        Some("csv") | Some("txt") | Some("tsv") | Some("dat") => Ok(Format::Csv),
        Some("parquet") | Some("pq") => Ok(Format::Parquet),
        Some("mcap") => Ok(Format::Mcap),
        Some("db3") => Ok(Format::Db3),
        _ => Err(IoError::UnknownFormat(path.to_path_buf())),
    }
}

/// The extension of `path` in lower case, that of the file inside for a log file
/// compressed whole (`mcap` for `bag_0.mcap.zstd`).
fn log_extension(path: &Path) -> Option<String> {
    let ext = |p: &Path| p.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
    match ext(path).as_deref() {
        Some("zstd" | "zst") => ext(&path.with_extension("")).filter(|e| e == "mcap" || e == "db3"),
        _ => ext(path),
    }
}

enum Reader {
    Csv(CsvReader),
    #[cfg(feature = "parquet")]
    Parquet(crate::parquet_io::ParquetReader),
    #[cfg(feature = "mcap")]
    Bag(Box<crate::ros2::bag::BagReader>),
}

impl Reader {
    fn read_row(&mut self, row: &mut Vec<f64>) -> Result<bool, IoError> {
        match self {
            Reader::Csv(r) => r.read_row(row),
            #[cfg(feature = "parquet")]
            Reader::Parquet(r) => r.read_row(row),
            #[cfg(feature = "mcap")]
            Reader::Bag(r) => r.read_row(row),
        }
    }

    /// A table's time column: `Some(name)` read in seconds, `None` the time column as
    /// written; the table's units after it. A log's time is in seconds already: `None`.
    fn set_time_column(&mut self, name: Option<&str>) -> Option<Vec<Option<String>>> {
        match self {
            Reader::Csv(r) => {
                match name {
                    Some(name) => r.set_time_column(name),
                    None => r.keep_time_as_written(),
                }
                Some(r.units().to_vec())
            }
            #[cfg(feature = "parquet")]
            Reader::Parquet(r) => {
                match name {
                    Some(name) => r.set_time_column(name),
                    None => r.keep_time_as_written(),
                }
                Some(r.units().to_vec())
            }
            #[cfg(feature = "mcap")]
            Reader::Bag(_) => None,
        }
    }
}

/// The resampler of a table on time column `ti` (`hz` and `max_gap_s` checked).
fn resampler(ti: usize, hz: f64, max_gap_s: f64) -> Option<Resampled> {
    LinearResampler::new(ti, hz, max_gap_s).map(|resampler| Resampled { resampler, ready: VecDeque::new(), skipped: 0 })
}

/// `--resample-hz` on a table without the time column `time`.
fn no_time_column(path: &Path, columns: &[String], time: &str) -> IoError {
    IoError::MissingColumn {
        path: path.to_path_buf(),
        column: time.into(),
        available: format!(
            "{} (needed by --resample-hz; name the time column in the config's channels.time, or with convert's \
             --time-column)",
            columns.join(", ")
        ),
    }
}

/// A table's rows interpolated onto a uniform clock (`--resample-hz`).
struct Resampled {
    resampler: LinearResampler,
    ready: VecDeque<Vec<f64>>,
    /// Input rows left out because their time does not increase.
    skipped: u64,
}

/// A recording being read.
pub struct RecordingReader {
    inner: Reader,
    path: std::path::PathBuf,
    columns: Vec<String>,
    units: Vec<Option<String>>,
    warnings: Vec<String>,
    /// The reader's warnings taken so far, and whether those found while reading go to
    /// standard error.
    reader_warnings: (usize, bool),
    resampled: Option<Resampled>,
    /// `--resample-hz` on a table whose time column is not known yet (a config's time
    /// channel names it, see [`Self::set_time_channel`]): rate, Hz, largest gap, s, and the
    /// error if the first row comes first.
    resample_pending: Option<(f64, f64, IoError)>,
    input_rows: u64,
    rows_read: u64,
}

impl RecordingReader {
    /// Opens a recording by its path, with the process's read options (see
    /// [`crate::set_default_read_options`]); warnings go to standard error when the options
    /// say so.
    pub fn open(path: &Path) -> Result<Self, IoError> {
        let options = default_read_options();
        let mut r = Self::open_with(path, &options)?;
        if options.print_warnings {
            for w in r.warnings() {
                let _ = writeln!(std::io::stderr(), "warning: {}: {w}", path.display());
            }
            r.reader_warnings.1 = true;
        }
        Ok(r)
    }

    /// Opens a recording by its path with these options.
    pub fn open_with(path: &Path, options: &ReadOptions) -> Result<Self, IoError> {
        let format = format_of(path)?;
        let bag = matches!(format, Format::Mcap | Format::Db3 | Format::RosbagFolder);
        let (inner, columns, units, warnings) = match format {
            Format::Csv => {
                let text = crate::csv_io::TextOptions {
                    delimiter: options.delimiter,
                    unreadable_as_nan: options.unreadable_as_nan,
                };
                let mut r = CsvReader::open_with(path, text)?;
                if let Some(name) = &options.time_column {
                    r.set_time_column(name);
                }
                let (columns, units, warnings) = (r.columns().to_vec(), r.units().to_vec(), r.warnings().to_vec());
                (Reader::Csv(r), columns, units, warnings)
            }
            #[cfg(feature = "parquet")]
            Format::Parquet => {
                let mut r = crate::parquet_io::ParquetReader::open(path)?;
                if let Some(name) = &options.time_column {
                    r.set_time_column(name);
                }
                let (columns, units, warnings) = (r.columns().to_vec(), r.units().to_vec(), r.warnings().to_vec());
                (Reader::Parquet(r), columns, units, warnings)
            }
            #[cfg(not(feature = "parquet"))]
            Format::Parquet => return Err(IoError::FeatureOff { path: path.to_path_buf(), feature: "parquet" }),
            #[cfg(feature = "mcap")]
            Format::Mcap | Format::Db3 | Format::RosbagFolder => {
                let r = crate::ros2::bag::BagReader::open(path, options)?;
                let columns = r.columns().to_vec();
                let warnings = r.warnings().to_vec();
                let units = vec![None; columns.len()];
                if columns.len() < 2 {
                    let mut msg = "no messages with numeric values on the selected topics".to_string();
                    if !warnings.is_empty() {
                        msg.push_str(&format!(" ({})", warnings.join("; ")));
                    }
                    return Err(IoError::Csv { path: path.to_path_buf(), msg });
                }
                (Reader::Bag(Box::new(r)), columns, units, warnings)
            }
            #[cfg(not(feature = "mcap"))]
            Format::Mcap | Format::Db3 | Format::RosbagFolder => {
                return Err(IoError::FeatureOff { path: path.to_path_buf(), feature: "mcap" })
            }
        };
        // Logs resample in the aligner; tables here, between neighbouring rows, on the
        // time column (`time` or `--time-column`, unless a config's time channel names
        // another before the first row).
        let (mut resampled, mut resample_pending) = (None, None);
        if let Some(hz) = options.resample_hz.filter(|_| !bag) {
            let max_gap_s = options.max_gap_s.unwrap_or(crate::resample::DEFAULT_MAX_GAP_S);
            if LinearResampler::new(0, hz, max_gap_s).is_none() {
                return Err(IoError::Csv {
                    path: path.to_path_buf(),
                    msg: format!("--resample-hz must be positive, got {hz} (--max-gap {max_gap_s})"),
                });
            }
            let time = options.time_column.as_deref().unwrap_or("time");
            match columns.iter().position(|c| c == time) {
                Some(ti) => resampled = resampler(ti, hz, max_gap_s),
                None => resample_pending = Some((hz, max_gap_s, no_time_column(path, &columns, time))),
            }
        }
        let reader_warnings = (warnings.len(), false);
        Ok(Self {
            inner,
            path: path.to_path_buf(),
            columns,
            units,
            warnings,
            reader_warnings,
            resampled,
            resample_pending,
            input_rows: 0,
            rows_read: 0,
        })
    }

    /// Column names in file order.
    pub fn columns(&self) -> &[String] {
        &self.columns
    }

    /// Makes the column of a config's time channel the table's time column, read in
    /// seconds whatever time unit its header gives (`Timestamp [ms]`), before any row is
    /// read. A channel with its own scale or offset converts it itself: the column is then
    /// read as written. Logs are unchanged (their times are seconds already).
    pub fn set_time_channel(&mut self, channel: &crate::Channel) {
        if self.rows_read > 0 {
            return;
        }
        let name = (channel.scale_offset() == (1.0, 0.0)).then(|| channel.column_name());
        if let Some(units) = self.inner.set_time_column(name) {
            self.units = units;
        }
        // `--resample-hz` runs on this column, in seconds.
        let spec = match (&self.resampled, self.resample_pending.take()) {
            (Some(rs), _) => Some((rs.resampler.rate_hz(), rs.resampler.max_gap_s())),
            (None, Some((hz, gap, _))) => Some((hz, gap)),
            (None, None) => None,
        };
        let Some((hz, max_gap_s)) = spec else { return };
        let (column, ti) = (channel.column_name(), self.columns.iter().position(|c| c == channel.column_name()));
        self.resampled = None;
        match (name, ti) {
            (Some(_), Some(ti)) => self.resampled = resampler(ti, hz, max_gap_s),
            (None, Some(_)) => {
                let msg = format!(
                    "--resample-hz needs the time in seconds, and the time channel `{column}` has a scale or \
                     offset; give the column's unit in its header instead (`{column} [ms]`)"
                );
                self.resample_pending = Some((hz, max_gap_s, IoError::Csv { path: self.path.clone(), msg }));
            }
            (_, None) => {
                self.resample_pending = Some((hz, max_gap_s, no_time_column(&self.path, &self.columns, column)))
            }
        }
    }

    /// The unit of each column where the file gives one (a text header's `[unit]` or
    /// `(unit)`, a Parquet field's `unit` metadata).
    pub fn units(&self) -> &[Option<String>] {
        &self.units
    }

    /// Warnings of the reader (skipped log channels, …); those found while reading
    /// (a log's messages at one time) once the last row is read.
    pub fn warnings(&self) -> &[String] {
        &self.warnings
    }

    /// The warnings the reader found while reading, printed as those at the start were.
    fn take_reader_warnings(&mut self) {
        let all = match &self.inner {
            Reader::Csv(r) => r.warnings(),
            #[cfg(feature = "mcap")]
            Reader::Bag(r) => r.warnings(),
            #[cfg(feature = "parquet")]
            Reader::Parquet(_) => return,
        };
        let (taken, print) = self.reader_warnings;
        for w in all.iter().skip(taken) {
            if print {
                let _ = writeln!(std::io::stderr(), "warning: {}: {w}", self.path.display());
            }
            self.warnings.push(w.clone());
        }
        self.reader_warnings.0 = all.len();
    }

    /// Input rows read so far: a table's data rows (before `--resample-hz`), a log's
    /// messages with values (all topics; see [`RecordingReader::messages_per_topic`]).
    pub fn input_rows(&self) -> u64 {
        match &self.inner {
            #[cfg(feature = "mcap")]
            Reader::Bag(r) => r.messages_per_topic().iter().map(|(_, n)| n).sum(),
            _ => self.input_rows,
        }
    }

    /// A log's messages with values read so far, per topic in first-seen order; `None`
    /// for a table.
    pub fn messages_per_topic(&self) -> Option<Vec<(String, u64)>> {
        match &self.inner {
            #[cfg(feature = "mcap")]
            Reader::Bag(r) => Some(r.messages_per_topic()),
            _ => None,
        }
    }

    /// Table rows left out of `--resample-hz` because their time does not increase.
    pub fn resample_skipped(&self) -> u64 {
        self.resampled.as_ref().map_or(0, |r| r.skipped)
    }

    /// A table's gaps longer than `--max-gap` that `--resample-hz` left NaN, and the
    /// largest as `(gap_s, ends_at_s)`.
    pub fn resample_gaps(&self) -> (u64, Option<(f64, f64)>) {
        self.resampled.as_ref().map_or((0, None), |r| r.resampler.gaps())
    }

    /// The path, for messages.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Index of a column, or an error listing the columns there are.
    pub fn column_index(&self, name: &str) -> Result<usize, IoError> {
        self.columns().iter().position(|c| c == name).ok_or_else(|| IoError::MissingColumn {
            path: self.path.clone(),
            column: name.to_string(),
            available: self.columns().join(", "),
        })
    }

    /// Data rows read so far.
    pub fn rows_read(&self) -> u64 {
        self.rows_read
    }

    /// How messages name `row`, the row last read, so that the user finds it: a table's
    /// `data row N` as in the file; a resampled row by its time and the file's data rows
    /// it lies between; a log's aligned row by its time.
    pub fn row_name(&self, row: &[f64]) -> String {
        let n = self.rows_read;
        if let Some(rs) = &self.resampled {
            let t = row.get(rs.resampler.time_index()).copied().unwrap_or(f64::NAN);
            let m = self.input_rows;
            let source =
                if m > 1 { format!("between data rows {} and {m}", m - 1) } else { format!("at data row {m}") };
            return format!("resampled row {n} (time {t} s, {source} of the file)");
        }
        match &self.inner {
            #[cfg(feature = "mcap")]
            Reader::Bag(_) => format!("aligned row {n} (time {} s)", row.first().copied().unwrap_or(f64::NAN)),
            _ => format!("data row {n}"),
        }
    }

    /// Reads the next row; `Ok(false)` at the end.
    pub fn read_row(&mut self, row: &mut Vec<f64>) -> Result<bool, IoError> {
        if let Some((_, _, e)) = self.resample_pending.take() {
            return Err(e);
        }
        let Some(rs) = self.resampled.as_mut() else {
            let more = self.inner.read_row(row)?;
            self.rows_read += u64::from(more);
            self.input_rows = self.rows_read;
            if !more {
                self.take_reader_warnings();
            }
            return Ok(more);
        };
        loop {
            if let Some(r) = rs.ready.pop_front() {
                *row = r;
                self.rows_read += 1;
                return Ok(true);
            }
            if !self.inner.read_row(row)? {
                self.take_reader_warnings();
                return Ok(false);
            }
            self.input_rows += 1;
            let ready = &mut rs.ready;
            let kept = rs
                .resampler
                .push(row, |o| {
                    ready.push_back(o.to_vec());
                    true
                })
                .map_err(|e| IoError::Csv {
                    path: self.path.clone(),
                    msg: format!(
                        "data row {}: time {} s after a gap of {} s would need more than {} resampled rows; \
                         fix the time column, or read without --resample-hz",
                        self.input_rows,
                        e.time_s,
                        e.gap_s,
                        crate::resample::MAX_ROWS_PER_GAP
                    ),
                })?;
            if !kept {
                rs.skipped += 1;
            }
            // Up-sampling beyond reason (kHz typed for Hz) would fill the disk with
            // made-up rows: stop early, with what to do.
            let out_rows = self.rows_read + rs.ready.len() as u64;
            if out_rows > MAX_RESAMPLED_PER_INPUT_ROW * self.input_rows + RESAMPLED_ROWS_ALLOWED {
                let (hz, t) = (rs.resampler.rate_hz(), row.get(rs.resampler.time_index()).copied().unwrap_or(f64::NAN));
                return Err(IoError::Csv {
                    path: self.path.clone(),
                    msg: format!(
                        "data row {}: --resample-hz {hz} makes more than {MAX_RESAMPLED_PER_INPUT_ROW} rows per input \
                         row ({out_rows} rows by time {t} s); choose a rate near the recording's own",
                        self.input_rows
                    ),
                });
            }
        }
    }
}

/// Most output rows `--resample-hz` may make per input row, beyond
/// [`RESAMPLED_ROWS_ALLOWED`] (a short recording may be up-sampled further).
const MAX_RESAMPLED_PER_INPUT_ROW: u64 = 1000;
/// Output rows of any resampling, whatever the input's length.
const RESAMPLED_ROWS_ALLOWED: u64 = 1_000_000;

// One writer per command: the size difference between variants does not matter.
#[allow(clippy::large_enum_variant)]
enum Writer {
    Csv(CsvWriter),
    #[cfg(feature = "parquet")]
    Parquet(crate::parquet_io::ParquetWriter),
    #[cfg(feature = "mcap")]
    Mcap(crate::mcap_out::McapWriter),
}

/// A recording being written; it appears under its name only on [`RecordingWriter::finish`].
pub struct RecordingWriter {
    inner: Writer,
}

impl RecordingWriter {
    /// Creates a recording by extension (no units but the `time` column's s).
    pub fn create(path: &Path, columns: &[&str]) -> Result<Self, IoError> {
        Self::create_with_units(path, columns, &[])
    }

    /// Creates a recording by extension: `.csv` and other text (`-`: standard output),
    /// `.parquet`, `.mcap`. `units[i]` is column `i`'s unit (missing or `None`: none):
    /// a text header writes it as `name [unit]`, Parquet as the field's `unit` metadata
    /// (`time` is `s` there by default); MCAP leaves units out (`std_msgs/msg/Float64`).
    pub fn create_with_units(path: &Path, columns: &[&str], units: &[Option<&str>]) -> Result<Self, IoError> {
        if path.is_dir() {
            return Err(IoError::IsDirectory(path.to_path_buf()));
        }
        let unit = |i: usize| units.get(i).copied().flatten().filter(|u| !u.is_empty());
        let inner = match format_of(path)? {
            Format::Csv => {
                let header: Vec<String> = columns
                    .iter()
                    .enumerate()
                    .map(|(i, c)| match unit(i) {
                        // `time` is in s by definition: its header stays `time`.
                        Some("s") if *c == "time" => (*c).to_string(),
                        Some(u) => format!("{c} [{u}]"),
                        None => (*c).to_string(),
                    })
                    .collect();
                let refs: Vec<&str> = header.iter().map(String::as_str).collect();
                Writer::Csv(CsvWriter::create(path, &refs)?)
            }
            #[cfg(feature = "parquet")]
            Format::Parquet => {
                let units: Vec<Option<&str>> =
                    (0..columns.len()).map(|i| unit(i).or((columns[i] == "time").then_some("s"))).collect();
                Writer::Parquet(crate::parquet_io::ParquetWriter::create_with_units(path, columns, &units)?)
            }
            #[cfg(not(feature = "parquet"))]
            Format::Parquet => return Err(IoError::FeatureOff { path: path.to_path_buf(), feature: "parquet" }),
            #[cfg(feature = "mcap")]
            Format::Mcap => Writer::Mcap(crate::mcap_out::McapWriter::create(path, columns)?),
            #[cfg(not(feature = "mcap"))]
            Format::Mcap => return Err(IoError::FeatureOff { path: path.to_path_buf(), feature: "mcap" }),
            Format::Db3 | Format::RosbagFolder => return Err(IoError::McapOutput(path.to_path_buf())),
        };
        Ok(Self { inner })
    }

    /// Writes one row.
    pub fn write_row(&mut self, row: &[f64]) -> Result<(), IoError> {
        match &mut self.inner {
            Writer::Csv(w) => w.write_row(row),
            #[cfg(feature = "parquet")]
            Writer::Parquet(w) => w.write_row(row),
            #[cfg(feature = "mcap")]
            Writer::Mcap(w) => w.write_row(row),
        }
    }

    /// Pushes buffered rows out (CSV: to the file or pipe; Parquet: as a batch).
    pub fn flush(&mut self) -> Result<(), IoError> {
        match &mut self.inner {
            Writer::Csv(w) => w.flush(),
            #[cfg(feature = "parquet")]
            Writer::Parquet(w) => w.flush(),
            #[cfg(feature = "mcap")]
            Writer::Mcap(_) => Ok(()),
        }
    }

    /// Finishes the file; returns rows written.
    pub fn finish(self) -> Result<u64, IoError> {
        match self.inner {
            Writer::Csv(w) => w.finish(),
            #[cfg(feature = "parquet")]
            Writer::Parquet(w) => w.finish(),
            #[cfg(feature = "mcap")]
            Writer::Mcap(w) => w.finish(),
        }
    }
}

/// Most values a recording read whole may hold (2²⁷, 1 GiB): a larger one is an error,
/// not an allocation that takes the machine's memory.
pub const MAX_TABLE_VALUES: u64 = 1 << 27;

/// Reads a whole recording (any format) into memory.
pub fn read_all(path: &Path) -> Result<crate::Table, IoError> {
    read_all_with_time(path, None)
}

/// [`read_all`] with a config's time channel read in seconds (see
/// [`RecordingReader::set_time_channel`]).
pub fn read_all_with_time(path: &Path, time: Option<&crate::Channel>) -> Result<crate::Table, IoError> {
    let mut r = RecordingReader::open(path)?;
    if let Some(time) = time {
        r.set_time_channel(time);
    }
    let columns = r.columns().to_vec();
    crate::Table::collect(path, &columns, |row| r.read_row(row))
}

/// How messages name row `k` (0-based) of `table`, read whole from `path` by
/// [`read_all`]: see [`row_label`].
pub fn row_name(path: &Path, table: &crate::Table, k: usize, plain: &str) -> String {
    let time = default_read_options().time_column.unwrap_or_else(|| "time".into());
    let t = table.column(&time).and_then(|c| c.get(k)).copied().unwrap_or(f64::NAN);
    row_label(&path.to_string_lossy(), k as u64 + 1, t, plain)
}

/// What interpolates between the rows of the recording `input`, read with the process's
/// read options, if anything does: `--resample-hz` for a table, `--align linear` for a
/// log (its values then lie between the file's, and a counter is no longer whole).
pub fn interpolated_by(input: &str) -> Option<&'static str> {
    let options = default_read_options();
    match format_of(Path::new(input)) {
        Ok(Format::Mcap | Format::Db3 | Format::RosbagFolder) => {
            (options.align == crate::ros2::align::Align::Linear).then_some("--align linear")
        }
        _ => options.resample_hz.map(|_| "--resample-hz"),
    }
}

/// How messages name row `n` (1-based) of the recording `input`, read with the process's
/// read options, whose time is `time_s`: `"{plain} {n}"` as in the file, unless the rows
/// are not the file's (resampled by `--resample-hz`, or a log's messages aligned on one
/// clock): then by the row's time, which the user can find.
pub fn row_label(input: &str, n: u64, time_s: f64, plain: &str) -> String {
    let kind = match format_of(Path::new(input)) {
        Ok(Format::Mcap | Format::Db3 | Format::RosbagFolder) => "aligned row",
        _ if default_read_options().resample_hz.is_some() => "resampled row",
        _ => return format!("{plain} {n}"),
    };
    format!("{kind} {n} (time {time_s} s)")
}

#[cfg(all(test, feature = "parquet"))]
mod tests {
    use super::*;

    #[test]
    fn parquet_round_trip_is_bit_exact_and_keeps_order() {
        let dir = std::env::temp_dir().join(format!("sw-pq-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join("r.parquet");
        let cols = ["time", "z", "a"];
        let mut w = RecordingWriter::create(&p, &cols).unwrap();
        let rows: Vec<[f64; 3]> =
            (0..20_000).map(|k| [k as f64 * 1e-3, (k as f64).sin() / 3.0, f64::MIN_POSITIVE * k as f64]).collect();
        for r in &rows {
            w.write_row(r).unwrap();
        }
        assert!(!p.exists());
        assert_eq!(w.finish().unwrap(), 20_000);
        let t = read_all(&p).unwrap();
        assert_eq!(t.columns, cols);
        for (k, r) in rows.iter().enumerate() {
            for (c, v) in r.iter().enumerate() {
                assert_eq!(t.data[c][k].to_bits(), v.to_bits());
            }
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn parquet_columns_of_text_are_left_out_and_named() {
        use arrow_array::{ArrayRef, Float64Array, RecordBatch, StringArray};
        use std::sync::Arc;
        let dir = std::env::temp_dir().join(format!("sw-pqt-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join("bad.parquet");
        let batch = RecordBatch::try_from_iter(vec![
            ("time", Arc::new(Float64Array::from(vec![0.0, 1.0])) as ArrayRef),
            ("label", Arc::new(StringArray::from(vec!["a", "b"])) as ArrayRef),
        ])
        .unwrap();
        let mut w =
            parquet::arrow::ArrowWriter::try_new(std::fs::File::create(&p).unwrap(), batch.schema(), None).unwrap();
        w.write(&batch).unwrap();
        w.close().unwrap();
        let mut r = RecordingReader::open(&p).unwrap();
        assert_eq!(r.columns(), ["time"]);
        assert_eq!(r.warnings(), ["column `label` (Utf8) is not numeric: left out"]);
        let mut row = Vec::new();
        assert!(r.read_row(&mut row).unwrap() && r.read_row(&mut row).unwrap() && row == [1.0]);
        assert!(!r.read_row(&mut row).unwrap());
        // With no numeric column at all, the file is refused.
        let batch =
            RecordBatch::try_from_iter(vec![("label", Arc::new(StringArray::from(vec!["a"])) as ArrayRef)]).unwrap();
        let mut w =
            parquet::arrow::ArrowWriter::try_new(std::fs::File::create(&p).unwrap(), batch.schema(), None).unwrap();
        w.write(&batch).unwrap();
        w.close().unwrap();
        let e = RecordingReader::open(&p).err().unwrap().to_string();
        assert!(e.ends_with("bad.parquet: column `label` has type Utf8, expected a number"), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn parquet_with_two_columns_of_one_name_is_refused() {
        use arrow_array::{ArrayRef, Float64Array, RecordBatch};
        use arrow_schema::{DataType, Field, Schema};
        use std::sync::Arc;
        let dir = std::env::temp_dir().join(format!("sw-pqd-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join("dup.parquet");
        let schema = Arc::new(Schema::new(vec![
            Field::new("time", DataType::Float64, false),
            Field::new("torque", DataType::Float64, false),
            Field::new("torque", DataType::Float64, false),
        ]));
        let col = || Arc::new(Float64Array::from(vec![0.0, 1.0])) as ArrayRef;
        let batch = RecordBatch::try_new(schema.clone(), vec![col(), col(), col()]).unwrap();
        let mut w = parquet::arrow::ArrowWriter::try_new(std::fs::File::create(&p).unwrap(), schema, None).unwrap();
        w.write(&batch).unwrap();
        w.close().unwrap();
        let e = RecordingReader::open(&p).err().unwrap().to_string();
        assert!(e.ends_with("dup.parquet: column `torque` appears twice in the header"), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn format_by_extension() {
        assert_eq!(format_of(Path::new("a.CSV")).unwrap(), Format::Csv);
        assert_eq!(format_of(Path::new("-")).unwrap(), Format::Csv);
        assert_eq!(format_of(Path::new("a.parquet")).unwrap(), Format::Parquet);
        assert!(format_of(Path::new("a.xlsx")).is_err());
        // A log compressed whole is its inner format; other files so compressed are not read.
        assert_eq!(format_of(Path::new("bag_0.mcap.zstd")).unwrap(), Format::Mcap);
        assert_eq!(format_of(Path::new("bag_0.DB3.zst")).unwrap(), Format::Db3);
        assert!(format_of(Path::new("a.csv.zstd")).is_err());
    }
}
