//! Explicit resampling of a recording to a uniform rate by linear interpolation between
//! neighbouring rows, streaming. Used only when asked (`--resample-hz`), never silently.

/// Most rows one interval between input rows may become. A longer interval is almost
/// always a glitched timestamp (one time of 1e308 s would fill the disk); it is an error.
/// At 1 kHz this is a gap of 2.8 hours.
pub const MAX_ROWS_PER_GAP: u64 = 10_000_000;

/// An interval between two input rows too long to fill.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("time {time_s} s is {gap_s} s after the previous row's: resampling would fill the gap with more than {max} rows (glitched time stamp?)", max = MAX_ROWS_PER_GAP)]
pub struct GapTooLong {
    /// Time of the row after the gap.
    pub time_s: f64,
    /// Length of the gap.
    pub gap_s: f64,
}

/// Streaming linear resampler: push rows (time in column `time_index`), take rows on
/// the grid `t0 + k / rate`.
#[derive(Debug, Clone)]
pub struct LinearResampler {
    time_index: usize,
    rate_hz: f64,
    max_gap_s: f64,
    start_s: f64,
    next_k: u64,
    prev: Option<Vec<f64>>,
    gaps: u64,
    largest_gap: Option<(f64, f64)>,
}

/// A table's default `max_gap_s`: the longest a log's columns are interpolated over.
pub const DEFAULT_MAX_GAP_S: f64 = 10.0;

impl LinearResampler {
    /// A resampler to `rate_hz` (> 0); the grid starts at the first row's time. Rows
    /// further apart than `max_gap_s` are not interpolated between: the grid rows inside
    /// such a gap are NaN but for their time.
    pub fn new(time_index: usize, rate_hz: f64, max_gap_s: f64) -> Option<Self> {
        (rate_hz.is_finite() && rate_hz > 0.0 && max_gap_s >= 0.0).then_some(Self {
            time_index,
            rate_hz,
            max_gap_s,
            start_s: 0.0,
            next_k: 0,
            prev: None,
            gaps: 0,
            largest_gap: None,
        })
    }

    /// The output rate, Hz.
    pub fn rate_hz(&self) -> f64 {
        self.rate_hz
    }

    /// The longest gap interpolated over, s.
    pub fn max_gap_s(&self) -> f64 {
        self.max_gap_s
    }

    /// The time column's index.
    pub fn time_index(&self) -> usize {
        self.time_index
    }

    /// Gaps longer than `max_gap_s` left NaN so far, and the largest: `(gap_s, ends_at_s)`.
    pub fn gaps(&self) -> (u64, Option<(f64, f64)>) {
        (self.gaps, self.largest_gap)
    }

