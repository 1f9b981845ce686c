//! CDR decoding of `sensor_msgs/msg/JointState` from hand-built bytes, and JSON
//! flattening, without any MCAP file.
#![cfg(feature = "mcap")]

use strainwave_io::mcap_in::{decode_joint_state, flatten_json, CdrError, JointState};

/// A tiny CDR writer for the tests: alignment relative to the end of the 4-byte header.
struct Enc {
    out: Vec<u8>,
    le: bool,
}

impl Enc {
    fn new(le: bool) -> Self {
        Self { out: vec![0, u8::from(le), 0, 0], le }
    }
    fn pad(&mut self, n: usize) {
        while !(self.out.len() - 4).is_multiple_of(n) {
            self.out.push(0xAA); // padding content must not matter
        }
    }
    fn u32(&mut self, v: u32) {
        self.pad(4);
        self.out.extend(if self.le { v.to_le_bytes() } else { v.to_be_bytes() });
    }
    fn f64(&mut self, v: f64) {
        self.pad(8);
        self.out.extend(if self.le { v.to_le_bytes() } else { v.to_be_bytes() });
    }
    fn string(&mut self, s: &str) {
        self.u32(s.len() as u32 + 1);
        self.out.extend(s.as_bytes());
        self.out.push(0);
    }
    fn joint_state(mut self, js: &JointState) -> Vec<u8> {
        self.u32(js.stamp_sec as u32);
        self.u32(js.stamp_nanosec);
        self.string(&js.frame_id);
        self.u32(js.name.len() as u32);
        for n in &js.name {
            self.string(n);
        }
        for v in [&js.position, &js.velocity, &js.effort] {
            self.u32(v.len() as u32);
            for x in v.iter() {
                self.f64(*x);
            }
        }
        self.out
    }
}

fn sample(frame_id: &str) -> JointState {
    JointState {
        stamp_sec: -3,
        stamp_nanosec: 999_999_999,
        frame_id: frame_id.to_string(),
        name: vec!["shoulder".into(), "elbow_joint".into(), "w".into()],
        position: vec![0.125, -1.5e-7, 3.0],
        velocity: vec![],
        effort: vec![12.5, f64::MAX, -0.0],
    }
}

#[test]
fn little_endian_round_trip_with_odd_frame_id() {
    // "base" + NUL = 5 bytes: the name count lands at 8 + 4 + 5 = 17, padded to 20.
    for frame in ["base", "", "ab", "link_7"] {
        let js = sample(frame);
        let bytes = Enc::new(true).joint_state(&js);
        assert_eq!(decode_joint_state(&bytes).unwrap(), js, "frame_id {frame:?}");
    }
}

#[test]
fn big_endian_round_trip() {
    let js = sample("odd");
    let bytes = Enc::new(false).joint_state(&js);
    assert_eq!(bytes[1], 0);
    assert_eq!(decode_joint_state(&bytes).unwrap(), js);
}

#[test]
fn alignment_of_float64_array_after_odd_strings() {
    // Names "a" and "bcd" leave the offset at 8+4+1(pad to 4: frame "x" = 2 bytes)...
    // whatever it is, position's first double must start at a multiple of 8 after the header.
    let js = JointState {
        stamp_sec: 1,
        stamp_nanosec: 2,
        frame_id: "x".into(),
        name: vec!["a".into()],
        position: vec![std::f64::consts::PI],
        velocity: vec![2.0],
        effort: vec![],
    };
    let bytes = Enc::new(true).joint_state(&js);
    // 4 sec + 4 nsec + (4 + 2) frame -> 14, pad to 16: count; 20: len 2; 24..26 "a\0";
    // pad to 28: position count; 32: PI (already aligned to 8), 40: velocity count, pad to 48: 2.0.
    let body = &bytes[4..];
    assert_eq!(f64::from_le_bytes(body[32..40].try_into().unwrap()), std::f64::consts::PI);
    assert_eq!(f64::from_le_bytes(body[48..56].try_into().unwrap()), 2.0);
    assert_eq!(decode_joint_state(&bytes).unwrap(), js);
}

#[test]
fn empty_arrays_add_no_padding() {
    // An empty float64[] right after a count at offset 4 mod 8 must not skip 4 bytes.
    let js = JointState {
        name: vec!["j".into()],
        position: vec![],
        velocity: vec![],
        effort: vec![7.0],
        ..Default::default()
    };
    let bytes = Enc::new(true).joint_state(&js);
    assert_eq!(decode_joint_state(&bytes).unwrap(), js);
}

#[test]
fn bad_messages_are_errors_not_panics() {
    let bytes = Enc::new(true).joint_state(&sample("base"));
    assert_eq!(decode_joint_state(&bytes[..3]), Err(CdrError::NoHeader));
    let mut pl = bytes.clone();
    pl[1] = 3;
    assert_eq!(decode_joint_state(&pl), Err(CdrError::Representation(3)));
    for cut in 4..bytes.len() {
        assert!(
            matches!(decode_joint_state(&bytes[..cut]), Err(CdrError::Truncated { .. })),
            "cut at {cut} of {}",
            bytes.len()
        );
    }
    // A huge sequence count must fail fast, not allocate.
    let mut e = Enc::new(true);
    e.u32(0);
    e.u32(0);
    e.string("");
    e.u32(u32::MAX);
    assert!(matches!(decode_joint_state(&e.out), Err(CdrError::Truncated { field: "name", .. })));
    let bad = JointState { name: vec!["a".into(), "b".into()], position: vec![1.0], ..Default::default() };
    assert_eq!(
        decode_joint_state(&Enc::new(true).joint_state(&bad)),
        Err(CdrError::Length { field: "position", got: 1, names: 2 })
    );
}

#[test]
fn json_flattens_numbers_by_path_in_document_order() {
    let doc = br#"{"z": 1, "accel": {"x": 0.5, "y": -2e-3, "label": "imu"}, "q": [1, [2, 3]],
                   "ok": true, "none": null, "big": 18446744073709551615, "neg": -7}"#;
    let mut out = Vec::new();
    flatten_json(doc, "/imu", &mut out).unwrap();
    let want: Vec<(String, f64)> = [
        ("/imu.z", 1.0),
        ("/imu.accel.x", 0.5),
        ("/imu.accel.y", -2e-3),
        ("/imu.q.0", 1.0),
        ("/imu.q.1.0", 2.0),
        ("/imu.q.1.1", 3.0),
        ("/imu.big", u64::MAX as f64),
        ("/imu.neg", -7.0),
    ]
    .iter()
    .map(|(k, v)| (k.to_string(), *v))
    .collect();
    assert_eq!(out, want);
}

#[test]
fn json_bare_number_and_errors() {
    let mut out = Vec::new();
    flatten_json(b"42.5", "/t", &mut out).unwrap();
    assert_eq!(out, vec![("/t".to_string(), 42.5)]);
    out.clear();
    assert!(flatten_json(br#"{"a": 1"#, "/t", &mut out).is_err());
    assert!(flatten_json(br#"{"a": 1} trailing"#, "/t", &mut out).is_err());
}
