//! ROS 2 `sensor_msgs/msg/JointState` from its CDR serialization.

/// Schema names read as ROS 2 `sensor_msgs/msg/JointState` (with message encoding `cdr`).
pub const JOINT_STATE_SCHEMAS: [&str; 2] = ["sensor_msgs/msg/JointState", "sensor_msgs/JointState"];

/// A decoded `sensor_msgs/msg/JointState`.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct JointState {
    /// `header.stamp.sec`.
    pub stamp_sec: i32,
    /// `header.stamp.nanosec`.
    pub stamp_nanosec: u32,
    /// `header.frame_id`.
    pub frame_id: String,
    /// Joint names.
    pub name: Vec<String>,
    /// Positions (rad or m), empty or one per name.
    pub position: Vec<f64>,
    /// Velocities (rad/s or m/s), empty or one per name.
    pub velocity: Vec<f64>,
    /// Efforts (N·m or N), empty or one per name.
    pub effort: Vec<f64>,
}

/// A CDR message that cannot be decoded.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum CdrError {
    /// Fewer than 4 bytes.
    #[error("shorter than the 4-byte CDR encapsulation header")]
    NoHeader,
    /// Not plain CDR (0x0000 big endian, 0x0001 little endian).
    #[error("CDR representation 0x{0:04x} is not supported (plain CDR only: 0x0000, 0x0001)")]
    Representation(u16),
    /// The message ends inside a field.
    #[error("truncated: ends at byte {offset} inside `{field}`")]
    Truncated {
        /// Offset after the encapsulation header.
        offset: usize,
        /// Field being read.
        field: &'static str,
    },
    /// A value array whose length is neither 0 nor the number of names.
    #[error("`{field}` has {got} values for {names} names")]
    Length {
        /// `position`, `velocity` or `effort`.
        field: &'static str,
        /// Its length.
        got: usize,
        /// Number of names.
        names: usize,
    },
}

/// A CDR cursor; alignment is relative to the end of the encapsulation header.
struct Cdr<'a> {
    body: &'a [u8],
    pos: usize,
    little_endian: bool,
}

impl<'a> Cdr<'a> {
    fn take(&mut self, n: usize, align: usize, field: &'static str) -> Result<&'a [u8], CdrError> {
        let start = self.pos.next_multiple_of(align);
        let end = start.checked_add(n).filter(|&e| e <= self.body.len());
        let Some(end) = end else { return Err(CdrError::Truncated { offset: self.body.len(), field }) };
        self.pos = end;
        Ok(&self.body[start..end])
    }

    fn u32(&mut self, field: &'static str) -> Result<u32, CdrError> {
        let b: [u8; 4] = self.take(4, 4, field)?.try_into().unwrap_or_default();
        Ok(if self.little_endian { u32::from_le_bytes(b) } else { u32::from_be_bytes(b) })
    }

    fn f64(&mut self, field: &'static str) -> Result<f64, CdrError> {
        let b: [u8; 8] = self.take(8, 8, field)?.try_into().unwrap_or_default();
        Ok(if self.little_endian { f64::from_le_bytes(b) } else { f64::from_be_bytes(b) })
    }

    /// uint32 length including the NUL, then the bytes.
    fn string(&mut self, field: &'static str) -> Result<String, CdrError> {
        let n = self.u32(field)? as usize;
        let bytes = self.take(n, 1, field)?;
        let bytes = bytes.strip_suffix(&[0]).unwrap_or(bytes);
        Ok(String::from_utf8_lossy(bytes).into_owned())
    }

    /// uint32 count, then each element aligned to its size (no padding when empty).
    fn count(&mut self, min_size: usize, field: &'static str) -> Result<usize, CdrError> {
        let n = self.u32(field)? as usize;
        if n.saturating_mul(min_size) > self.body.len() - self.pos {
            return Err(CdrError::Truncated { offset: self.body.len(), field });
        }
        Ok(n)
    }

    fn f64_seq(&mut self, field: &'static str) -> Result<Vec<f64>, CdrError> {
        let n = self.count(8, field)?;
        (0..n).map(|_| self.f64(field)).collect()
    }
}

/// Decodes a CDR-encoded `sensor_msgs/msg/JointState`: the 4-byte encapsulation header
/// (byte 1: 0 big endian, 1 little endian), then `header` {stamp {int32 sec, uint32
/// nanosec}, string frame_id}, string[] name, float64[] position, velocity, effort.
/// Value arrays must be empty or as long as `name`.
pub fn decode_joint_state(data: &[u8]) -> Result<JointState, CdrError> {
    let [b0, b1, _, _, body @ ..] = data else { return Err(CdrError::NoHeader) };
    let little_endian = match (*b0, *b1) {
        (0, 0) => false,
        (0, 1) => true,
        _ => return Err(CdrError::Representation(u16::from_be_bytes([*b0, *b1]))),
    };
    let mut c = Cdr { body, pos: 0, little_endian };
    let stamp_sec = c.u32("header.stamp.sec")? as i32;
    let stamp_nanosec = c.u32("header.stamp.nanosec")?;
    let frame_id = c.string("header.frame_id")?;
    let n = c.count(4, "name")?;
    let name = (0..n).map(|_| c.string("name")).collect::<Result<Vec<_>, _>>()?;
    let position = c.f64_seq("position")?;
    let velocity = c.f64_seq("velocity")?;
    let effort = c.f64_seq("effort")?;
    for (field, v) in [("position", &position), ("velocity", &velocity), ("effort", &effort)] {
        if !v.is_empty() && v.len() != name.len() {
            return Err(CdrError::Length { field, got: v.len(), names: name.len() });
        }
    }
    Ok(JointState { stamp_sec, stamp_nanosec, frame_id, name, position, velocity, effort })
}
