//! Any ROS 2 message in CDR, walked by its parsed definition: every numeric field becomes
//! one value (integers, floats and booleans as `f64`), in wire order.
//!
//! The wire format (plain CDR, XCDR1): a 4-byte encapsulation header whose second byte is
//! 1 for little endian and 0 for big endian, then the fields; each primitive is aligned to
//! its size (at most 8) counted from the end of the header. A string is a `uint32` length
//! that includes a terminating NUL, then the bytes; a sequence is a `uint32` count, then
//! the elements; a fixed array is its elements. A type with no fields takes one byte.
//!
//! Nothing is allocated from a length field: a count is checked against the bytes left
//! before anything is read, and values are only pushed as they are decoded, so the work
//! and memory are bounded by the message size. Arrays longer than [`MAX_ARRAY_VALUES`]
//! (images, point clouds) are read past but give no values.

use super::msg_def::{Arity, MsgDef, Prim, Ty, MAX_DEPTH};

/// A numeric array with more elements than this gives no columns.
pub const MAX_ARRAY_VALUES: usize = 256;

/// A message that does not match its definition.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum WalkError {
    /// Fewer than 4 bytes.
    #[error("shorter than the 4-byte CDR encapsulation header")]
    NoHeader,
    /// Not plain CDR.
    #[error("CDR representation 0x{0:04x} is not supported (plain CDR only: 0x0000, 0x0001)")]
    Representation(u16),
    /// The message ends inside a field.
    #[error("truncated: the message ends at byte {len}, inside `{field}` (shorter than its schema says)")]
    Truncated {
        /// Body length.
        len: usize,
        /// Field path.
        field: String,
    },
    /// Types nested too deep.
    #[error("types nested deeper than {MAX_DEPTH} levels")]
    TooDeep,
}

/// Names of what [`walk`] decodes, for the first message of each layout.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Naming {
    /// The dotted field path of each value (`wrench.force.x`, `position.2`).
    pub paths: Vec<String>,
    /// Every string field: `(path, text)`.
    pub strings: Vec<(String, String)>,
    /// Paths of arrays left out for their length.
    pub long_arrays: Vec<String>,
}

/// One decoded message.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Decoded {
    /// Numeric values in wire order (the top-level `header` left out).
    pub values: Vec<f64>,
    /// What the column names depend on: sequence lengths and string bytes. Two messages
    /// with the same layout key have the same [`Naming`].
    pub layout_key: Vec<u8>,
    /// `header.stamp` in ns, when the message starts with a `std_msgs/Header`.
    pub stamp_ns: Option<i64>,
}

struct Walker<'a, 'o> {
    def: &'a MsgDef,
    body: &'a [u8],
    pos: usize,
    little_endian: bool,
    out: &'o mut Decoded,
    naming: Option<&'o mut Naming>,
    path: String,
}

/// Decodes `data` by `def` into `out` (cleared first); with `naming`, also the path of
/// every value and the strings.
pub fn walk(def: &MsgDef, data: &[u8], out: &mut Decoded, naming: Option<&mut Naming>) -> Result<(), WalkError> {
    out.values.clear();
    out.layout_key.clear();
    out.stamp_ns = None;
    let [b0, b1, _, _, body @ ..] = data else { return Err(WalkError::NoHeader) };
    let little_endian = match (*b0, *b1) {
        (0, 0) => false,
        (0, 1) => true,
        _ => return Err(WalkError::Representation(u16::from_be_bytes([*b0, *b1]))),
    };
    let mut w = Walker { def, body, pos: 0, little_endian, out, naming, path: String::new() };
    let skip_header = def.has_header();
    w.walk_type(0, true, skip_header, 0)?;
    if skip_header && body.len() >= 8 {
        let sec = i32::from_le_bytes(body[0..4].try_into().unwrap_or_default());
        let sec = if little_endian { sec } else { sec.swap_bytes() };
        let nsec = u32::from_le_bytes(body[4..8].try_into().unwrap_or_default());
        let nsec = if little_endian { nsec } else { nsec.swap_bytes() };
        w.out.stamp_ns = Some(i64::from(sec) * 1_000_000_000 + i64::from(nsec));
    }
    Ok(())
}

