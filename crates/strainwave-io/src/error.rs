//! Errors of recording I/O; each names the file and, where it applies, row and column.

use std::path::PathBuf;

/// A recording that cannot be read or written.
#[derive(Debug, thiserror::Error)]
pub enum IoError {
    /// Opening, reading or writing failed at the OS level.
    #[error("{path}: {source}")]
    Os {
        /// File.
        path: PathBuf,
        /// Cause.
        source: std::io::Error,
    },
    /// The path is a directory.
    #[error("{0}: is a directory, expected a file")]
    IsDirectory(PathBuf),
    /// No header line.
    #[error("{0}: empty file (no header line)")]
    Empty(PathBuf),
    /// A column the command needs is absent.
    #[error("{path}: no column `{column}` (columns: {available})")]
    MissingColumn {
        /// File.
        path: PathBuf,
        /// Wanted column.
        column: String,
        /// What the header has.
        available: String,
    },
    /// A config channel names a column the recording does not have.
    #[error("{path}: no column `{column}` for channel `{key}` (columns: {available})")]
    MissingChannel {
        /// File.
        path: PathBuf,
        /// Config key of the channel.
        key: String,
        /// Wanted column.
        column: String,
        /// What the header has.
        available: String,
    },
    /// A column of a non-numeric type (Parquet).
    #[error("{path}: column `{column}` has type {found}, expected a number")]
    WrongType {
        /// File.
        path: PathBuf,
        /// Column.
        column: String,
        /// Its type.
        found: String,
    },
    /// An extension we do not know.
    #[error("{0}: unknown format (use .csv, .tsv, .txt, .parquet, .mcap, .db3 or a rosbag2 folder)")]
    UnknownFormat(PathBuf),
    /// A format compiled out.
    #[error("{path}: this build has no `{feature}` support")]
    FeatureOff {
        /// File.
        path: PathBuf,
        /// Cargo feature.
        feature: &'static str,
    },
    /// MCAP is converted first, not read as a table.
    #[error("{0}: MCAP logs are read by `strainwave convert --in LOG.mcap --out REC.csv|.parquet` first")]
    McapNotARecording(PathBuf),
    /// A format that is read but not written.
    #[error("{0}: this format is read, not written; write .csv, .parquet or .mcap")]
    McapOutput(PathBuf),
    /// A cell that is not a number.
    #[error("{path}: row {row}, column `{column}`: `{value}` is not a number")]
    NotANumber {
        /// File.
        path: PathBuf,
        /// 1-based data row (the header is row 0).
        row: u64,
        /// Column name.
        column: String,
        /// Cell text.
        value: String,
    },
    /// A row with the wrong number of cells (e.g. a truncated last line).
    #[error("{path}: row {row} has {got} cells, the header has {want} (truncated or malformed line)")]
    RowLength {
        /// File.
        path: PathBuf,
        /// 1-based data row.
        row: u64,
        /// Cells found.
        got: usize,
        /// Cells expected.
        want: usize,
    },
    /// A malformed CSV line.
    #[error("{path}: {msg}")]
    Csv {
        /// File.
        path: PathBuf,
        /// Parser message.
        msg: String,
    },
    /// A row error, with the delimiter the file was read with.
    #[error("{inner} ({note})")]
    Dialect {
        /// The row error.
        inner: Box<IoError>,
        /// Delimiter and column count.
        note: String,
    },
    /// Duplicate column names in a header.
    #[error("{path}: column `{column}` appears twice in the header")]
    DuplicateColumn {
        /// File.
        path: PathBuf,
        /// Name.
        column: String,
    },
}
