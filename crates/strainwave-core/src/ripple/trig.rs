//! Branch-free sine and cosine of a wrapped phase, phasor powers, the orders' phasors
//! of a step and angle wrapping.
//!
//! The phase `θ` is wrapped into `[−π, π]`, so no general range reduction is needed:
//!
//! ```text
//! h = a / 4                       |h| ≤ π/4
//! sin h, cos h                    minimax polynomials of degree 13 / 14 (9 / 8 for f32), Estrin form
//!                                 in a² (the powers of 1/16 folded into the coefficients, exactly)
//! sin 2h = (2 sin h) cos h,  cos 2h = 1 − (2 sin h) sin h      applied twice
//! ```
//!
//! Error below 4e-18 (f64) and 1e-9 (f32) on |h| ≤ π/4, times at most 4 after the
//! doublings. No branch and no table: every function works on lanes, so that a bank's
//! joints take one vector evaluation. Whole multiples of a reference angle come from its
//! phasor by doubling ([`Doubling::doubled`], which carries the phasor's exact double
//! along: one multiply–add per doubling).

use crate::lanes::Lanes as L;
use crate::Real;

/// Whether the scalar is single precision (decides the series length; constant-folded).
#[inline(always)]
pub(super) fn is_single<T: Real>() -> bool {
    T::EPSILON.to_f64() > 1e-10
}

/// `sin h / h` in `h²` on `|h| ≤ π/4`: minimax coefficients (fdlibm `__kernel_sin`,
/// degree 13, error below 2^-58), one term fewer than the Taylor series.
const SIN: [f64; 7] = [
    1.0,
    -0.16666666666666632,
    0.00833333333332249,
    -0.0001984126982985795,
    2.7557313707070068e-06,
    -2.5050760253406863e-08,
    1.58969099521155e-10,
];
/// `cos h` in `h²` on `|h| ≤ π/4` (fdlibm `__kernel_cos`, degree 14).
const COS: [f64; 8] = [
    1.0,
    -0.5,
    0.0416666666666666,
    -0.001388888888887411,
    2.480158728947673e-05,
    -2.7557314351390663e-07,
    2.087572321298175e-09,
    -1.1359647557788195e-11,
];
/// Single precision: `sin h / h` of degree 9 and `cos h` of degree 8 (minimax, FreeBSD
/// `__kernel_sindf` / `__kernel_cosdf`, errors below 1e-9 on `|h| ≤ π/4`).
const SIN_F32: [f64; 5] =
    [1.0, -0.16666666641626524, 0.008333329385889463, -0.00019839334836096632, 2.718311493989822e-06];
/// See [`SIN_F32`].
const COS_F32: [f64; 5] = [1.0, -0.499999997251031, 0.04166662332373906, -0.001388676377460993, 2.439044879627741e-05];

/// Estrin evaluation of `Σ c[k] x^k` for 5 to 8 coefficients: pairs `c[2k] + c[2k+1] x`
/// combined with `x²` and `x⁴`, a dependency chain of 4 multiply–adds instead of 7.
#[inline(always)]
fn estrin<T: Real, const N: usize, const F: bool, const K: usize>(c: &[f64; N], x: L<T, K>) -> L<T, K> {
    let k = |i: usize| L::splat(T::from_f64(c.get(i).copied().unwrap_or(0.0)));
    let (x2, pair) = (x * x, |i: usize| k(i).madd::<F>(k(i + 1), x));
    let x4 = x2 * x2;
    let low = pair(0).madd::<F>(x2, pair(2));
    let high = match N {
        5 => k(4),
        6 => pair(4),
        7 => pair(4).madd::<F>(x2, k(6)),
        _ => pair(4).madd::<F>(x2, pair(6)),
    };
    low.madd::<F>(x4, high)
}

