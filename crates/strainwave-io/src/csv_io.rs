//! CSV recordings: a header line of column names, then one row of numbers per sample.
//! Reading streams in chunks; writing goes to a temporary file renamed into place on
//! [`CsvWriter::finish`], so a failed run never leaves a half-written file behind
//! under the requested name. `-` means standard input / output.

use std::fs::File;
use std::io::{BufWriter, Read, Write};
use std::path::{Path, PathBuf};

use crate::error::IoError;

/// Rows per chunk when streaming.
pub const DEFAULT_CHUNK_ROWS: usize = 8192;

/// Formats an `f64` with the shortest text that parses back to the same bits.
pub fn format_f64(x: f64, out: &mut String) {
    use std::fmt::Write as _;
    let a = x.abs();
    if x == 0.0 || (1e-5..1e16).contains(&a) || !x.is_finite() {
        let _ = write!(out, "{x}");
    } else {
        let _ = write!(out, "{x:e}");
    }
}

/// Streaming reader of a numeric CSV recording.
pub struct CsvReader {
    path: PathBuf,
    reader: csv::Reader<Box<dyn Read>>,
    columns: Vec<String>,
    record: csv::StringRecord,
    rows_read: u64,
}

impl CsvReader {
    /// Opens a file (or standard input for `-`) and reads its header.
    pub fn open(path: &Path) -> Result<Self, IoError> {
        let input: Box<dyn Read> = if path == Path::new("-") {
            Box::new(std::io::stdin().lock())
        } else {
            if path.is_dir() {
                return Err(IoError::IsDirectory(path.to_path_buf()));
            }
            Box::new(File::open(path).map_err(|source| IoError::Os { path: path.to_path_buf(), source })?)
        };
        Self::from_reader(path, input)
    }

    /// Reads from any byte source; `path` is used in messages.
    pub fn from_reader(path: &Path, input: Box<dyn Read>) -> Result<Self, IoError> {
        let mut reader =
            csv::ReaderBuilder::new().has_headers(true).flexible(true).trim(csv::Trim::All).from_reader(input);
        let path = path.to_path_buf();
        let header = reader.headers().map_err(|e| IoError::Csv { path: path.clone(), msg: e.to_string() })?.clone();
        if header.is_empty() || (header.len() == 1 && header[0].is_empty()) {
            return Err(IoError::Empty(path));
        }
        let columns: Vec<String> = header.iter().map(str::to_string).collect();
        for (i, c) in columns.iter().enumerate() {
            if columns[..i].contains(c) {
                return Err(IoError::DuplicateColumn { path, column: c.clone() });
            }
        }
        Ok(Self { path, reader, columns, record: csv::StringRecord::new(), rows_read: 0 })
    }

