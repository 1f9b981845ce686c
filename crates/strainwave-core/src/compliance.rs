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
//! Beyond the catalogue curve this module holds the other compliance models of SPEC §5,
//! all behind the [`Compliance`] trait (torque → wind-up, odd and non-decreasing), which
//! the torsion solver of [`crate::torsion`] inverts:
//!
//! ```text
//! flexspline, stiffening (seed 002 B.2):   τ_f = tan(C_f K_f0 θ_f) / C_f  ⇔  θ_f = atan(C_f τ_f) / (C_f K_f0)
//! wave generator (seed 002 B.1):           θ_w = sgn(τ_w) (1 − e^(−c_w |τ_w|)) / (c_w K_w0)
//! series, seed 002:                        θ = θ_f(τ) + θ_w(τ/N) / N
//! cubic stiffness:                         τ = k1 θ + k3 θ³
//! catalogue + lost motion:                 θ = θ_3slope(τ) + (ℓ/2) tanh(τ / τ_ℓ)
//! hysteresis (Dahl, on the wind-up w):     dz/dw = (1 − z sgn ẇ) / λ,   elastic twist = w + h z
//! hysteresis (plays, Maxwell-slip):        p_i ← clamp(p_i, w ± r_i),  elastic twist = w + Σ β_i (w − p_i)/r_i
//! ```
//!
//! Sign of `c_w`: the seed calls the wave generator "softening", but with `c_w > 0` its
//! formula saturates the twist at `1/(c_w K_w0)`, i.e. the tangent stiffness
//! `K_w0 e^(c_w |τ_w|)` rises with torque. `c_w < 0` gives a softening spring and
//! `c_w = 0` the linear limit `τ_w / K_w0`; all three are accepted.

use crate::error::{finite, non_negative, positive, Error};
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

/// Seed-002 flexspline spring, stiffening: `τ_f = tan(C_f K_f0 θ_f) / C_f`.
///
/// Initial stiffness `K_f0`; the tangent stiffness `K_f0 (1 + (C_f τ)²)` grows with
/// torque, and the twist never exceeds `π / (2 C_f K_f0)`. `C_f = 0` is the linear spring.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FlexsplineStiffening<T: Real> {
    k0_nm_per_rad: T,
    c_per_nm: T,
}

impl<T: Real> FlexsplineStiffening<T> {
    /// `K_f0 > 0` (N·m/rad) and `C_f ≥ 0` (1/(N·m)).
    ///
    /// ```
    /// use strainwave_core::compliance::{Compliance, FlexsplineStiffening};
    /// let fs = FlexsplineStiffening::new(2.0e4_f64, 0.015).unwrap();
    /// let th = fs.twist_rad(40.0);
    /// assert!((fs.torque_nm(th).unwrap() - 40.0).abs() < 1e-9);
    /// assert!(FlexsplineStiffening::new(2.0e4_f64, -1.0).is_err());
    /// ```
    pub fn new(k0_nm_per_rad: T, c_per_nm: T) -> Result<Self, Error> {
        positive(k0_nm_per_rad, "flexspline_k0_nm_per_rad")?;
        non_negative(c_per_nm, "flexspline_c_per_nm")?;
        Ok(Self { k0_nm_per_rad, c_per_nm })
    }

    /// `(K_f0, C_f)`.
    pub fn parameters(&self) -> (T, T) {
        (self.k0_nm_per_rad, self.c_per_nm)
    }

    /// Largest twist the spring can reach, rad (`None` when linear).
    pub fn max_twist_rad(&self) -> Option<T> {
        if self.c_per_nm > T::ZERO {
            Some(T::HALF * T::PI / (self.c_per_nm * self.k0_nm_per_rad))
        } else {
            None
        }
    }

    /// Torque for a twist (seed eq. B.2), N·m; `OutOfRange` at or beyond the asymptote.
    pub fn torque_nm(&self, twist_rad: T) -> Result<T, Error> {
        finite(twist_rad, "twist_rad")?;
        if self.c_per_nm == T::ZERO {
            return Ok(twist_rad * self.k0_nm_per_rad);
        }
        let x = self.c_per_nm * self.k0_nm_per_rad * twist_rad;
        if x.abs() >= T::HALF * T::PI {
            return Err(Error::OutOfRange("twist_rad"));
        }
        let t = x.tan() / self.c_per_nm;
        finite(t, "twist_rad")
    }
}

