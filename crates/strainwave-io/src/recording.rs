//! Recordings in any supported format, chosen by the file extension: `.csv` (and `-`
//! for standard input/output) or `.parquet` (with the `parquet` feature). Commands
//! read and write through these types, row by row, in constant memory.

use std::path::Path;

use crate::csv_io::{CsvReader, CsvWriter};
use crate::error::IoError;

/// File formats.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    /// Comma-separated values with a header line.
    Csv,
    /// Apache Parquet.
    Parquet,
    /// MCAP (input only).
    Mcap,
}

/// The format of a path by its extension (`-` is CSV on standard input/output); a
/// directory is an error.
pub fn format_of(path: &Path) -> Result<Format, IoError> {
    if path == Path::new("-") {
        return Ok(Format::Csv);
    }
    if path.is_dir() {
        return Err(IoError::IsDirectory(path.to_path_buf()));
    }
    match path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase).as_deref() {
        Some("csv") | Some("txt") => Ok(Format::Csv),
        Some("parquet") | Some("pq") => Ok(Format::Parquet),
        Some("mcap") => Ok(Format::Mcap),
        _ => Err(IoError::UnknownFormat(path.to_path_buf())),
    }
}

enum Reader {
    Csv(CsvReader),
    #[cfg(feature = "parquet")]
    Parquet(crate::parquet_io::ParquetReader),
}

/// A recording being read.
pub struct RecordingReader {
    inner: Reader,
    path: std::path::PathBuf,
}

impl RecordingReader {
    /// Opens a recording by extension.
    pub fn open(path: &Path) -> Result<Self, IoError> {
        if path.is_dir() {
            return Err(IoError::IsDirectory(path.to_path_buf()));
        }
        let inner = match format_of(path)? {
            Format::Csv => Reader::Csv(CsvReader::open(path)?),
            #[cfg(feature = "parquet")]
            Format::Parquet => Reader::Parquet(crate::parquet_io::ParquetReader::open(path)?),
            #[cfg(not(feature = "parquet"))]
            Format::Parquet => return Err(IoError::FeatureOff { path: path.to_path_buf(), feature: "parquet" }),
            Format::Mcap => return Err(IoError::McapNotARecording(path.to_path_buf())),
        };
        Ok(Self { inner, path: path.to_path_buf() })
    }

    /// Column names in file order.
    pub fn columns(&self) -> &[String] {
        match &self.inner {
            Reader::Csv(r) => r.columns(),
            #[cfg(feature = "parquet")]
            Reader::Parquet(r) => r.columns(),
        }
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
        match &self.inner {
            Reader::Csv(r) => r.rows_read(),
            #[cfg(feature = "parquet")]
            Reader::Parquet(r) => r.rows_read(),
        }
    }

    /// Reads the next row; `Ok(false)` at the end.
    pub fn read_row(&mut self, row: &mut Vec<f64>) -> Result<bool, IoError> {
        match &mut self.inner {
            Reader::Csv(r) => r.read_row(row),
            #[cfg(feature = "parquet")]
            Reader::Parquet(r) => r.read_row(row),
        }
    }
}

// One writer per command: the size difference between variants does not matter.
#[allow(clippy::large_enum_variant)]
enum Writer {
    Csv(CsvWriter),
    #[cfg(feature = "parquet")]
    Parquet(crate::parquet_io::ParquetWriter),
}

/// A recording being written; it appears under its name only on [`RecordingWriter::finish`].
pub struct RecordingWriter {
    inner: Writer,
}

impl RecordingWriter {
    /// Creates a recording by extension.
    pub fn create(path: &Path, columns: &[&str]) -> Result<Self, IoError> {
        if path.is_dir() {
            return Err(IoError::IsDirectory(path.to_path_buf()));
        }
        let inner = match format_of(path)? {
            Format::Csv => Writer::Csv(CsvWriter::create(path, columns)?),
            #[cfg(feature = "parquet")]
            Format::Parquet => Writer::Parquet(crate::parquet_io::ParquetWriter::create(path, columns)?),
            #[cfg(not(feature = "parquet"))]
            Format::Parquet => return Err(IoError::FeatureOff { path: path.to_path_buf(), feature: "parquet" }),
            Format::Mcap => return Err(IoError::McapOutput(path.to_path_buf())),
        };
        Ok(Self { inner })
    }

    /// Writes one row.
    pub fn write_row(&mut self, row: &[f64]) -> Result<(), IoError> {
        match &mut self.inner {
            Writer::Csv(w) => w.write_row(row),
            #[cfg(feature = "parquet")]
            Writer::Parquet(w) => w.write_row(row),
        }
    }

    /// Pushes buffered rows out (CSV: to the file or pipe; Parquet: as a batch).
    pub fn flush(&mut self) -> Result<(), IoError> {
        match &mut self.inner {
            Writer::Csv(w) => w.flush(),
            #[cfg(feature = "parquet")]
            Writer::Parquet(w) => w.flush(),
        }
    }

    /// Finishes the file; returns rows written.
    pub fn finish(self) -> Result<u64, IoError> {
        match self.inner {
            Writer::Csv(w) => w.finish(),
            #[cfg(feature = "parquet")]
            Writer::Parquet(w) => w.finish(),
        }
    }
}

/// Reads a whole recording (any format) into memory.
pub fn read_all(path: &Path) -> Result<crate::Table, IoError> {
    let mut r = RecordingReader::open(path)?;
    let mut data = vec![Vec::new(); r.columns().len()];
    let mut row = Vec::new();
    while r.read_row(&mut row)? {
        for (c, v) in data.iter_mut().zip(&row) {
            c.push(*v);
        }
    }
    Ok(crate::Table { columns: r.columns().to_vec(), data })
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
    fn parquet_column_of_the_wrong_type_is_named() {
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
    }
}
