//! The background parser: splits the input into records and cells into batches of rows.

use super::*;

/// What the parsing thread hands to the reader.
pub(super) enum Batch {
    /// Whole rows, row-major.
    Rows(Vec<f64>),
    /// No more rows: the end of the input or the error that stopped it, with the rows
    /// counted (a row with a bad cell or the wrong length counts, as its message names it).
    /// With the cells read as NaN for not being numbers: their count and where the first
    /// was (`row 3, column `b`: `x``).
    End { rows: u64, result: Result<(), IoError>, unreadable: Option<(u64, String)> },
}

/// What a column's cells hold, as its cell in the first data row shows.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum CellKind {
    /// Numbers.
    Number,
    /// Text: the column is left out, its cells not read.
    Text,
    /// Dates and times, read as seconds since 1970 (see `date_time`).
    DateTime,
}

/// The parsing side, run on its own thread.
///
/// A record without a quote (the numeric case) is split by hand: it ends at the first `\r`
/// or `\n`, its cells at each `,`, and empty lines are skipped, as the `csv` crate does.
/// A record with a quote goes through `csv_core`, the `csv` crate's own tokenizer. Any
/// row that does not parse at once goes through [`Parser::slow_row`], which gives the
/// values and errors of the crate's text records with trimmed cells (Unicode whitespace).
pub(super) struct Parser {
    path: PathBuf,
    pub(super) columns: Vec<String>,
    /// Per column of the header, what its cells hold (empty: numbers, every column).
    pub(super) kinds: Vec<CellKind>,
    /// Cells after the last column that the header leaves unnamed (a delimiter at the end
    /// of each line, as spreadsheet and DAQ exports write): they must be empty.
    pub(super) unnamed_tail: usize,
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
    /// The cell delimiter, and whether a comma in a cell is a decimal point.
    delimiter: u8,
    decimal_comma: bool,
    /// A cell that is not a number is NaN (counted, the first named) instead of an error.
    pub(super) unreadable_as_nan: bool,
    unreadable: u64,
    first_unreadable: Option<String>,
    /// The rows being gathered, and where they go.
    batch: Vec<f64>,
    out: SyncSender<Batch>,
    spent: Receiver<Vec<f64>>,
}

impl Parser {
    /// A parser at the start of `input`.
    pub(super) fn new(
        path: PathBuf,
        input: Box<dyn Read + Send>,
        out: SyncSender<Batch>,
        spent: Receiver<Vec<f64>>,
        delimiter: u8,
    ) -> Self {
        Self {
            path,
            columns: Vec::new(),
            kinds: Vec::new(),
            unnamed_tail: 0,
            input,
            buf: vec![0; READ_BUFFER_BYTES],
            start: 0,
            end: 0,
            eof: false,
            starved: false,
            core: csv_core::ReaderBuilder::new().delimiter(delimiter).comment(Some(b'#')).build(),
            consumed: 0,
            line: 1,
            rows: 0,
            field_bytes: vec![0; 1024],
            field_ends: vec![0; 64],
            delimiter,
            decimal_comma: delimiter != b',',
            unreadable_as_nan: false,
            unreadable: 0,
            first_unreadable: None,
            batch: Vec::with_capacity(BATCH_CELLS),
            out,
            spent,
        }
    }