impl<T: Real> Compliance<T> for FlexsplineStiffening<T> {
    fn twist_rad(&self, torque_nm: T) -> T {
        if self.c_per_nm == T::ZERO {
            torque_nm / self.k0_nm_per_rad
        } else {
            (self.c_per_nm * torque_nm).atan() / (self.c_per_nm * self.k0_nm_per_rad)
        }
    }
    fn compliance_rad_per_nm(&self, torque_nm: T) -> T {
        let ct = self.c_per_nm * torque_nm;
        T::ONE / (self.k0_nm_per_rad * (T::ONE + ct * ct))
    }
}

/// Seed-002 wave-generator spring (eq. B.1), at the wave generator:
/// `θ_w = sgn(τ_w) (1 − e^(−c_w |τ_w|)) / (c_w K_w0)`, tangent stiffness `K_w0 e^(c_w |τ_w|)`.
///
/// See the module doc for the sign of `c_w`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WaveGeneratorSoftening<T: Real> {
    k0_nm_per_rad: T,
    c_per_nm: T,
}

impl<T: Real> WaveGeneratorSoftening<T> {
    /// `K_w0 > 0` (N·m/rad at the WG) and finite `c_w` (1/(N·m) of WG torque).
    ///
    /// ```
    /// use strainwave_core::compliance::{Compliance, WaveGeneratorSoftening};
    /// let wg = WaveGeneratorSoftening::new(2.5_f64, 1.5).unwrap();
    /// let th = wg.twist_rad(0.4);
    /// assert!((wg.torque_nm(th).unwrap() - 0.4).abs() < 1e-12);
    /// assert!(wg.torque_nm(1.0).is_err()); // beyond 1/(c_w K_w0) = 0.267 rad
    /// ```
    pub fn new(k0_nm_per_rad: T, c_per_nm: T) -> Result<Self, Error> {
        positive(k0_nm_per_rad, "wave_generator_k0_nm_per_rad")?;
        finite(c_per_nm, "wave_generator_c_per_nm")?;
        Ok(Self { k0_nm_per_rad, c_per_nm })
    }

    /// `(K_w0, c_w)`.
    pub fn parameters(&self) -> (T, T) {
        (self.k0_nm_per_rad, self.c_per_nm)
    }

    /// Largest twist the spring can reach, rad (`None` unless `c_w > 0`).
    pub fn max_twist_rad(&self) -> Option<T> {
        if self.c_per_nm > T::ZERO {
            Some(T::ONE / (self.c_per_nm * self.k0_nm_per_rad))
        } else {
            None
        }
    }

    /// WG torque for a WG twist, N·m: `−sgn θ ln(1 − c_w K_w0 |θ|) / c_w`.
    pub fn torque_nm(&self, twist_rad: T) -> Result<T, Error> {
        finite(twist_rad, "twist_rad")?;
        if self.c_per_nm == T::ZERO {
            return Ok(twist_rad * self.k0_nm_per_rad);
        }
        let x = T::ONE - self.c_per_nm * self.k0_nm_per_rad * twist_rad.abs();
        if x <= T::ZERO {
            return Err(Error::OutOfRange("twist_rad"));
        }
        finite(-x.ln() / self.c_per_nm * twist_rad.signum0(), "twist_rad")
    }
}

impl<T: Real> Compliance<T> for WaveGeneratorSoftening<T> {
    fn twist_rad(&self, torque_nm: T) -> T {
        let c = self.c_per_nm;
        let a = torque_nm.abs();
        let mag = if c == T::ZERO {
            a / self.k0_nm_per_rad
        } else {
            let x = c * a;
            // 1 − e^(−x) without cancellation for small x.
            let one_minus = if x.abs() < T::from_f64(1e-4) {
                x * (T::ONE - x * (T::HALF - x / T::from_f64(6.0)))
            } else {
                T::ONE - (-x).exp()
            };
            one_minus / (c * self.k0_nm_per_rad)
        };
        mag * torque_nm.signum0()
    }
    fn compliance_rad_per_nm(&self, torque_nm: T) -> T {
        (-self.c_per_nm * torque_nm.abs()).exp() / self.k0_nm_per_rad
    }
}