/// The phasor `(cos a, sin a)` for `|a| ≤ π` (beyond: clamped to `±π`, NaN to `−π`, so
/// always a finite unit vector) with its double, its multiply–adds
/// fused in the build `F` (see [`madd`]). Inlined everywhere but on 32-bit ARM, where the
/// compiler decides: with software double precision (Cortex-M4F) each inlined copy is
/// large, and the firmware library holds one step per order count.
#[cfg_attr(not(target_arch = "arm"), inline(always))]
pub(super) fn sin_cos_with<T: Real, const F: bool, const K: usize>(a: L<T, K>) -> Doubling<T, K> {
    phasor_of_wrapped::<T, F, K>(a.max(L::splat(-T::PI)).min(L::splat(T::PI)))
}

/// `(cos a, sin a)` and their doubles for `|a| ≤ π` (not checked: the caller's angle
/// is wrapped), bit for bit [`sin_cos_with`] there.
#[inline(always)]
pub(super) fn phasor_of_wrapped<T: Real, const F: bool, const K: usize>(a: L<T, K>) -> Doubling<T, K> {
    // Polynomials in u = a² = 16 h²: coefficient k scaled by 16^-k, exactly, so every
    // partial sum is the one in h² scaled by a power of two, and the result the same.
    let u = a * a;
    let (ps, pc) = if is_single::<T>() {
        (estrin::<T, 5, F, K>(&SIN_F32_IN_U, u), estrin::<T, 5, F, K>(&COS_F32_IN_U, u))
    } else {
        (estrin::<T, 7, F, K>(&SIN_IN_U, u), estrin::<T, 8, F, K>(&COS_IN_U, u))
    };
    // sin h = h P(h²) with h = a/4, and 2 sin h = (a/2) P: both products exact scalings.
    let quarter = Doubling { c: pc, s: a * T::from_f64(0.25) * ps, c2: pc + pc, s2: a * T::HALF * ps };
    // Two doublings: h → 2h → 4h = a.
    quarter.doubled::<F>().doubled::<F>()
}

/// [`SIN`] and [`COS`] as polynomials in `u = 16 h²`.
const SIN_IN_U: [f64; 7] = scaled(SIN);
/// See [`SIN_IN_U`].
const COS_IN_U: [f64; 8] = scaled(COS);
/// See [`SIN_IN_U`].
const SIN_F32_IN_U: [f64; 5] = scaled(SIN_F32);
/// See [`SIN_IN_U`].
const COS_F32_IN_U: [f64; 5] = scaled(COS_F32);

/// `c[k] / 16^k`: a power-of-two scaling, exact.
const fn scaled<const N: usize>(c: [f64; N]) -> [f64; N] {
    let mut out = c;
    let mut k = 0;
    let mut scale = 1.0;
    while k < N {
        out[k] = c[k] * scale;
        scale /= 16.0;
        k += 1;
    }
    out
}

/// Phasors `(cos x, sin x)` with their doubles `(2 cos x, 2 sin x)`, one per lane.
#[derive(Clone, Copy, Debug)]
pub(super) struct Doubling<T: Real, const K: usize> {
    pub(super) c: L<T, K>,
    pub(super) s: L<T, K>,
    c2: L<T, K>,
    s2: L<T, K>,
}

impl<T: Real, const K: usize> Doubling<T, K> {
    /// `(c, s)` and its double (exact).
    #[inline(always)]
    pub(super) fn new(c: L<T, K>, s: L<T, K>) -> Self {
        Self { c, s, c2: c + c, s2: s + s }
    }

    /// `(cos, sin)`.
    #[inline(always)]
    pub(super) fn pair(self) -> (L<T, K>, L<T, K>) {
        (self.c, self.s)
    }

    /// Lane 0's `[cos, sin, 2 cos, 2 sin]`.
    #[cfg(test)]
    fn parts(self) -> [T; 4] {
        [self.c.0[0], self.s.0[0], self.c2.0[0], self.s2.0[0]]
    }