    /// Reads the header record; its text and errors are the `csv` crate's (the column
    /// names trimmed), as it reads exactly the header's bytes.
    pub(super) fn header(&mut self) -> Result<csv::StringRecord, IoError> {
        // `csv_core` drops a byte-order mark only when it sees it whole, and takes an
        // input that is nothing but the mark for the end of the input.
        while self.end < 4 && self.fill()? {}
        if self.buf[..self.end].starts_with(b"\xff\xfe") || self.buf[..self.end].starts_with(b"\xfe\xff") {
            let msg = "the text is UTF-16: save it as UTF-8 (or as CSV from the program that wrote it)".to_string();
            return Err(IoError::Csv { path: self.path.clone(), msg });
        }
        let (first, _) = self.next_quoted_record()?;
        let bytes = &self.buf[first..self.start];
        let mut csv = csv::ReaderBuilder::new()
            .has_headers(true)
            .trim(csv::Trim::Headers)
            .delimiter(self.delimiter)
            .comment(Some(b'#'))
            .from_reader(bytes);
        match csv.headers() {
            Ok(h) => Ok(h.clone()),
            // Not UTF-8: the names in Windows-1252.
            Err(e) if matches!(e.kind(), csv::ErrorKind::Utf8 { .. }) => {
                let names = csv.byte_headers().map_err(|e| csv_error(&self.path, e))?;
                Ok(names.iter().map(|n| dialect::header_text(n).trim().to_string()).collect())
            }
            Err(e) => Err(csv_error(&self.path, e)),
        }
    }

    /// What each column holds, from the first data row (peeked at after the header,
    /// not consumed): a cell of text where others of the row hold numbers is a text
    /// column (a DAQ's state or comment), a date and time a time column. Empty (numbers
    /// everywhere) when that row is not wholly within the buffer, holds no number, or has
    /// another length: the parse then names what is wrong with it.
    pub(super) fn column_kinds(&mut self) -> Result<Vec<CellKind>, IoError> {
        let n = self.columns.len();
        let mut record = csv::ByteRecord::new();
        loop {
            let rest = &self.buf[self.start..self.end];
            let mut csv = csv::ReaderBuilder::new()
                .has_headers(false)
                .flexible(true)
                .delimiter(self.delimiter)
                .comment(Some(b'#'))
                .from_reader(rest);
            let found = csv.read_byte_record(&mut record).unwrap_or(false);
            // A record that reaches the end of the bytes read may go on past them.
            if (found && (csv.position().byte() as usize) < rest.len()) || self.eof {
                if !found {
                    return Ok(Vec::new());
                }
                break;
            }
            // Comment lines and the row beyond a buffer's worth: no peeking that far.
            if rest.len() >= READ_BUFFER_BYTES {
                return Ok(Vec::new());
            }
            self.fill()?;
        }
        if !(n..=n + self.unnamed_tail).contains(&record.len()) {
            return Ok(Vec::new());
        }
        let kinds: Vec<CellKind> = record
            .iter()
            .take(n)
            .map(|cell| {
                let text = String::from_utf8_lossy(cell);
                if text.trim().is_empty() || parse_slow(cell, self.decimal_comma).is_some() {
                    CellKind::Number
                } else if parse_date_time(&text).is_some() {
                    CellKind::DateTime
                } else {
                    CellKind::Text
                }
            })
            .collect();
        // A row without a number (a units line, a preamble) is no row of data.
        let numbers = record
            .iter()
            .take(n)
            .zip(&kinds)
            .any(|(cell, &k)| k == CellKind::DateTime || parse_slow(cell, self.decimal_comma).is_some());
        Ok(if numbers && kinds.iter().any(|&k| k != CellKind::Number) { kinds } else { Vec::new() })
    }

    /// What column `i`'s cells hold.
    #[inline]
    fn kind(&self, i: usize) -> CellKind {
        self.kinds.get(i).copied().unwrap_or(CellKind::Number)
    }

