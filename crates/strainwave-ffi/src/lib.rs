//! The C ABI of the strainwave canceller, for drive firmware (C on Cortex-M/Cortex-A)
//! and ros2_control hardware interfaces (C++).
//!
//! A joint's model ([`sw_model`], a plain struct that `strainwave export-c` writes as a
//! C initializer) goes into a caller-owned, fixed-size [`sw_state`] with [`sw_init`];
//! then [`sw_step`] takes one raw sample and gives the clean torque. Nothing allocates,
//! every loop has a fixed bound, and bad input (null pointers, a state never
//! initialised, model values the core refuses) returns an `SW_ERROR_*` code. The `sw32_`
//! functions do the same in single precision for FPUs without double precision.
//!
//! The header `include/strainwave.h` is generated from this crate by cbindgen (a test
//! checks it is current). Firmware builds, `panic = "abort"` and the bounded work of one
//! step are described in `docs/firmware.md`.
//!
//! **Why `unsafe` is allowed here**: a C ABI receives raw pointers, and the state is a
//! caller-owned byte buffer that holds the core's model and filter state. Each use is in
//! [`state`] (storing and finding the instance) or at the entry points (turning the
//! caller's pointers into references after checking them for null).
#![cfg_attr(not(feature = "std"), no_std)]
#![allow(unsafe_code)]

mod convert;
mod engine;
pub mod errors;
pub mod state;
pub mod types;

use core::ffi::c_char;

pub use errors::*;
pub use state::{sw32_state, sw_state, SW32_STATE_WORDS, SW_STATE_WORDS};
pub use types::*;

use engine::{Instance, Plain, Sample};
use state::Slot;

/// Bare-metal builds: a panic (there is no path to one on any input) stops the core.
#[cfg(all(not(feature = "std"), not(test)))]
#[panic_handler]
fn panic(_: &core::panic::PanicInfo) -> ! {
    loop {}
}

fn init<S: Slot, M>(state: Option<&mut S>, model: Option<&M>) -> i32
where
    for<'a> Plain<S::Real>: From<&'a M>,
{
    let Some(state) = state else { return SW_ERROR_NULL };
    *state.magic() = 0;
    let Some(model) = model else { return SW_ERROR_NULL };
    let plain = Plain::from(model);
    match state::init(state, |dest| Instance::build(&plain, dest)) {
        Ok(()) => SW_OK,
        Err(code) => code,
    }
}

fn step<S: Slot, I, O>(state: Option<&mut S>, input: Option<&I>, out: Option<&mut O>) -> i32
where
    for<'a> Sample<S::Real>: From<&'a I>,
    O: From<engine::Output<S::Real>>,
{
    let (Some(state), Some(input), Some(out)) = (state, input, out) else { return SW_ERROR_NULL };
    let Some(instance) = state::get(state) else { return SW_ERROR_NOT_INITIALIZED };
    let (o, code) = instance.step(&Sample::from(input));
    *out = O::from(o);
    code
}

fn reset<S: Slot>(state: Option<&mut S>) -> i32 {
    let Some(state) = state else { return SW_ERROR_NULL };
    let Some(instance) = state::get(state) else { return SW_ERROR_NOT_INITIALIZED };
    instance.reset();
    SW_OK
}

/// Checks `model` and sets `state` up for it (double precision). Returns `SW_OK` or an
/// `SW_ERROR_*` code; on error the state is left uninitialised.
///
/// # Safety
/// Each pointer is null or points to a valid object of its type (`state` writable).
#[no_mangle]
pub unsafe extern "C" fn sw_init(state: *mut sw_state, model: *const sw_model) -> i32 {
    // SAFETY: the caller passes null or valid pointers; `as_mut`/`as_ref` check null.
    init(unsafe { state.as_mut() }, unsafe { model.as_ref() })
}

/// Runs one sample through the canceller (double precision). Returns `SW_OK`, or
/// `SW_ERROR_NULL`, `SW_ERROR_NOT_INITIALIZED` (nothing written) or
/// `SW_ERROR_COVARIANCE` (state reset, `out` holds the calibrated torque).
///
/// # Safety
/// Each pointer is null or points to a valid object of its type (`state` and `out`
/// writable); `in` may alias nothing else.
#[no_mangle]
pub unsafe extern "C" fn sw_step(state: *mut sw_state, r#in: *const sw_sample, out: *mut sw_output) -> i32 {
    // SAFETY: as documented; null is checked.
    step(unsafe { state.as_mut() }, unsafe { r#in.as_ref() }, unsafe { out.as_mut() })
}

/// Restarts the canceller from its model's priors (e.g. after re-homing the encoders).
///
/// # Safety
/// `state` is null or points to a valid, writable `sw_state`.
#[no_mangle]
pub unsafe extern "C" fn sw_reset(state: *mut sw_state) -> i32 {
    // SAFETY: as documented; null is checked.
    reset(unsafe { state.as_mut() })
}

/// Single-precision [`sw_init`].
///
/// # Safety
/// As [`sw_init`].
#[no_mangle]
pub unsafe extern "C" fn sw32_init(state: *mut sw32_state, model: *const sw32_model) -> i32 {
    // SAFETY: as documented; null is checked.
    init(unsafe { state.as_mut() }, unsafe { model.as_ref() })
}

/// Single-precision [`sw_step`].
///
/// # Safety
/// As [`sw_step`].
#[no_mangle]
pub unsafe extern "C" fn sw32_step(state: *mut sw32_state, r#in: *const sw32_sample, out: *mut sw32_output) -> i32 {
    // SAFETY: as documented; null is checked.
    step(unsafe { state.as_mut() }, unsafe { r#in.as_ref() }, unsafe { out.as_mut() })
}

/// Single-precision [`sw_reset`].
///
/// # Safety
/// As [`sw_reset`].
#[no_mangle]
pub unsafe extern "C" fn sw32_reset(state: *mut sw32_state) -> i32 {
    // SAFETY: as documented; null is checked.
    reset(unsafe { state.as_mut() })
}

/// A static, NUL-terminated description of a return code (any value).
#[no_mangle]
pub extern "C" fn sw_error_text(code: i32) -> *const c_char {
    errors::text(code)
}
