//! Parquet recordings through Arrow: every column read as `f64` (integer, `f16`, `f32` and
//! decimal columns are widened, timestamps become seconds since the epoch with the unit `s`;
//! nulls become NaN; a column of another type, text or categories, is left out with a
//! warning naming it; a file without a numeric column is an error),
//! written as non-nullable `Float64` columns with snappy compression, in row groups
//! of [`crate::DEFAULT_CHUNK_ROWS`] rows, so both directions stream in constant memory.
//! A column's unit is its field's metadata `unit` (both ways); a `time` column in another
//! time unit (`ms`) is read in seconds, as from a text header.

use std::collections::HashMap;
use std::fs::File;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use arrow_array::cast::AsArray;
use arrow_array::types::{
    Decimal128Type, Float16Type, Float32Type, Float64Type, Int16Type, Int32Type, Int64Type, Int8Type,
    TimestampMicrosecondType, TimestampMillisecondType, TimestampNanosecondType, TimestampSecondType, UInt16Type,
    UInt32Type, UInt64Type, UInt8Type,
};
use arrow_array::{Array, ArrayRef, Float64Array, RecordBatch};
use arrow_schema::{DataType, Field, Schema, SchemaRef, TimeUnit};
use parquet::arrow::arrow_reader::{ParquetRecordBatchReader, ParquetRecordBatchReaderBuilder};
use parquet::arrow::ArrowWriter;
use parquet::basic::Compression;
use parquet::file::properties::WriterProperties;

use crate::error::IoError;
use crate::time_unit::TimeInSeconds;

/// The field metadata key of a column's unit.
pub const UNIT_KEY: &str = "unit";

fn pq_err(path: &Path, e: impl std::fmt::Display) -> IoError {
    IoError::Csv { path: path.to_path_buf(), msg: format!("parquet: {e}") }
}

fn numeric(dt: &DataType) -> bool {
    matches!(
        dt,
        DataType::Float64
            | DataType::Float32
            | DataType::Float16
            | DataType::Timestamp(..)
            | DataType::Int8
            | DataType::Int16
            | DataType::Int32
            | DataType::Int64
            | DataType::UInt8
            | DataType::UInt16
            | DataType::UInt32
            | DataType::UInt64
            | DataType::Decimal128(..)
    )
}

/// Value `k` of a numeric column as `f64` (NaN for null).
fn value(a: &dyn Array, k: usize) -> f64 {
    if a.is_null(k) {
        return f64::NAN;
    }
    match a.data_type() {
        DataType::Float64 => a.as_primitive::<Float64Type>().value(k),
        DataType::Float32 => a.as_primitive::<Float32Type>().value(k) as f64,
        DataType::Float16 => a.as_primitive::<Float16Type>().value(k).to_f64(),
        DataType::Timestamp(TimeUnit::Second, _) => a.as_primitive::<TimestampSecondType>().value(k) as f64,
        DataType::Timestamp(TimeUnit::Millisecond, _) => {
            seconds(a.as_primitive::<TimestampMillisecondType>().value(k), 1e3)
        }
        DataType::Timestamp(TimeUnit::Microsecond, _) => {
            seconds(a.as_primitive::<TimestampMicrosecondType>().value(k), 1e6)
        }
        DataType::Timestamp(TimeUnit::Nanosecond, _) => {
            seconds(a.as_primitive::<TimestampNanosecondType>().value(k), 1e9)
        }
        DataType::Int8 => a.as_primitive::<Int8Type>().value(k) as f64,
        DataType::Int16 => a.as_primitive::<Int16Type>().value(k) as f64,
        DataType::Int32 => a.as_primitive::<Int32Type>().value(k) as f64,
        DataType::Int64 => a.as_primitive::<Int64Type>().value(k) as f64,
        DataType::UInt8 => a.as_primitive::<UInt8Type>().value(k) as f64,
        DataType::UInt16 => a.as_primitive::<UInt16Type>().value(k) as f64,
        DataType::UInt32 => a.as_primitive::<UInt32Type>().value(k) as f64,
        DataType::UInt64 => a.as_primitive::<UInt64Type>().value(k) as f64,
        // A database's fixed-point numbers (`Decimal(10, 3)`: value × 10⁻³).
        DataType::Decimal128(_, scale) => {
            a.as_primitive::<Decimal128Type>().value(k) as f64 / 10f64.powi(i32::from(*scale))
        }
        _ => f64::NAN,
    }
}

