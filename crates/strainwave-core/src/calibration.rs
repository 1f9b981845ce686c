//! Applying a calibration in real time: a gain, an affine map, or an affine map whose
//! coefficients depend on speed (lookup table interpolated in speed, or polynomial).
//!
//! Every model is the one equation of docs/physics.md §3 (the embedded-sensor article):
//!
//! ```text
//! T_nm = α(ω) · x + β(ω)
//!
//! gain               α = g (N·m per sensor unit, e.g. N·m/V), β = 0     (Taghirad and Bélanger (1999))
//! affine (static)    α, β constant                                     (the embedded-sensor article static/dynamic rows)
//! speed table        α(ω), β(ω) linear between K breakpoints ω_0 < … < ω_{n−1}
//! speed polynomial   α(ω) = Σ_k a_k ω^k, β(ω) = Σ_k b_k ω^k, k < K, valid on [ω_min, ω_max]
//! ```
//!
//! `x` is the sensor reading in the unit the calibration was fitted in (bridge volts
//! for a gain, sensed flexspline torque in N·m for the embedded-sensor article's `T_sens`); `ω` is the
//! signed speed the coefficients were fitted against (rad/s, usually the output speed).
//! Gain and affine models ignore `ω` entirely, even a NaN one.
//!
//! Outside the speed range (table ends, or the polynomial's fitted range) an explicit
//! [`Extrapolation`] policy applies: hold the end coefficients, continue the end slope,
//! or reject the sample with [`Error::OutOfRange`]`("speed_rad_s")`. The flagged form
//! [`Calibration::apply_flagged`] reports whether a sample was extrapolated.
//!
//! Glossary: `α` (alpha) dimensionless or N·m per sensor unit; `β` (beta) N·m;
//! breakpoint = a speed at which the table holds coefficients.
//!
//! Storage is fixed: `K` bounds the table length and the number of polynomial
//! coefficients (degree ≤ K − 1). No allocation, no panics: every failure is an
//! [`Error`] naming the quantity.

use crate::error::{finite, Error};
use crate::Real;

/// What to do with a speed outside the table (or the polynomial's fitted range).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Extrapolation {
    /// Hold the coefficients of the nearest end.
    Clamp,
    /// Continue the end segment's slope (table) or the end tangent (polynomial).
    Linear,
    /// Refuse: `Err(Error::OutOfRange("speed_rad_s"))`.
    Reject,
}

/// Which form of `α(ω)`, `β(ω)` a [`Calibration`] holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Model {
    /// `T = g · x`.
    Gain,
    /// `T = α · x + β`, speed-independent.
    Affine,
    /// `α(ω)`, `β(ω)` interpolated linearly between speed breakpoints.
    SpeedTable,
    /// `α(ω)`, `β(ω)` polynomials in speed, lowest order first.
    SpeedPolynomial,
}

/// A calibrated torque with a flag telling whether the speed was outside the range.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Applied<T: Real> {
    /// Calibrated torque, N·m.
    pub torque_nm: T,
    /// `true` when the speed lay outside the table or fitted range and the
    /// extrapolation policy (`Clamp` or `Linear`) produced the coefficients.
    pub extrapolated: bool,
}

/// A sensor calibration `T = α(ω) x + β(ω)` with room for `K` breakpoints/coefficients.
///
/// The configuration is immutable and `Copy`; one value can serve several joints.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Calibration<T: Real, const K: usize> {
    model: Model,
    /// Gain or constant α.
    alpha0: T,
    /// Constant β, N·m.
    beta0_nm: T,
    /// Entries used in the arrays below.
    len: usize,
    /// Table breakpoints, rad/s (table only).
    speed_rad_s: [T; K],
    /// Table values of α, or polynomial coefficients of α (lowest order first).
    alpha: [T; K],
    /// Table values of β (N·m), or polynomial coefficients of β (lowest order first).
    beta_nm: [T; K],
    /// Fitted speed range of a polynomial, rad/s.
    speed_min_rad_s: T,
    speed_max_rad_s: T,
    extrapolation: Extrapolation,
}

impl<T: Real, const K: usize> Calibration<T, K> {
    fn empty(model: Model) -> Self {
        Self {
            model,
            alpha0: T::ZERO,
            beta0_nm: T::ZERO,
            len: 0,
            speed_rad_s: [T::ZERO; K],
            alpha: [T::ZERO; K],
            beta_nm: [T::ZERO; K],
            speed_min_rad_s: T::ZERO,
            speed_max_rad_s: T::ZERO,
            extrapolation: Extrapolation::Clamp,
        }
    }