/// Seed-002 harmonic drive compliance: flexspline and wave generator in series,
/// referred to the output: `θ(τ) = θ_f(τ) + θ_w(τ/N) / N`.
///
/// `N` is the ratio from the WG to the output (pass `N + 1` when the flexspline is fixed).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SeedCompliance<T: Real> {
    /// Flexspline spring.
    pub flexspline: FlexsplineStiffening<T>,
    /// Wave-generator spring, at the WG.
    pub wave_generator: WaveGeneratorSoftening<T>,
    ratio: T,
}

impl<T: Real> SeedCompliance<T> {
    /// Both springs and the ratio `N > 0`.
    ///
    /// ```
    /// use strainwave_core::compliance::{Compliance, FlexsplineStiffening, SeedCompliance, WaveGeneratorSoftening};
    /// let hd = SeedCompliance::new(
    ///     FlexsplineStiffening::new(2.0e4_f64, 0.015).unwrap(),
    ///     WaveGeneratorSoftening::new(2.5, 1.5).unwrap(),
    ///     100.0,
    /// ).unwrap();
    /// // Initial stiffness 1 / (1/K_f0 + 1/(N² K_w0)) = 1.11e4 N·m/rad.
    /// assert!((1.0 / hd.compliance_rad_per_nm(0.0) - 1.0e4 / 0.9).abs() < 1e-6);
    /// ```
    pub fn new(
        flexspline: FlexsplineStiffening<T>,
        wave_generator: WaveGeneratorSoftening<T>,
        ratio: T,
    ) -> Result<Self, Error> {
        positive(ratio, "ratio")?;
        Ok(Self { flexspline, wave_generator, ratio })
    }

    /// The ratio `N`.
    pub fn ratio(&self) -> T {
        self.ratio
    }

    /// Largest twist the pair can reach, rad (`None` when either spring is unbounded).
    pub fn max_twist_rad(&self) -> Option<T> {
        match (self.flexspline.max_twist_rad(), self.wave_generator.max_twist_rad()) {
            (Some(f), Some(w)) => Some(f + w / self.ratio),
            _ => None,
        }
    }
}

impl<T: Real> Compliance<T> for SeedCompliance<T> {
    fn twist_rad(&self, torque_nm: T) -> T {
        self.flexspline.twist_rad(torque_nm) + self.wave_generator.twist_rad(torque_nm / self.ratio) / self.ratio
    }
    fn compliance_rad_per_nm(&self, torque_nm: T) -> T {
        self.flexspline.compliance_rad_per_nm(torque_nm)
            + self.wave_generator.compliance_rad_per_nm(torque_nm / self.ratio) / (self.ratio * self.ratio)
    }
}

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

/// Hysteresis loss as a Dahl-type state on the wind-up `w` (the same law as the
/// simulator's joint): the elastic twist is `w + h z` with
///
/// ```text
/// dz/dw = (1 − z sgn ẇ) / λ,    |z| ≤ 1
/// exact over a monotone increment Δw:  z = s + (z0 − s) e^(−|Δw|/λ),  s = sgn Δw
/// ```
///
/// `h` is half the loop width in twist (catalogue hysteresis loss = `2h`), `λ` the twist
/// over which the loop closes after a reversal.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Hysteresis<T: Real> {
    half_width_rad: T,
    memory_rad: T,
}

