//! The core's error type: small, `Copy`, naming the offending parameter.

use core::fmt;

/// What went wrong, with the name of the parameter or quantity at fault.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Error {
    /// A parameter that must be > 0 was not (zero, negative or NaN).
    NonPositive(&'static str),
    /// A parameter or input was NaN or infinite.
    NonFinite(&'static str),
    /// A parameter was outside its allowed range.
    OutOfRange(&'static str),
    /// Parameters that must be ordered were not (e.g. break torques `T1 < T2`).
    NotIncreasing(&'static str),
    /// A covariance or a matrix lost positive definiteness.
    NotPositiveDefinite(&'static str),
    /// A bounded iteration stopped before converging.
    NoConvergence(&'static str),
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Error::NonPositive(p) => write!(f, "`{p}` must be positive"),
            Error::NonFinite(p) => write!(f, "`{p}` must be finite"),
            Error::OutOfRange(p) => write!(f, "`{p}` is out of range"),
            Error::NotIncreasing(p) => write!(f, "`{p}` must be increasing"),
            Error::NotPositiveDefinite(p) => write!(f, "`{p}` is not positive definite"),
            Error::NoConvergence(p) => write!(f, "`{p}` did not converge within its iteration cap"),
        }
    }
}

impl core::error::Error for Error {}

/// `Ok(x)` when `x > 0` and finite, else `Error::NonPositive(name)`.
pub fn positive<T: crate::Real>(x: T, name: &'static str) -> Result<T, Error> {
    if x.is_finite() && x > T::ZERO {
        Ok(x)
    } else {
        Err(Error::NonPositive(name))
    }
}

/// `Ok(x)` when `x ≥ 0` and finite, else `Error::OutOfRange(name)`.
pub fn non_negative<T: crate::Real>(x: T, name: &'static str) -> Result<T, Error> {
    if !x.is_finite() {
        Err(Error::NonFinite(name))
    } else if x >= T::ZERO {
        Ok(x)
    } else {
        Err(Error::OutOfRange(name))
    }
}

/// `Ok(x)` when finite, else `Error::NonFinite(name)`.
pub fn finite<T: crate::Real>(x: T, name: &'static str) -> Result<T, Error> {
    if x.is_finite() {
        Ok(x)
    } else {
        Err(Error::NonFinite(name))
    }
}
