//! The identity of a joint, as a learned file carries it: the gear ratio, the fixed
//! element, the phase source, the canceller's orders, the channels the coefficients
//! depend on (torque and phase) and a fingerprint of all of these. Learned coefficients belong to one joint: the phase of
//! a coefficient depends on the angle channels and their offsets, its order on the
//! gear. A learned file whose identity differs from the config that would use it is
//! refused, naming what differs.
//!
//! The fingerprint is FNV-1a (64 bit) of a canonical text of the physical keys, one
//! `key = value` line each, numbers in Rust's shortest round-trip form:
//!
//! ```text
//! gear.ratio = 100.0
//! gear.fixed = circular_spline
//! filter.phase = angle
//! order = 2 relative
//! order = 2 relative load-scaled
//! channels.torque = bridge_voltage * 1.0 + 0.0
//! ```
//!
//! It leaves out what does not change what a coefficient means: the tuning (noise,
//! sample rate, bandwidths) and the calibration (the coefficients are in N·m either
//! way).

use anyhow::Result;
use serde::{Deserialize, Serialize};
use strainwave_core::ripple::{Order, Reference, RippleModel};

use crate::canceller::{build_model, ModelVisitor};
use crate::config::{Fixed, JointConfig, PhaseChoice};

/// What a learned file records of its joint.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct JointIdentity {
    /// `gear.ratio`.
    pub ratio: f64,
    /// `gear.fixed`: `circular_spline` or `flexspline` (alias `circular-spline`).
    pub fixed: Fixed,
    /// `filter.phase`: `angle` or `velocity`.
    pub phase: PhaseChoice,
    /// The config's orders, e.g. `2 relative`, `2 relative load-scaled`, `1 output`.
    pub orders: Vec<String>,
    /// The channels the coefficients depend on (the torque, and the motor and output
    /// angles, or the tachometer for the velocity phase), `key = column`; their scale and
    /// offset are in the fingerprint.
    pub channels: Vec<String>,
    /// FNV-1a 64 of the canonical text, 16 hexadecimal digits.
    pub fingerprint: String,
}

/// The name of a reference angle in files and messages.
pub fn reference_name(r: Reference) -> &'static str {
    crate::config::ReferenceChoice::from(r).name()
}

/// An order as one word group: `2 relative`, `2 relative load-scaled`.
pub fn order_label(reference: &str, multiple: f64, load_scaled: bool) -> String {
    format!("{multiple} {reference}{}", if load_scaled { " load-scaled" } else { "" })
}

/// The orders of the config's model.
struct Orders;

impl ModelVisitor for Orders {
    type Output = Vec<String>;
    fn visit<const M: usize>(self, model: RippleModel<f64, M>) -> Result<Vec<String>> {
        Ok(model.orders().iter().map(label_of).collect())
    }
}

fn label_of(o: &Order<f64>) -> String {
    order_label(reference_name(o.reference()), o.multiple(), o.is_load_scaled())
}

/// FNV-1a, 64 bit: small, stable across versions and platforms.
fn fnv1a64(text: &str) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for b in text.bytes() {
        h ^= u64::from(b);
        h = h.wrapping_mul(0x0000_0100_0000_01b3);
    }
    h
}

impl JointIdentity {
    /// The identity of `cfg`'s joint. Errors are the config's own (its model cannot be built).
    pub fn of(cfg: &JointConfig) -> Result<Self> {
        let (fixed, phase) = (cfg.gear.fixed, cfg.filter.phase);
        let orders = build_model(cfg, false, Orders)?;
        let mut channels = Vec::new();
        // The canonical text (and so the fingerprint) spells the choices as they always were.
        let mut text = format!(
            "gear.ratio = {:?}\ngear.fixed = {}\nfilter.phase = {}\n",
            cfg.gear.ratio,
            fixed.name(),
            phase.name()
        );
        for o in &orders {
            text.push_str(&format!("order = {o}\n"));
        }
        // The channels the coefficients depend on: the torque and the phase's.
        let phase_keys: &[&str] = match cfg.filter.phase {
            PhaseChoice::Angle => &["torque", "motor_angle", "output_angle"],
            PhaseChoice::Velocity => &["torque", "motor_velocity"],
        };
        for (key, c) in cfg.channel_list().into_iter().filter(|(k, _)| phase_keys.contains(k)) {
            let (scale, offset) = c.scale_offset();
            channels.push(format!("{key} = {}", c.column_name()));
            text.push_str(&format!("channels.{key} = {} * {scale:?} + {offset:?}\n", c.column_name()));
        }
        Ok(Self {
            ratio: cfg.gear.ratio,
            fixed,
            phase,
            orders,
            channels,
            fingerprint: format!("{:016x}", fnv1a64(&text)),
        })
    }

    /// What differs between this (the config's) identity and `file`'s, in words, or
    /// `None` when they are the same joint.
    pub fn differences(&self, file: &JointIdentity) -> Option<String> {
        let mut d = Vec::new();
        if self.ratio != file.ratio {
            d.push(format!("gear.ratio {} in the file, {} in the config", file.ratio, self.ratio));
        }
        if self.fixed != file.fixed {
            d.push(format!("gear.fixed {} in the file, {} in the config", file.fixed.name(), self.fixed.name()));
        }
        if self.phase != file.phase {
            d.push(format!("filter.phase {} in the file, {} in the config", file.phase.name(), self.phase.name()));
        }
        if self.orders != file.orders {
            d.push(format!(
                "orders [{}] in the file, [{}] in the config",
                file.orders.join(", "),
                self.orders.join(", ")
            ));
        }
        if self.channels != file.channels {
            let only = |a: &[String], b: &[String]| a.iter().filter(|c| !b.contains(c)).cloned().collect::<Vec<_>>();
            d.push(format!(
                "channels [{}] in the file, [{}] in the config",
                only(&file.channels, &self.channels).join(", "),
                only(&self.channels, &file.channels).join(", ")
            ));
        }
        if d.is_empty() && self.fingerprint != file.fingerprint {
            d.push(format!(
                "fingerprint {} in the file, {} in the config (a channel's scale or offset)",
                file.fingerprint, self.fingerprint
            ));
        }
        (!d.is_empty()).then(|| d.join("; "))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fnv1a64_reference_values() {
        // Published test vectors of FNV-1a 64.
        assert_eq!(fnv1a64(""), 0xcbf29ce484222325);
        assert_eq!(fnv1a64("a"), 0xaf63dc4c8601ec8c);
        assert_eq!(fnv1a64("foobar"), 0x85944171f73967e8);
    }

    #[test]
    fn both_spellings_of_the_fixed_element_are_one_identity() {
        let text = |fixed: &str| {
            format!(
                "ratio = 100.0\nfixed = \"{fixed}\"\nphase = \"angle\"\norders = []\nchannels = []\n\
                 fingerprint = \"0\"\n"
            )
        };
        let snake: JointIdentity = toml::from_str(&text("circular_spline")).unwrap();
        let kebab: JointIdentity = toml::from_str(&text("circular-spline")).unwrap();
        assert_eq!(snake, kebab);
        assert_eq!(snake.fixed, Fixed::CircularSpline);
        assert!(toml::to_string(&kebab).unwrap().contains("fixed = \"circular_spline\""));
        let e = toml::from_str::<JointIdentity>(&text("ring")).unwrap_err().to_string();
        assert!(e.contains("`circular_spline`") && e.contains("`flexspline`"), "{e}");
    }

    #[test]
    fn labels() {
        assert_eq!(order_label("relative", 2.0, true), "2 relative load-scaled");
        assert_eq!(order_label("output", 0.5, false), "0.5 output");
    }
}
