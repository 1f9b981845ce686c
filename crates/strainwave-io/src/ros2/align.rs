//! Topics at different rates on one clock, streaming.
//!
//! Samples arrive in time order, each giving values to some columns. The clock is either
//! the message times of one topic (the fastest) or a uniform grid `t0 + round(k·10⁹/F)` ns.
//! Each column is interpolated between its own samples only, so a gap or a NaN in one
//! topic never reaches another:
//!
//! - `linear`: `v = a + (b − a)(t − tₐ)/(t_b − tₐ)` between the samples `(tₐ, a)` and
//!   `(t_b, b)` around `t`, when `t_b − tₐ ≤ max_gap`; the sample itself at `t = tₐ` or `t_b`.
//! - `hold`: the last sample at or before `t`, when `t − tₐ ≤ max_gap`.
//! - `nearest`: the nearer of the two (the earlier on a tie), within `max_gap` of `t`.
//!
//! Otherwise the value is NaN. A row is complete once every column has its next sample
//! after the row's time, or time has run more than that column's `max_gap` past it, so
//! the rows held back span at most the largest `max_gap`: memory is that many clock rows.

use std::collections::VecDeque;

use crate::resample::{GapTooLong, MAX_ROWS_PER_GAP};

/// How a column gets its value at a clock time.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Align {
    /// No clock: one row per message, NaN in the columns it does not have.
    None,
    /// Linear between the samples around the time.
    #[default]
    Linear,
    /// The last sample at or before the time.
    Hold,
    /// The nearer sample.
    Nearest,
}

/// Where the clock times come from.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ClockSource {
    /// Every (increasing) message time of this topic index.
    Topic(usize),
    /// A uniform grid from the first sample, at this rate, Hz.
    Grid(f64),
}

#[derive(Debug, Clone)]
struct Column {
    prev: Option<(i64, f64)>,
    /// Absolute row number of the first row this column has not given a value yet.
    resolved_upto: u64,
    max_gap_ns: i64,
}

/// Streaming aligner: [`Aligner::push`] samples in time order, [`Aligner::pop`] rows
/// (`time_s` then the columns).
#[derive(Debug, Clone)]
pub struct Aligner {
    mode: Align,
    source: ClockSource,
    columns: Vec<Column>,
    /// Rows waiting for values: `(time_ns, row)`, row[0] the time in s.
    pending: VecDeque<(i64, Vec<f64>)>,
    /// Absolute number of `pending[0]`.
    base: u64,
    ready: VecDeque<Vec<f64>>,
    spare: Vec<Vec<f64>>,
    last_clock_ns: Option<i64>,
    grid_t0_ns: Option<i64>,
    grid_k: u64,
    last_push_ns: Option<i64>,
}

fn interpolate(mode: Align, prev: Option<(i64, f64)>, next: Option<(i64, f64)>, t: i64, gap: i64) -> f64 {
    if let Some((_, vn)) = next.filter(|n| n.0 == t) {
        return vn;
    }
    if let Some((_, vp)) = prev.filter(|p| p.0 == t) {
        return vp;
    }
    let prev = prev.filter(|p| p.0 < t && t - p.0 <= gap);
    match mode {
        Align::Linear | Align::None => match (prev, next) {
            (Some((ta, a)), Some((tb, b))) if tb > t && tb - ta <= gap => {
                a + (b - a) * ((t - ta) as f64 / (tb - ta) as f64)
            }
            _ => f64::NAN,
        },
        Align::Hold => prev.map_or(f64::NAN, |p| p.1),
        Align::Nearest => match (prev, next.filter(|n| n.0 > t && n.0 - t <= gap)) {
            (Some(p), Some(n)) => {
                if t - p.0 <= n.0 - t {
                    p.1
                } else {
                    n.1
                }
            }
            (Some(p), None) => p.1,
            (None, Some(n)) => n.1,
            (None, None) => f64::NAN,
        },
    }
}

impl Aligner {
    /// An aligner of `max_gap_ns.len()` columns (the time column not counted).
    pub fn new(mode: Align, source: ClockSource, max_gap_ns: &[i64]) -> Self {
        let columns =
            max_gap_ns.iter().map(|&g| Column { prev: None, resolved_upto: 0, max_gap_ns: g.max(0) }).collect();
        Self {
            mode,
            source,
            columns,
            pending: VecDeque::new(),
            base: 0,
            ready: VecDeque::new(),
            spare: Vec::new(),
            last_clock_ns: None,
            grid_t0_ns: None,
            grid_k: 0,
            last_push_ns: None,
        }
    }

