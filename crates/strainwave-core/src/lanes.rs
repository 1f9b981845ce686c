//! `J` lanes of a number, one per joint, with element-wise arithmetic, comparisons and
//! selects. A computation written over lanes runs one joint (`J = 1`: plain scalars) or
//! a bank of joints, where each operation is a short loop over the lanes that the
//! compiler turns into vector instructions. A [`Mask`] holds one condition per lane as
//! an integer as wide as the number, as a vector comparison gives it, so that masks and
//! numbers share the vector registers without conversions.

// Each operation is a loop indexing its operands and result by the same lane.
#![allow(clippy::needless_range_loop)]

use core::ops::{Add, BitAnd, BitOr, Div, Mul, Neg, Not, Sub};

use crate::Real;

/// `c + a b`: rounded once (fused) in the build `F = true` (compiled for FMA), else
/// rounded twice exactly as written. `c − a b` is `madd(c, −a, b)`, bit for bit.
#[inline(always)]
pub(crate) fn madd<T: Real, const F: bool>(c: T, a: T, b: T) -> T {
    if F {
        c.fused_mul_add(a, b)
    } else {
        c + a * b
    }
}

/// One number per lane (joint).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Lanes<T: Real, const J: usize>(pub(crate) [T; J]);

/// One condition per lane: every bit set (true) or none.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Mask<T: Real, const J: usize>(pub(crate) [T::Bits; J]);

impl<T: Real, const J: usize> Lanes<T, J> {
    /// The same number in every lane.
    #[inline(always)]
    pub(crate) fn splat(v: T) -> Self {
        Self([v; J])
    }

    /// `f` of each lane.
    #[inline(always)]
    pub(crate) fn map(self, f: impl Fn(T) -> T) -> Self {
        let mut out = self.0;
        for l in 0..J {
            out[l] = f(self.0[l]);
        }
        Self(out)
    }

    /// `f` of each lane of `self` and `other`.
    #[inline(always)]
    fn zip(self, other: Self, f: impl Fn(T, T) -> T) -> Self {
        let mut out = self.0;
        for l in 0..J {
            out[l] = f(self.0[l], other.0[l]);
        }
        Self(out)
    }

    /// Where `f` of each lane of `self` and `other` holds.
    #[inline(always)]
    fn test(self, other: impl Into<Self>, f: impl Fn(T, T) -> bool) -> Mask<T, J> {
        let other = other.into();
        let mut out = [T::Bits::default(); J];
        for l in 0..J {
            out[l] = if f(self.0[l], other.0[l]) { T::ALL_BITS } else { T::Bits::default() };
        }
        Mask(out)
    }

    /// `|x|`.
    #[inline(always)]
    pub(crate) fn abs(self) -> Self {
        self.map(T::abs)
    }

    /// The larger of each pair (NaN-free inputs).
    #[inline(always)]
    pub(crate) fn max(self, other: Self) -> Self {
        self.zip(other, T::max)
    }

    /// The smaller of each pair (NaN-free inputs).
    #[inline(always)]
    pub(crate) fn min(self, other: Self) -> Self {
        self.zip(other, T::min)
    }

    /// `self + a b`: fused (rounded once) when `F`, else rounded twice as written.
    #[inline(always)]
    pub(crate) fn madd<const F: bool>(self, a: impl Into<Self>, b: impl Into<Self>) -> Self {
        let (a, b) = (a.into(), b.into());
        let mut out = self.0;
        for l in 0..J {
            out[l] = madd::<T, F>(self.0[l], a.0[l], b.0[l]);
        }
        Self(out)
    }

    /// Where the number is neither infinite nor NaN (`x − x` is 0 exactly then).
    #[inline(always)]
    #[allow(clippy::eq_op)]
    pub(crate) fn finite(self) -> Mask<T, J> {
        (self - self).equals(T::ZERO)
    }

    /// `self < other` (false with NaN).
    #[inline(always)]
    pub(crate) fn less(self, other: impl Into<Self>) -> Mask<T, J> {
        self.test(other, |a, b| a < b)
    }

    /// `self ≤ other` (false with NaN).
    #[inline(always)]
    pub(crate) fn at_most(self, other: impl Into<Self>) -> Mask<T, J> {
        self.test(other, |a, b| a <= b)
    }

    /// `self == other`.
    #[inline(always)]
    pub(crate) fn equals(self, other: impl Into<Self>) -> Mask<T, J> {
        self.test(other, |a, b| a == b)
    }
}

