//! The filter's health in the report: the figures `strainwave filter` prints at the end
//! of a run (share of the run each order was applied, mean NIS against 1, pass-through),
//! read back from a filtered recording's `nis` and `filter_flags` columns in one pass.

use strainwave_joint::health::{NIS_HIGH, NIS_LOW, PASS_THROUGH_WARN};
use strainwave_joint::run::{GUARD_FLAGS_SHIFT, WITHHELD_ORDERS_SHIFT};

/// Orders a `filter_flags` value can describe (bits 16–23).
const MAX_ORDERS: usize = 8;
/// Each sample's NIS is clipped to this, as in the filter's own summary.
const NIS_CLIP: f64 = 25.0;

/// Running counts over the rows.
#[derive(Debug, Clone, Default)]
pub struct HealthCounts {
    rows: u64,
    withheld: [u64; MAX_ORDERS],
    pass_through: u64,
    nis_sum: f64,
    nis_rows: u64,
}

impl HealthCounts {
    /// Adds one row's `nis` and `filter_flags`.
    pub fn push(&mut self, nis: f64, flags: f64) {
        self.rows += 1;
        if nis.is_finite() {
            self.nis_sum += nis.min(NIS_CLIP);
            self.nis_rows += 1;
        }
        if !(flags.is_finite() && flags >= 0.0 && flags < f64::from(u32::MAX)) {
            return;
        }
        let bits = flags as u32;
        self.pass_through += u64::from(bits >> GUARD_FLAGS_SHIFT & 1);
        for (i, n) in self.withheld.iter_mut().enumerate() {
            *n += u64::from(bits >> (WITHHELD_ORDERS_SHIFT + i as u32) & 1);
        }
    }

    /// The section's table rows (one per order label) and its warnings.
    pub fn table(&self, labels: &[String]) -> (Vec<Vec<String>>, Vec<String>) {
        let share = |n: u64| if self.rows == 0 { 0.0 } else { 100.0 * n as f64 / self.rows as f64 };
        let mut rows: Vec<Vec<String>> = labels
            .iter()
            .take(MAX_ORDERS)
            .enumerate()
            .map(|(i, l)| vec![l.clone(), format!("{:.1} %", 100.0 - share(self.withheld[i]))])
            .collect();
        let mean_nis = if self.nis_rows == 0 { f64::NAN } else { self.nis_sum / self.nis_rows as f64 };
        rows.push(vec!["mean NIS (expected 1)".into(), format!("{mean_nis:.2}")]);
        rows.push(vec!["pass-through (output = raw)".into(), format!("{:.1} %", share(self.pass_through))]);
        let mut warnings = Vec::new();
        if mean_nis > NIS_HIGH {
            warnings.push(format!("the model does not fit the data: mean NIS {mean_nis:.2}, expected 1"));
        } else if mean_nis < NIS_LOW {
            warnings.push(format!("mean NIS {mean_nis:.2}, expected 1: `filter.noise_nm` is larger than the noise"));
        }
        if share(self.pass_through) > 100.0 * PASS_THROUGH_WARN {
            warnings
                .push(format!("the raw torque was passed through for {:.1} % of the run", share(self.pass_through)));
        }
        (rows, warnings)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counts_shares_from_the_flag_bits() {
        let mut h = HealthCounts::default();
        // Two rows with order 1 not applied, one in pass-through (all orders out).
        h.push(1.0, f64::from(1u32 << 17));
        h.push(3.0, f64::from(1u32 << 17));
        h.push(f64::NAN, f64::from((1u32 << 8) | (0b11 << 16)));
        h.push(100.0, 0.0);
        let (rows, warnings) = h.table(&["2× relative".into(), "1× output".into()]);
        assert_eq!(rows[0], vec!["2× relative".to_string(), "75.0 %".into()]);
        assert_eq!(rows[1][1], "25.0 %");
        // (1 + 3 + 25) / 3 measured rows.
        assert_eq!(rows[2][1], "9.67");
        assert_eq!(rows[3][1], "25.0 %");
        assert_eq!(warnings.len(), 2, "{warnings:?}");
    }
}
