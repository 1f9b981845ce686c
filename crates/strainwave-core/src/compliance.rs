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
//!
//! Beyond the catalogue curve this module holds the other compliance models of docs/physics.md §5,
//! all behind the [`Compliance`] trait (torque → wind-up, odd and non-decreasing), which
//! the torsion solver of [`crate::torsion`] inverts:
//!
//! ```text
//! flexspline, stiffening (the HDA-arm paper B.2):   τ_f = tan(C_f K_f0 θ_f) / C_f  ⇔  θ_f = atan(C_f τ_f) / (C_f K_f0)
//! wave generator (the HDA-arm paper B.1):           θ_w = sgn(τ_w) (1 − e^(−c_w |τ_w|)) / (c_w K_w0)
//! series, the HDA-arm paper:                        θ = θ_f(τ) + θ_w(τ/N) / N
//! cubic stiffness:                         τ = k1 θ + k3 θ³
//! catalogue + lost motion:                 θ = θ_3slope(τ) + (ℓ/2) tanh(τ / τ_ℓ)
//! hysteresis (Dahl, on the wind-up w):     dz/dw = (1 − z sgn ẇ) / λ,   elastic twist = w + h z
//! hysteresis (plays, Maxwell-slip):        p_i ← clamp(p_i, w ± r_i),  elastic twist = w + Σ β_i (w − p_i)/r_i
//! ```
//!
//! Sign of `c_w`: the paper calls the wave generator "softening", but with `c_w > 0` its
//! formula saturates the twist at `1/(c_w K_w0)`, i.e. the tangent stiffness
//! `K_w0 e^(c_w |τ_w|)` rises with torque. `c_w < 0` gives a softening spring and
//! `c_w = 0` the linear limit `τ_w / K_w0`; all three are accepted.

mod cubic;
mod hda_arm;
mod hysteresis;

pub use cubic::CubicStiffness;
pub use hda_arm::{FlexsplineStiffening, HdaArmCompliance, WaveGeneratorSoftening};
pub use hysteresis::{Hysteresis, PlayHysteresis, MAX_PLAYS};

use crate::error::{non_negative, positive, Error};
use crate::Real;

/// A torsional compliance: the wind-up (twist) it carries at a transmitted torque.
///
/// Contract: `twist_rad` is odd, continuous and non-decreasing in the torque, and
/// `compliance_rad_per_nm` is its derivative (> 0 wherever the model is valid). The
/// solver in [`crate::torsion::TorqueSolver`] relies on nothing else.
pub trait Compliance<T: Real> {
    /// Wind-up for a transmitted torque, rad.
    fn twist_rad(&self, torque_nm: T) -> T;
    /// Derivative `dθ/dτ` at a torque, rad/(N·m).
    fn compliance_rad_per_nm(&self, torque_nm: T) -> T;
    /// Largest wind-up the model is valid for, rad (`None`: any). The solver rejects
    /// larger ones as `OutOfRange`.
    fn max_twist_rad(&self) -> Option<T> {
        None
    }
}

impl<T: Real, C: Compliance<T> + ?Sized> Compliance<T> for &C {
    fn twist_rad(&self, torque_nm: T) -> T {
        (**self).twist_rad(torque_nm)
    }
    fn compliance_rad_per_nm(&self, torque_nm: T) -> T {
        (**self).compliance_rad_per_nm(torque_nm)
    }
    fn max_twist_rad(&self) -> Option<T> {
        (**self).max_twist_rad()
    }
}

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
        positive(k_nm_per_rad, "k_nm_per_rad")?;
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

    /// `(K1, K2, K3, T1, T2)` in N·m/rad and N·m.
    pub fn parameters(&self) -> (T, T, T, T, T) {
        (self.k1_nm_per_rad, self.k2_nm_per_rad, self.k3_nm_per_rad, self.t1_nm, self.t2_nm)
    }

    /// Tangent stiffness at a torque, N·m/rad.
    pub fn stiffness_at_torque(&self, torque_nm: T) -> T {
        let a = torque_nm.abs();
        if a <= self.t1_nm {
            self.k1_nm_per_rad
        } else if a <= self.t2_nm {
            self.k2_nm_per_rad
        } else {
            self.k3_nm_per_rad
        }
    }
}

impl<T: Real> Compliance<T> for ThreeSlopeStiffness<T> {
    fn twist_rad(&self, torque_nm: T) -> T {
        ThreeSlopeStiffness::twist_rad(self, torque_nm)
    }
    fn compliance_rad_per_nm(&self, torque_nm: T) -> T {
        T::ONE / self.stiffness_at_torque(torque_nm)
    }
}

/// `tanh x` from `exp` (odd, no overflow for large `|x|`).
fn tanh<T: Real>(x: T) -> T {
    let e = (-T::TWO * x.abs()).exp();
    (T::ONE - e) / (T::ONE + e) * x.signum0()
}

/// Catalogue model with lost motion: the three-slope curve plus a smooth play of total
/// width `ℓ` taken up around zero torque, `θ = θ_3slope(τ) + (ℓ/2) tanh(τ / τ_ℓ)`.
///
/// Catalogues quote lost motion as the twist at a small measuring torque (a few % of
/// rated); `τ_ℓ` is the torque over which the play is taken up (≈ 96 % at `2 τ_ℓ`).
/// Hysteresis loss is the separate, stateful [`Hysteresis`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CatalogueCompliance<T: Real> {
    /// The three-slope stiffness.
    pub stiffness: ThreeSlopeStiffness<T>,
    lost_motion_rad: T,
    lost_motion_torque_nm: T,
}

impl<T: Real> CatalogueCompliance<T> {
    /// Three-slope curve, lost motion `ℓ ≥ 0` (rad, total width) and its take-up torque `τ_ℓ > 0`.
    ///
    /// ```
    /// use strainwave_core::compliance::{CatalogueCompliance, Compliance, ThreeSlopeStiffness};
    /// let k = ThreeSlopeStiffness::new(6.7e4, 1.1e5, 1.2e5, 29.0, 108.0).unwrap();
    /// let c = CatalogueCompliance::new(k, 2.9e-4_f64, 2.0).unwrap();
    /// assert!((c.twist_rad(60.0) - 7.15e-4 - 1.45e-4).abs() < 2e-6);
    /// ```
    pub fn new(stiffness: ThreeSlopeStiffness<T>, lost_motion_rad: T, lost_motion_torque_nm: T) -> Result<Self, Error> {
        non_negative(lost_motion_rad, "lost_motion_rad")?;
        positive(lost_motion_torque_nm, "lost_motion_torque_nm")?;
        Ok(Self { stiffness, lost_motion_rad, lost_motion_torque_nm })
    }

    /// `(ℓ, τ_ℓ)`.
    pub fn lost_motion(&self) -> (T, T) {
        (self.lost_motion_rad, self.lost_motion_torque_nm)
    }
}

impl<T: Real> Compliance<T> for CatalogueCompliance<T> {
    fn twist_rad(&self, torque_nm: T) -> T {
        self.stiffness.twist_rad(torque_nm)
            + T::HALF * self.lost_motion_rad * tanh(torque_nm / self.lost_motion_torque_nm)
    }
    fn compliance_rad_per_nm(&self, torque_nm: T) -> T {
        let th = tanh(torque_nm / self.lost_motion_torque_nm);
        T::ONE / self.stiffness.stiffness_at_torque(torque_nm)
            + T::HALF * self.lost_motion_rad * (T::ONE - th * th) / self.lost_motion_torque_nm
    }
}

#[cfg(test)]
mod tests;