impl<T: Real, const J: usize> Mask<T, J> {
    /// The same condition in every lane.
    #[inline(always)]
    pub(crate) fn splat(on: bool) -> Self {
        Self([if on { T::ALL_BITS } else { T::Bits::default() }; J])
    }

    /// Lane `l` set where `f(l)` holds.
    #[inline(always)]
    pub(crate) fn of(f: impl Fn(usize) -> bool) -> Self {
        let mut out = [T::Bits::default(); J];
        for l in 0..J {
            out[l] = if f(l) { T::ALL_BITS } else { T::Bits::default() };
        }
        Self(out)
    }

    /// Whether lane `l` is set.
    #[inline(always)]
    pub(crate) fn lane(self, l: usize) -> bool {
        self.0[l] != T::Bits::default()
    }

    /// `a` where set, else `b`.
    #[inline(always)]
    pub(crate) fn select(self, a: impl Into<Lanes<T, J>>, b: impl Into<Lanes<T, J>>) -> Lanes<T, J> {
        let (a, b) = (a.into(), b.into());
        let mut out = [T::ZERO; J];
        for l in 0..J {
            out[l] = if self.lane(l) { a.0[l] } else { b.0[l] };
        }
        Lanes(out)
    }

    /// `new` where set, else `old`: for state written back where `old` was read. In a
    /// bank the compiler would otherwise store `new` through the mask, and a masked
    /// store is slow and stalls the next step's load of that state.
    #[inline(always)]
    pub(crate) fn update(self, old: Lanes<T, J>, new: Lanes<T, J>) -> Lanes<T, J> {
        self.select(new, if J > 1 { core::hint::black_box(old) } else { old })
    }

    /// The lanes of `a` where set, else those of `b`.
    #[inline(always)]
    pub(crate) fn select_mask(self, a: Self, b: Self) -> Self {
        (self & a) | (!self & b)
    }

    /// `bits` where set, else 0: a word of flags per lane, combined with `|`.
    #[inline(always)]
    pub(crate) fn bits(self, bits: u16) -> Self {
        self & Self([T::Bits::from(bits); J])
    }

    /// The low 16 bits of each lane (a word of flags).
    #[inline(always)]
    #[allow(clippy::cast_possible_truncation)]
    pub(crate) fn low_bits(self) -> [u16; J] {
        let mut out = [0; J];
        for l in 0..J {
            out[l] = self.0[l].into() as u16;
        }
        out
    }

    /// Whether some lane is set.
    #[inline(always)]
    pub(crate) fn any(self) -> bool {
        self.0.iter().fold(T::Bits::default(), |acc, &m| acc | m) != T::Bits::default()
    }

    /// Whether every lane is set.
    #[inline(always)]
    pub(crate) fn all(self) -> bool {
        !(!self).any()
    }
}

impl<T: Real, const J: usize> From<T> for Lanes<T, J> {
    #[inline(always)]
    fn from(v: T) -> Self {
        Self::splat(v)
    }
}

/// Element-wise arithmetic, with a plain number on the right standing for every lane.
macro_rules! lane_op {
    ($op:ident, $f:ident) => {
        impl<T: Real, const J: usize> $op for Lanes<T, J> {
            type Output = Self;
            #[inline(always)]
            fn $f(self, rhs: Self) -> Self {
                self.zip(rhs, T::$f)
            }
        }
        impl<T: Real, const J: usize> $op<T> for Lanes<T, J> {
            type Output = Self;
            #[inline(always)]
            fn $f(self, rhs: T) -> Self {
                self.map(|x| x.$f(rhs))
            }
        }
    };
}
lane_op!(Add, add);
lane_op!(Sub, sub);
lane_op!(Mul, mul);
lane_op!(Div, div);

impl<T: Real, const J: usize> Neg for Lanes<T, J> {
    type Output = Self;
    #[inline(always)]
    fn neg(self) -> Self {
        self.map(T::neg)
    }
}

/// Element-wise logic of masks.
macro_rules! mask_op {
    ($op:ident, $f:ident) => {
        impl<T: Real, const J: usize> $op for Mask<T, J> {
            type Output = Self;
            #[inline(always)]
            fn $f(self, rhs: Self) -> Self {
                let mut out = self.0;
                for l in 0..J {
                    out[l] = self.0[l].$f(rhs.0[l]);
                }
                Self(out)
            }
        }
    };
}
mask_op!(BitAnd, bitand);
mask_op!(BitOr, bitor);

impl<T: Real, const J: usize> Not for Mask<T, J> {
    type Output = Self;
    #[inline(always)]
    fn not(self) -> Self {
        let mut out = self.0;
        for l in 0..J {
            out[l] = !self.0[l];
        }
        Self(out)
    }
}
