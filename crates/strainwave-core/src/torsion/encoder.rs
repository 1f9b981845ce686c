use super::*;

/// One encoder: counts per revolution, counter modulus, zero offset, direction, jump limit.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct EncoderConfig {
    counts_per_rev: u64,
    pub(super) modulus_counts: u64,
    pub(super) offset_counts: i64,
    reversed: bool,
    max_step_counts: u64,
}

impl EncoderConfig {
    /// A multi-turn (absolute, never wrapping) counter with `counts_per_rev > 0`.
    ///
    /// ```
    /// use strainwave_core::torsion::EncoderConfig;
    /// let e = EncoderConfig::multi_turn(1 << 24).unwrap().with_offset(-462_313_317).reversed();
    /// assert!(EncoderConfig::multi_turn(0).is_err());
    /// # let _ = e;
    /// ```
    pub fn multi_turn(counts_per_rev: u64) -> Result<Self, Error> {
        if counts_per_rev == 0 || counts_per_rev > (1 << 52) {
            return Err(Error::NonPositive("counts_per_rev"));
        }
        Ok(Self { counts_per_rev, modulus_counts: 0, offset_counts: 0, reversed: false, max_step_counts: 0 })
    }

    /// A single-turn counter reading `0 … counts_per_rev − 1` that wraps every revolution.
    pub fn single_turn(counts_per_rev: u64) -> Result<Self, Error> {
        Self::multi_turn(counts_per_rev)?.with_modulus(counts_per_rev)
    }

    /// A counter register that wraps at `modulus_counts` (e.g. 2^32 for a 32-bit
    /// multi-turn register; `counts_per_rev` for a single-turn one). 0 = never wraps.
    pub fn with_modulus(mut self, modulus_counts: u64) -> Result<Self, Error> {
        if modulus_counts != 0 && !(4..=(1 << 62)).contains(&modulus_counts) {
            return Err(Error::OutOfRange("modulus_counts"));
        }
        self.modulus_counts = modulus_counts;
        Ok(self)
    }

    /// Zero offset: the raw count at which the angle is 0.
    pub fn with_offset(mut self, offset_counts: i64) -> Self {
        self.offset_counts = offset_counts;
        self
    }

    /// The encoder counts against the gear's convention (angle = −counts × 2π/cpr).
    pub fn reversed(mut self) -> Self {
        self.reversed = true;
        self
    }

    /// Largest plausible change between two samples, counts; a larger change is flagged
    /// as a jump. 0 (default) = a quarter of the modulus, or never for a multi-turn counter.
    pub fn with_max_step(mut self, max_step_counts: u64) -> Self {
        self.max_step_counts = max_step_counts;
        self
    }

    /// Counts per revolution.
    pub fn counts_per_rev(&self) -> u64 {
        self.counts_per_rev
    }

    /// Counter modulus (0 = none).
    pub fn modulus_counts(&self) -> u64 {
        self.modulus_counts
    }

    /// Radians per count, with the direction.
    pub(super) fn rad_per_count(&self) -> f64 {
        let r = TAU_F64 / self.counts_per_rev as f64;
        if self.reversed {
            -r
        } else {
            r
        }
    }

    fn jump_limit(&self) -> u64 {
        if self.max_step_counts > 0 {
            self.max_step_counts
        } else if self.modulus_counts > 0 {
            self.modulus_counts / 4
        } else {
            u64::MAX
        }
    }
}

/// Unwrapping state of one encoder.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct EncoderState {
    pub(super) last_raw: i64,
    pub(super) accumulated: i64,
}

impl EncoderState {
    /// Accumulated counts from the zero offset (unwrapped, before the direction).
    pub fn accumulated_counts(&self) -> i64 {
        self.accumulated
    }
}

/// What the unwrapping saw on this sample.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct EncoderFlags {
    /// The motor counter rolled over (normal for a single-turn counter).
    pub motor_wrapped: bool,
    /// The link counter rolled over.
    pub link_wrapped: bool,
    /// The motor count changed by more than its plausible step: the unwrapped angle may be wrong.
    pub motor_jump: bool,
    /// The link count changed by more than its plausible step.
    pub link_jump: bool,
}

impl EncoderFlags {
    /// Whether either encoder jumped.
    pub fn any_jump(&self) -> bool {
        self.motor_jump || self.link_jump
    }
}

/// `(delta, wrapped, jump)` of a new raw count.
pub(super) fn unwrap_delta(cfg: &EncoderConfig, st: &EncoderState, raw: i64) -> (i64, bool, bool) {
    let mut d = raw.wrapping_sub(st.last_raw);
    let mut wrapped = false;
    if cfg.modulus_counts > 0 {
        let m = cfg.modulus_counts as i64;
        if d >= m / 2 {
            d -= m;
            wrapped = true;
        } else if d < -(m / 2) {
            d += m;
            wrapped = true;
        }
    }
    (d, wrapped, d.unsigned_abs() > cfg.jump_limit())
}

/// Checks a raw count against the counter's modulus.
pub(super) fn check_raw(cfg: &EncoderConfig, raw: i64, name: &'static str) -> Result<(), Error> {
    if cfg.modulus_counts > 0 && (raw < 0 || raw as u64 >= cfg.modulus_counts) {
        Err(Error::OutOfRange(name))
    } else {
        Ok(())
    }
}
