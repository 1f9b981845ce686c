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

/// Rows per chunk when streaming.
pub const DEFAULT_CHUNK_ROWS: usize = 8192;

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

/// Formats an `f64` with the shortest text that parses back to the same bits.
///
/// Plain decimal for `1e-5 <= |x| < 1e16` (and zero), exponent form (`1e-7`, `6.02e23`)
/// otherwise, no `.0` on integers, `NaN`, `inf` and `-inf`: the text of Rust's `{}`/`{:e}`.
pub fn format_f64(x: f64, out: &mut String) {
    let mut bytes = Vec::with_capacity(24);
    push_f64(x, &mut bytes);
    out.extend(bytes.iter().map(|&b| char::from(b)));
}

/// Appends the text of [`format_f64`] to a byte buffer.
#[inline]
fn push_f64(x: f64, out: &mut Vec<u8>) {
    let mut zmij = zmij::Buffer::new();
    let text = zmij.format(x).as_bytes();
    let start = out.len();
    // zmij chooses the notation as std does (plain for 1e-5 <= |x| < 1e16) and the same
    // digits, but writes `1.0` for `1`, `1e+30` for `1e30`, and breaks ties otherwise.
    if (1e-5..1e16).contains(&x.abs()) {
        out.extend_from_slice(text.strip_suffix(b".0").unwrap_or(text));
    } else {
        push_other(text, out);
    }
    if may_tie(x) {
        round_tie_away(x, start, out);
    }
}

/// Appends one CSV line: the cells as [`format_f64`] writes them, then `\n`.
#[inline]
pub fn format_row(row: &[f64], out: &mut Vec<u8>) {
    for (i, v) in row.iter().enumerate() {
        if i > 0 {
            out.push(b',');
        }
        push_f64(*v, out);
    }
    out.push(b'\n');
}

/// Zero, `NaN`, infinities and the exponent form, from zmij's text to std's.
#[cold]
fn push_other(text: &[u8], out: &mut Vec<u8>) {
    let text = text.strip_suffix(b".0").unwrap_or(text);
    match text.iter().position(|&c| c == b'e') {
        Some(e) if text.get(e + 1) == Some(&b'+') => {
            out.extend_from_slice(&text[..=e]);
            out.extend_from_slice(&text[e + 2..]);
        }
        _ => out.extend_from_slice(text),
    }
}

/// `|x| = m 2^p` with `m` odd (for finite non-zero `x`).
#[inline]
fn odd_mantissa(x: f64) -> (u64, i32) {
    let bits = x.to_bits();
    let biased = ((bits >> 52) & 0x7ff) as i32;
    let fraction = bits & ((1u64 << 52) - 1);
    let (m, p) = if biased == 0 { (fraction, -1074) } else { (fraction | (1u64 << 52), biased - 1075) };
    let zeros = m.trailing_zeros().min(63);
    (m >> zeros, p + zeros as i32)
}

/// Whether the shortest text of `x` can be an exact tie between two candidates. A tie is
/// `2|x| = m 2^(p+1) = (2d+1) 10^e`, `d` the digits (< 10^17): both sides are odd numbers
/// times powers of two, so `p + 1 = e`, and `5^|e|` times an odd number stays below 2^58.
/// Zero, infinities and `NaN` fall outside too.
#[inline]
fn may_tie(x: f64) -> bool {
    (-26..=22).contains(&odd_mantissa(x).1)
}

/// Where the digits `out[start..]` of `x` lie exactly half a unit of their last digit
/// below `|x|` (zmij took the even digit of a tie), moves the last digit away from zero, as
/// std does, so the text is std's byte for byte. The digit is even: no carry.
#[cold]
fn round_tie_away(x: f64, start: usize, out: &mut [u8]) {
    let (m, p) = odd_mantissa(x);
    let text = &out[start..];
    let (mut d, mut e) = (0u64, 0i32);
    let mut in_fraction = false;
    let mut bytes = text.iter();
    for &c in bytes.by_ref() {
        match c {
            b'-' => {}
            b'.' => in_fraction = true,
            b'e' => break,
            c => {
                d = d * 10 + u64::from(c - b'0');
                e -= i32::from(in_fraction);
            }
        }
    }
    match bytes.as_slice() {
        [] => {}
        [b'-', digits @ ..] => e -= digits.iter().fold(0, |a, &c| a * 10 + i32::from(c - b'0')),
        digits => e += digits.iter().fold(0, |a, &c| a * 10 + i32::from(c - b'0')),
    }
    if p + 1 != e {
        return;
    }
    let (odd, pow5) = (2 * u128::from(d) + 1, 5u128.pow(e.unsigned_abs()));
    let tie = if e >= 0 { odd * pow5 == u128::from(m) } else { u128::from(m) * pow5 == odd };
    if tie {
        let digits = text.iter().position(|&c| c == b'e').unwrap_or(text.len());
        out[start + digits - 1] += 1;
    }
}

/// Parses one cell: ASCII whitespace around it is ignored.
#[inline]
fn parse_cell(cell: &str) -> Option<f64> {
    cell.trim_ascii().parse().ok()
}