/// `ticks` of `per_s` to a second, as seconds: whole and fractional seconds apart, so
/// that the fraction keeps its digits.
fn seconds(ticks: i64, per_s: f64) -> f64 {
    let per = per_s as i64;
    ticks.div_euclid(per) as f64 + ticks.rem_euclid(per) as f64 / per_s
}

/// Every column chunk inside the file: the `parquet` crate panics on a negative offset
/// or size in the footer, and reads past the end on a large one.
fn check_byte_ranges(meta: &parquet::file::metadata::ParquetMetaData, file_bytes: u64) -> Result<(), String> {
    for (g, group) in meta.row_groups().iter().enumerate() {
        for c in group.columns() {
            let start = c.dictionary_page_offset().unwrap_or(c.data_page_offset());
            let len = c.compressed_size();
            let inside =
                start >= 0 && len >= 0 && (start as u64).checked_add(len as u64).is_some_and(|e| e <= file_bytes);
            if !inside {
                return Err(format!(
                    "row group {}, column `{}`: bytes {start}..+{len} are outside the file of {file_bytes} bytes (corrupt file)",
                    g + 1,
                    crate::error::shown(c.column_path().string().as_str())
                ));
            }
        }
    }
    Ok(())
}

/// Streaming reader of a Parquet recording.
pub struct ParquetReader {
    path: PathBuf,
    columns: Vec<String>,
    units: Vec<Option<String>>,
    time: TimeInSeconds,
    batches: ParquetRecordBatchReader,
    batch: Option<RecordBatch>,
    row_in_batch: usize,
    rows_read: u64,
    warnings: Vec<String>,
}

impl ParquetReader {
    /// Opens a file and checks that every column is numeric.
    pub fn open(path: &Path) -> Result<Self, IoError> {
        if path.is_dir() {
            return Err(IoError::IsDirectory(path.to_path_buf()));
        }
        let file = File::open(path).map_err(|source| IoError::Os { path: path.to_path_buf(), source })?;
        if file.metadata().map(|m| m.len()).unwrap_or(0) == 0 {
            return Err(IoError::Empty(path.to_path_buf()));
        }
        let size = file.metadata().map(|m| m.len()).unwrap_or(0);
        let builder = crate::guard::guarded(|| ParquetRecordBatchReaderBuilder::try_new(file))
            .map_err(|e| pq_err(path, e))?
            .map_err(|e| pq_err(path, e))?;
        check_byte_ranges(builder.metadata(), size).map_err(|msg| pq_err(path, msg))?;
        // Columns that are not numbers (text, categories) are left out, named in a warning.
        let all = builder.schema().clone();
        let (kept, left_out): (Vec<_>, Vec<_>) =
            all.fields().iter().enumerate().partition(|(_, f)| numeric(f.data_type()));
        if kept.is_empty() {
            if let Some((_, f)) = left_out.first() {
                return Err(IoError::WrongType {
                    path: path.to_path_buf(),
                    column: f.name().clone(),
                    found: f.data_type().to_string(),
                });
            }
        }
        let warnings = left_out
            .iter()
            .map(|(_, f)| {
                format!("column `{}` ({}) is not numeric: left out", crate::error::shown(f.name()), f.data_type())
            })
            .collect();
        let mask = parquet::arrow::ProjectionMask::roots(builder.parquet_schema(), kept.iter().map(|(i, _)| *i));
        let builder = builder.with_projection(mask);
        let schema = Arc::new(Schema::new(kept.iter().map(|(_, f)| Arc::clone(f)).collect::<Vec<_>>()));
        let columns: Vec<String> = schema.fields().iter().map(|f| f.name().clone()).collect();
        // As the CSV reader: a name twice would leave which column a command reads to chance.
        let mut seen = std::collections::HashSet::new();
        if let Some(dup) = columns.iter().find(|c| !seen.insert(c.as_str())) {
            return Err(IoError::DuplicateColumn { path: path.to_path_buf(), column: dup.clone() });
        }
        // A timestamp is read in seconds, whatever its metadata says.
        let unit = |f: &Field| match f.data_type() {
            DataType::Timestamp(..) => Some("s".to_string()),
            _ => f.metadata().get(UNIT_KEY).cloned(),
        };
        let mut units: Vec<Option<String>> = schema.fields().iter().map(|f| unit(f)).collect();
        let time = TimeInSeconds::new(&columns, &mut units);
        let batches = crate::guard::guarded(|| builder.with_batch_size(crate::DEFAULT_CHUNK_ROWS).build())
            .map_err(|e| pq_err(path, e))?
            .map_err(|e| pq_err(path, e))?;
        Ok(Self {
            path: path.to_path_buf(),
            columns,
            units,
            time,
            batches,
            batch: None,
            row_in_batch: 0,
            rows_read: 0,
            warnings,
        })
    }

