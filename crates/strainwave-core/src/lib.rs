#![doc = include_str!("../README.md")]
#![cfg_attr(not(any(feature = "std", test)), no_std)]

pub mod bridge;
pub mod compliance;
pub mod error;
pub mod gear;
pub mod real;
pub mod ripple;

pub use error::Error;
pub use real::Real;
