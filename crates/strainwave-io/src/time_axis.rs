//! Checks on a recording's time axis while it streams: non-monotonic or duplicated
//! timestamps and gaps are counted and located, never silently fixed.

/// Streaming monitor of a time column.
#[derive(Debug, Clone, Default)]
pub struct TimeMonitor {
    last_s: Option<f64>,
    rows: u64,
    dt_est_s: Option<f64>,
    /// Rows whose time is not after the previous one (duplicated or going back).
    pub non_monotonic: u64,
    /// Rows that follow a gap larger than `gap_factor` × the nominal period.
    pub gaps: u64,
    /// First problem seen: `(row, time_s, what)`.
    pub first_problem: Option<(u64, f64, &'static str)>,
    /// Largest gap, s.
    pub largest_gap_s: f64,
    /// Non-finite time values.
    pub non_finite: u64,
}

/// A gap is a step longer than this many nominal periods.
pub const GAP_FACTOR: f64 = 1.5;

/// What happened at one row.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TimeEvent {
    /// Regular step.
    Ok,
    /// Larger than `GAP_FACTOR` periods since the previous row.
    Gap,
    /// Not after the previous row.
    NonMonotonic,
    /// NaN or infinite time.
    NonFinite,
}

impl TimeMonitor {
    /// A monitor with a known nominal period (else it is taken from the first step).
    pub fn new(nominal_dt_s: Option<f64>) -> Self {
        Self { dt_est_s: nominal_dt_s, ..Default::default() }
    }

    /// Nominal period, s (once known).
    pub fn period_s(&self) -> Option<f64> {
        self.dt_est_s
    }

    /// Feeds the time of the next row (1-based row numbers in messages).
    pub fn push(&mut self, t_s: f64) -> TimeEvent {
        self.rows += 1;
        let note = |m: &mut Self, what| {
            if m.first_problem.is_none() {
                m.first_problem = Some((m.rows, t_s, what));
            }
        };
        if !t_s.is_finite() {
            self.non_finite += 1;
            note(self, "non-finite time");
            return TimeEvent::NonFinite;
        }
        let Some(last) = self.last_s else {
            self.last_s = Some(t_s);
            return TimeEvent::Ok;
        };
        let dt = t_s - last;
        if dt <= 0.0 {
            self.non_monotonic += 1;
            note(self, if dt == 0.0 { "duplicated time" } else { "time goes back" });
            return TimeEvent::NonMonotonic;
        }
        self.last_s = Some(t_s);
        let nominal = *self.dt_est_s.get_or_insert(dt);
        if dt > GAP_FACTOR * nominal {
            self.gaps += 1;
            self.largest_gap_s = self.largest_gap_s.max(dt);
            note(self, "gap in time");
            return TimeEvent::Gap;
        }
        TimeEvent::Ok
    }

    /// A one-line summary of problems, or `None` when the axis was regular.
    pub fn report(&self) -> Option<String> {
        if self.non_monotonic == 0 && self.gaps == 0 && self.non_finite == 0 {
            return None;
        }
        let mut s = format!(
            "time axis: {} gap(s) (largest {:.6} s), {} non-monotonic or duplicated, {} non-finite",
            self.gaps, self.largest_gap_s, self.non_monotonic, self.non_finite
        );
        if let Some((row, t, what)) = self.first_problem {
            s += &format!("; first at row {row} (time {t}): {what}");
        }
        Some(s)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn finds_gaps_duplicates_and_backsteps() {
        let mut m = TimeMonitor::new(None);
        let ev: Vec<TimeEvent> =
            [0.0, 0.001, 0.002, 0.002, 0.0015, 0.010, 0.011, f64::NAN].iter().map(|t| m.push(*t)).collect();
        assert_eq!(ev[3], TimeEvent::NonMonotonic);
        assert_eq!(ev[4], TimeEvent::NonMonotonic);
        assert_eq!(ev[5], TimeEvent::Gap);
        assert_eq!(ev[7], TimeEvent::NonFinite);
        assert_eq!((m.gaps, m.non_monotonic, m.non_finite), (1, 2, 1));
        let r = m.report().unwrap();
        assert!(r.contains("first at row 4 (time 0.002): duplicated time"), "{r}");
        let mut ok = TimeMonitor::new(Some(0.001));
        for k in 0..100 {
            ok.push(k as f64 * 0.001);
        }
        assert!(ok.report().is_none());
    }
}
