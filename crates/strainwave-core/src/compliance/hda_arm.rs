//! The HDA-arm harmonic drive springs: the flexspline (stiffening), the wave generator
//! and the two in series.

use super::Compliance;
use crate::error::{finite, non_negative, positive, Error};
use crate::Real;

/// HDA-arm flexspline spring, stiffening: `τ_f = tan(C_f K_f0 θ_f) / C_f`.
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

    /// Torque for a twist (the HDA-arm paper's eq. B.2), N·m; `OutOfRange` at or beyond the asymptote.
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

/// HDA-arm wave-generator spring (eq. B.1), at the wave generator:
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

/// HDA-arm harmonic drive compliance: flexspline and wave generator in series,
/// referred to the output: `θ(τ) = θ_f(τ) + θ_w(τ/N) / N`.
///
/// `N` is the ratio from the WG to the output (pass `N + 1` when the flexspline is fixed).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HdaArmCompliance<T: Real> {
    /// Flexspline spring.
    pub flexspline: FlexsplineStiffening<T>,
    /// Wave-generator spring, at the WG.
    pub wave_generator: WaveGeneratorSoftening<T>,
    ratio: T,
}

impl<T: Real> HdaArmCompliance<T> {
    /// Both springs and the ratio `N > 0`.
    ///
    /// ```
    /// use strainwave_core::compliance::{Compliance, FlexsplineStiffening, HdaArmCompliance, WaveGeneratorSoftening};
    /// let hd = HdaArmCompliance::new(
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

impl<T: Real> Compliance<T> for HdaArmCompliance<T> {
    fn twist_rad(&self, torque_nm: T) -> T {
        self.flexspline.twist_rad(torque_nm) + self.wave_generator.twist_rad(torque_nm / self.ratio) / self.ratio
    }
    fn compliance_rad_per_nm(&self, torque_nm: T) -> T {
        self.flexspline.compliance_rad_per_nm(torque_nm)
            + self.wave_generator.compliance_rad_per_nm(torque_nm / self.ratio) / (self.ratio * self.ratio)
    }
}