    /// Column names in file order (the numeric columns).
    pub fn columns(&self) -> &[String] {
        &self.columns
    }

    /// The columns left out, one warning each.
    pub fn warnings(&self) -> &[String] {
        &self.warnings
    }

    /// Each column's unit (field metadata `unit`), if it has one.
    pub fn units(&self) -> &[Option<String>] {
        &self.units
    }

    /// Makes `name` the time column (it is `time` by default), read in seconds whatever
    /// time unit its metadata gives. No such column: nothing changes.
    pub fn set_time_column(&mut self, name: &str) {
        self.time.set_column(&self.columns, &mut self.units, name);
    }

    /// Reads the time column as the file gives it, unconverted (a config's scale
    /// converts it instead).
    pub fn keep_time_as_written(&mut self) {
        self.time.keep_as_written(&mut self.units);
    }

    /// Data rows read so far.
    pub fn rows_read(&self) -> u64 {
        self.rows_read
    }

    /// Reads the next row; `Ok(false)` at the end.
    pub fn read_row(&mut self, row: &mut Vec<f64>) -> Result<bool, IoError> {
        loop {
            if let Some(b) = &self.batch {
                if self.row_in_batch < b.num_rows() {
                    row.clear();
                    for c in b.columns() {
                        row.push(value(c.as_ref(), self.row_in_batch));
                    }
                    self.row_in_batch += 1;
                    self.time.apply(row, &self.path, self.rows_read + 1)?;
                    self.rows_read += 1;
                    return Ok(true);
                }
            }
            let next = crate::guard::guarded(|| self.batches.next()).map_err(|e| pq_err(&self.path, e))?;
            match next {
                None => return Ok(false),
                Some(Err(e)) => return Err(pq_err(&self.path, e)),
                Some(Ok(b)) => {
                    self.batch = Some(b);
                    self.row_in_batch = 0;
                }
            }
        }
    }
}

/// Most columns [`ParquetWriter`] writes: memory grows by about 25 kB per column whatever
/// the rows (the writer's page and statistics buffers), so this bounds it near 400 MB.
pub const MAX_WRITTEN_COLUMNS: usize = 16_384;

/// Parquet writer; the file appears under its name only on [`ParquetWriter::finish`].
pub struct ParquetWriter {
    path: PathBuf,
    tmp: Option<crate::output::AtomicFile>,
    schema: SchemaRef,
    writer: Option<ArrowWriter<File>>,
    buffer: Vec<Vec<f64>>,
    rows: u64,
}

impl ParquetWriter {
    /// Creates the file with `Float64` columns.
    pub fn create(path: &Path, columns: &[&str]) -> Result<Self, IoError> {
        Self::create_with_units(path, columns, &[])
    }