    /// Column names in file order.
    pub fn columns(&self) -> &[String] {
        &self.columns
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
    pub fn read_row(&mut self, row: &mut Vec<f64>) -> Result<bool, IoError> {
        let ok = self
            .reader
            .read_record(&mut self.record)
            .map_err(|e| IoError::Csv { path: self.path.clone(), msg: e.to_string() })?;
        if !ok {
            return Ok(false);
        }
        self.rows_read += 1;
        if self.record.len() != self.columns.len() {
            return Err(IoError::RowLength {
                path: self.path.clone(),
                row: self.rows_read,
                got: self.record.len(),
                want: self.columns.len(),
            });
        }
        row.clear();
        for (i, cell) in self.record.iter().enumerate() {
            match cell.parse::<f64>() {
                Ok(v) => row.push(v),
                Err(_) => {
                    return Err(IoError::NotANumber {
                        path: self.path.clone(),
                        row: self.rows_read,
                        column: self.columns[i].clone(),
                        value: cell.chars().take(40).collect(),
                    });
                }
            }
        }
        Ok(true)
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
    let mut data = vec![Vec::new(); r.columns().len()];
    let mut row = Vec::new();
    while r.read_row(&mut row)? {
        for (c, v) in data.iter_mut().zip(&row) {
            c.push(*v);
        }
    }
    Ok(Table { columns: r.columns().to_vec(), data })
}

enum Sink {
    File { tmp: PathBuf, out: BufWriter<File> },
    Stdout(BufWriter<std::io::Stdout>),
}

/// CSV writer; the file appears under its name only on [`CsvWriter::finish`].
pub struct CsvWriter {
    path: PathBuf,
    sink: Option<Sink>,
    n_cols: usize,
    line: String,
    rows: u64,
}

impl CsvWriter {
    /// Creates the output (standard output for `-`) and writes the header.
    pub fn create(path: &Path, columns: &[&str]) -> Result<Self, IoError> {
        let os = |source| IoError::Os { path: path.to_path_buf(), source };
        let sink = if path == Path::new("-") {
            Sink::Stdout(BufWriter::new(std::io::stdout()))
        } else {
            if path.is_dir() {
                return Err(IoError::IsDirectory(path.to_path_buf()));
            }
            let name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_else(|| "out".into());
            let tmp = path.with_file_name(format!(".{name}.partial"));
            let file = File::create(&tmp).map_err(os)?;
            Sink::File { tmp, out: BufWriter::with_capacity(1 << 16, file) }
        };
        let mut w =
            Self { path: path.to_path_buf(), sink: Some(sink), n_cols: columns.len(), line: String::new(), rows: 0 };
        w.line = columns.join(",");
        w.line.push('\n');
        w.emit()?;
        Ok(w)
    }

    fn emit(&mut self) -> Result<(), IoError> {
        let r = match self.sink.as_mut() {
            Some(Sink::File { out, .. }) => out.write_all(self.line.as_bytes()),
            Some(Sink::Stdout(out)) => out.write_all(self.line.as_bytes()),
            None => Ok(()),
        };
        r.map_err(|source| IoError::Os { path: self.path.clone(), source })
    }

    /// Writes one row; its length must match the header.
    pub fn write_row(&mut self, row: &[f64]) -> Result<(), IoError> {
        if row.len() != self.n_cols {
            return Err(IoError::RowLength {
                path: self.path.clone(),
                row: self.rows + 1,
                got: row.len(),
                want: self.n_cols,
            });
        }
        self.line.clear();
        for (i, v) in row.iter().enumerate() {
            if i > 0 {
                self.line.push(',');
            }
            format_f64(*v, &mut self.line);
        }
        self.line.push('\n');
        self.rows += 1;
        self.emit()
    }

    /// Flushes buffered rows (for live pipes).
    pub fn flush(&mut self) -> Result<(), IoError> {
        let r = match self.sink.as_mut() {
            Some(Sink::File { out, .. }) => out.flush(),
            Some(Sink::Stdout(out)) => out.flush(),
            None => Ok(()),
        };
        r.map_err(|source| IoError::Os { path: self.path.clone(), source })
    }

    /// Rows written.
    pub fn rows(&self) -> u64 {
        self.rows
    }

    /// Flushes and moves the file into place.
    pub fn finish(mut self) -> Result<u64, IoError> {
        self.flush()?;
        if let Some(Sink::File { tmp, out }) = self.sink.take() {
            drop(out);
            std::fs::rename(&tmp, &self.path).map_err(|source| IoError::Os { path: self.path.clone(), source })?;
        }
        Ok(self.rows)
    }
}

impl Drop for CsvWriter {
    fn drop(&mut self) {
        if let Some(Sink::File { tmp, out }) = self.sink.take() {
            drop(out);
            let _ = std::fs::remove_file(tmp);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn reader(text: &'static str) -> Result<CsvReader, IoError> {
        CsvReader::from_reader(Path::new("rec.csv"), Box::new(text.as_bytes()))
    }

    #[test]
    fn shortest_round_trip_formatting() {
        for x in [0.0, 1.0, -2.5, 1e-7, 123456.789, 1.0 / 3.0, f64::MIN_POSITIVE, 6.02e23, -1e-300] {
            let mut s = String::new();
            format_f64(x, &mut s);
            assert_eq!(s.parse::<f64>().unwrap().to_bits(), x.to_bits(), "{s}");
            assert!(s.len() < 26, "{s}");
        }
    }

    #[test]
    fn reads_rows_and_names_bad_cells() {
        let mut r = reader("time,a\n0,1.5\n0.001,x\n").unwrap();
        let mut row = Vec::new();
        assert!(r.read_row(&mut row).unwrap());
        assert_eq!(row, vec![0.0, 1.5]);
        let e = r.read_row(&mut row).unwrap_err().to_string();
        assert_eq!(e, "rec.csv: row 2, column `a`: `x` is not a number");
    }

    #[test]
    fn truncated_line_and_empty_file_and_missing_column() {
        let mut r = reader("time,a,b\n0,1,2\n0.001,3").unwrap();
        let mut row = Vec::new();
        r.read_row(&mut row).unwrap();
        assert!(matches!(r.read_row(&mut row), Err(IoError::RowLength { row: 2, got: 2, want: 3, .. })));
        assert!(matches!(reader(""), Err(IoError::Empty(_))));
        let r = reader("time,a\n").unwrap();
        assert_eq!(r.column_index("b").unwrap_err().to_string(), "rec.csv: no column `b` (columns: time, a)");
        assert!(matches!(reader("a,a\n1,2\n"), Err(IoError::DuplicateColumn { .. })));
    }

    #[test]
    fn nan_passes_through_as_a_number() {
        let mut r = reader("a\nNaN\ninf\n").unwrap();
        let mut row = Vec::new();
        r.read_row(&mut row).unwrap();
        assert!(row[0].is_nan());
        r.read_row(&mut row).unwrap();
        assert!(row[0].is_infinite());
    }

    #[test]
    fn writer_is_atomic_and_round_trips() {
        let dir = std::env::temp_dir().join(format!("sw-io-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("out.csv");
        let mut w = CsvWriter::create(&path, &["time", "x"]).unwrap();
        w.write_row(&[0.0, 0.1]).unwrap();
        assert!(!path.exists(), "visible before finish");
        assert!(w.write_row(&[1.0]).is_err());
        w.finish().unwrap();
        let t = read_table(&path).unwrap();
        assert_eq!(t.column("x").unwrap(), &[0.1]);
        // Dropped without finish: nothing left behind.
        let p2 = dir.join("never.csv");
        drop(CsvWriter::create(&p2, &["a"]).unwrap());
        assert!(!p2.exists() && !dir.join(".never.csv.partial").exists());
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