    /// Feeds one input row; calls `emit` for every output row it completes, and stops
    /// when `emit` returns `false` (a write failed). Rows whose time is not finite or not
    /// after the previous one are skipped and returned as `Ok(false)`; a gap of more than
    /// [`MAX_ROWS_PER_GAP`] output rows is an error, checked before anything is emitted.
    pub fn push(&mut self, row: &[f64], mut emit: impl FnMut(&[f64]) -> bool) -> Result<bool, GapTooLong> {
        let t = row[self.time_index];
        if !t.is_finite() {
            return Ok(false);
        }
        let Some(prev) = self.prev.as_ref() else {
            // Grid times are `t0 + k / rate`, computed afresh so they never drift.
            self.start_s = t;
            emit(row);
            self.next_k = 1;
            self.prev = Some(row.to_vec());
            return Ok(true);
        };
        let t0 = prev[self.time_index];
        if t <= t0 {
            return Ok(false);
        }
        // Grid points up to `t`, counted before any is emitted.
        let last_k = ((t - self.start_s) * self.rate_hz).floor();
        let rows = last_k - self.next_k as f64;
        if rows.is_nan() || rows >= MAX_ROWS_PER_GAP as f64 {
            return Err(GapTooLong { time_s: t, gap_s: t - t0 });
        }
        // Time stamps written in decimal carry a rounding of their own: a step equal to
        // `max_gap_s` but for that rounding is not a gap.
        let rounding = 4.0 * f64::EPSILON * t.abs().max(t0.abs());
        let gap = t - t0 > self.max_gap_s + rounding;
        if gap {
            self.gaps += 1;
            if self.largest_gap.is_none_or(|(g, _)| t - t0 > g) {
                self.largest_gap = Some((t - t0, t));
            }
        }
        let mut out = vec![0.0; row.len()];
        loop {
            let tn = self.start_s + self.next_k as f64 / self.rate_hz;
            if tn > t {
                break;
            }
            let w = (tn - t0) / (t - t0);
            for (o, (a, b)) in out.iter_mut().zip(prev.iter().zip(row)) {
                // The rows themselves, never made-up values inside a gap.
                *o = match (gap, tn == t0, tn == t) {
                    (_, true, _) => *a,
                    (_, _, true) => *b,
                    (true, _, _) => f64::NAN,
                    _ => a + w * (b - a),
                };
            }
            out[self.time_index] = tn;
            self.next_k += 1;
            if !emit(&out) {
                break;
            }
        }
        self.prev = Some(row.to_vec());
        Ok(true)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_gap_beyond_max_gap_is_nan_not_a_ramp() {
        // 1 s of samples, 59 s without any, 1 s more. Before: a 59 s ramp that never was.
        let mut r = LinearResampler::new(0, 1.0, DEFAULT_MAX_GAP_S).unwrap();
        let mut out = Vec::new();
        for row in [[0.0, 0.0], [1.0, 0.0], [60.0, 100.0], [61.0, 100.0]] {
            r.push(&row, |o| {
                out.push(o.to_vec());
                true
            })
            .unwrap();
        }
        assert_eq!(out.len(), 62);
        assert_eq!(out[1], [1.0, 0.0]);
        assert!(out[2..60].iter().all(|o| o[1].is_nan()), "inside the gap");
        assert_eq!(out[60], [60.0, 100.0]);
        assert_eq!(r.gaps(), (1, Some((59.0, 60.0))));
    }

    /// `--max-gap` equal to the sample period is no gap anywhere, though the decimal time
    /// stamps' steps differ from it by a rounding (0.009000000000000001 − 0.008 is
    /// 0.0010000000000000009): before, 963 of 1000 steps of a 1 kHz file were gaps. A step
    /// longer by more than the rounding still is one.
    #[test]
    fn a_step_of_max_gap_within_the_stamps_rounding_is_no_gap() {
        let mut r = LinearResampler::new(0, 1000.0, 0.001).unwrap();
        let mut nan = 0;
        for k in 0..1000 {
            let t: f64 = format!("{}", 0.001 * k as f64).parse().unwrap();
            r.push(&[t, 1.0], |o| {
                nan += usize::from(o[1].is_nan());
                true
            })
            .unwrap();
        }
        assert_eq!((r.gaps().0, nan), (0, 0));
        r.push(&[1.0011, 1.0], |_| true).unwrap();
        assert_eq!(r.gaps().0, 1);
    }

    #[test]
    fn interpolates_onto_the_grid() {
        let mut r = LinearResampler::new(0, 10.0, DEFAULT_MAX_GAP_S).unwrap();
        let mut out = Vec::new();
        for row in [[0.0, 0.0], [0.25, 2.5], [0.3, 3.0], [0.3, 9.0], [0.52, 5.2]] {
            r.push(&row, |o| {
                out.push(o.to_vec());
                true
            })
            .unwrap();
        }
        let t: Vec<f64> = out.iter().map(|r| r[0]).collect();
        assert_eq!(t.len(), 6);
        for (k, row) in out.iter().enumerate() {
            assert!((row[0] - 0.1 * k as f64).abs() < 1e-12);
            assert!((row[1] - row[0] * 10.0).abs() < 1e-9, "{row:?}");
        }
        assert!(LinearResampler::new(0, 0.0, DEFAULT_MAX_GAP_S).is_none());
    }

    #[test]
    fn a_glitched_time_stamp_is_an_error_before_any_row_and_infinity_is_skipped() {
        let mut r = LinearResampler::new(0, 1000.0, DEFAULT_MAX_GAP_S).unwrap();
        let mut n = 0u64;
        let mut count = |_: &[f64]| {
            n += 1;
            true
        };
        assert_eq!(r.push(&[0.0, 1.0], &mut count), Ok(true));
        assert_eq!(r.push(&[f64::INFINITY, 1.0], &mut count), Ok(false));
        let e = r.push(&[1e308, 1.0], &mut count).unwrap_err();
        assert_eq!(e.gap_s, 1e308);
        assert!(e.to_string().contains("more than 10000000 rows"), "{e}");
        // A long but real gap is filled.
        assert_eq!(r.push(&[100.0, 2.0], &mut count), Ok(true));
        assert_eq!(n, 1 + 100_000);
    }

    #[test]
    fn a_failed_write_stops_the_filling() {
        let mut r = LinearResampler::new(0, 1000.0, DEFAULT_MAX_GAP_S).unwrap();
        let mut n = 0;
        r.push(&[0.0], |_| true).unwrap();
        r.push(&[5.0], |_| {
            n += 1;
            false
        })
        .unwrap();
        assert_eq!(n, 1);
    }
}
