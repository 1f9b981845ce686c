//! The health summary of a guarded run: how long each order was applied, the mean NIS
//! against its expected value 1, and a warning when the model does not fit the data.

use strainwave_core::guard::GuardStats;
use strainwave_core::ripple::{Order, Reference};

/// Mean NIS above this: the model does not fit (the innovations are larger than the
/// model expects: an order missing, `noise_nm` too small, a wrong learned file).
pub const NIS_HIGH: f64 = 2.0;
/// Mean NIS below this: `noise_nm` is larger than the data's noise (harmless, but the
/// canceller learns more slowly than it could).
pub const NIS_LOW: f64 = 0.25;
/// Share of the run in pass-through above which the summary warns.
pub const PASS_THROUGH_WARN: f64 = 0.01;

/// One order's line of the summary.
#[derive(Debug, Clone, PartialEq)]
pub struct OrderHealth {
    /// The order as the config names it, e.g. `2× relative` or `2× relative × |load|`.
    pub label: String,
    /// Share of the samples on which its correction was applied, 0–1.
    pub applied_share: f64,
}

/// The guard's figures over a run.
#[derive(Debug, Clone, PartialEq)]
pub struct Health {
    /// Per order.
    pub orders: Vec<OrderHealth>,
    /// Mean NIS over the measured samples (each clipped at 25); 1 when the model fits.
    pub mean_nis: f64,
    /// Share of the samples in pass-through (output = raw), 0–1.
    pub pass_through_share: f64,
    /// Share of the samples on which some order was stepped back by its health test.
    pub contradicted_share: f64,
    /// Samples the guard stepped.
    pub samples: u64,
}

impl Health {
    /// The summary of `stats` for the model's `orders`.
    pub fn new<const M: usize>(orders: &[Order<f64>; M], stats: &GuardStats<M>) -> Self {
        let share = |n: u64| if stats.samples == 0 { 0.0 } else { n as f64 / stats.samples as f64 };
        Self {
            orders: orders
                .iter()
                .enumerate()
                .map(|(i, o)| OrderHealth { label: order_label(o), applied_share: stats.applied_share(i) })
                .collect(),
            mean_nis: stats.mean_nis(),
            pass_through_share: stats.pass_through_share(),
            contradicted_share: share(stats.contradicted),
            samples: stats.samples,
        }
    }

    /// Warnings: the model does not fit the data, or the guard kept it out.
    pub fn warnings(&self) -> Vec<String> {
        let mut w = Vec::new();
        if self.mean_nis > NIS_HIGH {
            w.push(format!(
                "the model does not fit the data: mean NIS {:.2}, expected 1 (an order missing, \
                 `filter.noise_nm` too small, or a learned file of another joint?)",
                self.mean_nis
            ));
        } else if self.mean_nis < NIS_LOW {
            w.push(format!(
                "mean NIS {:.2}, expected 1: `filter.noise_nm` is larger than the recording's noise",
                self.mean_nis
            ));
        }
        if self.pass_through_share > PASS_THROUGH_WARN {
            w.push(format!(
                "the guard passed the raw torque through for {:.1} % of the run (the model did not fit there)",
                100.0 * self.pass_through_share
            ));
        }
        if self.contradicted_share > PASS_THROUGH_WARN {
            w.push(format!(
                "orders contradicted by the data were stepped back for {:.1} % of the run",
                100.0 * self.contradicted_share
            ));
        }
        w
    }

    /// The summary as lines of text (no warnings; see [`Self::warnings`]).
    pub fn lines(&self) -> Vec<String> {
        let mut l = vec![format!(
            "health: mean NIS {:.2} (expected 1), pass-through {:.1} % of {} samples",
            self.mean_nis,
            100.0 * self.pass_through_share,
            self.samples
        )];
        for o in &self.orders {
            l.push(format!("  {:<28} applied {:>5.1} % of the run", o.label, 100.0 * o.applied_share));
        }
        l
    }
}

/// `2× relative`, `1× output`, `2× relative × |load|`.
pub fn order_label(o: &Order<f64>) -> String {
    let reference = match o.reference() {
        Reference::Relative => "relative",
        Reference::Output => "output",
        Reference::Motor => "motor",
    };
    let scaled = if o.is_load_scaled() { " × |load|" } else { "" };
    format!("{}× {reference}{scaled}", o.multiple())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn warns_on_a_misfit_and_on_pass_through() {
        let order = Order::new(Reference::Output, 1.0).unwrap();
        let mut h = Health {
            orders: vec![OrderHealth { label: order_label(&order), applied_share: 0.5 }],
            mean_nis: 1.05,
            pass_through_share: 0.0,
            contradicted_share: 0.0,
            samples: 1000,
        };
        assert!(h.warnings().is_empty());
        assert_eq!(h.orders[0].label, "1× output");
        assert!(h.lines()[1].contains("50.0 %"), "{:?}", h.lines());
        h.mean_nis = 40.0;
        h.pass_through_share = 0.3;
        let w = h.warnings();
        assert_eq!(w.len(), 2, "{w:?}");
        assert!(w[0].contains("does not fit") && w[1].contains("30.0 %"), "{w:?}");
        h.mean_nis = 0.01;
        assert!(h.warnings()[0].contains("larger than"), "{:?}", h.warnings());
    }
}