impl<T: Real> Hysteresis<T> {
    /// Half loop width `h ≥ 0` and memory `λ > 0`, rad.
    ///
    /// ```
    /// use strainwave_core::compliance::Hysteresis;
    /// let h = Hysteresis::new(1.45e-4_f64, 1.45e-4).unwrap();
    /// let z = h.update(0.0, 1e-3); // a long loading stroke saturates z
    /// assert!((z - 1.0).abs() < 1e-2);
    /// ```
    pub fn new(half_width_rad: T, memory_rad: T) -> Result<Self, Error> {
        non_negative(half_width_rad, "hysteresis_half_width_rad")?;
        positive(memory_rad, "hysteresis_memory_rad")?;
        Ok(Self { half_width_rad, memory_rad })
    }

    /// From a catalogue hysteresis loss (full loop width, rad), closing over half of it.
    pub fn from_loss(loss_rad: T) -> Result<Self, Error> {
        non_negative(loss_rad, "hysteresis_loss_rad")?;
        let h = T::HALF * loss_rad;
        Self::new(h, h.max(T::from_f64(1e-12)))
    }

    /// `(h, λ)`.
    pub fn parameters(&self) -> (T, T) {
        (self.half_width_rad, self.memory_rad)
    }

    /// The state after a wind-up increment, exact for a monotone increment.
    pub fn update(&self, z: T, delta_windup_rad: T) -> T {
        if !delta_windup_rad.is_finite() || !z.is_finite() {
            return z.clamp(-T::ONE, T::ONE);
        }
        let s = delta_windup_rad.signum0();
        if s == T::ZERO {
            return z;
        }
        (s + (z - s) * (-delta_windup_rad.abs() / self.memory_rad).exp()).clamp(-T::ONE, T::ONE)
    }

    /// Elastic twist `w + h z`.
    pub fn elastic_twist_rad(&self, windup_rad: T, z: T) -> T {
        windup_rad + self.half_width_rad * z
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
    fn cubic_closed_form_inverts_both_signs() {
        for k3 in [0.0, 1e3, 5e8, 1e12, -5e8] {
            let c = CubicStiffness::new(1.1e4_f64, k3).unwrap();
            // The softening cubic peaks at 19.9 N·m.
            for i in -39..=39 {
                let t = i as f64 * 0.5;
                let th = c.twist_rad(t);
                assert!((c.torque_nm(th) - t).abs() < 1e-9 * (1.0 + t.abs()), "k3 {k3} t {t}: {}", c.torque_nm(th));
            }
        }
    }

    #[test]
    fn wave_generator_small_torque_is_linear() {
        let wg = WaveGeneratorSoftening::new(2.5_f64, 1.5).unwrap();
        assert!((wg.twist_rad(1e-9) / (1e-9 / 2.5) - 1.0).abs() < 1e-8);
        let soft = WaveGeneratorSoftening::new(2.5_f64, -1.5).unwrap();
        assert!(soft.twist_rad(1.0) > 1.0 / 2.5);
        assert!((soft.torque_nm(soft.twist_rad(0.7)).unwrap() - 0.7).abs() < 1e-12);
    }

    #[test]
    fn hysteresis_loop_width() {
        let h = Hysteresis::new(1e-4_f64, 1e-5).unwrap();
        let z_up = h.update(-1.0, 1e-3);
        let z_down = h.update(1.0, -1e-3);
        let width = h.elastic_twist_rad(0.0, z_up) - h.elastic_twist_rad(0.0, z_down);
        assert!((width - 2e-4).abs() < 1e-12);
        assert_eq!(h.update(0.3, 0.0), 0.3);
    }

    #[test]
    fn rejects_bad_parameters() {
        assert_eq!(ThreeSlopeStiffness::new(1.0, 1.0, 1.0, 5.0, 4.0), Err(Error::NotIncreasing("t2_nm")));
        assert_eq!(ThreeSlopeStiffness::new(0.0, 1.0, 1.0, 1.0, 4.0), Err(Error::NonPositive("k1_nm_per_rad")));
    }
}

/// Most play operators a [`PlayHysteresis`] can hold.
pub const MAX_PLAYS: usize = 8;

/// Rate-independent hysteresis as a weighted sum of play (backlash) operators on the
/// wind-up — the Maxwell-slip / Prandtl–Ishlinskii model of gear friction:
///
/// ```text
/// p_i ← clamp(p_i, w − r_i, w + r_i)          play of half-width r_i
/// elastic twist = w + Σ_i β_i (w − p_i) / r_i  each term within ±β_i
/// ```
///
/// The loop width once every play slides is `2 Σ β_i` (the catalogue hysteresis loss).
/// Wind-up changes smaller than a play leave it alone, so encoder noise below the
/// narrowest play does not walk the state (unlike a Dahl law). State: one value per play.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlayHysteresis<T: Real> {
    half_widths_rad: [T; MAX_PLAYS],
    weights_rad: [T; MAX_PLAYS],
    count: usize,
}

