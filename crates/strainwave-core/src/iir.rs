//! Small discrete filters: first-order sections and biquads in transposed direct form II
//! (DF2T), designed from analog prototypes by the bilinear transform with prewarping.
//!
//! Glossary: `fs` sample rate (Hz); `f_w` the prewarp frequency (Hz), where the digital
//! response equals the analog one exactly; `c = ω_w / tan(ω_w / 2fs)`, `ω_w = 2π f_w`, the
//! bilinear constant, so that `s = c (1 − z⁻¹) / (1 + z⁻¹)`.
//!
//! ```text
//! analog     H(s) = (n2 s² + n1 s + n0) / (d2 s² + d1 s + d0)
//! digital    H(z) = (b0 + b1 z⁻¹ + b2 z⁻²) / (1 + a1 z⁻¹ + a2 z⁻²)
//! DF2T       y = b0 x + s1;   s1 ← b1 x − a1 y + s2;   s2 ← b2 x − a2 y
//! ```
//!
//! A first-order section is a biquad with `b2 = a2 = 0` ([`Biquad::first_order_lowpass`]).
//! Coefficients are immutable values; the two state words live in [`BiquadState`]
//! (configuration apart from state, the project's style notes). [`Complex`] is the small complex number
//! the frequency responses of this module and of [`crate::fusion`] are returned in.

use core::ops::{Add, Div, Mul, Neg, Sub};

use crate::error::{finite, positive, Error};
use crate::Real;

/// A complex number `re + j im` (frequency responses).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Complex<T: Real> {
    /// Real part.
    pub re: T,
    /// Imaginary part.
    pub im: T,
}

impl<T: Real> Complex<T> {
    /// `re + j im`.
    ///
    /// ```
    /// use strainwave_core::iir::Complex;
    /// let z = Complex::new(3.0_f64, 4.0);
    /// assert_eq!(z.norm(), 5.0);
    /// ```
    pub const fn new(re: T, im: T) -> Self {
        Self { re, im }
    }
    /// A real number.
    pub fn real(re: T) -> Self {
        Self { re, im: T::ZERO }
    }
    /// `e^{jθ} = cos θ + j sin θ`.
    pub fn cis(theta: T) -> Self {
        let (s, c) = theta.sin_cos();
        Self { re: c, im: s }
    }
    /// `|z|²`.
    pub fn norm_sqr(self) -> T {
        self.re * self.re + self.im * self.im
    }
    /// `|z|` (scaled to avoid overflow).
    pub fn norm(self) -> T {
        let (a, b) = (self.re.abs(), self.im.abs());
        let m = a.max(b);
        if m == T::ZERO || !m.is_finite() {
            return m;
        }
        let (x, y) = (a / m, b / m);
        m * (x * x + y * y).sqrt()
    }
    /// Argument in `(−π, π]`, rad.
    pub fn arg(self) -> T {
        self.im.atan2(self.re)
    }
    /// Complex conjugate.
    pub fn conj(self) -> Self {
        Self { re: self.re, im: -self.im }
    }
    /// `k z` for a real `k`.
    pub fn scale(self, k: T) -> Self {
        Self { re: self.re * k, im: self.im * k }
    }
}

impl<T: Real> Add for Complex<T> {
    type Output = Self;
    fn add(self, o: Self) -> Self {
        Self { re: self.re + o.re, im: self.im + o.im }
    }
}
impl<T: Real> Sub for Complex<T> {
    type Output = Self;
    fn sub(self, o: Self) -> Self {
        Self { re: self.re - o.re, im: self.im - o.im }
    }
}
impl<T: Real> Mul for Complex<T> {
    type Output = Self;
    fn mul(self, o: Self) -> Self {
        Self { re: self.re * o.re - self.im * o.im, im: self.re * o.im + self.im * o.re }
    }
}
impl<T: Real> Div for Complex<T> {
    type Output = Self;
    /// Smith's algorithm (no overflow of `|o|²`); division by zero gives non-finite parts.
    fn div(self, o: Self) -> Self {
        if o.re.abs() >= o.im.abs() {
            let r = o.im / o.re;
            let d = o.re + o.im * r;
            Self { re: (self.re + self.im * r) / d, im: (self.im - self.re * r) / d }
        } else {
            let r = o.re / o.im;
            let d = o.re * r + o.im;
            Self { re: (self.re * r + self.im) / d, im: (self.im * r - self.re) / d }
        }
    }
}
impl<T: Real> Neg for Complex<T> {
    type Output = Self;
    fn neg(self) -> Self {
        Self { re: -self.re, im: -self.im }
    }
}

