//! One order's side of the guard: evidence, travel, health and standstill bound.

use super::GuardSettings;
use crate::ripple::{Order, OrderStatus, Reference};
use crate::Real;

/// The guard's decision inputs for one order, as of the last sample.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Verdict {
    /// Its amplitude is significant.
    pub(super) evidence: bool,
    /// Its line turned enough cycles.
    pub(super) travelled: bool,
    /// Removing it fits the data better.
    pub(super) contradicted: bool,
    /// All of these, and the model is not in pass-through.
    pub(super) apply: bool,
}

/// What the guard keeps per order.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct OrderGuard<T: Real> {
    /// Full cycles of the line needed before it may apply.
    cycles_needed: T,
    /// Full cycles seen so far (each: all eight octants of the phase visited).
    cycles: T,
    /// Octants visited in the cycle under way (bit per octant).
    octants: u8,
    /// Hysteresis state of the evidence test.
    evidence: bool,
    /// Running mean of the estimate `z`, N·m.
    mean_z: [T; 2],
    /// Running mean of `|z − mean z|²`, N·m²: how much the estimate wanders.
    spread_nm2: T,
    /// Running mean of `(e + c_i)²` (the model keeps that of `e²`), from `R` as that one.
    mean_without: T,
    /// Hysteresis state of the health test.
    contradicted: bool,
    /// Weight the running mean of `(e + c_i)²` has gathered (it is judged from 1 on,
    /// so that its start from zero is no verdict).
    fit_weight: T,
    /// Amplitude of the contribution at the last moving (active) sample, N·m; `None`:
    /// not bounded (a learned prior before the first moving sample).
    moving_amplitude_nm: Option<T>,
    /// Running mean of the line's phase increment `|a_i|`, rad per sample.
    mean_increment_rad: T,
    /// The last phase increment `|a_i|`, rad per sample.
    last_increment_rad: T,
}

impl<T: Real> OrderGuard<T> {
    /// The initial guard of `order`.
    pub(super) fn new(order: &Order<T>, s: &GuardSettings<T>, r_nm2: T) -> Self {
        let cycles_needed = if s.learned_prior {
            T::ZERO
        } else if order.reference() == Reference::Output {
            s.min_cycles_output
        } else {
            s.min_cycles
        };
        Self {
            cycles_needed,
            cycles: T::ZERO,
            octants: 0,
            evidence: false,
            mean_z: [T::ZERO; 2],
            // NaN until the first estimate, which starts the mean.
            spread_nm2: T::from_f64(f64::NAN),
            mean_without: r_nm2,
            contradicted: false,
            fit_weight: T::ZERO,
            moving_amplitude_nm: if s.learned_prior { None } else { Some(T::ZERO) },
            mean_increment_rad: T::ZERO,
            last_increment_rad: T::ZERO,
        }
    }

    /// Whether the order is applied on this sample, from what was known before it.
    pub(super) fn verdict(&self, pass_through: bool) -> Verdict {
        let travelled = self.cycles >= self.cycles_needed;
        let apply = self.evidence && travelled && !self.contradicted && !pass_through;
        Verdict { evidence: self.evidence, travelled, contradicted: self.contradicted, apply }
    }

    /// The contribution as subtracted: clamped to the moving amplitude while held.
    /// Also whether the clamp bit.
    pub(super) fn bounded(&self, c_nm: T, status: OrderStatus) -> (T, bool) {
        match (status, self.moving_amplitude_nm) {
            (OrderStatus::Held, Some(a)) => {
                let v = c_nm.clamp(-a, a);
                (v, v != c_nm)
            }
            _ => (c_nm, false),
        }
    }