    /// A pure gain `T = g · x` (Taghirad and Bélanger (1999): 6.60 N·m/V). `g` must be finite and non-zero
    /// (negative is allowed for a bridge wired the other way round).
    ///
    /// ```
    /// use strainwave_core::calibration::Calibration;
    /// let cal = Calibration::<f64, 1>::gain(6.60).unwrap();
    /// assert!((cal.apply(1.5, 0.0).unwrap() - 9.9).abs() < 1e-12);
    /// assert!(Calibration::<f32, 1>::gain(0.0).is_err());
    /// ```
    pub fn gain(gain_nm_per_v: T) -> Result<Self, Error> {
        nonzero(gain_nm_per_v, "gain_nm_per_v")?;
        let mut c = Self::empty(Model::Gain);
        c.alpha0 = gain_nm_per_v;
        Ok(c)
    }

    /// An affine map `T = α · x + β` (the embedded-sensor article static: α = 1.284, β = −0.0812 N·m).
    /// `α` finite and non-zero, `β` finite.
    ///
    /// ```
    /// use strainwave_core::calibration::Calibration;
    /// let cal = Calibration::<f32, 1>::affine(1.284, -0.0812).unwrap();
    /// assert!((cal.apply(10.0, 0.0).unwrap() - 12.7588).abs() < 1e-4);
    /// ```
    pub fn affine(alpha: T, beta_nm: T) -> Result<Self, Error> {
        nonzero(alpha, "alpha")?;
        finite(beta_nm, "beta_nm")?;
        let mut c = Self::empty(Model::Affine);
        c.alpha0 = alpha;
        c.beta0_nm = beta_nm;
        Ok(c)
    }

    /// A speed lookup table: `α`, `β` given at `n` breakpoints (2 ≤ n ≤ K), strictly
    /// increasing in speed, interpolated linearly in speed between them:
    ///
    /// ```text
    /// ω_i ≤ ω ≤ ω_{i+1}:  t = (ω − ω_i)/(ω_{i+1} − ω_i),  α = α_i + t (α_{i+1} − α_i),  same for β
    /// ```
    ///
    /// Errors: lengths differ or exceed `K` or are below 2 → `OutOfRange`; a NaN or
    /// infinite value → `NonFinite`; breakpoints not strictly increasing →
    /// `NotIncreasing("speed_rad_s")`; a zero `α` value → `OutOfRange("alpha")`.
    ///
    /// ```
    /// use strainwave_core::calibration::{Calibration, Extrapolation};
    /// let cal = Calibration::<f64, 4>::speed_table(
    ///     &[0.0, 10.0],
    ///     &[1.5, 1.6],
    ///     &[-0.09, -0.11],
    ///     Extrapolation::Clamp,
    /// )
    /// .unwrap();
    /// // Half way: α = 1.55, β = −0.10.
    /// assert!((cal.apply(2.0, 5.0).unwrap() - 3.0).abs() < 1e-12);
    /// // Beyond the table the end values are held, and the flag says so.
    /// let out = cal.apply_flagged(2.0, 20.0).unwrap();
    /// assert!(out.extrapolated && (out.torque_nm - 3.09).abs() < 1e-12);
    /// ```
    pub fn speed_table(
        speed_rad_s: &[T],
        alpha: &[T],
        beta_nm: &[T],
        extrapolation: Extrapolation,
    ) -> Result<Self, Error> {
        let n = speed_rad_s.len();
        if !(2..=K).contains(&n) {
            return Err(Error::OutOfRange("speed_rad_s"));
        }
        if alpha.len() != n {
            return Err(Error::OutOfRange("alpha"));
        }
        if beta_nm.len() != n {
            return Err(Error::OutOfRange("beta_nm"));
        }
        let mut c = Self::empty(Model::SpeedTable);
        for i in 0..n {
            finite(speed_rad_s[i], "speed_rad_s")?;
            nonzero(alpha[i], "alpha")?;
            finite(beta_nm[i], "beta_nm")?;
            if i > 0 && speed_rad_s[i] <= speed_rad_s[i - 1] {
                return Err(Error::NotIncreasing("speed_rad_s"));
            }
            c.speed_rad_s[i] = speed_rad_s[i];
            c.alpha[i] = alpha[i];
            c.beta_nm[i] = beta_nm[i];
        }
        c.len = n;
        c.extrapolation = extrapolation;
        Ok(c)
    }

