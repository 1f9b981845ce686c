//! Gear compliance: stiffness models mapping torque ↔ twist, with their inverses.
//!
//! The catalogue model of strain wave gear makers is a three-slope curve, odd in torque:
//!
//! ```text
//! |T| ≤ T1:       θ = T / K1
//! T1 < |T| ≤ T2:  θ = sgn T (T1/K1 + (|T| − T1)/K2)
//! |T| > T2:       θ = sgn T (T1/K1 + (T2 − T1)/K2 + (|T| − T2)/K3)
//! ```
//!
//! Units: torque N·m, twist rad, stiffness N·m/rad.

use crate::error::{positive, Error};
use crate::Real;

/// Catalogue three-slope stiffness (`K1` up to `T1`, `K2` up to `T2`, `K3` beyond).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ThreeSlopeStiffness<T: Real> {
    k1_nm_per_rad: T,
    k2_nm_per_rad: T,
    k3_nm_per_rad: T,
    t1_nm: T,
    t2_nm: T,
}

impl<T: Real> ThreeSlopeStiffness<T> {
    /// Builds the curve; requires positive stiffnesses and `0 < T1 < T2`.
    ///
    /// ```
    /// use strainwave_core::compliance::ThreeSlopeStiffness;
    /// // Catalogue example: T = 60 N·m → 7.15e-4 rad.
    /// let k = ThreeSlopeStiffness::new(6.7e4, 1.1e5, 1.2e5, 29.0, 108.0).unwrap();
    /// assert!((k.twist_rad(60.0_f64) - 7.15e-4).abs() < 1e-6);
    /// assert!((k.torque_nm(k.twist_rad(60.0)) - 60.0).abs() < 1e-9);
    /// ```
    pub fn new(k1_nm_per_rad: T, k2_nm_per_rad: T, k3_nm_per_rad: T, t1_nm: T, t2_nm: T) -> Result<Self, Error> {
        positive(k1_nm_per_rad, "k1_nm_per_rad")?;
        positive(k2_nm_per_rad, "k2_nm_per_rad")?;
        positive(k3_nm_per_rad, "k3_nm_per_rad")?;
        positive(t1_nm, "t1_nm")?;
        positive(t2_nm, "t2_nm")?;
        if t2_nm <= t1_nm {
            return Err(Error::NotIncreasing("t2_nm"));
        }
        Ok(Self { k1_nm_per_rad, k2_nm_per_rad, k3_nm_per_rad, t1_nm, t2_nm })
    }

    /// A single linear stiffness (all three slopes equal).
    pub fn linear(k_nm_per_rad: T) -> Result<Self, Error> {
        positive(k_nm_per_rad, "stiffness_nm_per_rad")?;
        Ok(Self {
            k1_nm_per_rad: k_nm_per_rad,
            k2_nm_per_rad: k_nm_per_rad,
            k3_nm_per_rad: k_nm_per_rad,
            t1_nm: T::ONE,
            t2_nm: T::TWO,
        })
    }

    /// Twist at the break torques `(θ1, θ2)`, rad.
    fn break_twists(&self) -> (T, T) {
        let th1 = self.t1_nm / self.k1_nm_per_rad;
        (th1, th1 + (self.t2_nm - self.t1_nm) / self.k2_nm_per_rad)
    }

    /// Twist for a torque, rad.
    pub fn twist_rad(&self, torque_nm: T) -> T {
        let a = torque_nm.abs();
        let (th1, th2) = self.break_twists();
        let mag = if a <= self.t1_nm {
            a / self.k1_nm_per_rad
        } else if a <= self.t2_nm {
            th1 + (a - self.t1_nm) / self.k2_nm_per_rad
        } else {
            th2 + (a - self.t2_nm) / self.k3_nm_per_rad
        };
        mag * torque_nm.signum0()
    }

    /// Torque for a twist, N·m (exact inverse of [`Self::twist_rad`]).
    pub fn torque_nm(&self, twist_rad: T) -> T {
        let a = twist_rad.abs();
        let (th1, th2) = self.break_twists();
        let mag = if a <= th1 {
            a * self.k1_nm_per_rad
        } else if a <= th2 {
            self.t1_nm + (a - th1) * self.k2_nm_per_rad
        } else {
            self.t2_nm + (a - th2) * self.k3_nm_per_rad
        };
        mag * twist_rad.signum0()
    }

    /// Tangent stiffness at a twist, N·m/rad.
    pub fn stiffness_at(&self, twist_rad: T) -> T {
        let a = twist_rad.abs();
        let (th1, th2) = self.break_twists();
        if a <= th1 {
            self.k1_nm_per_rad
        } else if a <= th2 {
            self.k2_nm_per_rad
        } else {
            self.k3_nm_per_rad
        }
    }

    /// The largest of the three slopes, N·m/rad (sets the integrator step).
    pub fn max_stiffness(&self) -> T {
        self.k1_nm_per_rad.max(self.k2_nm_per_rad).max(self.k3_nm_per_rad)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn catalogue_example() {
        let k = ThreeSlopeStiffness::new(6.7e4, 1.1e5, 1.2e5, 29.0, 108.0).unwrap();
        let th = k.twist_rad(60.0_f64);
        assert!((th - 7.15e-4).abs() < 5e-7, "{th}");
        assert!((k.twist_rad(-60.0) + th).abs() < 1e-15);
        assert!((k.torque_nm(th) - 60.0).abs() < 1e-9);
    }

    #[test]
    fn continuous_at_breaks_and_invertible() {
        let k = ThreeSlopeStiffness::new(3.1e4, 5.0e4, 5.7e4, 14.0, 48.0).unwrap();
        for i in -400..=400 {
            let t = i as f64 * 0.25;
            let back = k.torque_nm(k.twist_rad(t));
            assert!((back - t).abs() < 1e-9, "{t} -> {back}");
        }
        let eps = 1e-9;
        assert!((k.twist_rad(14.0 + eps) - k.twist_rad(14.0 - eps)).abs() < 1e-12);
        assert!((k.twist_rad(48.0 + eps) - k.twist_rad(48.0 - eps)).abs() < 1e-12);
    }

    #[test]
    fn rejects_bad_parameters() {
        assert_eq!(ThreeSlopeStiffness::new(1.0, 1.0, 1.0, 5.0, 4.0), Err(Error::NotIncreasing("t2_nm")));
        assert_eq!(ThreeSlopeStiffness::new(0.0, 1.0, 1.0, 1.0, 4.0), Err(Error::NonPositive("k1_nm_per_rad")));
    }
}
