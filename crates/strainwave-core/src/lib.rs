#![doc = include_str!("../README.md")]
#![cfg_attr(not(any(feature = "std", test)), no_std)]

pub mod bridge;
pub mod calibration;
pub mod compliance;
pub mod denoise;
pub mod error;
pub mod fusion;
pub mod gear;
pub mod guard;
pub mod iir;
mod lanes;
pub mod pmsm;
pub mod real;
pub mod ripple;
pub mod torsion;
pub mod tuning;

pub use error::Error;
pub use real::Real;