/// Evaluates the polynomial `p[0] s^(N−1) + … + p[N−1]` (descending powers) at `s`.
pub fn polyval<T: Real, const N: usize>(p: &[T; N], s: Complex<T>) -> Complex<T> {
    let mut acc = Complex::real(T::ZERO);
    for &c in p.iter() {
        acc = acc * s + Complex::real(c);
    }
    acc
}

/// Bilinear constant `c = ω_w / tan(ω_w / 2fs)` for a prewarp frequency `f_w` in `(0, fs/2)`;
/// `f_w` is named `name` in the error.
pub fn prewarp_constant<T: Real>(prewarp_hz: T, sample_rate_hz: T, name: &'static str) -> Result<T, Error> {
    positive(sample_rate_hz, "sample_rate_hz")?;
    positive(prewarp_hz, name)?;
    if prewarp_hz >= sample_rate_hz * T::HALF {
        return Err(Error::OutOfRange(name));
    }
    let w = T::TAU * prewarp_hz;
    let c = w / (w / (T::TWO * sample_rate_hz)).tan();
    finite(c, name)
}

/// Biquad coefficients (`a0 = 1`). A first-order section has `b2 = a2 = 0`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Biquad<T: Real> {
    /// Feed-forward `b0, b1, b2`.
    pub b: [T; 3],
    /// Feedback `a1, a2` (the sign convention of the difference equation above).
    pub a: [T; 2],
}

/// The two state words of a DF2T biquad.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct BiquadState<T: Real> {
    /// `s1`, `s2`.
    pub s: [T; 2],
}

impl<T: Real> Biquad<T> {
    /// The identity filter `H = 1`.
    ///
    /// ```
    /// use strainwave_core::iir::{Biquad, BiquadState};
    /// let f = Biquad::<f32>::identity();
    /// assert_eq!(f.step(&mut BiquadState::default(), 3.0), 3.0);
    /// ```
    pub fn identity() -> Self {
        Self { b: [T::ONE, T::ZERO, T::ZERO], a: [T::ZERO, T::ZERO] }
    }

    /// Bilinear transform of `H(s) = (n2 s² + n1 s + n0) / (d2 s² + d1 s + d0)`, prewarped
    /// at `prewarp_hz` (errors name `prewarp_hz`; `OutOfRange("denominator")` when the
    /// digital `a0` vanishes).
    ///
    /// ```
    /// use strainwave_core::iir::Biquad;
    /// // 1 / (s/ω + 1) prewarped at its corner: −3.01 dB there, exactly.
    /// let w = std::f64::consts::TAU * 100.0;
    /// let f = Biquad::from_analog([0.0, 0.0, 1.0], [0.0, 1.0 / w, 1.0], 100.0, 1000.0).unwrap();
    /// assert!((f.response(100.0, 1000.0).norm() - 0.5f64.sqrt()).abs() < 1e-12);
    /// ```
    pub fn from_analog(num: [T; 3], den: [T; 3], prewarp_hz: T, sample_rate_hz: T) -> Result<Self, Error> {
        for v in num.iter().chain(den.iter()) {
            finite(*v, "coefficient")?;
        }
        let c = prewarp_constant(prewarp_hz, sample_rate_hz, "prewarp_hz")?;
        if num[0] == T::ZERO && den[0] == T::ZERO {
            // First order: transformed as such (through the second-order formula it would get
            // a pole and a zero at z = −1, on the unit circle).
            let a0 = den[1] * c + den[2];
            if a0 == T::ZERO || !a0.is_finite() {
                return Err(Error::OutOfRange("denominator"));
            }
            let b = [(num[1] * c + num[2]) / a0, (num[2] - num[1] * c) / a0, T::ZERO];
            return Ok(Self { b, a: [(den[2] - den[1] * c) / a0, T::ZERO] });
        }
        let c2 = c * c;
        let two = T::TWO;
        let z = |p: [T; 3]| [p[0] * c2 + p[1] * c + p[2], two * (p[2] - p[0] * c2), p[0] * c2 - p[1] * c + p[2]];
        let nb = z(num);
        let da = z(den);
        let a0 = da[0];
        if a0 == T::ZERO || !a0.is_finite() {
            return Err(Error::OutOfRange("denominator"));
        }
        Ok(Self { b: [nb[0] / a0, nb[1] / a0, nb[2] / a0], a: [da[1] / a0, da[2] / a0] })
    }

