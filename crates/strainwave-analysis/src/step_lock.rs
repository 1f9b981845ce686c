//! A learning canceller that its own load-step test keeps from learning, and the way out.
//!
//! The load-step test takes an innovation beyond its NIS limit as a jump of the torque:
//! the bias takes it whole and the ripple oscillators learn nothing from that sample.
//! That is right for a step, which the bias absorbs at once (the joint's ringing after
//! it keeps the test firing for some tens of samples). It is wrong for a canceller whose
//! oscillators went wrong with a small variance: its innovations are then large most of
//! the time, the test fires on most samples, the oscillators rarely see the data that
//! would correct them, and the bias, jumping with each firing, drags the slow
//! misalignment line along.
//!
//! A learning canceller that starts cold at standstill gets there when the run starts
//! with a speed ramp. While the lines are at a few Hz, the orthogonal coefficient of each
//! oscillator (prior 1σ 1 N·m) explains the ramp's acceleration torque better than the
//! slow commissioning bias does, with a gain of about `1 / Δψ` (`Δψ` the line's phase step
//! per sample). On the twin, random joint 18 learned 6.2 N·m of 2× ripple that way in the
//! first 40 samples and its test then fired on 29 950 of 30 400 samples (a lock for good);
//! random joint 15 fired on 270 of the 600 samples after its ramp, and its misalignment
//! came out 0.008 N·m off after 30 s.
//!
//! [`StepLock`] watches the share of samples the test fires on, as a running mean over
//! [`WINDOW_S`]. Above [`LOCKED_SHARE`] the canceller does not fit its data and its
//! learning state should start again (after a ramp, the lines are then well clear of the
//! load's frequencies).

/// Time constant of the running share of load steps, s.
pub const WINDOW_S: f64 = 0.2;

/// A running share of load steps at or above this is a canceller that does not fit. A
/// genuine step fired the test on at most 31 consecutive samples at 1 kHz on the twin's
/// commissioning runs (presets and random joints 11–20): a share of 14 %.
pub const LOCKED_SHARE: f64 = 0.4;

/// The running share of load steps; see the module.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepLock {
    weight: f64,
    share: f64,
    restarts: u64,
}

impl StepLock {
    /// A watch for a canceller at `sample_rate_hz`.
    ///
    /// ```
    /// use strainwave_analysis::step_lock::StepLock;
    /// let mut w = StepLock::new(1000.0);
    /// assert!((0..100).all(|_| !w.locked(true)));
    /// assert!((0..5).any(|_| w.locked(true))); // about 0.1 s of steps in a row
    /// assert_eq!(w.restarts(), 1);
    /// ```
    pub fn new(sample_rate_hz: f64) -> Self {
        let n = WINDOW_S * sample_rate_hz;
        // At least one sample; a rate that is not a number watches nothing.
        let weight = if n.is_nan() { 0.0 } else { 1.0 / n.max(1.0) };
        Self { weight, share: 0.0, restarts: 0 }
    }

    /// Takes one sample's load-step flag; `true`: the canceller does not fit, restart its
    /// learning state now (the share starts again from 0).
    pub fn locked(&mut self, load_step: bool) -> bool {
        let x = if load_step { 1.0 } else { 0.0 };
        self.share += self.weight * (x - self.share);
        if self.share < LOCKED_SHARE {
            return false;
        }
        self.share = 0.0;
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
    fn genuine_steps_do_not_count_as_a_lock() {
        // 31 firings in a row (the longest genuine step measured), one step a second.
        let mut w = StepLock::new(1000.0);
        for _ in 0..20 {
            assert!((0..31).all(|_| !w.locked(true)));
            assert!((0..969).all(|_| !w.locked(false)));
        }
        assert_eq!(w.restarts(), 0);
    }

    #[test]
    fn firing_on_half_the_samples_is_a_lock() {
        let mut w = StepLock::new(1000.0);
        let at = (0..1000).position(|k| w.locked(k % 2 == 0)).unwrap();
        assert!((150..400).contains(&at), "{at}");
    }

    #[test]
    fn odd_rates_never_panic() {
        for fs in [0.0, -5.0, 1.0] {
            assert!(StepLock::new(fs).locked(true), "{fs}");
        }
        for fs in [f64::NAN, f64::INFINITY] {
            let mut w = StepLock::new(fs);
            assert!((0..1000).all(|_| !w.locked(true)), "{fs}");
        }
    }
}