    /// Speed polynomials `α(ω) = Σ a_k ω^k`, `β(ω) = Σ b_k ω^k` (coefficients lowest
    /// order first, at most `K` each, `a_k` in units per (rad/s)^k; the shorter list is
    /// padded with zeros), valid on `[speed_min_rad_s, speed_max_rad_s]`; outside it the
    /// policy applies (`Linear` continues the tangent at the range end).
    ///
    /// ```
    /// use strainwave_core::calibration::{Calibration, Extrapolation};
    /// // α linear in speed, β constant (the embedded-sensor article: "potentially linear").
    /// let cal = Calibration::<f64, 3>::speed_polynomial(
    ///     &[1.5, 0.01],
    ///     &[-0.09],
    ///     -10.0,
    ///     10.0,
    ///     Extrapolation::Reject,
    /// )
    /// .unwrap();
    /// assert!((cal.apply(2.0, 5.0).unwrap() - (2.0 * 1.55 - 0.09)).abs() < 1e-12);
    /// assert!(cal.apply(2.0, 11.0).is_err());
    /// ```
    pub fn speed_polynomial(
        alpha_coeffs: &[T],
        beta_coeffs_nm: &[T],
        speed_min_rad_s: T,
        speed_max_rad_s: T,
        extrapolation: Extrapolation,
    ) -> Result<Self, Error> {
        if alpha_coeffs.is_empty() || alpha_coeffs.len() > K {
            return Err(Error::OutOfRange("alpha"));
        }
        if beta_coeffs_nm.is_empty() || beta_coeffs_nm.len() > K {
            return Err(Error::OutOfRange("beta_nm"));
        }
        finite(speed_min_rad_s, "speed_min_rad_s")?;
        finite(speed_max_rad_s, "speed_max_rad_s")?;
        if speed_max_rad_s <= speed_min_rad_s {
            return Err(Error::NotIncreasing("speed_range_rad_s"));
        }
        let mut c = Self::empty(Model::SpeedPolynomial);
        for (i, &a) in alpha_coeffs.iter().enumerate() {
            c.alpha[i] = finite(a, "alpha")?;
        }
        for (i, &b) in beta_coeffs_nm.iter().enumerate() {
            c.beta_nm[i] = finite(b, "beta_nm")?;
        }
        c.len = alpha_coeffs.len().max(beta_coeffs_nm.len());
        c.speed_min_rad_s = speed_min_rad_s;
        c.speed_max_rad_s = speed_max_rad_s;
        c.extrapolation = extrapolation;
        Ok(c)
    }

    /// The model form.
    pub fn model(&self) -> Model {
        self.model
    }

    /// The extrapolation policy (meaningful for the speed models only).
    pub fn extrapolation(&self) -> Extrapolation {
        self.extrapolation
    }

    /// Table breakpoints in rad/s (empty unless a speed table).
    pub fn speed_breakpoints_rad_s(&self) -> &[T] {
        match self.model {
            Model::SpeedTable => &self.speed_rad_s[..self.len],
            _ => &[],
        }
    }

    /// The speed range over which no extrapolation happens, rad/s (`None` for gain
    /// and affine models).
    pub fn speed_range_rad_s(&self) -> Option<(T, T)> {
        match self.model {
            Model::Gain | Model::Affine => None,
            Model::SpeedTable => Some((self.speed_rad_s[0], self.speed_rad_s[self.len - 1])),
            Model::SpeedPolynomial => Some((self.speed_min_rad_s, self.speed_max_rad_s)),
        }
    }

    /// Table values of α (table) or α's polynomial coefficients (polynomial); for gain
    /// and affine models the single constant.
    pub fn alpha_values(&self) -> &[T] {
        match self.model {
            Model::Gain | Model::Affine => core::slice::from_ref(&self.alpha0),
            _ => &self.alpha[..self.len],
        }
    }

    /// Table values or coefficients of β in N·m, as [`Self::alpha_values`].
    pub fn beta_values_nm(&self) -> &[T] {
        match self.model {
            Model::Gain | Model::Affine => core::slice::from_ref(&self.beta0_nm),
            _ => &self.beta_nm[..self.len],
        }
    }

    /// `(α(ω), β(ω), extrapolated)` at a speed.
    pub fn coefficients(&self, speed_rad_s: T) -> Result<(T, T, bool), Error> {
        match self.model {
            Model::Gain => Ok((self.alpha0, T::ZERO, false)),
            Model::Affine => Ok((self.alpha0, self.beta0_nm, false)),
            Model::SpeedTable => self.table_coefficients(finite(speed_rad_s, "speed_rad_s")?),
            Model::SpeedPolynomial => self.polynomial_coefficients(finite(speed_rad_s, "speed_rad_s")?),
        }
    }

