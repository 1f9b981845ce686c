//! Motion profile (motor speed reference or open-loop current) and external torque,
//! both as functions of time.

use crate::scenario::{ExternalTorque, MotionSegment};
use std::f64::consts::TAU;

/// What the motor is asked to do at an instant.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Command {
    /// Follow a motor speed, rad/s, with its derivative, rad/s².
    Speed {
        /// Reference speed, rad/s.
        speed_rad_s: f64,
        /// Reference acceleration, rad/s².
        accel_rad_s2: f64,
    },
    /// Apply a motor current, A (speed loop off).
    Current(f64),
}

#[derive(Debug, Clone)]
struct Segment {
    start_s: f64,
    end_s: f64,
    start_speed: f64,
    kind: MotionSegment,
}

/// The motion profile with start times and start speeds resolved.
#[derive(Debug, Clone)]
pub struct MotionProfile {
    segments: Vec<Segment>,
}

impl MotionProfile {
    /// Resolves the segments; an empty profile is a standstill.
    pub fn new(segments: &[MotionSegment]) -> Self {
        let mut t = 0.0;
        let mut speed = 0.0;
        let mut out = Vec::with_capacity(segments.len());
        for seg in segments {
            let (dur, end_speed) = match seg {
                MotionSegment::Ramp { to_rad_s, duration_s } => (*duration_s, *to_rad_s),
                MotionSegment::Hold { duration_s } => (*duration_s, speed),
                // A sine segment returns to its centre speed after whole periods; the
                // profile continues from the centre speed.
                MotionSegment::Sine { duration_s, .. } => (*duration_s, speed),
                MotionSegment::Current { duration_s, .. } => (*duration_s, speed),
            };
            out.push(Segment { start_s: t, end_s: t + dur, start_speed: speed, kind: seg.clone() });
            t += dur;
            speed = end_speed;
        }
        Self { segments: out }
    }

    /// The command at time `t_s`; after the last segment the last speed is held.
    pub fn command(&self, t_s: f64) -> Command {
        let Some(seg) = self.segments.iter().find(|s| t_s < s.end_s).or(self.segments.last()) else {
            return Command::Speed { speed_rad_s: 0.0, accel_rad_s2: 0.0 };
        };
        let tau = (t_s - seg.start_s).max(0.0);
        let past_end = t_s >= seg.end_s;
        match seg.kind {
            MotionSegment::Ramp { to_rad_s, duration_s } => {
                if past_end {
                    Command::Speed { speed_rad_s: to_rad_s, accel_rad_s2: 0.0 }
                } else {
                    let a = (to_rad_s - seg.start_speed) / duration_s;
                    Command::Speed { speed_rad_s: seg.start_speed + a * tau, accel_rad_s2: a }
                }
            }
            MotionSegment::Hold { .. } => Command::Speed { speed_rad_s: seg.start_speed, accel_rad_s2: 0.0 },
            MotionSegment::Sine { amplitude_rad_s, frequency_hz, .. } => {
                if past_end {
                    Command::Speed { speed_rad_s: seg.start_speed, accel_rad_s2: 0.0 }
                } else {
                    let w = TAU * frequency_hz;
                    Command::Speed {
                        speed_rad_s: seg.start_speed + amplitude_rad_s * (w * tau).sin(),
                        accel_rad_s2: amplitude_rad_s * w * (w * tau).cos(),
                    }
                }
            }
            MotionSegment::Current { current_a, .. } => {
                if past_end {
                    Command::Current(0.0)
                } else {
                    Command::Current(current_a)
                }
            }
        }
    }
}

/// External torque on the load at `t_s`, N·m: the sum of the components.
pub fn external_torque_nm(components: &[ExternalTorque], t_s: f64) -> f64 {
    components
        .iter()
        .map(|c| match *c {
            ExternalTorque::Step { at_s, torque_nm } => {
                if t_s >= at_s {
                    torque_nm
                } else {
                    0.0
                }
            }
            ExternalTorque::Sine { amplitude_nm, frequency_hz, phase_rad, start_s } => {
                if t_s >= start_s {
                    amplitude_nm * (TAU * frequency_hz * (t_s - start_s) + phase_rad).sin()
                } else {
                    0.0
                }
            }
            ExternalTorque::Ramp { from_s, to_s, torque_nm } => {
                torque_nm * ((t_s - from_s) / (to_s - from_s)).clamp(0.0, 1.0)
            }
        })
        .sum()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ramp_hold_reversal() {
        let p = MotionProfile::new(&[
            MotionSegment::Ramp { to_rad_s: 100.0, duration_s: 1.0 },
            MotionSegment::Hold { duration_s: 1.0 },
            MotionSegment::Ramp { to_rad_s: -100.0, duration_s: 2.0 },
        ]);
        assert_eq!(p.command(0.5), Command::Speed { speed_rad_s: 50.0, accel_rad_s2: 100.0 });
        assert_eq!(p.command(1.5), Command::Speed { speed_rad_s: 100.0, accel_rad_s2: 0.0 });
        assert_eq!(p.command(3.0), Command::Speed { speed_rad_s: 0.0, accel_rad_s2: -100.0 });
        assert_eq!(p.command(9.0), Command::Speed { speed_rad_s: -100.0, accel_rad_s2: 0.0 });
    }

    #[test]
    fn empty_profile_is_standstill() {
        assert_eq!(MotionProfile::new(&[]).command(1.0), Command::Speed { speed_rad_s: 0.0, accel_rad_s2: 0.0 });
    }

    #[test]
    fn external_components_add() {
        let c = [
            ExternalTorque::Step { at_s: 1.0, torque_nm: 2.0 },
            ExternalTorque::Ramp { from_s: 0.0, to_s: 2.0, torque_nm: 4.0 },
        ];
        assert_eq!(external_torque_nm(&c, 0.5), 1.0);
        assert_eq!(external_torque_nm(&c, 1.5), 5.0);
        assert_eq!(external_torque_nm(&c, 3.0), 6.0);
    }
}