/// What the parsing thread hands to the reader.
enum Batch {
    /// Whole rows, row-major.
    Rows(Vec<f64>),
    /// No more rows: the end of the input or the error that stopped it, with the rows
    /// counted (a row with a bad cell or the wrong length counts, as its message names it).
    End { rows: u64, result: Result<(), IoError> },
}

/// The parsing side, run on its own thread.
///
/// A record without a quote (the numeric case) is split by hand: it ends at the first `\r`
/// or `\n`, its cells at each `,`, and empty lines are skipped, as the `csv` crate does.
/// A record with a quote goes through `csv_core`, the `csv` crate's own tokenizer. Any
/// row that does not parse at once goes through [`Parser::slow_row`], which gives the
/// values and errors of the crate's text records with trimmed cells (Unicode whitespace).
struct Parser {
    path: PathBuf,
    columns: Vec<String>,
    input: Box<dyn Read + Send>,
    /// Input bytes; `buf[start..end]` is not consumed yet.
    buf: Vec<u8>,
    start: usize,
    end: usize,
    eof: bool,
    /// The last read returned less than asked: the source may not be keeping up.
    starved: bool,
    core: csv_core::Reader,
    /// Bytes consumed before `buf[start]`, and the line there (1-based), for messages.
    consumed: u64,
    line: u64,
    /// Data rows parsed.
    rows: u64,
    /// Cells of quoted records, as `csv_core` writes them.
    field_bytes: Vec<u8>,
    field_ends: Vec<usize>,
    /// The rows being gathered, and where they go.
    batch: Vec<f64>,
    out: SyncSender<Batch>,
    spent: Receiver<Vec<f64>>,
}

impl Parser {
    /// A parser at the start of `input`.
    fn new(path: PathBuf, input: Box<dyn Read + Send>, out: SyncSender<Batch>, spent: Receiver<Vec<f64>>) -> Self {
        Self {
            path,
            columns: Vec::new(),
            input,
            buf: vec![0; READ_BUFFER_BYTES],
            start: 0,
            end: 0,
            eof: false,
            starved: false,
            core: csv_core::Reader::new(),
            consumed: 0,
            line: 1,
            rows: 0,
            field_bytes: vec![0; 1024],
            field_ends: vec![0; 64],
            batch: Vec::with_capacity(BATCH_CELLS),
            out,
            spent,
        }
    }

    /// Reads the header record; its text and errors are the `csv` crate's (the column
    /// names trimmed), as it reads exactly the header's bytes.
    fn header(&mut self) -> Result<csv::StringRecord, IoError> {
        // `csv_core` drops a byte-order mark only when it sees it whole, and takes an
        // input that is nothing but the mark for the end of the input.
        while self.end < 4 && self.fill()? {}
        let (first, _) = self.next_quoted_record()?;
        let bytes = &self.buf[first..self.start];
        let mut csv = csv::ReaderBuilder::new().has_headers(true).trim(csv::Trim::Headers).from_reader(bytes);
        csv.headers().cloned().map_err(|e| csv_error(&self.path, e))
    }

    fn run(mut self) {
        let n = self.columns.len();
        let result = loop {
            match self.parse_row() {
                Ok(true) => {
                    if self.batch.len() + n > self.batch.capacity() && !self.send() {
                        return;
                    }
                }
                Ok(false) => break Ok(()),
                Err(e) => break Err(e),
            }
        };
        if self.send() {
            let _ = self.out.send(Batch::End { rows: self.rows, result });
        }
    }

    /// Passes the rows gathered so far on; `false` when the reader is gone.
    fn send(&mut self) -> bool {
        if self.batch.is_empty() {
            return true;
        }
        let mut next = self.spent.try_recv().unwrap_or_else(|_| Vec::with_capacity(BATCH_CELLS));
        next.clear();
        let full = std::mem::replace(&mut self.batch, next);
        self.out.send(Batch::Rows(full)).is_ok()
    }

    /// Reads more input after `buf[start..end]`; `Ok(false)` at the end of the input.
    fn fill(&mut self) -> Result<bool, IoError> {
        if self.eof {
            return Ok(false);
        }
        // Rows gathered so far go on before a read that may wait for a slow source.
        if self.starved && !self.send() {
            return Err(IoError::Csv { path: self.path.clone(), msg: "the reader of the rows is gone".into() });
        }
        if self.start > 0 {
            self.buf.copy_within(self.start..self.end, 0);
            self.end -= self.start;
            self.start = 0;
        }
        if self.end == self.buf.len() {
            // One record longer than the buffer.
            self.buf.resize(2 * self.buf.len(), 0);
        }
        loop {
            match self.input.read(&mut self.buf[self.end..]) {
                Ok(0) => {
                    self.eof = true;
                    return Ok(false);
                }
                Ok(n) => {
                    self.starved = n < self.buf.len() - self.end;
                    self.end += n;
                    return Ok(true);
                }
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                Err(e) => return Err(IoError::Csv { path: self.path.clone(), msg: e.to_string() }),
            }
        }
    }

    fn consume(&mut self, n: usize) {
        self.start += n;
        self.consumed += n as u64;
    }