impl<T: Real> PlayHysteresis<T> {
    /// Plays of half-widths `r_i > 0` with weights `β_i` (rad, finite), at most [`MAX_PLAYS`].
    ///
    /// ```
    /// use strainwave_core::compliance::PlayHysteresis;
    /// let h = PlayHysteresis::new(&[2e-5_f64, 1e-4], &[5e-5, 1e-4]).unwrap();
    /// let mut plays = h.initial_state(0.0);
    /// h.advance(&mut plays, 1e-3); // a long loading stroke: every play slides
    /// assert!((h.offset_rad(&plays, 1e-3) - 1.5e-4).abs() < 1e-15);
    /// assert!(PlayHysteresis::<f64>::new(&[0.0], &[1e-4]).is_err());
    /// ```
    pub fn new(half_widths_rad: &[T], weights_rad: &[T]) -> Result<Self, Error> {
        if half_widths_rad.len() != weights_rad.len() || half_widths_rad.len() > MAX_PLAYS {
            return Err(Error::OutOfRange("play_count"));
        }
        let mut r = [T::ONE; MAX_PLAYS];
        let mut b = [T::ZERO; MAX_PLAYS];
        for (i, (&ri, &bi)) in half_widths_rad.iter().zip(weights_rad).enumerate() {
            r[i] = positive(ri, "play_half_width_rad")?;
            b[i] = finite(bi, "play_weight_rad")?;
        }
        Ok(Self { half_widths_rad: r, weights_rad: b, count: half_widths_rad.len() })
    }

    /// Number of plays.
    pub fn len(&self) -> usize {
        self.count
    }

    /// Whether there are no plays.
    pub fn is_empty(&self) -> bool {
        self.count == 0
    }

    /// Half-widths `r_i`, rad.
    pub fn half_widths_rad(&self) -> &[T] {
        &self.half_widths_rad[..self.count]
    }

    /// Weights `β_i`, rad.
    pub fn weights_rad(&self) -> &[T] {
        &self.weights_rad[..self.count]
    }

    /// Play state centred on a wind-up (no memory yet).
    pub fn initial_state(&self, windup_rad: T) -> [T; MAX_PLAYS] {
        [windup_rad; MAX_PLAYS]
    }

    /// Moves every play to a new wind-up (exact for any path between samples that is monotone).
    pub fn advance(&self, plays: &mut [T; MAX_PLAYS], windup_rad: T) {
        if !windup_rad.is_finite() {
            return;
        }
        for (p, &r) in plays.iter_mut().zip(&self.half_widths_rad).take(self.count) {
            *p = p.clamp(windup_rad - r, windup_rad + r);
        }
    }

    /// Normalised play deflections `(w − p_i)/r_i ∈ [−1, 1]`.
    pub fn deflections(&self, plays: &[T; MAX_PLAYS], windup_rad: T, out: &mut [T; MAX_PLAYS]) {
        for i in 0..MAX_PLAYS {
            out[i] = if i < self.count { (windup_rad - plays[i]) / self.half_widths_rad[i] } else { T::ZERO };
        }
    }

    /// `Σ β_i (w − p_i) / r_i`, rad: add to the wind-up to get the elastic twist.
    pub fn offset_rad(&self, plays: &[T; MAX_PLAYS], windup_rad: T) -> T {
        (0..self.count)
            .fold(T::ZERO, |acc, i| acc + self.weights_rad[i] * (windup_rad - plays[i]) / self.half_widths_rad[i])
    }
}
