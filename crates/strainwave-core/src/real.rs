//! The scalar trait: every numeric item of the core is generic over [`Real`],
//! implemented for `f32` (joint controllers with a single-precision FPU) and `f64`.
//!
//! Transcendental functions come from `libm`, so the crate stays `no_std`.

use core::fmt::Debug;
use core::ops::{Add, AddAssign, BitAnd, BitOr, Div, DivAssign, Mul, MulAssign, Neg, Not, Sub, SubAssign};

/// A floating-point scalar: `f32` or `f64`.
pub trait Real:
    Copy
    + Debug
    + Default
    + PartialEq
    + PartialOrd
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
    + AddAssign
    + SubAssign
    + MulAssign
    + DivAssign
    + Send
    + Sync
    + 'static
{
    /// A signed integer as wide as the number: one lane of a mask (all bits set for
    /// true, else 0), so that masks fill vector registers as the numbers do.
    type Bits: Copy
        + Debug
        + Default
        + PartialEq
        + BitAnd<Output = Self::Bits>
        + BitOr<Output = Self::Bits>
        + Not<Output = Self::Bits>
        + From<u16>
        + Into<i64>
        + Send
        + Sync
        + 'static;
    /// Every bit of [`Self::Bits`] set.
    const ALL_BITS: Self::Bits;
    /// 0.
    const ZERO: Self;
    /// 1.
    const ONE: Self;
    /// 2.
    const TWO: Self;
    /// 1/2.
    const HALF: Self;
    /// π.
    const PI: Self;
    /// 2π.
    const TAU: Self;
    /// Machine epsilon.
    const EPSILON: Self;

    /// Converts from `f64`, rounding to nearest for `f32`.
    fn from_f64(x: f64) -> Self;
    /// Converts to `f64` exactly.
    fn to_f64(self) -> f64;
    /// Converts from a count (`usize`).
    fn from_usize(n: usize) -> Self {
        Self::from_f64(n as f64)
    }
    /// sin x.
    fn sin(self) -> Self;
    /// cos x.
    fn cos(self) -> Self;
    /// (sin x, cos x).
    fn sin_cos(self) -> (Self, Self) {
        (self.sin(), self.cos())
    }
    /// tan x.
    fn tan(self) -> Self;
    /// atan x.
    fn atan(self) -> Self;
    /// atan2(self, x).
    fn atan2(self, x: Self) -> Self;
    /// e^x.
    fn exp(self) -> Self;
    /// ln x.
    fn ln(self) -> Self;
    /// √x.
    fn sqrt(self) -> Self;
    /// |x|.
    fn abs(self) -> Self;
    /// Largest integer ≤ x.
    fn floor(self) -> Self;
    /// Nearest integer, ties away from zero.
    fn round(self) -> Self;
    /// x^y.
    fn powf(self, y: Self) -> Self;
    /// Whether x is neither infinite nor NaN.
    fn is_finite(self) -> bool;

    /// −1, 0 or +1 (0 for ±0 and NaN).
    #[inline(always)]
    fn signum0(self) -> Self {
        if self > Self::ZERO {
            Self::ONE
        } else if self < Self::ZERO {
            -Self::ONE
        } else {
            Self::ZERO
        }
    }
    /// The larger of two values (NaN-free inputs).
    #[inline(always)]
    fn max(self, other: Self) -> Self {
        if self > other {
            self
        } else {
            other
        }
    }
    /// The smaller of two values (NaN-free inputs).
    #[inline(always)]
    fn min(self, other: Self) -> Self {
        if self < other {
            self
        } else {
            other
        }
    }
    /// `self + a b` rounded once (fused multiply–add): one instruction where the code is
    /// compiled for a CPU with FMA, a library call otherwise.
    fn fused_mul_add(self, a: Self, b: Self) -> Self;
    /// Clamps into `[lo, hi]`.
    #[inline(always)]
    fn clamp(self, lo: Self, hi: Self) -> Self {
        self.max(lo).min(hi)
    }
    /// Wraps an angle into `(−π, π]`.
    fn wrap_pi(self) -> Self {
        let wrapped = self - Self::TAU * ((self + Self::PI) / Self::TAU).floor();
        if wrapped <= -Self::PI {
            wrapped + Self::TAU
        } else {
            wrapped
        }
    }
}