    /// Appends the next row to the batch; `Ok(false)` at the end of the input.
    fn parse_row(&mut self) -> Result<bool, IoError> {
        // Where the `csv` crate puts the record, for messages: before the empty lines it skips.
        let mut pos = csv::Position::new();
        pos.set_byte(self.consumed).set_line(self.line).set_record(self.rows + 1);
        loop {
            while let Some(&c @ (b'\r' | b'\n')) = self.buf[self.start..self.end].first() {
                self.line += u64::from(c == b'\n');
                self.consume(1);
            }
            if self.start < self.end {
                break;
            }
            if !self.fill()? {
                return Ok(false);
            }
        }
        let mut scanned = 0;
        loop {
            let rest = &self.buf[self.start + scanned..self.end];
            match memchr::memchr3(b'\n', b'\r', b'"', rest) {
                Some(i) if rest[i] == b'"' => {
                    let (_, cells) = self.next_quoted_record()?;
                    let record = self.quoted_record(cells, pos);
                    self.slow_row(&record)?;
                    return Ok(true);
                }
                Some(i) => {
                    let t = self.start + scanned + i;
                    self.fast_row(self.start, t, pos)?;
                    self.line += u64::from(self.buf[t] == b'\n');
                    self.consume(t + 1 - self.start);
                    return Ok(true);
                }
                None => {
                    scanned = self.end - self.start;
                    if !self.fill()? {
                        // The last record, without a line end.
                        self.fast_row(self.start, self.end, pos)?;
                        self.consume(self.end - self.start);
                        return Ok(true);
                    }
                }
            }
        }
    }

    /// Parses the quote-free record `buf[from..to]` into the batch.
    #[inline]
    fn fast_row(&mut self, from: usize, to: usize, pos: csv::Position) -> Result<(), IoError> {
        let line = &self.buf[from..to];
        let n = self.columns.len();
        let before = self.batch.len();
        let mut cells = 0;
        if let Ok(text) = std::str::from_utf8(line) {
            let mut a = 0;
            for b in memchr::memchr_iter(b',', line).chain(std::iter::once(line.len())) {
                cells += 1;
                match parse_cell(&text[a..b]) {
                    Some(v) if cells <= n => self.batch.push(v),
                    _ => {
                        cells = 0;
                        break;
                    }
                }
                a = b + 1;
            }
        }
        if cells == n {
            self.rows += 1;
            return Ok(());
        }
        self.batch.truncate(before);
        let mut record = csv::ByteRecord::new();
        for cell in line.split(|&c| c == b',') {
            record.push_field(cell);
        }
        record.set_position(Some(pos));
        self.slow_row(&record)
    }

    /// Runs `csv_core` over the record at `buf[start..]`: its cells go to `field_bytes`
    /// and `field_ends`; returns where its bytes begin in the buffer (they stay there, and
    /// `start` moves past them) and its number of cells (0 at the end of the input).
    fn next_quoted_record(&mut self) -> Result<(usize, usize), IoError> {
        use csv_core::ReadRecordResult::*;
        self.core.set_line(self.line);
        let (mut first, mut nout, mut nend) = (self.start, 0, 0);
        loop {
            if self.start == self.end && !self.eof {
                let keep = self.start - first;
                self.start = first;
                self.fill()?;
                first = self.start;
                self.start += keep;
                continue;
            }
            // An empty input here is the end of the input: `csv_core` finishes the record.
            let (res, nin, o, e) = self.core.read_record(
                &self.buf[self.start..self.end],
                &mut self.field_bytes[nout..],
                &mut self.field_ends[nend..],
            );
            self.consume(nin);
            nout += o;
            nend += e;
            match res {
                InputEmpty => {}
                OutputFull => self.field_bytes.resize(2 * self.field_bytes.len(), 0),
                OutputEndsFull => self.field_ends.resize(2 * self.field_ends.len(), 0),
                Record | End => break,
            }
        }
        self.line = self.core.line();
        Ok((first, nend))
    }

    /// The quoted record just read, with its position.
    fn quoted_record(&self, cells: usize, pos: csv::Position) -> csv::ByteRecord {
        let mut record = csv::ByteRecord::new();
        let mut a = 0;
        for &b in &self.field_ends[..cells] {
            record.push_field(&self.field_bytes[a..b]);
            a = b;
        }
        record.set_position(Some(pos));
        record
    }

    /// A row that does not parse at once: the values and errors of a text-record reader
    /// with trimmed cells. The record's UTF-8 comes first, then its length, then each cell
    /// with Unicode whitespace trimmed.
    #[cold]
    fn slow_row(&mut self, record: &csv::ByteRecord) -> Result<(), IoError> {
        utf8_check(&self.path, record)?;
        self.rows += 1;
        if record.len() != self.columns.len() {
            return Err(IoError::RowLength {
                path: self.path.clone(),
                row: self.rows,
                got: record.len(),
                want: self.columns.len(),
            });
        }
        let before = self.batch.len();
        for (i, cell) in record.iter().enumerate() {
            let cell = std::str::from_utf8(cell).unwrap_or_default().trim();
            match cell.parse() {
                Ok(v) => self.batch.push(v),
                Err(_) => {
                    self.batch.truncate(before);
                    return Err(IoError::NotANumber {
                        path: self.path.clone(),
                        row: self.rows,
                        column: self.columns[i].clone(),
                        value: cell.chars().take(40).collect(),
                    });
                }
            }
        }
        Ok(())
    }
}