    /// First-order low-pass `ω / (s + ω)`, `ω = 2π cutoff_hz`, prewarped at the cutoff.
    ///
    /// ```
    /// use strainwave_core::iir::Biquad;
    /// let f = Biquad::first_order_lowpass(250.0_f64, 20_000.0).unwrap();
    /// assert!((f.response(0.0, 20_000.0).re - 1.0).abs() < 1e-12);
    /// assert!(Biquad::first_order_lowpass(10_000.0_f64, 20_000.0).is_err());
    /// ```
    pub fn first_order_lowpass(cutoff_hz: T, sample_rate_hz: T) -> Result<Self, Error> {
        let w = T::TAU * positive(cutoff_hz, "cutoff_hz")?;
        Self::named(Self::from_analog([T::ZERO, T::ZERO, w], [T::ZERO, T::ONE, w], cutoff_hz, sample_rate_hz))
    }

    /// First-order high-pass `s / (s + ω)`, prewarped at the cutoff.
    ///
    /// ```
    /// use strainwave_core::iir::Biquad;
    /// let f = Biquad::first_order_highpass(250.0_f64, 20_000.0).unwrap();
    /// assert!(f.response(0.0, 20_000.0).norm() < 1e-12);
    /// ```
    pub fn first_order_highpass(cutoff_hz: T, sample_rate_hz: T) -> Result<Self, Error> {
        let w = T::TAU * positive(cutoff_hz, "cutoff_hz")?;
        Self::named(Self::from_analog([T::ZERO, T::ONE, T::ZERO], [T::ZERO, T::ONE, w], cutoff_hz, sample_rate_hz))
    }

    /// Second-order low-pass `ω² / (s² + (ω/Q) s + ω²)` (Butterworth for `Q = 1/√2`).
    ///
    /// ```
    /// use strainwave_core::iir::Biquad;
    /// let f = Biquad::lowpass(1000.0_f64, core::f64::consts::FRAC_1_SQRT_2, 48_000.0).unwrap();
    /// assert!((f.response(1000.0, 48_000.0).norm() - 0.5f64.sqrt()).abs() < 1e-12);
    /// ```
    pub fn lowpass(cutoff_hz: T, q: T, sample_rate_hz: T) -> Result<Self, Error> {
        let w = T::TAU * positive(cutoff_hz, "cutoff_hz")?;
        let q = positive(q, "q")?;
        Self::named(Self::from_analog([T::ZERO, T::ZERO, w * w], [T::ONE, w / q, w * w], cutoff_hz, sample_rate_hz))
    }

    /// Second-order high-pass `s² / (s² + (ω/Q) s + ω²)`.
    ///
    /// ```
    /// use strainwave_core::iir::Biquad;
    /// let f = Biquad::highpass(100.0_f64, 0.5, 1000.0).unwrap();
    /// assert!(f.response(0.0, 1000.0).norm() < 1e-12);
    /// assert!((f.response(500.0, 1000.0).re - 1.0).abs() < 1e-12);
    /// ```
    pub fn highpass(cutoff_hz: T, q: T, sample_rate_hz: T) -> Result<Self, Error> {
        let w = T::TAU * positive(cutoff_hz, "cutoff_hz")?;
        let q = positive(q, "q")?;
        Self::named(Self::from_analog([T::ONE, T::ZERO, T::ZERO], [T::ONE, w / q, w * w], cutoff_hz, sample_rate_hz))
    }

    /// Renames the prewarp error of the designs to their `cutoff_hz`.
    fn named(r: Result<Self, Error>) -> Result<Self, Error> {
        r.map_err(|e| match e {
            Error::OutOfRange("prewarp_hz") => Error::OutOfRange("cutoff_hz"),
            Error::NonPositive("prewarp_hz") => Error::NonPositive("cutoff_hz"),
            other => other,
        })
    }

    /// `1 − H`: the exact complement (same poles).
    pub fn complement(&self) -> Self {
        Self { b: [T::ONE - self.b[0], self.a[0] - self.b[1], self.a[1] - self.b[2]], a: self.a }
    }

    /// One sample: `y = b0 x + s1`, then the state update of DF2T.
    #[inline]
    pub fn step(&self, state: &mut BiquadState<T>, x: T) -> T {
        let y = self.b[0] * x + state.s[0];
        state.s[0] = self.b[1] * x - self.a[0] * y + state.s[1];
        state.s[1] = self.b[2] * x - self.a[1] * y;
        y
    }

    /// DC gain `H(z = 1)`.
    pub fn dc_gain(&self) -> T {
        (self.b[0] + self.b[1] + self.b[2]) / (T::ONE + self.a[0] + self.a[1])
    }

