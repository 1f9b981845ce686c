//! Explicit resampling of a recording to a uniform rate by linear interpolation between
//! neighbouring rows, streaming. Used only when asked (`--resample-hz`), never silently.

/// Streaming linear resampler: push rows (time in column `time_index`), take rows on
/// the grid `t0 + k / rate`.
#[derive(Debug, Clone)]
pub struct LinearResampler {
    time_index: usize,
    rate_hz: f64,
    start_s: f64,
    next_k: u64,
    prev: Option<Vec<f64>>,
}

impl LinearResampler {
    /// A resampler to `rate_hz` (> 0); the grid starts at the first row's time.
    pub fn new(time_index: usize, rate_hz: f64) -> Option<Self> {
        (rate_hz.is_finite() && rate_hz > 0.0).then_some(Self {
            time_index,
            rate_hz,
            start_s: 0.0,
            next_k: 0,
            prev: None,
        })
    }

    /// Feeds one input row; calls `emit` for every output row it completes. Rows whose
    /// time is not after the previous one are skipped and returned as `false`.
    pub fn push(&mut self, row: &[f64], mut emit: impl FnMut(&[f64])) -> bool {
        let t = row[self.time_index];
        let Some(prev) = self.prev.as_ref() else {
            // Grid times are `t0 + k / rate`, computed afresh so they never drift.
            self.start_s = t;
            emit(row);
            self.next_k = 1;
            self.prev = Some(row.to_vec());
            return true;
        };
        let t0 = prev[self.time_index];
        if t.is_nan() || t <= t0 {
            return false;
        }
        let mut out = vec![0.0; row.len()];
        loop {
            let tn = self.start_s + self.next_k as f64 / self.rate_hz;
            if tn > t {
                break;
            }
            let w = (tn - t0) / (t - t0);
            for (o, (a, b)) in out.iter_mut().zip(prev.iter().zip(row)) {
                *o = a + w * (b - a);
            }
            out[self.time_index] = tn;
            emit(&out);
            self.next_k += 1;
        }
        self.prev = Some(row.to_vec());
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn interpolates_onto_the_grid() {
        let mut r = LinearResampler::new(0, 10.0).unwrap();
        let mut out = Vec::new();
        for row in [[0.0, 0.0], [0.25, 2.5], [0.3, 3.0], [0.3, 9.0], [0.52, 5.2]] {
            r.push(&row, |o| out.push(o.to_vec()));
        }
        let t: Vec<f64> = out.iter().map(|r| r[0]).collect();
        assert_eq!(t.len(), 6);
        for (k, row) in out.iter().enumerate() {
            assert!((row[0] - 0.1 * k as f64).abs() < 1e-12);
            assert!((row[1] - row[0] * 10.0).abs() < 1e-9, "{row:?}");
        }
        assert!(LinearResampler::new(0, 0.0).is_none());
    }
}