macro_rules! impl_real {
    ($t:ty, $bits:ty, $sin:path, $cos:path, $tan:path, $atan:path, $atan2:path, $exp:path, $ln:path,
     $sqrt:path, $floor:path, $round:path, $pow:path, $fma:path) => {
        impl Real for $t {
            type Bits = $bits;
            const ALL_BITS: $bits = -1;
            #[cfg(feature = "std")]
            #[inline(always)]
            fn fused_mul_add(self, a: Self, b: Self) -> Self {
                a.mul_add(b, self)
            }
            #[cfg(not(feature = "std"))]
            #[inline(always)]
            fn fused_mul_add(self, a: Self, b: Self) -> Self {
                $fma(a, b, self)
            }
            const ZERO: Self = 0.0;
            const ONE: Self = 1.0;
            const TWO: Self = 2.0;
            const HALF: Self = 0.5;
            const PI: Self = core::f64::consts::PI as $t;
            const TAU: Self = core::f64::consts::TAU as $t;
            const EPSILON: Self = <$t>::EPSILON;
            #[inline(always)]
            fn from_f64(x: f64) -> Self {
                x as $t
            }
            #[inline(always)]
            fn to_f64(self) -> f64 {
                self as f64
            }
            #[inline]
            fn sin(self) -> Self {
                $sin(self)
            }
            #[inline]
            fn cos(self) -> Self {
                $cos(self)
            }
            #[inline]
            fn tan(self) -> Self {
                $tan(self)
            }
            #[inline]
            fn atan(self) -> Self {
                $atan(self)
            }
            #[inline]
            fn atan2(self, x: Self) -> Self {
                $atan2(self, x)
            }
            #[inline]
            fn exp(self) -> Self {
                $exp(self)
            }
            #[inline]
            fn ln(self) -> Self {
                $ln(self)
            }
            #[inline]
            fn sqrt(self) -> Self {
                $sqrt(self)
            }
            #[inline(always)]
            fn abs(self) -> Self {
                <$t>::abs(self)
            }
            #[inline]
            fn floor(self) -> Self {
                $floor(self)
            }
            #[inline]
            fn round(self) -> Self {
                $round(self)
            }
            #[inline]
            fn powf(self, y: Self) -> Self {
                $pow(self, y)
            }
            #[inline(always)]
            fn is_finite(self) -> bool {
                <$t>::is_finite(self)
            }
        }
    };
}

impl_real!(
    f32,
    i32,
    libm::sinf,
    libm::cosf,
    libm::tanf,
    libm::atanf,
    libm::atan2f,
    libm::expf,
    libm::logf,
    libm::sqrtf,
    libm::floorf,
    libm::roundf,
    libm::powf,
    libm::fmaf
);
impl_real!(
    f64,
    i64,
    libm::sin,
    libm::cos,
    libm::tan,
    libm::atan,
    libm::atan2,
    libm::exp,
    libm::log,
    libm::sqrt,
    libm::floor,
    libm::round,
    libm::pow,
    libm::fma
);

#[cfg(test)]
mod tests {
    use super::*;

    fn wrap_case<T: Real>(tol: f64) {
        for &(x, want) in &[
            (0.0, 0.0),
            (3.5, 3.5 - core::f64::consts::TAU),
            (-3.5, -3.5 + core::f64::consts::TAU),
            (7.0, 7.0 - core::f64::consts::TAU),
        ] {
            let got = T::from_f64(x).wrap_pi().to_f64();
            assert!((got - want).abs() < tol, "wrap_pi({x}) = {got}, want {want}");
        }
        assert!(T::PI.wrap_pi() == T::PI);
        assert!((-T::PI).wrap_pi() == T::PI);
    }

    #[test]
    fn wrap_pi_f32_f64() {
        wrap_case::<f32>(1e-6);
        wrap_case::<f64>(1e-12);
    }

    #[test]
    fn signum0_of_zero_is_zero() {
        assert_eq!(0.0f64.signum0(), 0.0);
        assert_eq!((-2.0f32).signum0(), -1.0);
        assert_eq!(f64::NAN.signum0(), 0.0);
    }
}