    fn new_row(&mut self, t_ns: i64) -> Vec<f64> {
        let mut row = self.spare.pop().unwrap_or_default();
        row.clear();
        row.resize(self.columns.len() + 1, f64::NAN);
        row[0] = t_ns as f64 / 1e9;
        row
    }

    /// How the columns meet the clock.
    pub fn mode(&self) -> Align {
        self.mode
    }

    fn add_clock_row(&mut self, t_ns: i64) {
        if self.last_clock_ns.is_some_and(|l| t_ns <= l) {
            return;
        }
        self.last_clock_ns = Some(t_ns);
        let row = self.new_row(t_ns);
        self.pending.push_back((t_ns, row));
    }

    /// One message at `t_ns` (not before the previous one) of `topic`, giving `values`
    /// as `(column, value)` (columns counted without the time column). On a grid, a
    /// message more than [`MAX_ROWS_PER_GAP`] grid rows after the last is an error (a
    /// glitched stamp would fill memory), found before anything changes.
    pub fn push(&mut self, t_ns: i64, topic: usize, values: &[(usize, f64)]) -> Result<(), GapTooLong> {
        if self.mode == Align::None {
            let mut row = self.new_row(t_ns);
            for &(c, v) in values {
                row[c + 1] = v;
            }
            self.ready.push_back(row);
            return Ok(());
        }
        match self.source {
            ClockSource::Topic(clock) => {
                if clock == topic {
                    self.add_clock_row(t_ns);
                }
            }
            ClockSource::Grid(rate_hz) => {
                let t0 = *self.grid_t0_ns.get_or_insert(t_ns);
                let rows = ((t_ns - t0) as f64 * rate_hz / 1e9).floor() - self.grid_k as f64;
                if rows >= MAX_ROWS_PER_GAP as f64 {
                    let last_ns = self.last_push_ns.unwrap_or(t0);
                    return Err(GapTooLong { time_s: t_ns as f64 / 1e9, gap_s: (t_ns - last_ns) as f64 / 1e9 });
                }
                loop {
                    let t = t0.saturating_add((self.grid_k as f64 * 1e9 / rate_hz).round() as i64);
                    if t > t_ns {
                        break;
                    }
                    self.add_clock_row(t);
                    self.grid_k += 1;
                }
            }
        }
        self.last_push_ns = Some(t_ns);
        for &(c, v) in values {
            self.sample(c, t_ns, v);
        }
        self.settle(Some(t_ns));
        Ok(())
    }

    /// Gives column `c` its values in the rows up to `t_ns`, then makes `(t_ns, v)` its
    /// last sample.
    fn sample(&mut self, c: usize, t_ns: i64, v: f64) {
        let col = &mut self.columns[c];
        let mut at = col.resolved_upto.saturating_sub(self.base) as usize;
        while let Some((t, row)) = self.pending.get_mut(at) {
            if *t > t_ns {
                break;
            }
            row[c + 1] = interpolate(self.mode, col.prev, Some((t_ns, v)), *t, col.max_gap_ns);
            at += 1;
        }
        col.resolved_upto = self.base + at as u64;
        col.prev = Some((t_ns, v));
    }

    /// Moves complete rows to the output: a column is done with a row once its next
    /// sample came, or time (`None`: the end) ran past its `max_gap`.
    fn settle(&mut self, now_ns: Option<i64>) {
        while let Some((t, row)) = self.pending.front_mut() {
            let seq = self.base;
            let mut complete = true;
            for (c, col) in self.columns.iter_mut().enumerate() {
                if col.resolved_upto > seq {
                    continue;
                }
                if now_ns.is_some_and(|now| now.saturating_sub(*t) <= col.max_gap_ns) {
                    complete = false;
                    continue;
                }
                row[c + 1] = interpolate(self.mode, col.prev, None, *t, col.max_gap_ns);
                col.resolved_upto = seq + 1;
            }
            if !complete {
                break;
            }
            if let Some((_, row)) = self.pending.pop_front() {
                self.ready.push_back(row);
            }
            self.base += 1;
        }
    }

    /// No more samples: every waiting row gets its values.
    pub fn finish(&mut self) {
        self.settle(None);
    }

