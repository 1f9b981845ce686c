//! Cubic stiffness.

use super::Compliance;
use crate::error::{finite, positive, Error};
use crate::Real;

/// Cubic stiffness `τ = k1 θ + k3 θ³` (`k1 > 0`; `k3 ≥ 0` stiffening, `k3 < 0` softening,
/// valid up to the peak torque `(2/3) k1 θ*` at `θ* = √(k1 / (3|k3|))`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CubicStiffness<T: Real> {
    k1_nm_per_rad: T,
    k3_nm_per_rad3: T,
}

impl<T: Real> CubicStiffness<T> {
    /// `k1 > 0` (N·m/rad) and finite `k3` (N·m/rad³).
    ///
    /// ```
    /// use strainwave_core::compliance::{Compliance, CubicStiffness};
    /// let k = CubicStiffness::new(1.1e4_f64, 5.0e8).unwrap();
    /// let th = k.twist_rad(40.0);
    /// assert!((k.torque_nm(th) - 40.0).abs() < 1e-9);
    /// ```
    pub fn new(k1_nm_per_rad: T, k3_nm_per_rad3: T) -> Result<Self, Error> {
        positive(k1_nm_per_rad, "k1_nm_per_rad")?;
        finite(k3_nm_per_rad3, "k3_nm_per_rad3")?;
        Ok(Self { k1_nm_per_rad, k3_nm_per_rad3 })
    }

    /// `(k1, k3)`.
    pub fn parameters(&self) -> (T, T) {
        (self.k1_nm_per_rad, self.k3_nm_per_rad3)
    }

    /// Torque for a twist, N·m (explicit). For `k3 < 0`, twists beyond `θ*` give the peak.
    pub fn torque_nm(&self, twist_rad: T) -> T {
        let th = match self.peak_twist_rad() {
            Some(p) => twist_rad.clamp(-p, p),
            None => twist_rad,
        };
        th * (self.k1_nm_per_rad + self.k3_nm_per_rad3 * th * th)
    }

    /// Stiffness floor used past the peak of a softening cubic, `1e-6 k1`.
    fn floor_stiffness(&self) -> T {
        self.k1_nm_per_rad * T::from_f64(1e-6)
    }

    /// `θ* = √(k1 / (3|k3|))` for a softening cubic, else `None`.
    pub fn peak_twist_rad(&self) -> Option<T> {
        if self.k3_nm_per_rad3 < T::ZERO {
            Some((self.k1_nm_per_rad / (T::from_f64(3.0) * -self.k3_nm_per_rad3)).sqrt())
        } else {
            None
        }
    }
}

impl<T: Real> Compliance<T> for CubicStiffness<T> {
    /// Closed-form root of `k3 θ³ + k1 θ − τ = 0`:
    /// `θ = a sinh(asinh(x)/3)` (k3 > 0) or `a sin(asin(x)/3)` (k3 < 0), with
    /// `a = √(4 k1 / (3|k3|))`, `x = (3√3/2) τ √|k3| / k1^(3/2)`.
    fn twist_rad(&self, torque_nm: T) -> T {
        let (k1, k3) = (self.k1_nm_per_rad, self.k3_nm_per_rad3);
        if k3 == T::ZERO {
            return torque_nm / k1;
        }
        let three = T::from_f64(3.0);
        let a = (T::from_f64(4.0) * k1 / (three * k3.abs())).sqrt();
        let x = T::from_f64(2.598_076_211_353_316) * torque_nm * k3.abs().sqrt() / (k1 * k1.sqrt());
        if k3 > T::ZERO {
            let ax = x.abs();
            let s = if ax < T::from_f64(1e-3) {
                // sinh(asinh(x)/3) = x/3 − 4x³/81 + 16x⁵/729 + O(x⁷)
                let x2 = ax * ax;
                ax * (T::ONE / three - x2 * (T::from_f64(4.0 / 81.0) - x2 * T::from_f64(16.0 / 729.0)))
            } else {
                let y = (ax + (ax * ax + T::ONE).sqrt()).ln() / three;
                let e = y.exp();
                T::HALF * (e - T::ONE / e)
            };
            a * s * x.signum0()
        } else {
            // Beyond the peak torque the model is invalid; continue with the floor stiffness
            // so that the curve stays increasing and consistent with its derivative.
            let excess = (x.abs() - T::ONE).max(T::ZERO);
            let xc = x.clamp(-T::ONE, T::ONE);
            let asin = xc.atan2((T::ONE - xc * xc).max(T::ZERO).sqrt());
            let beyond = excess * (k1 * k1.sqrt()) / (T::from_f64(2.598_076_211_353_316) * k3.abs().sqrt());
            a * (asin / three).sin() + beyond / self.floor_stiffness() * x.signum0()
        }
    }
    fn compliance_rad_per_nm(&self, torque_nm: T) -> T {
        let th = self.twist_rad(torque_nm);
        let k = self.k1_nm_per_rad + T::from_f64(3.0) * self.k3_nm_per_rad3 * th * th;
        T::ONE / k.max(self.floor_stiffness())
    }
    fn max_twist_rad(&self) -> Option<T> {
        self.peak_twist_rad()
    }
}
