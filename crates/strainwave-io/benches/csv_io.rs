//! Recording CSV throughput, in input (reading) or output (writing) bytes per second, of
//! the reader and writer beside the straightforward alternatives, on an in-memory
//! recording shaped like `strainwave simulate`'s (1 kHz, 17 columns of sensor values).
//!
//! Run: `cargo bench -p strainwave-io --bench csv_io`

use std::fmt::Write as _;
use std::path::Path;
use std::time::Duration;

use criterion::{black_box, Criterion, Throughput};
use strainwave_io::csv_io::{format_f64, format_row};
use strainwave_io::CsvReader;

const ROWS: usize = 20_000;
const COLUMNS: usize = 17;

/// Rows like a simulated joint's: time, angles, quantized ADC voltages, noisy torques, flags.
fn rows() -> Vec<[f64; COLUMNS]> {
    let mut seed = 0x2545_F491_4F6C_DD1D_u64;
    let mut noise = move || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5
    };
    (0..ROWS)
        .map(|k| {
            let t = k as f64 * 1e-3;
            let motor = 156.0 * t * t;
            let mut row = [0.0; COLUMNS];
            row[0] = t;
            row[1] = (motor / (std::f64::consts::TAU / 4096.0)).round() * (std::f64::consts::TAU / 4096.0);
            row[2] = -motor / 100.0;
            row[3] = 312.0 * t + noise();
            row[4] = 0.9 + 0.1 * noise();
            row[5] = ((0.1 + 0.05 * noise()) * 4096.0 / 10.0).round() * (10.0 / 4096.0);
            for (c, v) in row.iter_mut().enumerate().skip(6) {
                *v = match c {
                    10 => (k % 3) as f64,
                    16 => -0.0,
                    _ => (c as f64 * motor).sin() * 0.5 + 1e-3 * noise(),
                };
            }
            row
        })
        .collect()
}

/// The rows as CSV text, with a header.
fn csv_text(rows: &[[f64; COLUMNS]]) -> Vec<u8> {
    let header: Vec<String> = (0..COLUMNS).map(|c| format!("col{c}")).collect();
    let mut text = header.join(",").into_bytes();
    text.push(b'\n');
    for row in rows {
        format_row(row, &mut text);
    }
    text
}

fn read(c: &mut Criterion) {
    let data: &'static [u8] = Box::leak(csv_text(&rows()).into_boxed_slice());
    let mut g = c.benchmark_group("csv_read");
    g.throughput(Throughput::Bytes(data.len() as u64));
    g.sample_size(10).warm_up_time(Duration::from_secs(1)).measurement_time(Duration::from_secs(3));
    g.bench_function("strainwave CsvReader", |b| {
        b.iter(|| {
            let mut r = CsvReader::from_reader(Path::new("bench.csv"), Box::new(data)).unwrap();
            let (mut row, mut sum) = (Vec::new(), 0.0);
            while r.read_row(&mut row).unwrap() {
                sum += row[3];
            }
            black_box(sum)
        })
    });
    g.bench_function("csv StringRecord + str::parse", |b| {
        b.iter(|| {
            let mut r = csv::ReaderBuilder::new().flexible(true).trim(csv::Trim::All).from_reader(data);
            let n = r.headers().unwrap().len();
            let (mut record, mut row, mut sum) = (csv::StringRecord::new(), Vec::with_capacity(n), 0.0);
            while r.read_record(&mut record).unwrap() {
                row.clear();
                row.extend(record.iter().map(|cell| cell.parse::<f64>().unwrap()));
                sum += row[3];
            }
            black_box(sum)
        })
    });
    g.bench_function("csv ByteRecord reused + str::parse", |b| {
        b.iter(|| {
            let mut r = csv::ReaderBuilder::new().flexible(true).from_reader(data);
            let n = r.byte_headers().unwrap().len();
            let (mut record, mut row, mut sum) = (csv::ByteRecord::new(), Vec::with_capacity(n), 0.0);
            while r.read_byte_record(&mut record).unwrap() {
                row.clear();
                row.extend(
                    record.iter().map(|cell| std::str::from_utf8(cell.trim_ascii()).unwrap().parse::<f64>().unwrap()),
                );
                sum += row[3];
            }
            black_box(sum)
        })
    });
    g.finish();
}

fn write(c: &mut Criterion) {
    let rows = rows();
    let bytes = csv_text(&rows).len() as u64;
    let mut g = c.benchmark_group("csv_write");
    g.throughput(Throughput::Bytes(bytes));
    g.sample_size(10).warm_up_time(Duration::from_secs(1)).measurement_time(Duration::from_secs(3));
    let mut out = Vec::with_capacity(bytes as usize + 4096);
    g.bench_function("strainwave format_row", |b| {
        b.iter(|| {
            out.clear();
            for row in &rows {
                format_row(row, &mut out);
            }
            black_box(out.len())
        })
    });
    let mut text = String::with_capacity(bytes as usize + 4096);
    g.bench_function("format! {} (the text format_row keeps)", |b| {
        b.iter(|| {
            text.clear();
            for row in &rows {
                for (i, v) in row.iter().enumerate() {
                    if i > 0 {
                        text.push(',');
                    }
                    let a = v.abs();
                    if *v == 0.0 || (1e-5..1e16).contains(&a) || !v.is_finite() {
                        let _ = write!(text, "{v}");
                    } else {
                        let _ = write!(text, "{v:e}");
                    }
                }
                text.push('\n');
            }
            black_box(text.len())
        })
    });
    g.bench_function("ryu (other text: 1.0, ties to even)", |b| {
        b.iter(|| {
            out.clear();
            let mut ryu = ryu::Buffer::new();
            for row in &rows {
                for (i, v) in row.iter().enumerate() {
                    if i > 0 {
                        out.push(b',');
                    }
                    out.extend_from_slice(ryu.format(*v).as_bytes());
                }
                out.push(b'\n');
            }
            black_box(out.len())
        })
    });
    g.finish();
    // The text is the one `format_f64` gives, which the tests hold to std's byte for byte.
    let mut s = String::new();
    format_f64(rows[7][3], &mut s);
    assert!(String::from_utf8(csv_text(&rows[7..8])).unwrap().lines().nth(1).unwrap().contains(&s));
}

fn main() {
    let mut c = Criterion::default().configure_from_args();
    read(&mut c);
    write(&mut c);
    c.final_summary();
}
