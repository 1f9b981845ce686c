//! The CSV writer: rows formatted into a buffer that a thread writes to a temporary file.

use super::*;

/// Writes full buffers to a file on its own thread, so that the copy into the OS overlaps
/// the formatting of the next rows; written buffers come back for reuse.
pub(super) struct FileWriter {
    full: Option<SyncSender<Vec<u8>>>,
    empty: Receiver<Vec<u8>>,
    /// Buffers handed over and not back yet.
    in_flight: usize,
    thread: Option<std::thread::JoinHandle<std::io::Result<()>>>,
    failed: bool,
}

impl FileWriter {
    pub(super) fn spawn(mut file: File) -> std::io::Result<Self> {
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
    pub(super) fn write(&mut self, buf: &mut Vec<u8>) -> std::io::Result<()> {
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
    pub(super) fn wait(&mut self) -> std::io::Result<()> {
        while self.in_flight > 0 {
            if self.empty.recv().is_err() {
                return self.finish().and(Err(std::io::Error::other("the writing thread stopped")));
            }
            self.in_flight -= 1;
        }
        Ok(())
    }

    /// Writes what was handed over and closes the file; its first error, if any.
    pub(super) fn finish(&mut self) -> std::io::Result<()> {
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

pub(super) enum Sink {
    File { tmp: AtomicFile, out: FileWriter },
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
    /// `\t` for a `.tsv` file, else `,`.
    delimiter: u8,
}

impl CsvWriter {
    /// Creates the output (standard output for `-`) and writes the header. A `.tsv` file
    /// is tab-separated, any other comma-separated.
    pub fn create(path: &Path, columns: &[&str]) -> Result<Self, IoError> {
        let os = |source| IoError::Os { path: path.to_path_buf(), source };
        let (sink, limit) = if path == Path::new("-") {
            (Sink::Stdout(std::io::stdout()), STDOUT_WRITE_BUFFER_BYTES)
        } else {
            if path.is_dir() {
                return Err(IoError::IsDirectory(path.to_path_buf()));
            }
            let tmp = AtomicFile::create(path)?;
            let out = FileWriter::spawn(tmp.try_clone_file()?).map_err(os)?;
            (Sink::File { tmp, out }, FILE_WRITE_BUFFER_BYTES)
        };
        // Room for the last row past the limit, so the buffer never grows.
        let mut buf = Vec::with_capacity(limit + 4096);
        let tsv = path.extension().is_some_and(|e| e.eq_ignore_ascii_case("tsv"));
        let delimiter = if tsv { b'\t' } else { b',' };
        write_header(columns, delimiter, &mut buf);
        let (path, n_cols) = (path.to_path_buf(), columns.len());
        let mut w = Self { path, sink: Some(sink), n_cols, buf, limit, rows: 0, delimiter };
        if w.buf.len() >= w.limit {
            w.write_out()?;
        }
        Ok(w)
    }

    /// Writes the buffer out (to a file: hands it to the writing thread).
    pub(super) fn write_out(&mut self) -> Result<(), IoError> {
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
        format_row_with(row, self.delimiter, &mut self.buf);
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
            tmp.commit()?;
        }
        Ok(self.rows)
    }
}

impl Drop for CsvWriter {
    fn drop(&mut self) {
        match self.sink.take() {
            // Dropping the temporary file removes it.
            Some(Sink::File { tmp, out }) => {
                drop(out);
                drop(tmp);
            }
            // Rows already written stay written, as with a buffered writer dropped.
            Some(Sink::Stdout(mut out)) => {
                let _ = out.write_all(&self.buf).and_then(|()| out.flush());
            }
            None => {}
        }
    }
}

/// The header line, each name quoted when CSV requires it (the delimiter, a quote or a
/// line break), so that the reader gets back the names as written.
pub(super) fn write_header(columns: &[&str], delimiter: u8, buf: &mut Vec<u8>) {
    for (i, c) in columns.iter().enumerate() {
        if i > 0 {
            buf.push(delimiter);
        }
        if c.bytes().any(|b| b == delimiter || matches!(b, b'"' | b'\n' | b'\r')) {
            buf.push(b'"');
            for b in c.bytes() {
                if b == b'"' {
                    buf.push(b'"');
                }
                buf.push(b);
            }
            buf.push(b'"');
        } else {
            buf.extend_from_slice(c.as_bytes());
        }
    }
    buf.push(b'\n');
}