    /// Creates the file with `Float64` columns, `units[i]` as column `i`'s field metadata
    /// `unit` where it is `Some`.
    pub fn create_with_units(path: &Path, columns: &[&str], units: &[Option<&str>]) -> Result<Self, IoError> {
        if path.is_dir() {
            return Err(IoError::IsDirectory(path.to_path_buf()));
        }
        if columns.len() > MAX_WRITTEN_COLUMNS {
            let msg = format!(
                "{} columns: a Parquet file is written with at most {MAX_WRITTEN_COLUMNS} (each column's writer keeps \
                 its own buffers); choose topics with --topic, or write CSV",
                columns.len()
            );
            return Err(IoError::Csv { path: path.to_path_buf(), msg });
        }
        let tmp = crate::output::AtomicFile::create(path)?;
        let file = tmp.try_clone_file()?;
        let fields: Vec<Field> = columns
            .iter()
            .enumerate()
            .map(|(i, c)| {
                let field = Field::new(*c, DataType::Float64, false);
                match units.get(i).copied().flatten() {
                    Some(u) => field.with_metadata(HashMap::from([(UNIT_KEY.to_string(), u.to_string())])),
                    None => field,
                }
            })
            .collect();
        let schema: SchemaRef = Arc::new(Schema::new(fields));
        let props = WriterProperties::builder()
            .set_compression(Compression::SNAPPY)
            .set_max_row_group_row_count(Some(crate::DEFAULT_CHUNK_ROWS * 16))
            .build();
        let writer = ArrowWriter::try_new(file, schema.clone(), Some(props)).map_err(|e| pq_err(path, e))?;
        Ok(Self {
            path: path.to_path_buf(),
            tmp: Some(tmp),
            schema,
            writer: Some(writer),
            buffer: vec![Vec::with_capacity(crate::DEFAULT_CHUNK_ROWS); columns.len()],
            rows: 0,
        })
    }

    /// Writes one row.
    pub fn write_row(&mut self, row: &[f64]) -> Result<(), IoError> {
        if row.len() != self.buffer.len() {
            return Err(IoError::RowLength {
                path: self.path.clone(),
                row: self.rows + 1,
                got: row.len(),
                want: self.buffer.len(),
            });
        }
        for (c, v) in self.buffer.iter_mut().zip(row) {
            c.push(*v);
        }
        self.rows += 1;
        if self.buffer[0].len() >= crate::DEFAULT_CHUNK_ROWS {
            self.flush()?;
        }
        Ok(())
    }

    /// Writes the buffered rows as one batch.
    pub fn flush(&mut self) -> Result<(), IoError> {
        if self.buffer.first().is_none_or(|c| c.is_empty()) {
            return Ok(());
        }
        let arrays: Vec<ArrayRef> =
            self.buffer.iter_mut().map(|c| Arc::new(Float64Array::from(std::mem::take(c))) as ArrayRef).collect();
        let batch = RecordBatch::try_new(self.schema.clone(), arrays).map_err(|e| pq_err(&self.path, e))?;
        if let Some(w) = self.writer.as_mut() {
            w.write(&batch).map_err(|e| pq_err(&self.path, e))?;
        }
        Ok(())
    }

    /// Rows written.
    pub fn rows(&self) -> u64 {
        self.rows
    }

    /// Closes the file and moves it into place.
    pub fn finish(mut self) -> Result<u64, IoError> {
        self.flush()?;
        if let Some(w) = self.writer.take() {
            w.close().map_err(|e| pq_err(&self.path, e))?;
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
    fn more_columns_than_the_limit_are_refused_before_any_file() {
        let dir = std::env::temp_dir().join(format!("strainwave-parquet-wide-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("wide.parquet");
        let names: Vec<String> = (0..=MAX_WRITTEN_COLUMNS).map(|i| format!("c{i}")).collect();
        let columns: Vec<&str> = names.iter().map(String::as_str).collect();
        let e = ParquetWriter::create(&path, &columns).err().expect("refused").to_string();
        assert!(e.contains("16385 columns: a Parquet file is written with at most 16384"), "{e}");
        assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 0, "no file, no temporary");
        assert!(ParquetWriter::create(&path, &columns[..3]).is_ok());
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
