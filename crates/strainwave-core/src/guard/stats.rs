//! The guard's figures over a run, for the health summary.

use super::GuardFlags;

/// Counts over the samples a [`Guard`](super::Guard) has stepped.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GuardStats<const M: usize> {
    /// Samples stepped.
    pub samples: u64,
    /// Samples on which each order was applied.
    pub applied: [u64; M],
    /// Samples in pass-through (the model did not fit: output = raw).
    pub pass_through: u64,
    /// Samples on which some order was stepped back by its health test.
    pub contradicted: u64,
    /// Samples on which a held order was clamped to its moving amplitude.
    pub standstill_bound: u64,
    /// Sum of the NIS over the measured samples, each clipped to
    /// [`GuardSettings::nis_clip`](super::GuardSettings::nis_clip).
    pub nis_sum: f64,
    /// Measured samples (finite innovation).
    pub nis_samples: u64,
    /// The largest running mean NIS seen.
    pub max_mean_nis: f64,
}

impl<const M: usize> Default for GuardStats<M> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const M: usize> GuardStats<M> {
    /// No samples yet.
    pub fn new() -> Self {
        Self {
            samples: 0,
            applied: [0; M],
            pass_through: 0,
            contradicted: 0,
            standstill_bound: 0,
            nis_sum: 0.0,
            nis_samples: 0,
            max_mean_nis: 0.0,
        }
    }

    pub(super) fn record(&mut self, applied: &[bool; M], flags: GuardFlags, nis: f64, measured: bool, mean_nis: f64) {
        self.samples += 1;
        for (n, a) in self.applied.iter_mut().zip(applied) {
            *n += u64::from(*a);
        }
        self.pass_through += u64::from(flags.contains(GuardFlags::PASS_THROUGH));
        self.contradicted += u64::from(flags.contains(GuardFlags::CONTRADICTED));
        self.standstill_bound += u64::from(flags.contains(GuardFlags::STANDSTILL_BOUND));
        if measured {
            self.nis_sum += nis;
            self.nis_samples += 1;
            self.max_mean_nis = self.max_mean_nis.max(mean_nis);
        }
    }

    /// Share of the samples on which order `i` was applied (0 with no samples).
    ///
    /// ```
    /// let s = strainwave_core::guard::GuardStats::<2>::new();
    /// assert_eq!(s.applied_share(0), 0.0);
    /// ```
    pub fn applied_share(&self, i: usize) -> f64 {
        match (self.applied.get(i), self.samples) {
            (Some(&n), s) if s > 0 => n as f64 / s as f64,
            _ => 0.0,
        }
    }

    /// Mean NIS over the run (1 when the model fits; NaN with no measured sample).
    pub fn mean_nis(&self) -> f64 {
        if self.nis_samples == 0 {
            f64::NAN
        } else {
            self.nis_sum / self.nis_samples as f64
        }
    }

    /// Share of the samples in pass-through.
    pub fn pass_through_share(&self) -> f64 {
        if self.samples == 0 {
            0.0
        } else {
            self.pass_through as f64 / self.samples as f64
        }
    }
}
