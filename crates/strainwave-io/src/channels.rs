//! Channel mapping: a config names, for each signal a command needs, the column of the
//! recording that holds it, with an optional scale and offset into SI units, so that a
//! log is used as it is (`value = scale · cell + offset`).
//!
//! In TOML a channel is either a column name or a table:
//!
//! ```toml
//! [channels]
//! time = "Timestamp"
//! motor_angle = { column = "encoder_motorinc_3", scale = 3.745070282923e-7, offset = 173.1, unit = "rad" }
//! ```

use serde::{Deserialize, Serialize};

use crate::csv_io::CsvReader;
use crate::error::IoError;

/// Where a signal comes from. A table with a key other than `column`, `scale`,
/// `offset` and `unit` is refused with the key named (a misspelt `scale` must not
/// leave the signal unscaled).
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(untagged)]
pub enum Channel {
    /// Just the column name (scale 1, offset 0).
    Column(String),
    /// Column with scale, offset and unit.
    Mapped(ChannelTable),
}

/// The table form of a channel; unknown keys are refused.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ChannelTable {
    /// Column name in the recording.
    pub column: String,
    /// Multiplier into SI units.
    #[serde(default = "one")]
    pub scale: f64,
    /// Added after scaling, SI units.
    #[serde(default)]
    pub offset: f64,
    /// Unit after scaling (documentation only).
    #[serde(default)]
    pub unit: Option<String>,
}

fn one() -> f64 {
    1.0
}

impl<'de> Deserialize<'de> for Channel {
    fn deserialize<D: serde::Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        struct Form;
        impl<'de> serde::de::Visitor<'de> for Form {
            type Value = Channel;

            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("a column name or a table { column, scale, offset, unit }")
            }

            fn visit_str<E: serde::de::Error>(self, v: &str) -> Result<Channel, E> {
                Ok(Channel::Column(v.to_string()))
            }

            fn visit_map<A: serde::de::MapAccess<'de>>(self, map: A) -> Result<Channel, A::Error> {
                ChannelTable::deserialize(serde::de::value::MapAccessDeserializer::new(map)).map(Channel::Mapped)
            }
        }
        deserializer.deserialize_any(Form)
    }
}

impl Channel {
    /// A plain column.
    pub fn column(name: &str) -> Self {
        Channel::Column(name.to_string())
    }

    /// The column name.
    pub fn column_name(&self) -> &str {
        match self {
            Channel::Column(c) | Channel::Mapped(ChannelTable { column: c, .. }) => c,
        }
    }

    /// `(scale, offset)`.
    pub fn scale_offset(&self) -> (f64, f64) {
        match self {
            Channel::Column(_) => (1.0, 0.0),
            Channel::Mapped(t) => (t.scale, t.offset),
        }
    }

    /// Binds the channel to a reader's columns; `key` is the config key, for messages.
    pub fn bind(&self, reader: &CsvReader, key: &str) -> Result<BoundChannel, IoError> {
        let (scale, offset) = self.scale_offset();
        if !scale.is_finite() || !offset.is_finite() || scale == 0.0 {
            return Err(IoError::Csv {
                path: reader.path().to_path_buf(),
                msg: format!("channel `{key}`: scale must be finite and non-zero, offset finite"),
            });
        }
        let index = reader.column_index(self.column_name()).map_err(|e| match e {
            IoError::MissingColumn { path, column, available } => {
                IoError::MissingChannel { path, key: key.to_string(), column, available }
            }
            other => other,
        })?;
        Ok(BoundChannel { index, scale, offset })
    }
}

/// A channel resolved to a column index.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BoundChannel {
    /// Column index in the row.
    pub index: usize,
    /// Multiplier.
    pub scale: f64,
    /// Offset.
    pub offset: f64,
}

impl BoundChannel {
    /// The scaled value of this channel in a row.
    #[inline]
    pub fn get(&self, row: &[f64]) -> f64 {
        row.get(self.index).map_or(f64::NAN, |v| v * self.scale + self.offset)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

    #[derive(Deserialize)]
    struct Cfg {
        channels: std::collections::BTreeMap<String, Channel>,
    }

    #[test]
    fn parses_both_forms_and_binds() {
        let cfg: Cfg =
            toml::from_str("[channels]\ntime = \"t\"\nangle = { column = \"counts\", scale = 0.5, offset = 1.0 }\n")
                .unwrap();
        let r = CsvReader::from_reader(Path::new("log.csv"), Box::new("t,counts\n0,4\n".as_bytes())).unwrap();
        let a = cfg.channels["angle"].bind(&r, "angle").unwrap();
        assert_eq!(a.get(&[0.0, 4.0]), 3.0);
        let t = cfg.channels["time"].bind(&r, "time").unwrap();
        assert_eq!(t.get(&[0.25, 4.0]), 0.25);
        let e = Channel::column("torque").bind(&r, "torque").unwrap_err().to_string();
        assert_eq!(e, "log.csv: no column `torque` for channel `torque` (columns: t, counts)");
    }

    #[test]
    fn a_misspelt_key_in_a_channel_table_is_refused_by_name() {
        let e = toml::from_str::<Cfg>("[channels]\ntorque = { column = \"v\", sclae = 2.0 }\n").err().unwrap();
        assert!(e.to_string().contains("unknown field `sclae`"), "{e}");
        assert!(toml::from_str::<Cfg>("[channels]\ntorque = 3\n").is_err());
        let ok: Cfg = toml::from_str("[channels]\nt = { column = \"c\", unit = \"s\" }\n").unwrap();
        assert_eq!((ok.channels["t"].column_name(), ok.channels["t"].scale_offset()), ("c", (1.0, 0.0)));
    }
}