    /// The next complete row, if any.
    pub fn pop(&mut self) -> Option<Vec<f64>> {
        self.ready.pop_front()
    }

    /// Gives a row's buffer back for reuse.
    pub fn recycle(&mut self, row: Vec<f64>) {
        if self.spare.len() < 64 {
            self.spare.push(row);
        }
    }

    /// Rows held back now (for tests of the memory bound).
    pub fn held_rows(&self) -> usize {
        self.pending.len() + self.ready.len()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const MS: i64 = 1_000_000;

    fn run(mode: Align, source: ClockSource, gap: i64) -> Vec<Vec<f64>> {
        // Topic 0 (column 0) every 1 ms: v = t_ms; topic 1 (column 1) every 4 ms: v = 10 t_ms,
        // with its samples at 8 and 12 ms missing (a gap of 12 ms).
        let mut a = Aligner::new(mode, source, &[gap, gap]);
        let mut out = Vec::new();
        for k in 0..=20i64 {
            a.push(k * MS, 0, &[(0, k as f64)]).unwrap();
            if k % 4 == 0 && k != 8 && k != 12 {
                a.push(k * MS, 1, &[(1, 10.0 * k as f64)]).unwrap();
            }
            while let Some(r) = a.pop() {
                out.push(r);
            }
        }
        a.finish();
        while let Some(r) = a.pop() {
            out.push(r);
        }
        out
    }

    #[test]
    fn linear_interpolates_each_column_and_leaves_gaps_nan() {
        let rows = run(Align::Linear, ClockSource::Topic(0), 5 * MS);
        assert_eq!(rows.len(), 21);
        for (k, r) in rows.iter().enumerate() {
            assert_eq!(r[0], (k as i64 * MS) as f64 / 1e9);
            assert_eq!(r[1], k as f64, "the clock topic is exact");
            if (4..=16).contains(&k) && !(k == 4 || k == 16) {
                assert!(r[2].is_nan(), "row {k}: inside the 12 ms gap: {}", r[2]);
            } else {
                assert!((r[2] - 10.0 * k as f64).abs() < 1e-12, "row {k}: {}", r[2]);
            }
        }
    }

    #[test]
    fn hold_and_nearest() {
        let rows = run(Align::Hold, ClockSource::Topic(0), 5 * MS);
        assert_eq!(rows[3][2], 0.0);
        assert_eq!(rows[5][2], 40.0);
        assert_eq!(rows[9][2], 40.0, "5 ms after the last sample, within max_gap");
        assert!(rows[10][2].is_nan());
        let rows = run(Align::Nearest, ClockSource::Topic(0), 5 * MS);
        assert_eq!(rows[1][2], 0.0);
        assert_eq!(rows[2][2], 0.0, "tie: the earlier");
        assert_eq!(rows[3][2], 40.0);
    }

    #[test]
    fn grid_clock_and_bounded_memory() {
        let rows = run(Align::Linear, ClockSource::Grid(500.0), 5 * MS);
        assert_eq!(rows.len(), 11);
        assert_eq!(rows[3][0], (6 * MS) as f64 / 1e9);
        assert_eq!(rows[3][1], 6.0);
        let mut a = Aligner::new(Align::Linear, ClockSource::Topic(0), &[2 * MS, 2 * MS]);
        let mut most = 0;
        for k in 0..10_000i64 {
            a.push(k * MS, 0, &[(0, 1.0)]).unwrap();
            while a.pop().is_some() {}
            most = most.max(a.held_rows());
        }
        assert!(most <= 3, "column 1 never comes, yet only {most} rows wait");
    }

    #[test]
    fn a_grid_gap_beyond_the_row_limit_is_refused_before_any_row() {
        // A first stamp at 1 ms, then Unix time: 1.7e12 rows at 1 kHz.
        let mut a = Aligner::new(Align::Linear, ClockSource::Grid(1000.0), &[MS]);
        a.push(MS, 0, &[(0, 1.0)]).unwrap();
        let unix_ns = 1_700_000_000 * 1_000_000_000;
        let e = a.push(unix_ns, 0, &[(0, 2.0)]).unwrap_err();
        assert_eq!(e.time_s, 1.7e9);
        assert_eq!(a.held_rows(), 1, "the grid row of the first sample only");
        // A shorter gap is filled.
        a.push(MS + 1000 * MS, 0, &[(0, 2.0)]).unwrap();
        assert_eq!(a.held_rows(), 1001);
    }
}
