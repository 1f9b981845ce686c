//! A learning canceller locked by its own load-step test, and the way out.
//!
//! The load-step test takes an innovation beyond its NIS limit as a jump of the torque:
//! the bias takes it whole and the ripple oscillators learn nothing from that sample.
//! That is right for a step, which the bias absorbs in one sample (the joint's ringing
//! after it keeps the test firing for some tens of samples). It locks a canceller whose
//! oscillators went wrong with a small variance: every innovation is then large, every
//! sample is a "step", and the oscillators never see the data that would correct them.
//!
//! A learning canceller starting cold at standstill gets there when the run starts with
//! a speed ramp. While the lines are at a few Hz, the orthogonal coefficient of each
//! oscillator (prior 1σ 1 N·m) explains the ramp's acceleration torque better than the
//! slow commissioning bias does, with a gain of about `1 / Δψ` (`Δψ` the line's phase step
//! per sample): random joint 18 of the twin learned 6.2 N·m of 2× ripple that way in the
//! first 40 samples, and its test then fired on 29 950 of 30 400 samples.
//!
//! [`StepLock`] watches the test's flags: a run of consecutive load steps longer than
//! [`LOCKED_AFTER_S`] is not a load but a lock, and the learning state should start again.

/// A run of consecutive load steps this long (seconds) is a lock. On the twin's
/// commissioning runs genuine steps fired the test on at most 31 consecutive samples at
/// 1 kHz (presets and random joints 11–20); a locked canceller fires it without end.
pub const LOCKED_AFTER_S: f64 = 0.1;

/// Counts consecutive load steps; see the module.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepLock {
    limit: u64,
    run: u64,
    restarts: u64,
}

impl StepLock {
    /// A watch for a canceller at `sample_rate_hz` (at least one sample).
    ///
    /// ```
    /// use strainwave_analysis::step_lock::StepLock;
    /// let mut w = StepLock::new(1000.0);
    /// assert!((0..99).all(|_| !w.locked(true)));
    /// assert!(w.locked(true)); // the 100th in a row
    /// assert!(!w.locked(true)); // counting starts again
    /// assert_eq!(w.restarts(), 1);
    /// ```
    pub fn new(sample_rate_hz: f64) -> Self {
        let n = (LOCKED_AFTER_S * sample_rate_hz).round();
        let limit = if n.is_finite() && n >= 1.0 { n.min(u64::MAX as f64) as u64 } else { 1 };
        Self { limit, run: 0, restarts: 0 }
    }

    /// Takes one sample's load-step flag; `true`: the canceller is locked, restart its
    /// learning state now (the count starts again).
    pub fn locked(&mut self, load_step: bool) -> bool {
        self.run = if load_step { self.run + 1 } else { 0 };
        if self.run < self.limit {
            return false;
        }
        self.run = 0;
        self.restarts += 1;
        true
    }

    /// How many times [`Self::locked`] said so.
    pub fn restarts(&self) -> u64 {
        self.restarts
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_break_in_the_run_resets_the_count() {
        let mut w = StepLock::new(1000.0);
        for _ in 0..10 {
            assert!((0..99).all(|_| !w.locked(true)));
            assert!(!w.locked(false));
        }
        assert_eq!(w.restarts(), 0);
    }

    #[test]
    fn odd_rates_give_at_least_one_sample() {
        for fs in [0.0, -5.0, f64::NAN, 1.0] {
            let mut w = StepLock::new(fs);
            assert!(w.locked(true), "{fs}");
        }
        let mut w = StepLock::new(f64::INFINITY);
        assert!(!w.locked(true));
    }
}