    pub(super) fn run(mut self) {
        let n = self.columns.len() - self.kinds.iter().filter(|&&k| k == CellKind::Text).count();
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
            let unreadable = self.first_unreadable.take().map(|first| (self.unreadable, first));
            let _ = self.out.send(Batch::End { rows: self.rows, result, unreadable });
        }
    }

    /// Passes the rows gathered so far on; `false` when the reader is gone.
    pub(super) fn send(&mut self) -> bool {
        if self.batch.is_empty() {
            return true;
        }
        let mut next = self.spent.try_recv().unwrap_or_else(|_| Vec::with_capacity(BATCH_CELLS));
        next.clear();
        let full = std::mem::replace(&mut self.batch, next);
        self.out.send(Batch::Rows(full)).is_ok()
    }

    /// Reads more input after `buf[start..end]`; `Ok(false)` at the end of the input.
    pub(super) fn fill(&mut self) -> Result<bool, IoError> {
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
            // One record longer than the buffer: it may grow up to the limit.
            if self.buf.len() >= MAX_RECORD_BYTES {
                let at = if self.rows == 0 && self.columns.is_empty() {
                    "the header line".to_string()
                } else {
                    format!("row {}", self.rows + 1)
                };
                return Err(IoError::Csv {
                    path: self.path.clone(),
                    msg: format!("{at} is longer than {} MiB (not a recording?)", MAX_RECORD_BYTES >> 20),
                });
            }
            self.buf.resize((2 * self.buf.len()).min(MAX_RECORD_BYTES), 0);
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

    pub(super) fn consume(&mut self, n: usize) {
        self.start += n;
        self.consumed += n as u64;
    }

    /// Appends the next row to the batch; `Ok(false)` at the end of the input.
    pub(super) fn parse_row(&mut self) -> Result<bool, IoError> {
        // Where the `csv` crate puts the record, for messages: before the empty lines it skips.
        let mut pos = csv::Position::new();
        pos.set_byte(self.consumed).set_line(self.line).set_record(self.rows + 1);
        loop {
            while let Some(&c @ (b'\r' | b'\n')) = self.buf[self.start..self.end].first() {
                self.line += u64::from(c == b'\n');
                self.consume(1);
            }
            // A comment line: up to its line end.
            if self.buf[self.start..self.end].first() == Some(&b'#') {
                match memchr::memchr(b'\n', &self.buf[self.start..self.end]) {
                    Some(i) => {
                        self.line += 1;
                        self.consume(i + 1);
                        continue;
                    }
                    None if self.eof => {
                        self.consume(self.end - self.start);
                    }
                    None => {}
                }
            }
            if self.start < self.end && self.buf[self.start] != b'#' {
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
    pub(super) fn fast_row(&mut self, from: usize, to: usize, pos: csv::Position) -> Result<(), IoError> {
        let mut line = &self.buf[from..to];
        for _ in 0..self.unnamed_tail {
            match line.trim_ascii_end().strip_suffix(&[self.delimiter]) {
                Some(rest) => line = rest,
                None => break,
            }
        }
        let n = self.columns.len();
        let before = self.batch.len();
        let mut cells = 0;
        if let Ok(text) = std::str::from_utf8(line) {
            let mut a = 0;
            let decimal_comma = self.decimal_comma;
            for b in memchr::memchr_iter(self.delimiter, line).chain(std::iter::once(line.len())) {
                cells += 1;
                let cell = &text[a..b];
                let value = match self.kind(cells - 1) {
                    CellKind::Number if decimal_comma && cell.contains(',') => parse_decimal_comma(cell),
                    CellKind::Number => parse_cell(cell),
                    CellKind::Text => {
                        a = b + 1;
                        continue;
                    }
                    CellKind::DateTime => parse_date_time(cell),
                };
                match value {
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
        for cell in line.split(|&c| c == self.delimiter) {
            record.push_field(cell);
        }
        record.set_position(Some(pos));
        self.slow_row(&record)
    }

    /// Runs `csv_core` over the record at `buf[start..]`: its cells go to `field_bytes`
    /// and `field_ends`; returns where its bytes begin in the buffer (they stay there, and
    /// `start` moves past them) and its number of cells (0 at the end of the input).
    pub(super) fn next_quoted_record(&mut self) -> Result<(usize, usize), IoError> {
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
    pub(super) fn quoted_record(&self, cells: usize, pos: csv::Position) -> csv::ByteRecord {
        let mut record = csv::ByteRecord::new();
        let mut a = 0;
        for &b in &self.field_ends[..cells] {
            record.push_field(&self.field_bytes[a..b]);
            a = b;
        }
        record.set_position(Some(pos));
        record
    }

    /// A row that does not parse at once: its length, then each cell with Unicode
    /// whitespace trimmed. A cell that is not UTF-8 is not a number, shown with `�` for
    /// the bytes that are not text.
    #[cold]
    pub(super) fn slow_row(&mut self, record: &csv::ByteRecord) -> Result<(), IoError> {
        self.rows += 1;
        let n = self.columns.len();
        let in_tail = record.len() > n && record.len() <= n + self.unnamed_tail;
        if let Some(cell) = record.iter().skip(n).find(|c| in_tail && !c.trim_ascii().is_empty()) {
            return Err(IoError::UnnamedCell { path: self.path.clone(), row: self.rows, value: shown_cell(cell) });
        }
        if record.len() != n && !in_tail {
            return Err(IoError::RowLength {
                path: self.path.clone(),
                row: self.rows,
                got: record.len(),
                // The header's cells, its unnamed ones too.
                want: n + self.unnamed_tail,
            });
        }
        let decimal_comma = self.decimal_comma;
        let parse = |cell: &[u8]| parse_slow(cell, decimal_comma);
        let before = self.batch.len();
        for (i, cell) in record.iter().take(n).enumerate() {
            // An empty cell is a missing value.
            let value = match self.kind(i) {
                CellKind::Text => continue,
                _ if is_blank(cell) => Some(f64::NAN),
                CellKind::Number => parse(cell),
                CellKind::DateTime => parse_date_time(&String::from_utf8_lossy(cell)),
            };
            match value {
                Some(v) => self.batch.push(v),
                None => {
                    let (column, value) = (self.columns[i].clone(), shown_cell(cell));
                    // A first row of text alone: most likely the header is a preamble line.
                    let text_row = self.rows == 1 && record.iter().take(n).all(|c| is_blank(c) || parse(c).is_none());
                    if self.unreadable_as_nan && !text_row {
                        self.unreadable += 1;
                        self.first_unreadable.get_or_insert_with(|| {
                            format!(
                                "row {}, column `{}`: `{}`",
                                self.rows,
                                crate::error::shown(&column),
                                crate::error::shown(&value)
                            )
                        });
                        self.batch.push(f64::NAN);
                        continue;
                    }
                    self.batch.truncate(before);
                    let path = self.path.clone();
                    if text_row {
                        return Err(IoError::TextRow { path, column, value });
                    }
                    if self.kind(i) == CellKind::DateTime {
                        return Err(IoError::NotATime { path, row: self.rows, column, value });
                    }
                    return Err(IoError::NotANumber { path, row: self.rows, column, value });
                }
            }
        }
        Ok(())
    }
}

/// A cell's value as a row that does not parse at once reads it: Unicode whitespace
/// trimmed, a decimal comma where the delimiter allows one.
fn parse_slow(cell: &[u8], decimal_comma: bool) -> Option<f64> {
    let text = String::from_utf8_lossy(cell);
    let cell = text.trim();
    if decimal_comma && cell.contains(',') {
        parse_decimal_comma(cell)
    } else {
        cell.parse().ok()
    }
}

/// Whether a cell holds nothing but whitespace.
fn is_blank(cell: &[u8]) -> bool {
    String::from_utf8_lossy(cell).trim().is_empty()
}

/// A cell as an error shows it: trimmed, at most 40 characters, `�` for bytes that are
/// not text.
pub(super) fn shown_cell(cell: &[u8]) -> String {
    String::from_utf8_lossy(cell).trim().chars().take(40).collect()
}

pub(super) fn csv_error(path: &Path, e: csv::Error) -> IoError {
    IoError::Csv { path: path.to_path_buf(), msg: e.to_string() }
}