    /// The state after a constant input `x` for ever (output `dc_gain · x`): starts a
    /// filter without a transient.
    pub fn settled_state(&self, x: T) -> BiquadState<T> {
        let y = self.dc_gain() * x;
        BiquadState { s: [y - self.b[0] * x, self.b[2] * x - self.a[1] * y] }
    }

    /// `H(e^{jω/fs})` at `freq_hz`.
    pub fn response(&self, freq_hz: T, sample_rate_hz: T) -> Complex<T> {
        let zi = Complex::cis(-T::TAU * freq_hz / sample_rate_hz);
        let zi2 = zi * zi;
        let num = Complex::real(self.b[0]) + zi.scale(self.b[1]) + zi2.scale(self.b[2]);
        let den = Complex::real(T::ONE) + zi.scale(self.a[0]) + zi2.scale(self.a[1]);
        num / den
    }

    /// Whether both poles lie strictly inside the unit circle (Jury conditions).
    pub fn is_stable(&self) -> bool {
        let (a1, a2) = (self.a[0], self.a[1]);
        a2.abs() < T::ONE && a1.abs() < T::ONE + a2
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const TOL: f64 = 1e-12;

    fn analog(num: [f64; 3], den: [f64; 3], f: f64) -> Complex<f64> {
        let s = Complex::new(0.0, core::f64::consts::TAU * f);
        polyval(&num, s) / polyval(&den, s)
    }

    #[test]
    fn prewarped_point_matches_analog() {
        let (fs, fc, q) = (20_000.0, 250.0, 0.7);
        let w = core::f64::consts::TAU * fc;
        let lp = Biquad::lowpass(fc, q, fs).unwrap();
        let want = analog([0.0, 0.0, w * w], [1.0, w / q, w * w], fc);
        let got = lp.response(fc, fs);
        assert!((got - want).norm() < TOL, "{got:?} vs {want:?}");
        assert!(lp.is_stable());
    }

    #[test]
    fn complement_sums_to_one_and_steps_agree() {
        let lp = Biquad::lowpass(300.0, 0.6, 8000.0).unwrap();
        let hp = lp.complement();
        for f in [0.0, 10.0, 300.0, 3999.0] {
            let s = lp.response(f, 8000.0) + hp.response(f, 8000.0);
            assert!((s - Complex::real(1.0)).norm() < TOL);
        }
        let (mut a, mut b) = (BiquadState::default(), BiquadState::default());
        for k in 0..500 {
            let x = ((k * 37) % 11) as f64 - 5.0;
            let y = lp.step(&mut a, x) + hp.step(&mut b, x);
            assert!((y - x).abs() < 1e-9);
        }
    }

    #[test]
    fn first_order_stays_first_order() {
        let f = Biquad::first_order_lowpass(250.0, 20_000.0).unwrap();
        assert_eq!((f.b[2], f.a[1]), (0.0, 0.0));
        assert!(f.is_stable());
        let k = (core::f64::consts::PI * 250.0 / 20_000.0).tan();
        assert!((f.b[0] - k / (1.0 + k)).abs() < TOL && (f.a[0] - (k - 1.0) / (k + 1.0)).abs() < TOL);
    }

    #[test]
    fn settled_state_has_no_transient() {
        let lp = Biquad::lowpass(50.0_f32, 0.707, 1000.0).unwrap();
        let mut st = lp.settled_state(2.0);
        for _ in 0..100 {
            assert!((lp.step(&mut st, 2.0) - 2.0).abs() < 1e-5);
        }
    }

    #[test]
    fn rejects_bad_designs() {
        assert_eq!(Biquad::first_order_lowpass(500.0, 1000.0), Err(Error::OutOfRange("cutoff_hz")));
        assert_eq!(Biquad::lowpass(-1.0, 0.7, 1000.0), Err(Error::NonPositive("cutoff_hz")));
        assert_eq!(Biquad::lowpass(1.0, 0.0, 1000.0), Err(Error::NonPositive("q")));
        assert_eq!(Biquad::highpass(1.0, 0.7, f64::NAN), Err(Error::NonPositive("sample_rate_hz")));
        assert!(Biquad::from_analog([0.0, 0.0, 1.0], [f64::INFINITY, 0.0, 1.0], 1.0, 10.0).is_err());
    }

    #[test]
    fn complex_division_and_norm() {
        let a = Complex::new(1.0e300, -2.0e300);
        let b = Complex::new(3.0e300, 4.0e300);
        let q = a / b;
        let back = q * b;
        assert!(((back - a).norm() / a.norm()) < 1e-12);
        assert!((Complex::new(3.0e200, 4.0e200).norm() - 5.0e200).abs() < 1e188);
    }
}