    /// The angle doubled: `sin 2x = (2 sin x) cos x`, `cos 2x = 1 − (2 sin x) sin x`, and
    /// the same times two from the doubles (rounded alike: doubling is exact). The four
    /// are independent, so the chain is one multiply–add per doubling.
    #[inline(always)]
    pub(super) fn doubled<const F: bool>(self) -> Self {
        Self {
            c: L::splat(T::ONE).madd::<F>(-self.s2, self.s),
            s: self.s2 * self.c,
            c2: L::splat(T::TWO).madd::<F>(-self.s2, self.s2),
            s2: self.s2 * self.c2,
        }
    }
}

/// `(cos nψ, sin nψ)` from `(cos ψ, sin ψ)` for a whole `n ≥ 1`, by binary powers:
/// squarings by angle doubling, products by complex multiplication.
#[inline(always)]
pub(super) fn phasor_power_with<T: Real, const F: bool, const K: usize>(
    c: L<T, K>,
    s: L<T, K>,
    n: u8,
) -> Doubling<T, K> {
    type Pair<T, const K: usize> = (L<T, K>, L<T, K>);
    let sq = |(c, s): Pair<T, K>| {
        let d = Doubling::new(c, s).doubled::<F>();
        (d.c, d.s)
    };
    let mul = |(a, b): Pair<T, K>, (c, d): Pair<T, K>| ((a * c).madd::<F>(-b, d), (a * d).madd::<F>(b, c));
    let (mut acc, mut base, mut k) = ((L::splat(T::ONE), L::splat(T::ZERO)), (c, s), n);
    while k > 0 {
        if k & 1 == 1 {
            acc = mul(acc, base);
        }
        base = sq(base);
        k >>= 1;
    }
    Doubling::new(acc.0, acc.1)
}

