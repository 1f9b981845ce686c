//! Oscillator-bank Kalman canceller of torque ripple and misalignment, after Taghirad
//! and Bélanger, “An intelligent built-in torque sensor for harmonic drive systems”
//! (IEEE Trans. Instrumentation and Measurement, 1999), with the torque as a random-walk
//! state of its own.
//!
//! The measured torque carries ripple periodic in the relative WG–FS angle (2×, 4×),
//! misalignment periodic in the output angle (1×) and noise. Each order is a
//! 2-state oscillator rotated by its measured phase increment; a prediction-type
//! time-varying Kalman filter estimates them, and the clean torque subtracts the
//! prediction made *before* the sample is seen, so nothing lags:
//!
//! ```text
//! y(k)   = T_meas(k) − T_exp(k) = Σ_i [1 0] x_i(k) + b(k) + v(k)
//! K(k)   = Φ P Cᵀ / (R + C P Cᵀ)
//! x̂(k+1) = Φ x̂ + K (y − C x̂),   P(k+1) = Q + (Φ − K C) P Φᵀ
//! T̂(k)   = T_meas(k) − C_osc x̂(k|k−1)
//! ```
//!
//! **Feeding angles.** Each sample carries the three reference angles in
//! [`ReferenceValues`] (`relative` = `φ = θ_wg − θ_fs`, wave generator minus flexspline; `output`; `motor`),
//! e.g. [`ReferenceValues::from_gear`] from the two encoders; only the references some
//! order uses are read. Angles may be unwrapped or wrapped (prefer wrapped, e.g. encoder
//! counts modulo one turn, in f32): the filter uses `Δθ = wrap_π(θ(k) − θ(k−1))`, so
//! each reference must move less than π per sample. With
//! [`PhaseSource::Velocity`] the values are rates (rad/s) and `Δθ = (ω(k−1) + ω(k))/2 · dt`.
//!
//! **Robustness** (see [`Limits`], [`StepFlags`]): non-finite torque → time update
//! only; non-finite angle or `dt` → state untouched, the next increment spans the gap;
//! jump or gap → the affected oscillators restart from their prior; a line above
//! `0.45 fs` → order off; a line below `hold_below_hz` (standstill) → order held; an
//! innovation beyond the load-step NIS → the bias takes it; a bad covariance → state
//! reset and `Err`. Nothing panics.
//!
//! Glossary: *order* — an oscillator at `n ×` a reference angle; *line* — its frequency
//! `n θ̇ / 2π`; *held* — too slow to tell from load, predicted but not updated; *off* —
//! above `0.45 fs`, dropped instead of aliased; *NIS* — normalized innovation squared.
//!
//! ```
//! use strainwave_core::ripple::{step, ReferenceValues, RippleInput, RippleModel, RippleState};
//! let model = RippleModel::<f32, 3>::product(1000.0, 0.05)?;
//! let mut state = RippleState::new(&model);
//! // Per sample: measured torque and the three reference angles (rad).
//! let out = step(&model, &mut state, &RippleInput::new(12.5, ReferenceValues::new(0.31, -0.003, 0.307)))?;
//! assert!(out.torque_nm.is_finite());
//! # Ok::<(), strainwave_core::Error>(())
//! ```

mod bank;
mod filter;
mod io;
pub mod kernel;
mod model;
mod presets;
mod snapshot;
mod trace;
mod trig;

/// The tuning formulas, also at this path.
pub use crate::tuning;
pub use bank::{BankInput, BankOutput, RippleBank};
pub use filter::{step, step_traced, RippleState};
pub use io::{OrderStatus, ReferenceValues, RippleInput, RippleOutput, StepFlags};
pub use kernel::step_many;
pub use model::{Limits, Order, PhaseSource, Reference, RippleModel};
pub use trace::{RotatingGaussian, StepTrace};
