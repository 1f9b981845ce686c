//! MCAP input helpers: JSON messages flattened to columns, the JointState CDR decoder,
//! and [`read_mcap`], a whole log in memory as it was recorded. Logs are read as
//! recordings by [`BagReader`] (see `crate::ros2::bag` for the columns, the clock and the
//! memory bound).
//!
//! `time` is `t_ns / 1e9` in s: below 2^53 ns (104 days) the correctly rounded quotient;
//! at Unix-epoch magnitudes (about 1.7e9 s) an f64 resolves about 240 ns.

use std::fmt;
use std::path::Path;

use serde::de::{DeserializeSeed, Deserializer, MapAccess, SeqAccess, Visitor};

use crate::error::IoError;
pub use crate::read_options::{Align, ReadOptions, TimeSource};
pub use crate::ros2::bag::BagReader;
use crate::Table;

mod cdr;
pub use cdr::{decode_joint_state, CdrError, JointState, JOINT_STATE_SCHEMAS};

/// Appends `(column, value)` for every numeric field of one JSON document, in document
/// order: `prefix.a.b` for nested objects, `prefix.a.0` for array items (`prefix` alone
/// for a bare number). Strings, booleans and nulls are left out.
///
/// ```
/// let mut out = Vec::new();
/// strainwave_io::mcap_in::flatten_json(br#"{"q": [1, 2.5], "id": "x"}"#, "/arm", &mut out).unwrap();
/// assert_eq!(out, vec![("/arm.q.0".to_string(), 1.0), ("/arm.q.1".to_string(), 2.5)]);
/// ```
pub fn flatten_json(data: &[u8], prefix: &str, out: &mut Vec<(String, f64)>) -> Result<(), serde_json::Error> {
    let mut path = prefix.to_string();
    let mut de = serde_json::Deserializer::from_slice(data);
    Flatten { path: &mut path, out }.deserialize(&mut de)?;
    de.end()
}

/// Walks a JSON document without building a tree, keeping key order.
struct Flatten<'p> {
    path: &'p mut String,
    out: &'p mut Vec<(String, f64)>,
}

impl Flatten<'_> {
    fn child(&mut self, segment: &str) -> Flatten<'_> {
        if !self.path.is_empty() {
            self.path.push('.');
        }
        self.path.push_str(segment);
        Flatten { path: self.path, out: self.out }
    }
}

impl<'de> DeserializeSeed<'de> for Flatten<'_> {
    type Value = ();
    fn deserialize<D: Deserializer<'de>>(self, d: D) -> Result<(), D::Error> {
        d.deserialize_any(self)
    }
}

impl<'de> Visitor<'de> for Flatten<'_> {
    type Value = ();
    fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
        f.write_str("a JSON value")
    }
    fn visit_f64<E: serde::de::Error>(self, v: f64) -> Result<(), E> {
        self.out.push((self.path.clone(), v));
        Ok(())
    }
    fn visit_i64<E: serde::de::Error>(self, v: i64) -> Result<(), E> {
        self.visit_f64(v as f64)
    }
    fn visit_u64<E: serde::de::Error>(self, v: u64) -> Result<(), E> {
        self.visit_f64(v as f64)
    }
    fn visit_bool<E: serde::de::Error>(self, _: bool) -> Result<(), E> {
        Ok(())
    }
    fn visit_str<E: serde::de::Error>(self, _: &str) -> Result<(), E> {
        Ok(())
    }
    fn visit_unit<E: serde::de::Error>(self) -> Result<(), E> {
        Ok(())
    }
    fn visit_seq<A: SeqAccess<'de>>(mut self, mut seq: A) -> Result<(), A::Error> {
        let base = self.path.len();
        for i in 0usize.. {
            let more = seq.next_element_seed(self.child(&i.to_string()))?;
            self.path.truncate(base);
            if more.is_none() {
                break;
            }
        }
        Ok(())
    }
    fn visit_map<A: MapAccess<'de>>(mut self, mut map: A) -> Result<(), A::Error> {
        let base = self.path.len();
        while let Some(key) = map.next_key::<String>()? {
            map.next_value_seed(self.child(&key))?;
            self.path.truncate(base);
        }
        Ok(())
    }
}

/// A whole MCAP log as a table, with the warnings of skipped channels.
#[derive(Debug, Clone, PartialEq)]
pub struct McapTable {
    /// `time` and the message columns (NaN where a message lacks a column).
    pub table: Table,
    /// One line per skipped channel, naming topic and schema.
    pub warnings: Vec<String>,
}

/// Reads a whole log into memory as it was recorded: one row per message with values,
/// at its log time, NaN in the columns it does not have (see [`BagReader`] to stream it
/// and to align topics on one clock).
pub fn read_mcap(path: &Path) -> Result<McapTable, IoError> {
    let options = ReadOptions { align: Align::None, time: TimeSource::Log, ..ReadOptions::default() };
    let mut r = BagReader::open(path, &options)?;
    let columns = r.columns().to_vec();
    let table = Table::collect(path, &columns, |row| r.read_row(row))?;
    Ok(McapTable { table, warnings: r.warnings().to_vec() })
}
