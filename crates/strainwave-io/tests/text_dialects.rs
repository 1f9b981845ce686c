//! Text exports as DAQ systems write them: tab and semicolon delimiters, decimal commas,
//! units in the header, byte-order marks, CRLF line ends and comment lines; and units
//! through the writers.

use std::path::{Path, PathBuf};

use strainwave_io::{IoError, ReadOptions, RecordingReader, RecordingWriter};

fn temp(name: &str, bytes: &[u8]) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("sw-dialects-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let p = dir.join(name);
    std::fs::write(&p, bytes).unwrap();
    p
}

/// Columns, units and rows.
type Read = (Vec<String>, Vec<Option<String>>, Vec<Vec<f64>>);

fn read(path: &Path, options: &ReadOptions) -> Result<Read, IoError> {
    let mut r = RecordingReader::open_with(path, options)?;
    let mut rows = Vec::new();
    let mut row = Vec::new();
    while r.read_row(&mut row)? {
        rows.push(row.clone());
    }
    Ok((r.columns().to_vec(), r.units().to_vec(), rows))
}

#[test]
fn daq_tab_export_with_bom_crlf_comments_and_units() {
    let text = "\u{feff}# NAIO export, 2 channels\r\n# sampled at 1 kHz\r\nTime [s]\t163.05 NAIO-03 ch1 torq.(P:00A305h)\r\n0.000\t-0.0123\r\n# a marker\r\n0.001\t1.5e-2\r\n\r\n0.002\t0.25\r\n";
    let p = temp("naio.txt", text.as_bytes());
    let (cols, units, rows) = read(&p, &ReadOptions::default()).unwrap();
    assert_eq!(cols, ["time", "163.05 NAIO-03 ch1 torq.(P:00A305h)"]);
    assert_eq!(units, [Some("s".to_string()), None]);
    assert_eq!(rows, [vec![0.0, -0.0123], vec![0.001, 0.015], vec![0.002, 0.25]]);
}

#[test]
fn semicolon_with_decimal_comma_and_units_in_parentheses() {
    let text = "time [s];torque (N·m);speed (rpm);note\n0,000;1,25;-3,5e2;7\n0,5;-0,125;1000;8\n";
    let p = temp("semi.csv", text.as_bytes());
    let (cols, units, rows) = read(&p, &ReadOptions::default()).unwrap();
    assert_eq!(cols, ["time", "torque", "speed", "note"]);
    assert_eq!(units, [Some("s".into()), Some("N·m".into()), Some("rpm".into()), None]);
    assert_eq!(rows, [vec![0.0, 1.25, -350.0, 7.0], vec![0.5, -0.125, 1000.0, 8.0]]);
}

#[test]
fn tab_with_decimal_comma_and_a_set_delimiter() {
    let text = "time\ta;b\n0,5\t1,5\n";
    let p = temp("tab.tsv", text.as_bytes());
    // Detected: one tab against one semicolon, tab first.
    let (cols, _, rows) = read(&p, &ReadOptions::default()).unwrap();
    assert_eq!(cols, ["time", "a;b"]);
    assert_eq!(rows, [vec![0.5, 1.5]]);
    // Set: semicolon splits the header in two, and the rows do not parse.
    let options = ReadOptions { delimiter: Some(b';'), ..ReadOptions::default() };
    let e = read(&p, &options).unwrap_err().to_string();
    assert!(e.contains("tab.tsv") && e.contains("row 1") && e.contains("semicolon"), "{e}");
}

#[test]
fn an_unreadable_file_names_the_delimiter_it_saw() {
    let p = temp("mixed.csv", b"time;torque\n0;1\n1;2,5,0\n");
    let e = read(&p, &ReadOptions::default()).unwrap_err().to_string();
    assert!(e.contains("mixed.csv: row 2, column `torque`: `2,5,0`"), "{e}");
    assert!(e.contains("read as semicolon-delimited, decimal comma accepted, 2 column(s)"), "{e}");
    // One column found: the message says so.
    let p = temp("pipes.csv", b"time|torque\n0|1\n");
    let e = read(&p, &ReadOptions::default()).unwrap_err().to_string();
    assert!(e.contains("read as comma-delimited, 1 column(s); set --delimiter"), "{e}");
    let options = ReadOptions { delimiter: Some(b'|'), ..ReadOptions::default() };
    assert_eq!(read(&p, &options).unwrap().2, [vec![0.0, 1.0]]);
    // A one-cell device line above the header: read as a one-column header, rows longer.
    let p = temp("daq.csv", b"NI 9237\ntime,torque\n0,1\n");
    let e = read(&p, &ReadOptions::default()).unwrap_err().to_string();
    assert!(e.starts_with(&format!("{}: row 1 has 2 cells, the header has 1", p.display())), "{e}");
    assert!(e.ends_with("set --delimiter if that is wrong, or start lines above the header with `#`)"), "{e}");
}

#[test]
fn comma_files_read_as_before() {
    let p = temp("plain.csv", b"time,torque_nm\n0,1.5\n1,-2\n");
    let (cols, units, rows) = read(&p, &ReadOptions::default()).unwrap();
    assert_eq!(cols, ["time", "torque_nm"]);
    assert_eq!(units, [None, None]);
    assert_eq!(rows, [vec![0.0, 1.5], vec![1.0, -2.0]]);
}

#[test]
fn units_survive_a_text_round_trip() {
    let p = temp("units-out.csv", b"");
    let mut w =
        RecordingWriter::create_with_units(&p, &["time", "torque", "raw"], &[Some("s"), Some("N·m"), None]).unwrap();
    w.write_row(&[0.0, 1.0, 2.0]).unwrap();
    w.finish().unwrap();
    assert!(std::fs::read_to_string(&p).unwrap().starts_with("time,torque [N·m],raw\n"));
    let (cols, units, _) = read(&p, &ReadOptions::default()).unwrap();
    assert_eq!(cols, ["time", "torque", "raw"]);
    assert_eq!(units, [None, Some("N·m".into()), None], "time is s by definition, not written");
}

#[cfg(feature = "parquet")]
#[test]
fn units_survive_a_parquet_round_trip() {
    let p = temp("units.parquet", b"");
    let mut w = RecordingWriter::create_with_units(&p, &["time", "torque", "raw"], &[None, Some("N·m"), None]).unwrap();
    w.write_row(&[0.0, 1.0, 2.0]).unwrap();
    w.finish().unwrap();
    let (cols, units, rows) = read(&p, &ReadOptions::default()).unwrap();
    assert_eq!(cols, ["time", "torque", "raw"]);
    assert_eq!(units, [Some("s".into()), Some("N·m".into()), None], "time is in s by default");
    assert_eq!(rows, [vec![0.0, 1.0, 2.0]]);
}

#[test]
fn resample_option_applies_to_tables() {
    let p = temp("jitter.csv", b"time,x\n0,0\n0.15,1.5\n0.3,3\n");
    let options = ReadOptions { resample_hz: Some(10.0), ..ReadOptions::default() };
    let (_, _, rows) = read(&p, &options).unwrap();
    assert_eq!(rows.len(), 4);
    for (k, r) in rows.iter().enumerate() {
        assert!((r[0] - 0.1 * k as f64).abs() < 1e-12 && (r[1] - k as f64).abs() < 1e-9, "{r:?}");
    }
}