fn csv_error(path: &Path, e: csv::Error) -> IoError {
    IoError::Csv { path: path.to_path_buf(), msg: e.to_string() }
}

/// The error the text-record reader gives for a record that is not UTF-8 (after
/// trimming ASCII whitespace around its cells), with the same message.
fn utf8_check(path: &Path, record: &csv::ByteRecord) -> Result<(), IoError> {
    if record.as_slice().is_ascii() {
        return Ok(());
    }
    let mut trimmed = record.clone();
    trimmed.trim();
    let Err(e) = csv::StringRecord::from_byte_record(trimmed) else {
        return Ok(());
    };
    let err = e.utf8_error();
    let msg = match record.position() {
        Some(pos) => format!(
            "CSV parse error: record {} (line {}, field: {}, byte: {}): {err}",
            pos.record(),
            pos.line(),
            err.field(),
            pos.byte()
        ),
        None => format!("CSV parse error: field {}: {err}", err.field()),
    };
    Err(IoError::Csv { path: path.to_path_buf(), msg })
}

/// Streaming reader of a numeric CSV recording.
///
/// The header is read by [`CsvReader::open`]; the rows are tokenized and parsed on a
/// background thread, a few batches ahead, in constant memory.
pub struct CsvReader {
    path: PathBuf,
    columns: Vec<String>,
    rows_read: u64,
    batches: Receiver<Batch>,
    spent: Sender<Vec<f64>>,
    cells: Vec<f64>,
    next: usize,
    done: bool,
}

impl CsvReader {
    /// Opens a file (or standard input for `-`) and reads its header.
    pub fn open(path: &Path) -> Result<Self, IoError> {
        let input: Box<dyn Read + Send> = if path == Path::new("-") {
            Box::new(std::io::stdin())
        } else {
            if path.is_dir() {
                return Err(IoError::IsDirectory(path.to_path_buf()));
            }
            Box::new(File::open(path).map_err(|source| IoError::Os { path: path.to_path_buf(), source })?)
        };
        Self::from_reader(path, input)
    }

