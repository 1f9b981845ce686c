//! Errors of recording I/O; each names the file and, where it applies, row and column.

use std::path::PathBuf;

/// Text from a file as a message shows it: on one line (control characters escaped)
/// and at most 40 characters.
pub(crate) fn shown(text: &str) -> String {
    let mut out = String::new();
    for (i, c) in text.chars().enumerate() {
        if i == 40 {
            out.push('…');
            break;
        }
        if c.is_control() {
            out.extend(c.escape_default());
        } else {
            out.push(c);
        }
    }
    out
}

/// A list of names on one line, at most 400 characters.
fn shown_list(text: &str) -> String {
    let one_line: String = text.chars().map(|c| if c.is_control() { ' ' } else { c }).collect();
    match one_line.char_indices().nth(400) {
        Some((i, _)) => format!("{}…", &one_line[..i]),
        None => one_line,
    }
}

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
    #[error("{path}: no column `{column}` (columns: {})", shown_list(available))]
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
    #[error("{path}: column `{}` has type {found}, expected a number", shown(column))]
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
    #[error("{path}: row {row}, column `{}`: `{}` is not a number", shown(column), shown(value))]
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
    /// A cell of a date-and-time column that is not one.
    #[error(
        "{path}: row {row}, column `{}`: `{}` is not a date and time as in data row 1 (`2026-11-29 06:00:00.125`)",
        shown(column),
        shown(value)
    )]
    NotATime {
        /// File.
        path: PathBuf,
        /// 1-based data row.
        row: u64,
        /// Column name.
        column: String,
        /// Cell text.
        value: String,
    },
    /// The first data row is text in every cell: most likely the line read as the header
    /// is a preamble above it (a DAQ's device and date lines), or a units line follows it.
    #[error(
        "{path}: row 1, column `{}`: `{}` is not a number, nor is any cell of row 1: lines above the \
         header (a preamble), or a units line below it? Start such lines with `#`, or remove them",
        shown(column),
        shown(value)
    )]
    TextRow {
        /// File.
        path: PathBuf,
        /// Column name.
        column: String,
        /// Cell text.
        value: String,
    },
    /// A value in a column after the named ones, which the header left unnamed (its line
    /// ends with a delimiter).
    #[error(
        "{path}: row {row}: `{}` in a column the header does not name (the header line ends with a \
         delimiter): name that column, or leave its cells empty",
        shown(value)
    )]
    UnnamedCell {
        /// File.
        path: PathBuf,
        /// 1-based data row.
        row: u64,
        /// Cell text.
        value: String,
    },
    /// A recording too large to be read whole (after resampling, if asked for).
    #[error(
        "{path}: more than {rows} rows of {columns} columns: too large to read whole (at most {} values); \
         read a shorter part, fewer columns or a lower --resample-hz",
        crate::recording::MAX_TABLE_VALUES
    )]
    TooLarge {
        /// File.
        path: PathBuf,
        /// Rows read when the bound was passed.
        rows: u64,
        /// Columns per row.
        columns: usize,
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
    #[error("{path}: column `{}` appears twice in the header", shown(column))]
    DuplicateColumn {
        /// File.
        path: PathBuf,
        /// Name.
        column: String,
    },
    /// Two outputs of one run would be written to one file.
    #[error("{path}: named by both {first} and {second}; give each output its own file")]
    OutputsShareFile {
        /// The path (as the second flag gave it).
        path: PathBuf,
        /// The flag that named it first.
        first: String,
        /// The flag that named it again.
        second: String,
    },
    /// The output would be written inside an input folder (a rosbag2 bag).
    #[error("{output}: is inside the input folder {input}; write the output outside it")]
    OutputInInputFolder {
        /// The output path.
        output: PathBuf,
        /// The input folder.
        input: PathBuf,
    },
    /// The output would replace an input.
    #[error("{output}: is also an input ({input}); write the output to another file")]
    OutputIsInput {
        /// The output path.
        output: PathBuf,
        /// The input it names.
        input: PathBuf,
    },
}