/// Wraps angles into `[−π, π]` (to within a rounding of `π`): `x − 2π k` with `k` the
/// nearest whole number of turns, rounded by adding and removing 1.5 / ε, which leaves no
/// fraction (exact below 2⁵¹ turns in f64, 2²² in f32). No branch, so a bank vectorizes.
/// Non-finite inputs come back non-finite.
#[inline(always)]
pub(super) fn wrap_angle<T: Real, const J: usize>(x: L<T, J>) -> L<T, J> {
    let big = T::from_f64(1.5) / T::EPSILON;
    let turns = x * T::from_f64(1.0 / core::f64::consts::TAU);
    x - ((turns + big) - big) * T::TAU
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lanes::madd;

    /// `(sin a, cos a)` for `|a| ≤ π`; arguments beyond are clamped to `±π` (NaN to `−π`),
    /// so the result is always a finite unit vector.
    ///
    /// Accurate to a few ulp of 1 (absolute) over the whole range.
    fn sin_cos_small<T: Real>(a: T) -> (T, T) {
        let p = sin_cos_with::<T, false, 1>(L([a]));
        (p.s.0[0], p.c.0[0])
    }

    const TOL_F64: f64 = 2e-15;
    const TOL_F32: f64 = 1.5e-6;

    fn sweep<T: Real>(tol: f64) {
        let n = 20_001;
        for k in 0..n {
            let a = -core::f64::consts::PI + core::f64::consts::TAU * k as f64 / (n - 1) as f64;
            let at = T::from_f64(a);
            let (s, c) = sin_cos_small(at);
            let exact = at.to_f64();
            assert!((s.to_f64() - exact.sin()).abs() < tol, "sin({a})");
            assert!((c.to_f64() - exact.cos()).abs() < tol, "cos({a})");
        }
    }

    #[test]
    fn matches_std_over_the_range() {
        sweep::<f64>(TOL_F64);
        sweep::<f32>(TOL_F32);
    }

    #[test]
    fn clamps_even_nan() {
        let (s, c) = sin_cos_small(10.0_f64);
        assert!(s.abs() < TOL_F64 && (c + 1.0).abs() < TOL_F64);
        let (s, c) = sin_cos_small(f64::NAN);
        assert!(s.is_finite() && (s * s + c * c - 1.0).abs() < TOL_F64);
    }

    /// The phasors (polynomials in `a²`, doubles carried along) are bit for bit those
    /// of the plain algorithm: polynomials in `h² = (a/4)²`, then `(c, s)` doubled
    /// alone, `sin 2x = (2 sin x) cos x`, `cos 2x = 1 − (2 sin x) sin x`.
    fn ladder_is_exact<T: Real, const F: bool>() {
        let plain_double = |(c, s): (T, T)| (madd::<T, F>(T::ONE, -(s + s), s), (s + s) * c);
        let n = 4001;
        for k in 0..n {
            let a = T::from_f64(-core::f64::consts::PI + core::f64::consts::TAU * k as f64 / (n - 1) as f64);
            let a = a.clamp(-T::PI, T::PI);
            let h = a * T::from_f64(0.25);
            let h2 = L([h * h]);
            let quarter = if is_single::<T>() {
                (estrin::<T, 5, F, 1>(&COS_F32, h2).0[0], h * estrin::<T, 5, F, 1>(&SIN_F32, h2).0[0])
            } else {
                (estrin::<T, 8, F, 1>(&COS, h2).0[0], h * estrin::<T, 7, F, 1>(&SIN, h2).0[0])
            };
            let mut want = plain_double(plain_double(quarter));
            let mut d = phasor_of_wrapped::<T, F, 1>(L([a]));
            for _ in 0..3 {
                let [c, s, c2, s2] = d.parts();
                assert_eq!((c, s), want, "{a:?}");
                assert_eq!((c2, s2), (c + c, s + s), "{a:?}");
                d = d.doubled::<F>();
                want = plain_double(want);
            }
        }
    }

    #[test]
    fn doubling_ladder_is_the_plain_algorithm_bit_for_bit() {
        ladder_is_exact::<f64, false>();
        ladder_is_exact::<f32, false>();
        ladder_is_exact::<f64, true>();
        ladder_is_exact::<f32, true>();
    }

    /// Angles near the edges of the range wrap to within a rounding of `±π`, so that the
    /// clamp before the polynomials changes them by at most that rounding.
    fn wrapped_within_pi<T: Real>() {
        let ulp = |x: T| x.abs() * T::EPSILON;
        let bound = T::PI + ulp(T::PI) + ulp(T::PI);
        for v in [T::from_f64(3.0) * T::PI, T::PI, T::TAU, T::ZERO, T::from_f64(1e3)] {
            for v in [v, -v] {
                for k in -3..=3 {
                    let x = v + T::from_f64(f64::from(k)) * ulp(v).max(T::EPSILON);
                    let w = wrap_angle(L([x])).0[0];
                    assert!(w.abs() <= bound, "{x:?} wraps to {w:?}");
                }
            }
        }
    }

    #[test]
    fn wrapped_angles_are_within_a_rounding_of_pi() {
        wrapped_within_pi::<f64>();
        wrapped_within_pi::<f32>();
    }

    #[test]
    fn phasor_powers_match_multiple_angles() {
        for &psi in &[0.3_f64, -2.9, 3.1, 1.0] {
            for n in [1u8, 2, 3, 4, 5, 7, 12] {
                let p = phasor_power_with::<f64, false, 1>(L([psi.cos()]), L([psi.sin()]), n);
                let (c, s) = (p.c.0[0], p.s.0[0]);
                let want = psi * n as f64;
                assert!((c - want.cos()).abs() < 1e-13 && (s - want.sin()).abs() < 1e-13, "{psi} × {n}");
            }
        }
    }

    #[test]
    fn wrap_angle_covers_near_and_far() {
        for &x in &[0.0_f64, 3.5, -3.5, 6.2, -9.0, 1e6, -1e6, 100.0] {
            let w = wrap_angle(L([x])).0[0];
            assert!(w.abs() <= core::f64::consts::PI + 1e-12, "{x} → {w}");
            assert!(((x - w) / core::f64::consts::TAU - ((x - w) / core::f64::consts::TAU).round()).abs() < 1e-9);
        }
        let wrap = |x: f64| wrap_angle(L([x])).0[0];
        assert!(wrap(f64::NAN).is_nan() && !wrap(f64::INFINITY).is_finite());
    }
}