    /// Reads from any byte source; `path` is used in messages.
    pub fn from_reader(path: &Path, input: Box<dyn Read + Send>) -> Result<Self, IoError> {
        let path = path.to_path_buf();
        let (out, batches) = mpsc::sync_channel(BATCHES_AHEAD);
        let (spent, spent_rx) = mpsc::channel();
        let mut parser = Parser::new(path.clone(), input, out, spent_rx);
        let header = parser.header()?;
        if header.is_empty() || (header.len() == 1 && header[0].is_empty()) {
            return Err(IoError::Empty(path));
        }
        let columns: Vec<String> = header.iter().map(str::to_string).collect();
        let mut seen = std::collections::HashSet::with_capacity(columns.len());
        if let Some(c) = columns.iter().find(|c| !seen.insert(c.as_str())) {
            return Err(IoError::DuplicateColumn { path, column: c.clone() });
        }
        parser.columns = columns.clone();
        std::thread::Builder::new()
            .name("csv-parse".into())
            .spawn(move || parser.run())
            .map_err(|source| IoError::Os { path: path.clone(), source })?;
        Ok(Self { path, columns, rows_read: 0, batches, spent, cells: Vec::new(), next: 0, done: false })
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
            Ok(Batch::End { rows, result }) => {
                self.done = true;
                self.rows_read = rows;
                result.map(|()| false)
            }
            Err(_) => {
                self.done = true;
                Err(IoError::Csv { path: self.path.clone(), msg: "the CSV parsing thread stopped".into() })
            }
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

/// Writes full buffers to a file on its own thread, so that the copy into the OS overlaps
/// the formatting of the next rows; written buffers come back for reuse.
struct FileWriter {
    full: Option<SyncSender<Vec<u8>>>,
    empty: Receiver<Vec<u8>>,
    /// Buffers handed over and not back yet.
    in_flight: usize,
    thread: Option<std::thread::JoinHandle<std::io::Result<()>>>,
    failed: bool,
}

impl FileWriter {
    fn spawn(mut file: File) -> std::io::Result<Self> {
        let (full, full_rx) = mpsc::sync_channel::<Vec<u8>>(1);
        let (empty_tx, empty) = mpsc::channel();
        let thread = std::thread::Builder::new().name("csv-write".into()).spawn(move || {
            for mut buf in full_rx {
                file.write_all(&buf)?;
                buf.clear();
                let _ = empty_tx.send(buf);
            }
            file.flush()
        })?;
        Ok(Self { full: Some(full), empty, in_flight: 0, thread: Some(thread), failed: false })
    }

    /// Hands the rows in `buf` over, leaving an empty buffer in their place.
    fn write(&mut self, buf: &mut Vec<u8>) -> std::io::Result<()> {
        let spare = match self.empty.try_recv() {
            Ok(spare) => {
                self.in_flight -= 1;
                spare
            }
            Err(_) => Vec::with_capacity(buf.capacity()),
        };
        let rows = std::mem::replace(buf, spare);
        let sent = self.full.as_ref().is_some_and(|full| full.send(rows).is_ok());
        if !sent {
            return self.finish().and(Err(std::io::Error::other("the writing thread stopped")));
        }
        self.in_flight += 1;
        Ok(())
    }

    /// Waits until every buffer handed over is written.
    fn wait(&mut self) -> std::io::Result<()> {
        while self.in_flight > 0 {
            if self.empty.recv().is_err() {
                return self.finish().and(Err(std::io::Error::other("the writing thread stopped")));
            }
            self.in_flight -= 1;
        }
        Ok(())
    }

    /// Writes what was handed over and closes the file; its first error, if any.
    fn finish(&mut self) -> std::io::Result<()> {
        self.full = None;
        let result = match self.thread.take() {
            Some(thread) => thread.join().unwrap_or_else(|_| Err(std::io::Error::other("the writing thread panicked"))),
            None if self.failed => Err(std::io::Error::other("an earlier write failed")),
            None => Ok(()),
        };
        self.failed |= result.is_err();
        result
    }
}

impl Drop for FileWriter {
    fn drop(&mut self) {
        let _ = self.finish();
    }
}

enum Sink {
    File { tmp: PathBuf, out: FileWriter },
    Stdout(std::io::Stdout),
}

/// CSV writer; the file appears under its name only on [`CsvWriter::finish`].
///
/// Rows are formatted straight into one buffer, written out when it holds 1 MiB
/// (standard output: 64 KiB); a file is written on a thread of its own.
pub struct CsvWriter {
    path: PathBuf,
    sink: Option<Sink>,
    n_cols: usize,
    buf: Vec<u8>,
    limit: usize,
    rows: u64,
}

impl CsvWriter {
    /// Creates the output (standard output for `-`) and writes the header.
    pub fn create(path: &Path, columns: &[&str]) -> Result<Self, IoError> {
        let os = |source| IoError::Os { path: path.to_path_buf(), source };
        let (sink, limit) = if path == Path::new("-") {
            (Sink::Stdout(std::io::stdout()), STDOUT_WRITE_BUFFER_BYTES)
        } else {
            if path.is_dir() {
                return Err(IoError::IsDirectory(path.to_path_buf()));
            }
            let name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_else(|| "out".into());
            let tmp = path.with_file_name(format!(".{name}.partial"));
            let file = File::create(&tmp).map_err(os)?;
            let out = match FileWriter::spawn(file) {
                Ok(out) => out,
                Err(e) => {
                    let _ = std::fs::remove_file(&tmp);
                    return Err(os(e));
                }
            };
            (Sink::File { tmp, out }, FILE_WRITE_BUFFER_BYTES)
        };
        // Room for the last row past the limit, so the buffer never grows.
        let mut buf = Vec::with_capacity(limit + 4096);
        buf.extend_from_slice(columns.join(",").as_bytes());
        buf.push(b'\n');
        let mut w = Self { path: path.to_path_buf(), sink: Some(sink), n_cols: columns.len(), buf, limit, rows: 0 };
        if w.buf.len() >= w.limit {
            w.write_out()?;
        }
        Ok(w)
    }

    /// Writes the buffer out (to a file: hands it to the writing thread).
    fn write_out(&mut self) -> Result<(), IoError> {
        let r = match self.sink.as_mut() {
            Some(Sink::File { out, .. }) => out.write(&mut self.buf),
            Some(Sink::Stdout(out)) => out.write_all(&self.buf),
            None => Ok(()),
        };
        self.buf.clear();
        r.map_err(|source| IoError::Os { path: self.path.clone(), source })
    }

    /// Writes one row; its length must match the header.
    #[inline]
    pub fn write_row(&mut self, row: &[f64]) -> Result<(), IoError> {
        if row.len() != self.n_cols {
            return Err(IoError::RowLength {
                path: self.path.clone(),
                row: self.rows + 1,
                got: row.len(),
                want: self.n_cols,
            });
        }
        format_row(row, &mut self.buf);
        self.rows += 1;
        if self.buf.len() >= self.limit {
            self.write_out()?;
        }
        Ok(())
    }

    /// Flushes buffered rows (for live pipes).
    pub fn flush(&mut self) -> Result<(), IoError> {
        self.write_out()?;
        let r = match self.sink.as_mut() {
            Some(Sink::File { out, .. }) => out.wait(),
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
        self.write_out()?;
        let os = |source| IoError::Os { path: self.path.clone(), source };
        match self.sink.as_mut() {
            Some(Sink::File { out, .. }) => out.finish().map_err(os)?,
            Some(Sink::Stdout(out)) => out.flush().map_err(os)?,
            None => {}
        }
        if let Some(Sink::File { tmp, out }) = self.sink.take() {
            drop(out);
            std::fs::rename(&tmp, &self.path).map_err(|source| IoError::Os { path: self.path.clone(), source })?;
        }
        Ok(self.rows)
    }
}

impl Drop for CsvWriter {
    fn drop(&mut self) {
        match self.sink.take() {
            Some(Sink::File { tmp, out }) => {
                drop(out);
                let _ = std::fs::remove_file(tmp);
            }
            // Rows already written stay written, as with a buffered writer dropped.
            Some(Sink::Stdout(mut out)) => {
                let _ = out.write_all(&self.buf).and_then(|()| out.flush());
            }
            None => {}
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

    /// std's shortest text, plain or exponent form: what `format_f64` must write.
    fn std_text(x: f64) -> String {
        if x == 0.0 || (1e-5..1e16).contains(&x.abs()) || !x.is_finite() {
            format!("{x}")
        } else {
            format!("{x:e}")
        }
    }

    /// A small xorshift generator, so the cases are the same in every run.
    struct Rng(u64);

    impl Rng {
        fn next(&mut self) -> u64 {
            self.0 ^= self.0 << 13;
            self.0 ^= self.0 >> 7;
            self.0 ^= self.0 << 17;
            self.0
        }

        fn below(&mut self, n: usize) -> usize {
            (self.next() % n as u64) as usize
        }
    }

    #[test]
    fn formatting_is_std_text_byte_for_byte() {
        let mut values = vec![
            0.0,
            -0.0,
            f64::NAN,
            -f64::NAN,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::MAX,
            f64::MIN,
            f64::MIN_POSITIVE,
            5e-324,
            1e-5,
            1e16,
            9999999999999998.0,
            0.1 + 0.2,
            64.0,
            -3.0,
        ];
        for e in -1074..1024 {
            let x = 2f64.powi(e);
            values.extend([x, x.next_up(), x.next_down(), -x]);
        }
        for e in -324..=308 {
            let x: f64 = format!("1e{e}").parse().unwrap();
            values.extend([x, x.next_up(), x.next_down()]);
        }
        // Exact ties between two shortest texts (e.g. 2^-25, 2^49 + 1/4), where ryu-style
        // formatters pick the even digit and std the one away from zero.
        for m in (1..2000u64).step_by(2) {
            for p in -30..=25 {
                values.push(m as f64 * 2f64.powi(p));
            }
        }
        let mut rng = Rng(0x9E37_79B9_7F4A_7C15);
        for _ in 0..100_000 {
            values.push(f64::from_bits(rng.next()));
            let odd = (rng.next() >> 11) | 1;
            values.push(-(odd as f64) * 2f64.powi(-(rng.below(27) as i32) - 1));
            values.push((rng.next() >> 11) as f64 / (1u64 << 53) as f64 * 200.0 - 100.0);
        }
        let mut line = Vec::new();
        for x in values {
            line.clear();
            push_f64(x, &mut line);
            let text = String::from_utf8(line.clone()).unwrap();
            assert_eq!(text, std_text(x), "{:016x}", x.to_bits());
            if !x.is_nan() {
                assert_eq!(text.parse::<f64>().unwrap().to_bits(), x.to_bits(), "{text}");
            }
        }
    }

    #[test]
    fn values_are_bit_exact_and_quoted_cells_parse() {
        let text = "time,\"torque, N·m\" ,x\n\
                    0.30000000000000004,5e-324,1.7976931348623157e308\n\
                    \"1.5\",\" -0 \",\"2.5e-8\"\r\n\
                    \n\
                    \u{feff}1,\"multi\nline\",3\r\
                    4 , 5\t,\u{a0}6\u{3000}\n";
        let mut r = CsvReader::from_reader(Path::new("rec.csv"), Box::new(text.as_bytes())).unwrap();
        assert_eq!(r.columns(), ["time", "torque, N·m", "x"]);
        let mut row = Vec::new();
        assert!(r.read_row(&mut row).unwrap());
        let bits: Vec<u64> = row.iter().map(|v| v.to_bits()).collect();
        assert_eq!(bits, [0.30000000000000004f64.to_bits(), 1, f64::MAX.to_bits()]);
        assert!(r.read_row(&mut row).unwrap());
        assert_eq!(row.iter().map(|v| v.to_bits()).collect::<Vec<_>>(), [1.5f64, -0.0, 2.5e-8].map(f64::to_bits));
        let e = r.read_row(&mut row).unwrap_err().to_string();
        assert_eq!(e, "rec.csv: row 3, column `time`: `\u{feff}1` is not a number");
        assert_eq!(r.rows_read(), 3);
        let mut r = CsvReader::from_reader(Path::new("rec.csv"), Box::new(&text.as_bytes()[97..])).unwrap();
        assert_eq!(r.columns(), ["1", "multi\nline", "3"]);
        assert!(r.read_row(&mut row).unwrap());
        assert_eq!(row, [4.0, 5.0, 6.0]);
        assert!(!r.read_row(&mut row).unwrap());
        assert_eq!(r.rows_read(), 1);
    }

    #[test]
    fn errors_name_file_row_and_column() {
        let mut row = Vec::new();
        let mut r = reader("time,a,b\n0,1,2\n1,2,\"x y\"\n").unwrap();
        r.read_row(&mut row).unwrap();
        let e = r.read_row(&mut row).unwrap_err().to_string();
        assert_eq!(e, "rec.csv: row 2, column `b`: `x y` is not a number");
        let mut r = reader("time,a,b\n0,1,2\n1,2,3,4\n").unwrap();
        r.read_row(&mut row).unwrap();
        let e = r.read_row(&mut row).unwrap_err().to_string();
        assert_eq!(e, "rec.csv: row 2 has 4 cells, the header has 3 (truncated or malformed line)");
        let bad = CsvReader::from_reader(Path::new("rec.csv"), Box::new(&b"a,b\n1,2\r\n3,\xff\n"[..]));
        let e = bad.unwrap().read_chunk(&mut row, 10).unwrap_err().to_string();
        assert_eq!(
            e,
            "rec.csv: CSV parse error: record 2 (line 2, field: 1, byte: 8): \
             invalid utf-8: invalid UTF-8 in field 1 near byte index 0"
        );
        assert!(matches!(reader("\n\n"), Err(IoError::Empty(_))));
        let mut r = reader("time\n").unwrap();
        assert!(!r.read_row(&mut row).unwrap());
        assert_eq!(r.rows_read(), 0);
    }

    /// Reads at most a few bytes per call, to cross every buffer boundary.
    struct Trickle {
        data: Vec<u8>,
        at: usize,
        rng: Rng,
    }

    impl Read for Trickle {
        fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
            let n = (1 + self.rng.below(7)).min(buf.len()).min(self.data.len() - self.at);
            buf[..n].copy_from_slice(&self.data[self.at..self.at + n]);
            self.at += n;
            Ok(n)
        }
    }

    /// What a reader gives for `data`: the header or its error, then each row's bits or
    /// error and the rows counted after it, up to the first error.
    type Outcome = (Result<Vec<String>, String>, Vec<(Result<Vec<u64>, String>, u64)>);

    /// The plain reader: the `csv` crate's text records, cells trimmed, `str::parse`.
    fn reference(data: &[u8]) -> Outcome {
        let path = Path::new("rec.csv");
        let mut csv = csv::ReaderBuilder::new().flexible(true).trim(csv::Trim::All).from_reader(data);
        let header = match csv.headers() {
            Ok(h) => h.clone(),
            Err(e) => return (Err(csv_error(path, e).to_string()), Vec::new()),
        };
        if header.is_empty() || (header.len() == 1 && header[0].is_empty()) {
            return (Err(IoError::Empty(path.into()).to_string()), Vec::new());
        }
        let columns: Vec<String> = header.iter().map(str::to_string).collect();
        if let Some(c) = columns.iter().enumerate().find_map(|(i, c)| columns[..i].contains(c).then_some(c)) {
            return (Err(IoError::DuplicateColumn { path: path.into(), column: c.clone() }.to_string()), Vec::new());
        }
        let mut rows = Vec::new();
        let mut record = csv::StringRecord::new();
        let mut n = 0;
        loop {
            let row = match csv.read_record(&mut record) {
                Ok(false) => return (Ok(columns), rows),
                Err(e) => Err(csv_error(path, e).to_string()),
                Ok(true) => {
                    n += 1;
                    if record.len() != columns.len() {
                        let (got, want) = (record.len(), columns.len());
                        Err(IoError::RowLength { path: path.into(), row: n, got, want }.to_string())
                    } else {
                        record
                            .iter()
                            .enumerate()
                            .map(|(i, cell)| {
                                cell.parse::<f64>().map(f64::to_bits).map_err(|_| {
                                    let value = cell.chars().take(40).collect();
                                    let column = columns[i].clone();
                                    IoError::NotANumber { path: path.into(), row: n, column, value }.to_string()
                                })
                            })
                            .collect()
                    }
                }
            };
            let stop = row.is_err();
            rows.push((row, n));
            if stop {
                return (Ok(columns), rows);
            }
        }
    }

    fn ours(data: &[u8], seed: u64) -> Outcome {
        let input = Trickle { data: data.to_vec(), at: 0, rng: Rng(seed) };
        let mut r = match CsvReader::from_reader(Path::new("rec.csv"), Box::new(input)) {
            Ok(r) => r,
            Err(e) => return (Err(e.to_string()), Vec::new()),
        };
        let mut rows = Vec::new();
        let mut row = Vec::new();
        loop {
            match r.read_row(&mut row) {
                Ok(false) => return (Ok(r.columns().to_vec()), rows),
                Ok(true) => rows.push((Ok(row.iter().map(|v| v.to_bits()).collect()), r.rows_read())),
                Err(e) => {
                    rows.push((Err(e.to_string()), r.rows_read()));
                    return (Ok(r.columns().to_vec()), rows);
                }
            }
        }
    }

    #[test]
    fn reads_what_the_csv_crate_reads() {
        let cells: &[&[u8]] = &[
            b"1.5",
            b" 2 ",
            b"-0",
            b"1e-7",
            b"NaN",
            b"inf",
            b"-inf",
            b"+3",
            b".5",
            b"0.30000000000000004",
            b"\"3.25\"",
            b"\" 4 \"",
            b"\"5,5\"",
            b"\"a\"\"b\"",
            b"\"7\r\n\"",
            b"1\"2",
            b"abc",
            b"",
            b" ",
            "\u{a0}6\u{a0}".as_bytes(),
            "\u{3000}7".as_bytes(),
            b"\x0b8",
            b"\x0c9\t",
            b"\xff",
            b"\xc3",
            b"\xa9",
            "é".as_bytes(),
            b"1e400",
            b"0x10",
        ];
        let ends: &[&[u8]] = &[b"\n", b"\n", b"\n", b"\r\n", b"\r", b"\n\n", b"\r\n\r\n"];
        let mut rng = Rng(0x2545_F491_4F6C_DD1D);
        for case in 0..3000 {
            let mut data = Vec::new();
            if rng.below(20) == 0 {
                data.extend_from_slice("\u{feff}".as_bytes());
            }
            if rng.below(10) == 0 {
                data.extend_from_slice(ends[rng.below(ends.len())]);
            }
            let columns = 1 + rng.below(4);
            let names: &[&[u8]] = &[b"time", b" a ", b"\"b,c\"", b"d", b"e", b"\"\"", b"\xfe"];
            for c in 0..columns {
                if c > 0 {
                    data.push(b',');
                }
                data.extend_from_slice(names[(c + rng.below(3) * usize::from(rng.below(5) == 0)) % names.len()]);
            }
            for _ in 0..rng.below(12) {
                data.extend_from_slice(ends[rng.below(ends.len())]);
                let n = if rng.below(8) == 0 { rng.below(6) } else { columns };
                for c in 0..n {
                    if c > 0 {
                        data.push(b',');
                    }
                    if rng.below(3) == 0 {
                        data.extend_from_slice(cells[rng.below(cells.len())]);
                    } else {
                        data.extend_from_slice(std_text(f64::from_bits(rng.next())).as_bytes());
                    }
                }
            }
            if rng.below(2) == 0 {
                data.extend_from_slice(ends[rng.below(ends.len())]);
            }
            let (want, got) = (reference(&data), ours(&data, case));
            assert_eq!(got, want, "case {case}: {:?}", String::from_utf8_lossy(&data));
        }
    }

    #[test]
    fn long_records_cross_the_read_buffer() {
        // Rows of about 1.5 MB: wide, with cells padded by spaces.
        let columns = 2_500;
        let mut text = (0..columns).map(|c| format!("c{c}")).collect::<Vec<_>>().join(",");
        for k in 0..3 {
            text.push('\n');
            let cells: Vec<String> =
                (0..columns).map(|c| format!("{:>600}", std_text((k * columns + c) as f64 / 7.0))).collect();
            text.push_str(&cells.join(","));
        }
        assert!(text.len() > 2 * READ_BUFFER_BYTES);
        let mut r = CsvReader::from_reader(Path::new("rec.csv"), Box::new(std::io::Cursor::new(text))).unwrap();
        let mut row = Vec::new();
        for k in 0..3 {
            assert!(r.read_row(&mut row).unwrap());
            assert_eq!(row.len(), columns);
            assert_eq!(row[columns - 1], ((k + 1) * columns - 1) as f64 / 7.0);
        }
        assert!(!r.read_row(&mut row).unwrap());
    }

    /// A pipe: reads wait for what the other end sends.
    struct Pipe(std::sync::mpsc::Receiver<Vec<u8>>, Vec<u8>);

    impl Read for Pipe {
        fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
            if self.1.is_empty() {
                self.1 = self.0.recv().unwrap_or_default();
            }
            let n = self.1.len().min(buf.len());
            buf[..n].copy_from_slice(&self.1[..n]);
            self.1.drain(..n);
            Ok(n)
        }
    }

    #[test]
    fn rows_from_a_live_pipe_arrive_without_waiting_for_a_batch() {
        let (send, receive) = std::sync::mpsc::channel();
        send.send(b"time,x\n0,1\n0.001,2\n".to_vec()).unwrap();
        let mut r = CsvReader::from_reader(Path::new("-"), Box::new(Pipe(receive, Vec::new()))).unwrap();
        let (done, wait) = std::sync::mpsc::channel();
        let t = std::thread::spawn(move || {
            let mut row = Vec::new();
            for want in [[0.0, 1.0], [0.001, 2.0]] {
                assert!(r.read_row(&mut row).unwrap());
                assert_eq!(row, want);
            }
            done.send(()).unwrap();
            assert!(r.read_row(&mut row).unwrap());
            assert_eq!(row, [0.002, 3.0]);
            assert!(!r.read_row(&mut row).unwrap());
        });
        // The two rows come while the pipe stays open.
        wait.recv_timeout(std::time::Duration::from_secs(30)).expect("rows held back");
        send.send(b"0.002,3\n".to_vec()).unwrap();
        drop(send);
        t.join().unwrap();
    }

    #[test]
    fn writer_output_is_byte_for_byte_the_std_text() {
        let dir = std::env::temp_dir().join(format!("sw-io-w-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("out.csv");
        let mut w = CsvWriter::create(&path, &["a", "b", "c"]).unwrap();
        let mut want = String::from("a,b,c\n");
        let mut rng = Rng(7);
        // Enough rows to cross the write buffer a few times.
        for k in 0..150_000 {
            let row = [k as f64 * 1e-3, f64::from_bits(rng.next()), (k % 7) as f64 - 3.0];
            w.write_row(&row).unwrap();
            want.push_str(&row.map(std_text).join(","));
            want.push('\n');
        }
        assert_eq!(w.finish().unwrap(), 150_000);
        assert!(std::fs::read_to_string(&path).unwrap() == want, "output differs from std's text");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
