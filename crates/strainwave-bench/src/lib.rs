//! A motor test bench as the tools see it: the bench config file (columns, the
//! accelerometer pair, the crossover, the mechanics) and the torque fusion run over a
//! whole recording.
//!
//! The command line and the Python package both go through this crate, so that they
//! read the same files the same way and give the same numbers. Its errors are the
//! one-line, user-facing messages the command line prints (file, row, key). Rows come
//! from the joint crate's row sources and go to its row sinks.

pub mod fuse;

pub use fuse::{BenchConfig, Fuse, Method, FUSED_COLUMN, METHODS};