    /// This sample's evidence: significance of the prior estimate `z` (N·m, of the unit
    /// phasor) with covariance `p`, the phase octant of `phasor`, the moving amplitude.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn observe(
        &mut self,
        s: &GuardSettings<T>,
        alpha: T,
        p: &[[T; 2]; 2],
        z: [T; 2],
        phasor: [T; 2],
        status: OrderStatus,
    ) {
        let amplitude2 = z[0] * z[0] + z[1] * z[1];
        let amplitude_nm = amplitude2.sqrt();
        let chi2 = chi2(p, z);
        // A periodic line has a steady estimate in the rotating frame; one that wanders
        // is fitting something else (load the bias did not take, while it learns).
        if amplitude2.is_finite() && !self.spread_nm2.is_finite() {
            self.mean_z = z;
            self.spread_nm2 = T::ZERO;
        } else if amplitude2.is_finite() {
            let d = [z[0] - self.mean_z[0], z[1] - self.mean_z[1]];
            self.spread_nm2 += alpha * (d[0] * d[0] + d[1] * d[1] - self.spread_nm2);
            self.mean_z = [self.mean_z[0] + alpha * d[0], self.mean_z[1] + alpha * d[1]];
        }
        let (chi2_limit, steady) =
            if self.evidence { (s.release_chi2, s.release_wander) } else { (s.apply_chi2, s.apply_wander) };
        let steady = self.spread_nm2 <= steady * steady * amplitude2;
        self.evidence = chi2 > chi2_limit && steady;
        if let Some(o) = octant(phasor) {
            self.octants |= 1 << o;
            if self.octants == u8::MAX {
                self.cycles += T::ONE;
                self.octants = 1 << o;
            }
        }
        if status == OrderStatus::Active && amplitude_nm.is_finite() {
            self.moving_amplitude_nm = Some(amplitude_nm);
        }
    }

    /// Updates the running mean of the line's phase increment `a` (rad per sample).
    pub(super) fn observe_line(&mut self, alpha: T, a_rad: T) {
        let a = a_rad.abs();
        if a.is_finite() {
            self.last_increment_rad = a;
            self.mean_increment_rad += alpha * (a - self.mean_increment_rad);
        }
    }

    /// The line's frequency, Hz (`rad_to_hz`: `fs / 2π`): the lower of the running mean
    /// increment and the last one, so that a slowing line counts as slow at once.
    pub(super) fn line_hz(&self, rad_to_hz: T) -> T {
        self.mean_increment_rad.min(self.last_increment_rad) * rad_to_hz
    }

    /// Updates the running mean of `(e + c_i)²` (weight `alpha` for the newest sample).
    pub(super) fn observe_fit(&mut self, alpha: T, e_nm: T, c_nm: T) {
        let w = e_nm + c_nm;
        self.mean_without += alpha * (w * w - self.mean_without);
        self.fit_weight += alpha;
    }

    /// The health test against the model's running mean `mean_e2` of `e²`.
    pub(super) fn judge_fit(&mut self, s: &GuardSettings<T>, mean_e2: T) {
        let m = s.contradiction_margin;
        if self.fit_weight < T::ONE {
            return;
        }
        // It comes back only when the order clearly helps (a NaN keeps it stepped back).
        let helps = self.mean_without > (T::ONE + m) * mean_e2;
        self.contradicted = if self.contradicted { !helps } else { self.mean_without < (T::ONE - m) * mean_e2 };
    }
}

/// `zᵀ P⁻¹ z` of a 2×2 block; 0 when `P` is not positive definite.
pub(super) fn chi2<T: Real>(p: &[[T; 2]; 2], z: [T; 2]) -> T {
    let det = p[0][0] * p[1][1] - p[0][1] * p[1][0];
    // NaN compares false, so it gives no evidence either.
    let positive = det > T::ZERO && p[0][0] > T::ZERO;
    if !positive {
        return T::ZERO;
    }
    let q = p[1][1] * z[0] * z[0] - (p[0][1] + p[1][0]) * z[0] * z[1] + p[0][0] * z[1] * z[1];
    let v = q / det;
    if v.is_finite() {
        v
    } else {
        T::ZERO
    }
}

/// The octant (0–7) of the phase of `(cos ψ, sin ψ)` (times any positive scale);
/// `None` for a zero or non-finite phasor.
pub(super) fn octant<T: Real>([c, s]: [T; 2]) -> Option<u8> {
    if !(c.is_finite() && s.is_finite()) || (c == T::ZERO && s == T::ZERO) {
        return None;
    }
    let quadrant: u8 = match (s >= T::ZERO, c >= T::ZERO) {
        (true, true) => 0,
        (true, false) => 1,
        (false, false) => 2,
        (false, true) => 3,
    };
    // Within the quadrant, the first or second half.
    let second = if quadrant.is_multiple_of(2) { s.abs() > c.abs() } else { c.abs() > s.abs() };
    Some(2 * quadrant + u8::from(second))
}
