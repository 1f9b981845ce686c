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

/// An empty cell is a missing value (as pandas and DAQ exports take it); with
/// `unreadable_as_nan` a cell that is not a number is one too, counted in a warning at
/// the end; without, it stops the read at its row.
#[test]
fn empty_cells_are_missing_and_text_is_nan_only_when_asked() {
    let text = "time;a;b\n0;1,5;\n0,001; ;2\n0,002;OVL;3\n0,003;4;ERR\n";
    let mut row = Vec::new();
    let mut strict = CsvReader::from_reader(Path::new("daq.csv"), Box::new(text.as_bytes())).unwrap();
    assert!(strict.read_row(&mut row).unwrap() && row[1] == 1.5 && row[2].is_nan(), "{row:?}");
    assert!(strict.read_row(&mut row).unwrap() && row[1].is_nan() && row[2] == 2.0, "{row:?}");
    let e = strict.read_row(&mut row).unwrap_err().to_string();
    assert!(e.starts_with("daq.csv: row 3, column `a`: `OVL` is not a number"), "{e}");
    let options = TextOptions { delimiter: None, unreadable_as_nan: true };
    let mut lenient = CsvReader::from_reader_with(Path::new("daq.csv"), Box::new(text.as_bytes()), options).unwrap();
    let mut rows = Vec::new();
    while lenient.read_row(&mut row).unwrap() {
        rows.push(row.clone());
    }
    assert_eq!(rows.len(), 4);
    assert!(rows[2][1].is_nan() && rows[2][2] == 3.0 && rows[3][1] == 4.0 && rows[3][2].is_nan(), "{rows:?}");
    assert_eq!(
        lenient.warnings(),
        ["2 cell(s) that are not numbers read as NaN, the first at row 3, column `a`: `OVL`"]
    );
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
fn a_time_column_in_another_unit_is_read_in_seconds() {
    // Before: `Time [ms]` was taken as seconds (a 1 kHz log read as 1 Hz, with exit 0).
    for (unit, t, want_s) in [("ms", "1500", 1.5), ("us", "250", 250e-6), ("min", "2", 120.0), ("s", "0.25", 0.25)] {
        let text = format!("Time [{unit}],torque [ms]\n{t},7\n");
        let mut r = CsvReader::from_reader(Path::new("rec.csv"), Box::new(std::io::Cursor::new(text))).unwrap();
        assert_eq!(r.units(), [Some("s".to_string()), Some("ms".to_string())], "{unit}");
        let mut row = Vec::new();
        assert!(r.read_row(&mut row).unwrap());
        assert_eq!(row, [want_s, 7.0], "{unit}: other columns keep their unit");
    }
}

/// Another column named as the time column is read in seconds instead; `time` then
/// keeps its own unit and values.
#[test]
fn a_named_time_column_is_read_in_seconds() {
    let text = "Time [ms],t [us],x\n1500,250,7\n";
    let mut r = CsvReader::from_reader(Path::new("rec.csv"), Box::new(std::io::Cursor::new(text))).unwrap();
    r.set_time_column("t");
    assert_eq!(r.units(), [Some("ms".to_string()), Some("s".to_string()), None]);
    let mut row = Vec::new();
    assert!(r.read_row(&mut row).unwrap());
    assert_eq!(row, [1500.0, 250e-6, 7.0]);
    r.set_time_column("missing");
    assert_eq!(r.units()[1].as_deref(), Some("s"), "no such column: nothing changes");
    // A config that scales its time channel itself gets the column as written.
    let text = "time [ms],x\n1500,7\n";
    let mut r = CsvReader::from_reader(Path::new("rec.csv"), Box::new(std::io::Cursor::new(text))).unwrap();
    r.keep_time_as_written();
    assert_eq!(r.units()[0].as_deref(), Some("ms"));
    assert!(r.read_row(&mut row).unwrap());
    assert_eq!(row, [1500.0, 7.0]);
}

/// DAQ software on Windows writes headers in Windows-1252: they read as the characters
/// meant, so that a config typed in UTF-8 finds them. UTF-16 is refused with what to do.
#[test]
fn windows_1252_headers_read_and_utf16_is_named() {
    let text = b"time,Drehmoment [N\xb7m],\x80 cost,W\xe4rme [\xb0C]\n0,1.5,2,3\n".to_vec();
    let mut r = CsvReader::from_reader(Path::new("rec.csv"), Box::new(std::io::Cursor::new(text))).unwrap();
    assert_eq!(r.columns(), ["time", "Drehmoment", "€ cost", "Wärme"]);
    assert_eq!(r.units()[1].as_deref(), Some("N·m"));
    let mut row = Vec::new();
    assert!(r.read_row(&mut row).unwrap());
    assert_eq!(row, [0.0, 1.5, 2.0, 3.0]);
    let utf16: Vec<u8> =
        [0xff, 0xfe].into_iter().chain("time,x\n0,1\n".encode_utf16().flat_map(u16::to_le_bytes)).collect();
    let e = CsvReader::from_reader(Path::new("rec.csv"), Box::new(std::io::Cursor::new(utf16))).err().unwrap();
    assert!(e.to_string().starts_with("rec.csv:") && e.to_string().contains("UTF-16: save it as UTF-8"), "{e}");
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
    assert_eq!(e, "rec.csv: row 2, column `b`: `\u{fffd}` is not a number");
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

/// The plain reader: the `csv` crate's records, cells trimmed, `str::parse` (a cell that
/// is not UTF-8 shown with `�`); a header that is not UTF-8 read as Windows-1252.
fn reference(data: &[u8]) -> Outcome {
    let path = Path::new("rec.csv");
    let mut csv = csv::ReaderBuilder::new().flexible(true).trim(csv::Trim::All).from_reader(data);
    let header = match csv.headers() {
        Ok(h) => h.clone(),
        Err(e) if matches!(e.kind(), csv::ErrorKind::Utf8 { .. }) => {
            let names = csv.byte_headers().unwrap();
            names.iter().map(|n| dialect::header_text(n).trim().to_string()).collect()
        }
        Err(e) => return (Err(csv_error(path, e).to_string()), Vec::new()),
    };
    let mut columns: Vec<String> = header.iter().map(str::to_string).collect();
    // Empty names at the end of the header: no columns, their cells empty.
    let unnamed = columns.iter().rev().take_while(|c| c.trim().is_empty()).count();
    let tail = if columns.len() > 1 && unnamed < columns.len() { unnamed } else { 0 };
    columns.truncate(columns.len() - tail);
    if columns.is_empty() || (columns.len() == 1 && columns[0].is_empty()) {
        return (Err(IoError::Empty(path.into()).to_string()), Vec::new());
    }
    if let Some(c) = columns.iter().enumerate().find_map(|(i, c)| columns[..i].contains(c).then_some(c)) {
        return (Err(IoError::DuplicateColumn { path: path.into(), column: c.clone() }.to_string()), Vec::new());
    }
    // Text columns: where the first record holds text, others numbers (its length right).
    let parse = |cell: &[u8]| String::from_utf8_lossy(cell).trim().parse::<f64>();
    let mut text = vec![false; columns.len()];
    let mut first = csv::ByteRecord::new();
    let mut peek = csv::ReaderBuilder::new().flexible(true).trim(csv::Trim::All).from_reader(data);
    let _ = peek.byte_headers();
    if peek.read_byte_record(&mut first).unwrap_or(false)
        && (columns.len()..=columns.len() + tail).contains(&first.len())
        && first.iter().take(columns.len()).any(|c| parse(c).is_ok())
    {
        for (t, cell) in text.iter_mut().zip(first.iter()) {
            *t = !String::from_utf8_lossy(cell).trim().is_empty() && parse(cell).is_err();
        }
    }
    let kept: Vec<String> = columns.iter().zip(&text).filter(|(_, &t)| !t).map(|(c, _)| c.clone()).collect();
    let mut rows = Vec::new();
    let mut record = csv::ByteRecord::new();
    let mut n = 0;
    loop {
        let row = match csv.read_byte_record(&mut record) {
            Ok(false) => return (Ok(kept), rows),
            Err(e) => Err(csv_error(path, e).to_string()),
            Ok(true) => {
                n += 1;
                let width = columns.len();
                let in_tail = record.len() > width && record.len() <= width + tail;
                let unnamed = record.iter().skip(width).find(|c| in_tail && !c.trim_ascii().is_empty());
                if let Some(cell) = unnamed {
                    Err(IoError::UnnamedCell { path: path.into(), row: n, value: shown_cell(cell) }.to_string())
                } else if !(record.len() == width || in_tail) {
                    let (got, want) = (record.len(), width + tail);
                    Err(IoError::RowLength { path: path.into(), row: n, got, want }.to_string())
                } else {
                    // A first row of text alone is named as a likely preamble.
                    let all_text = n == 1 && record.iter().take(width).all(|c| parse(c).is_err());
                    record
                        .iter()
                        .take(width)
                        .enumerate()
                        .filter(|&(i, _)| !text[i])
                        .map(|(i, cell)| {
                            // An empty cell is a missing value.
                            let blank = String::from_utf8_lossy(cell).trim().is_empty();
                            let value = if blank { Ok(f64::NAN) } else { parse(cell) };
                            value.map(f64::to_bits).map_err(|_| {
                                let (path, value, column) = (path.into(), shown_cell(cell), columns[i].clone());
                                match all_text {
                                    true => IoError::TextRow { path, column, value }.to_string(),
                                    false => IoError::NotANumber { path, row: n, column, value }.to_string(),
                                }
                            })
                        })
                        .collect()
                }
            }
        };
        let stop = row.is_err();
        rows.push((row, n));
        if stop {
            return (Ok(kept), rows);
        }
    }
}

fn ours(data: &[u8], seed: u64) -> Outcome {
    let input = Trickle { data: data.to_vec(), at: 0, rng: Rng(seed) };
    // The `csv` crate reads commas: the same delimiter, set.
    let mut r = match CsvReader::from_reader_with(
        Path::new("rec.csv"),
        Box::new(input),
        TextOptions { delimiter: Some(b','), ..Default::default() },
    ) {
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

#[test]
fn header_names_with_commas_quotes_and_line_breaks_read_back_as_written() {
    let dir = std::env::temp_dir().join(format!("sw-hdr-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("h.csv");
    let cols = ["time", "a,b", "say \"hi\"", "two\nlines"];
    let mut w = CsvWriter::create(&path, &cols).unwrap();
    w.write_row(&[0.0, 1.0, 2.0, 3.0]).unwrap();
    w.finish().unwrap();
    let t = read_table(&path).unwrap();
    assert_eq!(t.columns, cols);
    assert_eq!(t.data[3], [3.0]);
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A `.tsv` output is tab-separated (a name with a tab quoted, one with a comma not),
/// and reads back as written.
#[test]
fn a_tsv_output_is_tab_separated_and_reads_back() {
    let dir = std::env::temp_dir().join(format!("sw-tsv-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("out.TSV");
    let cols = ["time", "a,b", "c\td"];
    let mut w = CsvWriter::create(&path, &cols).unwrap();
    w.write_row(&[0.5, 1000.25, -2.0]).unwrap();
    w.finish().unwrap();
    let text = std::fs::read_to_string(&path).unwrap();
    assert_eq!(text, "time\ta,b\t\"c\td\"\n0.5\t1000.25\t-2\n");
    let t = read_table(&path).unwrap();
    assert_eq!(t.columns, cols);
    assert_eq!(t.data[1], [1000.25]);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_line_longer_than_the_limit_is_an_error_not_an_allocation() {
    let dir = std::env::temp_dir().join(format!("sw-long-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("long.csv");
    let mut text = b"time,x\n0,1\n1,".to_vec();
    text.resize(text.len() + MAX_RECORD_BYTES + 10, b'7');
    text.push(b'\n');
    std::fs::write(&path, &text).unwrap();
    let e = read_table(&path).unwrap_err().to_string();
    assert!(e.contains("long.csv: row 2 is longer than 64 MiB"), "{e}");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Spreadsheet and DAQ exports end each line with a delimiter: the header's empty names at
/// the end are no columns, and their cells must be empty. Before: refused (``row 1,
/// column ``: `` is not a number``, or ``column `` appears twice``).
#[test]
fn a_delimiter_at_the_end_of_each_line_names_no_column() {
    let read = |text: &str| {
        let mut r = CsvReader::from_reader(Path::new("daq.txt"), Box::new(std::io::Cursor::new(text.to_string())))?;
        let mut rows = Vec::new();
        let mut row = Vec::new();
        while r.read_row(&mut row)? {
            rows.push(row.clone());
        }
        Ok::<_, IoError>((r.columns().to_vec(), r.units().to_vec(), rows))
    };
    for text in [
        "Time [s];Torque [N·m];\n0,0;1,5;\n0,001;-2,25;\n",
        "Time [s];Torque [N·m];;;\r\n0,0;1,5;;;\r\n0,001;-2,25;\r\n",
        "Time [s]\tTorque [N·m]\t\n0.0\t1.5\t \n0.001\t-2.25\n",
        "time,Torque,\n0,1.5,\n\"0.001\",-2.25,\"\"\n",
    ] {
        let (columns, units, rows) = read(text).unwrap();
        assert_eq!(columns, ["time", "Torque"], "{text:?}");
        assert_eq!(units[1].as_deref().unwrap_or("N·m"), "N·m");
        assert_eq!(rows, [vec![0.0, 1.5], vec![0.001, -2.25]], "{text:?}");
    }
    // A value in the unnamed column: before, read as a column named ``.
    let e = read("time;torque;\n0;1;\n1;2;7\n").unwrap_err().to_string();
    assert!(e.starts_with("daq.txt: row 2: `7` in a column the header does not name"), "{e}");
    let e = read("time,torque,\n0,1,5\n").unwrap_err().to_string();
    assert!(e.starts_with("daq.txt: row 1: `5` in a column the header does not name"), "{e}");
    let e = read("time;torque;\n0;1;;4\n").unwrap_err().to_string();
    assert!(e.starts_with("daq.txt: row 1 has 4 cells, the header has 3"), "{e}");
}

/// A DAQ export with device and date lines above its header: the first line is taken for
/// the header, so row 1 is text in every cell, and the error says what is likely wrong.
#[test]
fn a_preamble_above_the_header_is_named_as_such() {
    for (text, want) in [
        (
            "Device,NI 9237\nTime [s],Torque [N*m]\n0.0,1.5\n",
            "row 1, column `Device`: `Time [s]` is not a number, nor is",
        ),
        (
            "Device: NI 9237\nOperator: X\ntime\n0\n",
            "row 1, column `Device: NI 9237`: `Operator: X` is not a number, nor is",
        ),
        ("time,torque\ns,N*m\n0,1\n", "row 1, column `time`: `s` is not a number, nor is"),
    ] {
        let mut r =
            CsvReader::from_reader(Path::new("daq.csv"), Box::new(std::io::Cursor::new(text.to_string()))).unwrap();
        let e = r.read_row(&mut Vec::new()).unwrap_err().to_string();
        assert!(e.starts_with(&format!("daq.csv: {want}")) && e.contains("preamble"), "{e}");
    }
    // A first row with a number in it is data: its text columns are left out, an empty
    // cell is a missing value.
    let mut r = reader("time,a,b\n0,x,\n").unwrap();
    let mut row = Vec::new();
    assert!(r.read_row(&mut row).unwrap());
    assert_eq!(r.columns(), ["time", "b"]);
    assert!(row[0] == 0.0 && row[1].is_nan(), "{row:?}");
}

/// A DAQ's state or comment column, text in the first data row where others hold
/// numbers, is left out with a warning; text in a numeric column later is an error.
#[test]
fn a_text_column_is_left_out_with_a_warning() {
    let text = "# device\n\n# operator\ntime;torque [N*m];state;note\n0;1,5;\"Ramp up\";a b\n0,001;2;\"hold\";\n";
    let mut r = CsvReader::from_reader(Path::new("daq.csv"), Box::new(std::io::Cursor::new(text.to_string()))).unwrap();
    assert_eq!(r.columns(), ["time", "torque"]);
    assert_eq!(r.units(), [None, Some("N*m".to_string())]);
    assert_eq!(
        r.warnings(),
        ["column `state` holds text in data row 1: left out", "column `note` holds text in data row 1: left out"]
    );
    let mut row = Vec::new();
    assert!(r.read_row(&mut row).unwrap() && row == [0.0, 1.5]);
    assert!(r.read_row(&mut row).unwrap() && row == [0.001, 2.0]);
    assert!(!r.read_row(&mut row).unwrap());
    // Numbers first, text later: the row and cell are named.
    let mut r = reader("time,a,b\n0,1,2\n1,2,RUN\n").unwrap();
    assert!(r.warnings().is_empty() && r.read_row(&mut row).unwrap());
    let e = r.read_row(&mut row).unwrap_err().to_string();
    assert_eq!(e, "rec.csv: row 2, column `b`: `RUN` is not a number");
    // Read a few bytes at a time, the same.
    let data = b"time,state,x\n\n0,\"a,b\",1\r\n1,c,2".to_vec();
    let input = Trickle { data, at: 0, rng: Rng(7) };
    let mut r = CsvReader::from_reader(Path::new("rec.csv"), Box::new(input)).unwrap();
    assert_eq!(r.columns(), ["time", "x"]);
    let mut all = Vec::new();
    assert_eq!(r.read_chunk(&mut all, 10).unwrap(), 2);
    assert_eq!(all, [0.0, 1.0, 1.0, 2.0]);
}

/// A recording read whole stops with an error at its bound, before the values are held.
#[test]
fn a_table_beyond_its_bound_is_an_error() {
    let columns = vec!["time".to_string(), "torque".to_string()];
    // Five rows of (k, 2k).
    let rows = || {
        let mut k = 0.0;
        move |row: &mut Vec<f64>| {
            k += 1.0;
            *row = vec![k, 2.0 * k];
            Ok(k <= 5.0)
        }
    };
    let t = Table::collect_within(Path::new("r.csv"), &columns, 10, rows()).unwrap();
    assert_eq!(t.data, [vec![1.0, 2.0, 3.0, 4.0, 5.0], vec![2.0, 4.0, 6.0, 8.0, 10.0]]);
    let e = Table::collect_within(Path::new("r.csv"), &columns, 9, rows()).unwrap_err().to_string();
    assert!(e.starts_with("r.csv: more than 4 rows of 2 columns: too large to read whole"), "{e}");
}

/// A time column of dates and times (pandas' `to_csv` of a datetime index, a logger's
/// export) is read as seconds since 1970 UTC; a later cell that is not one is named.
#[test]
fn a_date_and_time_column_is_seconds_since_1970() {
    let text = "time,torque\n2026-11-29 06:00:00.000000,1.5\n2026-11-29 06:00:00.001000,2\n";
    let mut r = reader(text).unwrap();
    assert_eq!(r.columns(), ["time", "torque"]);
    assert_eq!(r.units(), [Some("s".to_string()), None]);
    assert!(r.warnings().is_empty());
    let mut all = Vec::new();
    assert_eq!(r.read_chunk(&mut all, 10).unwrap(), 2);
    assert_eq!(all[0], 1_795_932_000.0);
    assert!((all[2] - all[0] - 0.001).abs() < 1e-6 && all[1] == 1.5 && all[3] == 2.0);
    // Semicolons and decimal commas, a zone, a text column beside it.
    let text = "Zeit;Moment [N*m];Schritt\n2026-11-29T07:00:00,5+01:00;1,5;Rampe\n";
    let mut r = CsvReader::from_reader(Path::new("daq.csv"), Box::new(std::io::Cursor::new(text.to_string()))).unwrap();
    assert_eq!(r.columns(), ["Zeit", "Moment"]);
    let mut row = Vec::new();
    assert!(r.read_row(&mut row).unwrap() && row == [1_795_932_000.5, 1.5]);
    let mut r = reader("time,x\n2026-11-29 06:00:00,1\n2026-11-29 06:00:01,2\n06:00:02,3\n").unwrap();
    assert!(r.read_row(&mut row).unwrap() && r.read_row(&mut row).unwrap() && row == [1_795_932_001.0, 2.0]);
    let e = r.read_row(&mut row).unwrap_err().to_string();
    assert!(e.starts_with("rec.csv: row 3, column `time`: `06:00:02` is not a date and time as in data row 1"), "{e}");
}

/// A time that its unit makes infinite in seconds is an error naming its row and column
/// (before: `inf` read, and written by `convert`).
#[test]
fn a_time_beyond_the_seconds_a_number_holds_is_named() {
    let mut r = reader("time [h],x\n0,1\n1e306,2\n").unwrap();
    let mut row = Vec::new();
    assert!(r.read_row(&mut row).unwrap());
    let e = r.read_row(&mut row).unwrap_err().to_string();
    assert_eq!(e, "rec.csv: row 2, column `time`: 1e306 h is beyond the seconds a number holds");
}