impl<'a> Walker<'a, '_> {
    fn truncated(&self) -> WalkError {
        WalkError::Truncated {
            len: self.body.len(),
            field: if self.path.is_empty() { "?".into() } else { self.path.clone() },
        }
    }

    fn take(&mut self, n: usize, align: usize) -> Result<&'a [u8], WalkError> {
        let start = self.pos.next_multiple_of(align);
        match start.checked_add(n).filter(|&e| e <= self.body.len()) {
            Some(end) => {
                self.pos = end;
                Ok(&self.body[start..end])
            }
            None => Err(self.truncated()),
        }
    }

    fn u32(&mut self) -> Result<u32, WalkError> {
        let b: [u8; 4] = self.take(4, 4)?.try_into().unwrap_or_default();
        Ok(if self.little_endian { u32::from_le_bytes(b) } else { u32::from_be_bytes(b) })
    }

    fn push_segment(&mut self, segment: &dyn std::fmt::Display) -> usize {
        let base = self.path.len();
        if self.naming.is_some() {
            use std::fmt::Write;
            if !self.path.is_empty() {
                self.path.push('.');
            }
            let _ = write!(self.path, "{segment}");
        }
        base
    }

    /// Walks one value of type `t`; `skip_first` leaves the first field's values out
    /// (the top-level header).
    fn walk_type(&mut self, t: usize, emit: bool, skip_first: bool, depth: usize) -> Result<(), WalkError> {
        if depth > MAX_DEPTH {
            return Err(WalkError::TooDeep);
        }
        let def = self.def;
        let fields = &def.types[t].fields;
        if fields.is_empty() {
            self.take(1, 1)?;
            return Ok(());
        }
        for (i, f) in fields.iter().enumerate() {
            let emit = emit && !(skip_first && i == 0);
            let base = self.push_segment(&f.name);
            let n = match f.arity {
                Arity::One => {
                    self.elem(f.ty, emit, depth)?;
                    self.path.truncate(base);
                    continue;
                }
                Arity::Fixed(n) => n,
                Arity::Seq => {
                    let n = self.u32()? as usize;
                    if emit {
                        self.out.layout_key.extend_from_slice(&(n as u32).to_le_bytes());
                    }
                    n
                }
            };
            // Elements that hold no value take no bytes: nothing to walk (a count of
            // billions would otherwise spin). The others must fit in what is left.
            let min = def.min_bytes(f.ty);
            if min == 0 {
                self.path.truncate(base);
                continue;
            }
            if n.saturating_mul(min) > self.body.len() - self.pos {
                return Err(self.truncated());
            }
            let numeric = matches!(f.ty, Ty::Prim(p) if p != Prim::Str);
            let keep = emit && !(numeric && n > MAX_ARRAY_VALUES);
            if emit && !keep {
                if let Some(naming) = self.naming.as_mut() {
                    naming.long_arrays.push(self.path.clone());
                }
            }
            for k in 0..n {
                let base_k = self.push_segment(&k);
                self.elem(f.ty, keep, depth)?;
                self.path.truncate(base_k);
            }
            self.path.truncate(base);
        }
        Ok(())
    }

    fn elem(&mut self, ty: Ty, emit: bool, depth: usize) -> Result<(), WalkError> {
        let p = match ty {
            Ty::Nested(i) => return self.walk_type(i, emit, false, depth + 1),
            Ty::Prim(p) => p,
        };
        if p == Prim::Str {
            let n = self.u32()? as usize;
            let bytes = self.take(n, 1)?;
            if emit {
                self.out.layout_key.extend_from_slice(&(n as u32).to_le_bytes());
                self.out.layout_key.extend_from_slice(bytes);
                if let Some(naming) = self.naming.as_mut() {
                    let text = bytes.strip_suffix(&[0]).unwrap_or(bytes);
                    naming.strings.push((self.path.clone(), String::from_utf8_lossy(text).into_owned()));
                }
            }
            return Ok(());
        }
        let size = p.size();
        let b = self.take(size, size)?;
        if !emit {
            return Ok(());
        }
        let mut a = [0u8; 8];
        a[..size].copy_from_slice(b);
        if !self.little_endian {
            a[..size].reverse();
        }
        let v = match p {
            Prim::Bool => f64::from(u8::from(a[0] != 0)),
            Prim::I8 => f64::from(a[0] as i8),
            Prim::U8 => f64::from(a[0]),
            Prim::I16 => f64::from(i16::from_le_bytes([a[0], a[1]])),
            Prim::U16 => f64::from(u16::from_le_bytes([a[0], a[1]])),
            Prim::I32 => f64::from(i32::from_le_bytes([a[0], a[1], a[2], a[3]])),
            Prim::U32 => f64::from(u32::from_le_bytes([a[0], a[1], a[2], a[3]])),
            Prim::F32 => f64::from(f32::from_le_bytes([a[0], a[1], a[2], a[3]])),
            Prim::I64 => i64::from_le_bytes(a) as f64,
            Prim::U64 => u64::from_le_bytes(a) as f64,
            Prim::F64 => f64::from_le_bytes(a),
            Prim::Str => return Ok(()),
        };
        self.out.values.push(v);
        if let Some(naming) = self.naming.as_mut() {
            naming.paths.push(self.path.clone());
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Little-endian CDR writer for the tests.
    struct W(Vec<u8>);
    impl W {
        fn new() -> Self {
            W(vec![0, 1, 0, 0])
        }
        fn align(&mut self, n: usize) {
            while !(self.0.len() - 4).is_multiple_of(n) {
                self.0.push(0);
            }
        }
        fn u32(&mut self, v: u32) {
            self.align(4);
            self.0.extend(v.to_le_bytes());
        }
        fn f64(&mut self, v: f64) {
            self.align(8);
            self.0.extend(v.to_le_bytes());
        }
        fn string(&mut self, s: &str) {
            self.u32(s.len() as u32 + 1);
            self.0.extend(s.as_bytes());
            self.0.push(0);
        }
    }

    #[test]
    fn nested_message_paths_values_and_stamp() {
        let def = MsgDef::parse(
            "my/Outer",
            "std_msgs/Header header\nInner[] inner\nint16[2] pair\n===\nMSG: my/Inner\nstring label\nfloat64 v\n",
        )
        .unwrap();
        let mut w = W::new();
        w.u32(7); // sec
        w.u32(250); // nanosec
        w.string("odd");
        w.u32(2);
        w.string("a");
        w.f64(1.5);
        w.string("bcd");
        w.f64(-2.0);
        w.align(2);
        w.0.extend(3i16.to_le_bytes());
        w.0.extend((-4i16).to_le_bytes());
        let mut out = Decoded::default();
        let mut naming = Naming::default();
        walk(&def, &w.0, &mut out, Some(&mut naming)).unwrap();
        assert_eq!(out.values, [1.5, -2.0, 3.0, -4.0]);
        assert_eq!(naming.paths, ["inner.0.v", "inner.1.v", "pair.0", "pair.1"]);
        assert_eq!(naming.strings[1], ("inner.1.label".to_string(), "bcd".to_string()));
        assert_eq!(out.stamp_ns, Some(7_000_000_250));
        let key = out.layout_key.clone();
        walk(&def, &w.0, &mut out, None).unwrap();
        assert_eq!(out.layout_key, key);
        // Every shorter prefix is an error, never a panic.
        for cut in 0..w.0.len() {
            assert!(walk(&def, &w.0[..cut], &mut out, None).is_err(), "cut at {cut}");
        }
    }

    #[test]
    fn huge_counts_are_refused_before_allocating() {
        let def = MsgDef::parse("my/A", "float64[] v").unwrap();
        let mut w = W::new();
        w.u32(u32::MAX);
        let e = walk(&def, &w.0, &mut Decoded::default(), None).unwrap_err();
        assert!(matches!(e, WalkError::Truncated { .. }), "{e}");
    }

    #[test]
    fn arrays_of_elements_without_bytes_or_beyond_the_message_end_at_once() {
        // Four billion elements that hold nothing: before, a walk that never ended.
        let def = MsgDef::parse("my/A", "Z[4000000000] z\nfloat64 x\n===\nMSG: my/Z\nfloat64[0] a").unwrap();
        let mut w = W::new();
        w.f64(2.5);
        let mut out = Decoded::default();
        walk(&def, &w.0, &mut out, None).unwrap();
        assert_eq!(out.values, [2.5]);
        // A fixed array longer than the message: refused before walking it.
        let def = MsgDef::parse("my/A", "float64[4000000000] v").unwrap();
        let e = walk(&def, &W::new().0, &mut Decoded::default(), None).unwrap_err();
        assert!(matches!(e, WalkError::Truncated { .. }), "{e}");
    }

    #[test]
    fn long_arrays_give_no_values() {
        let def = MsgDef::parse("my/A", "uint8[] data\nfloat64 x").unwrap();
        let mut w = W::new();
        w.u32(1000);
        w.0.extend(std::iter::repeat_n(7u8, 1000));
        w.f64(2.5);
        let mut out = Decoded::default();
        let mut naming = Naming::default();
        walk(&def, &w.0, &mut out, Some(&mut naming)).unwrap();
        assert_eq!(out.values, [2.5]);
        assert_eq!(naming.long_arrays, ["data"]);
    }
}