    /// Calibrated torque `T = α(ω) x + β(ω)`, N·m.
    ///
    /// Errors: `NonFinite("sensor")` or `NonFinite("speed_rad_s")` for a NaN/∞ input
    /// (speed only checked by speed models), `OutOfRange("speed_rad_s")` outside the
    /// range under [`Extrapolation::Reject`], `NonFinite("torque_nm")` on overflow.
    pub fn apply(&self, sensor: T, speed_rad_s: T) -> Result<T, Error> {
        self.apply_flagged(sensor, speed_rad_s).map(|a| a.torque_nm)
    }

    /// As [`Self::apply`], also telling whether the speed was extrapolated.
    pub fn apply_flagged(&self, sensor: T, speed_rad_s: T) -> Result<Applied<T>, Error> {
        finite(sensor, "sensor")?;
        let (alpha, beta, extrapolated) = self.coefficients(speed_rad_s)?;
        let torque_nm = finite(alpha * sensor + beta, "torque_nm")?;
        Ok(Applied { torque_nm, extrapolated })
    }

    /// The inverse map: the sensor reading that gives `torque_nm` at this speed,
    /// `x = (T − β(ω)) / α(ω)`. `OutOfRange("alpha")` where `α(ω) = 0`.
    pub fn invert(&self, torque_nm: T, speed_rad_s: T) -> Result<T, Error> {
        finite(torque_nm, "torque_nm")?;
        let (alpha, beta, _) = self.coefficients(speed_rad_s)?;
        if alpha == T::ZERO {
            return Err(Error::OutOfRange("alpha"));
        }
        finite((torque_nm - beta) / alpha, "sensor")
    }

    fn table_coefficients(&self, w: T) -> Result<(T, T, bool), Error> {
        let n = self.len;
        let s = &self.speed_rad_s;
        let (lo, extrapolated) = if w < s[0] {
            (0, true)
        } else if w > s[n - 1] {
            (n - 2, true)
        } else {
            // Binary search for s[lo] ≤ w ≤ s[lo + 1].
            let (mut lo, mut hi) = (0usize, n - 1);
            while hi - lo > 1 {
                let mid = (lo + hi) / 2;
                if s[mid] <= w {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            (lo, false)
        };
        if extrapolated {
            match self.extrapolation {
                Extrapolation::Reject => return Err(Error::OutOfRange("speed_rad_s")),
                Extrapolation::Clamp => {
                    let end = if w < s[0] { 0 } else { n - 1 };
                    return Ok((self.alpha[end], self.beta_nm[end], true));
                }
                Extrapolation::Linear => {}
            }
        }
        let t = (w - s[lo]) / (s[lo + 1] - s[lo]);
        let alpha = self.alpha[lo] + t * (self.alpha[lo + 1] - self.alpha[lo]);
        let beta = self.beta_nm[lo] + t * (self.beta_nm[lo + 1] - self.beta_nm[lo]);
        Ok((alpha, beta, extrapolated))
    }

    fn polynomial_coefficients(&self, w: T) -> Result<(T, T, bool), Error> {
        let (ca, cb) = (&self.alpha[..self.len], &self.beta_nm[..self.len]);
        let (lo, hi) = (self.speed_min_rad_s, self.speed_max_rad_s);
        if w >= lo && w <= hi {
            return Ok((horner(ca, w).0, horner(cb, w).0, false));
        }
        let end = if w < lo { lo } else { hi };
        match self.extrapolation {
            Extrapolation::Reject => Err(Error::OutOfRange("speed_rad_s")),
            Extrapolation::Clamp => Ok((horner(ca, end).0, horner(cb, end).0, true)),
            Extrapolation::Linear => {
                let (a, da) = horner(ca, end);
                let (b, db) = horner(cb, end);
                let dw = w - end;
                Ok((a + da * dw, b + db * dw, true))
            }
        }
    }
}

/// `(p(x), p'(x))` for coefficients lowest order first.
fn horner<T: Real>(c: &[T], x: T) -> (T, T) {
    let mut p = T::ZERO;
    let mut dp = T::ZERO;
    for &ck in c.iter().rev() {
        dp = dp * x + p;
        p = p * x + ck;
    }
    (p, dp)
}

fn nonzero<T: Real>(x: T, name: &'static str) -> Result<T, Error> {
    finite(x, name)?;
    if x == T::ZERO {
        Err(Error::OutOfRange(name))
    } else {
        Ok(x)
    }
}

#[cfg(test)]
mod tests;
