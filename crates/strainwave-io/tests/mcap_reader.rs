//! MCAP logs written with the `mcap` crate's writer (chunked and compressed or not) read
//! back as a table: JointState and JSON columns, NaN where a message lacks a column,
//! rows in log-time order, unknown schemas skipped with a warning, bad files named.
#![cfg(feature = "mcap")]

use std::collections::BTreeMap;
use std::io::Cursor;
use std::path::PathBuf;

use mcap::records::MessageHeader;
use strainwave_io::mcap_in::{read_mcap, Align, BagReader, ReadOptions, TimeSource};
use strainwave_io::IoError;

const JOINT_STATE_MSG: &[u8] =
    b"std_msgs/Header header\nstring[] name\nfloat64[] position\nfloat64[] velocity\nfloat64[] effort\n";

fn temp_path(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("strainwave-mcap-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

/// Little-endian CDR JointState (names, positions, efforts; velocities empty).
fn joint_state_cdr(names: &[&str], position: &[f64], effort: &[f64]) -> Vec<u8> {
    let mut b = vec![0u8, 1, 0, 0];
    let align = |b: &mut Vec<u8>, n: usize| {
        while !(b.len() - 4).is_multiple_of(n) {
            b.push(0);
        }
    };
    let u32 = |b: &mut Vec<u8>, v: u32| {
        align(b, 4);
        b.extend(v.to_le_bytes());
    };
    u32(&mut b, 5);
    u32(&mut b, 7);
    u32(&mut b, 6);
    b.extend(b"frame\0");
    u32(&mut b, names.len() as u32);
    for s in names {
        u32(&mut b, s.len() as u32 + 1);
        b.extend(s.as_bytes());
        b.push(0);
    }
    for v in [position, &[], effort] {
        u32(&mut b, v.len() as u32);
        for x in v {
            align(&mut b, 8);
            b.extend(x.to_le_bytes());
        }
    }
    b
}

struct Msg {
    channel: usize,
    log_time_ns: u64,
    data: Vec<u8>,
}

/// Channels: 0 JointState on /joint_states, 1 JSON on /imu, 2 protobuf on /camera.
fn write_log(name: &str, messages: &[Msg], options: mcap::WriteOptions) -> PathBuf {
    let mut w = options.create(Cursor::new(Vec::new())).unwrap();
    let js = w.add_schema("sensor_msgs/msg/JointState", "ros2msg", JOINT_STATE_MSG).unwrap();
    let pb = w.add_schema("foxglove.CompressedImage", "protobuf", &[0x0a, 0x03, 0xff, 0x00]).unwrap();
    let none = BTreeMap::new();
    let channels = [
        w.add_channel(js, "/joint_states", "cdr", &none).unwrap(),
        w.add_channel(0, "/imu", "json", &none).unwrap(),
        w.add_channel(pb, "/camera", "protobuf", &none).unwrap(),
    ];
    for (seq, m) in messages.iter().enumerate() {
        let header = MessageHeader {
            channel_id: channels[m.channel],
            sequence: seq as u32,
            log_time: m.log_time_ns,
            publish_time: m.log_time_ns,
        };
        w.write_to_known_channel(&header, &m.data).unwrap();
    }
    w.finish().unwrap();
    let bytes = w.into_inner().into_inner();
    let path = temp_path(name);
    std::fs::write(&path, bytes).unwrap();
    path
}

fn mixed_messages() -> Vec<Msg> {
    vec![
        Msg { channel: 0, log_time_ns: 1_000_000_000, data: joint_state_cdr(&["j1", "j2"], &[0.1, 0.2], &[1.5, -2.5]) },
        Msg { channel: 2, log_time_ns: 1_100_000_000, data: vec![1, 2, 3, 4, 5] },
        Msg { channel: 1, log_time_ns: 1_250_000_000, data: br#"{"accel": {"x": 0.5, "y": -1}, "id": "a"}"#.to_vec() },
        Msg { channel: 0, log_time_ns: 1_500_000_000, data: joint_state_cdr(&["j1", "j2"], &[0.3, 0.4], &[3.0, 4.0]) },
        Msg { channel: 1, log_time_ns: 1_750_000_000, data: br#"{"id": "no numbers"}"#.to_vec() },
    ]
}

fn same(a: f64, b: f64) -> bool {
    a == b || (a.is_nan() && b.is_nan())
}

fn check_mixed(path: &std::path::Path) {
    let t = read_mcap(path).unwrap();
    let cols: Vec<&str> = t.table.columns.iter().map(String::as_str).collect();
    assert_eq!(cols, ["time", "j1.position", "j1.effort", "j2.position", "j2.effort", "/imu.accel.x", "/imu.accel.y"]);
    let nan = f64::NAN;
    let want = [
        [1.0, 0.1, 1.5, 0.2, -2.5, nan, nan],
        [1.25, nan, nan, nan, nan, 0.5, -1.0],
        [1.5, 0.3, 3.0, 0.4, 4.0, nan, nan],
    ];
    for (c, col) in t.table.data.iter().enumerate() {
        assert_eq!(col.len(), want.len());
        for (r, v) in col.iter().enumerate() {
            assert!(same(*v, want[r][c]), "row {r} column {}: {v} != {}", cols[c], want[r][c]);
        }
    }
    assert_eq!(t.warnings.len(), 2, "{:?}", t.warnings);
    assert!(
        t.warnings[0].contains("/camera") && t.warnings[0].contains("foxglove.CompressedImage"),
        "{}",
        t.warnings[0]
    );
    assert!(t.warnings[0].contains("skipped 1 message"), "{}", t.warnings[0]);
    assert!(t.warnings[1].contains("/imu") && t.warnings[1].contains("1 of 2"), "{}", t.warnings[1]);
}

#[test]
fn chunked_zstd_log_reads_back() {
    let opts = mcap::WriteOptions::new().compression(Some(mcap::Compression::Zstd));
    check_mixed(&write_log("zstd.mcap", &mixed_messages(), opts));
}

#[test]
fn chunked_lz4_log_reads_back() {
    let opts = mcap::WriteOptions::new().compression(Some(mcap::Compression::Lz4)).chunk_size(Some(64));
    check_mixed(&write_log("lz4.mcap", &mixed_messages(), opts));
}

#[test]
fn unchunked_log_reads_back() {
    check_mixed(&write_log("plain.mcap", &mixed_messages(), mcap::WriteOptions::new().use_chunks(false)));
}

#[test]
fn rows_come_in_log_time_order_when_the_file_is_not() {
    let mut msgs = mixed_messages();
    msgs.reverse();
    let path = write_log("reversed.mcap", &msgs, mcap::WriteOptions::new().use_chunks(false));
    let t = read_mcap(&path).unwrap();
    assert_eq!(t.table.column("time").unwrap(), [1.0, 1.25, 1.5]);
    // rows sorted, columns still in first-seen (file) order
    assert_eq!(t.table.columns[1], "j1.position");
    assert_eq!(t.table.column("j1.position").unwrap()[0], 0.1);
    assert_eq!(t.table.column("j1.position").unwrap()[2], 0.3);
    assert_eq!(t.table.column("/imu.accel.y").unwrap()[1], -1.0);
}

#[test]
fn streaming_reader_counts_rows_and_keeps_epoch_times() {
    let t0 = 1_700_000_000_000_000_000u64;
    let msgs: Vec<Msg> = (0..1000u64)
        .map(|k| Msg { channel: 0, log_time_ns: t0 + k * 1_000_000, data: joint_state_cdr(&["a"], &[k as f64], &[]) })
        .collect();
    let path = write_log("long.mcap", &msgs, mcap::WriteOptions::new().chunk_size(Some(4096)));
    let options = ReadOptions { align: Align::None, time: TimeSource::Log, ..ReadOptions::default() };
    let mut r = BagReader::open(&path, &options).unwrap();
    assert_eq!(r.columns(), ["time", "a.position"]);
    assert!(r.warnings().is_empty());
    let mut row = Vec::new();
    let mut k = 0u64;
    while r.read_row(&mut row).unwrap() {
        assert_eq!(row[1], k as f64);
        // an f64 at 1.7e9 s resolves 2^-22 s (about 240 ns)
        assert!((row[0] - (1.7e9 + k as f64 * 1e-3)).abs() <= 2.4e-7, "{k}: {}", row[0]);
        k += 1;
    }
    assert_eq!((k, r.rows_read()), (1000, 1000));
}

#[test]
fn bad_files_are_errors_naming_the_file() {
    let path = temp_path("not-mcap.mcap");
    std::fs::write(&path, "time,a\n0,1\n").unwrap();
    let e = read_mcap(&path).unwrap_err();
    assert!(e.to_string().contains("not-mcap.mcap") && e.to_string().contains("not an MCAP"), "{e}");

    let good = std::fs::read(write_log("cut.mcap", &mixed_messages(), mcap::WriteOptions::new())).unwrap();
    // Cut short (a recorder killed): the messages before the cut, with a warning; cut
    // before the first message, an error naming the file.
    let full = read_mcap(&temp_path("cut.mcap")).unwrap().table.data[0].len();
    let cut = temp_path("cut-short.mcap");
    std::fs::write(&cut, &good[..good.len() - 40]).unwrap();
    let t = read_mcap(&cut).unwrap();
    assert!(t.warnings.iter().any(|w| w.contains("ends before its footer")), "{:?}", t.warnings);
    assert!((1..=full).contains(&t.table.data[0].len()));
    std::fs::write(&cut, &good[..20]).unwrap();
    let e = read_mcap(&cut).unwrap_err();
    assert!(e.to_string().contains("cut-short.mcap") && e.to_string().contains("cut short"), "{e}");

    let missing = temp_path("missing.mcap");
    assert!(matches!(read_mcap(&missing), Err(IoError::Os { .. })));

    let bad_cdr = vec![Msg { channel: 0, log_time_ns: 5, data: vec![0, 1, 0, 0, 1] }];
    let e = read_mcap(&write_log("bad-cdr.mcap", &bad_cdr, mcap::WriteOptions::new())).unwrap_err();
    let s = e.to_string();
    assert!(s.contains("bad-cdr.mcap") && s.contains("/joint_states") && s.contains("truncated"), "{s}");

    let bad_json = vec![Msg { channel: 1, log_time_ns: 5, data: b"{\"a\": ".to_vec() }];
    let s = read_mcap(&write_log("bad-json.mcap", &bad_json, mcap::WriteOptions::new())).unwrap_err().to_string();
    assert!(s.contains("bad-json.mcap") && s.contains("/imu") && s.contains("JSON"), "{s}");
}

#[test]
fn only_unknown_channels_give_no_rows_and_a_warning() {
    let msgs = vec![Msg { channel: 2, log_time_ns: 1, data: vec![9; 10] }];
    let t = read_mcap(&write_log("unknown.mcap", &msgs, mcap::WriteOptions::new())).unwrap();
    assert_eq!(t.table.columns, ["time"]);
    assert!(t.table.data[0].is_empty());
    assert_eq!(t.warnings.len(), 1);
}

/// A fuzz case that made the MCAP library subtract past zero: an uncompressed chunk
/// whose inner record claims more bytes than the chunk holds.
#[test]
fn chunk_record_overrun_is_an_error_not_a_panic() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/chunk-record-overrun.mcap");
    let e = read_mcap(&path).unwrap_err().to_string();
    assert!(
        e.contains("chunk-record-overrun.mcap") && e.contains("runs past the chunk's end") && !e.contains('\n'),
        "{e}"
    );
}

#[test]
fn messages_are_counted_per_topic_apart_from_aligned_rows() {
    // JointState every 10 ms, JSON every 20 ms out of phase (5 ms late), a skipped
    // protobuf channel and a JSON message without numbers: aligned on the 100 Hz clock
    // there are as many rows as JointState messages, fewer than messages read.
    let mut msgs = Vec::new();
    for k in 0..40u64 {
        let t = 1_000_000_000 + k * 10_000_000;
        msgs.push(Msg { channel: 0, log_time_ns: t, data: joint_state_cdr(&["j1"], &[k as f64], &[0.0]) });
        if k % 2 == 0 {
            let data = format!("{{\"accel\": {{\"x\": {k}}}}}").into_bytes();
            msgs.push(Msg { channel: 1, log_time_ns: t + 5_000_000, data });
            msgs.push(Msg { channel: 2, log_time_ns: t + 6_000_000, data: vec![1, 2, 3] });
        }
    }
    msgs.push(Msg { channel: 1, log_time_ns: 2_000_000_000, data: br#"{"id": "none"}"#.to_vec() });
    let path = write_log("per-topic.mcap", &msgs, mcap::WriteOptions::new());
    let options = ReadOptions { time: TimeSource::Log, ..ReadOptions::default() };
    let mut r = BagReader::open(&path, &options).unwrap();
    assert_eq!(r.clock_topic(), Some("/joint_states"));
    let mut row = Vec::new();
    let mut rows = 0u64;
    while r.read_row(&mut row).unwrap() {
        rows += 1;
    }
    assert_eq!(rows, 40);
    assert_eq!(r.rows_read(), 40);
    assert_eq!(r.messages_per_topic(), [("/joint_states".to_string(), 40), ("/imu".to_string(), 20)]);

    // Through the recording reader: the input count is messages, not rows.
    let mut r = strainwave_io::RecordingReader::open_with(&path, &options).unwrap();
    while r.read_row(&mut row).unwrap() {}
    assert_eq!((r.input_rows(), r.rows_read()), (60, 40));
    assert_eq!(r.messages_per_topic().unwrap().len(), 2);
}
