//! Return codes of the C functions and their texts.

use core::ffi::{c_char, CStr};

/// Success.
pub const SW_OK: i32 = 0;
/// A pointer argument is null.
pub const SW_ERROR_NULL: i32 = 1;
/// The state was not set up by a successful `sw_init` (or `sw32_init`).
pub const SW_ERROR_NOT_INITIALIZED: i32 = 2;
/// The model's `version` is not this library's `SW_MODEL_VERSION`.
pub const SW_ERROR_VERSION: i32 = 3;
/// `order_count` is not 1 to `SW_MAX_ORDERS`.
pub const SW_ERROR_ORDER_COUNT: i32 = 4;
/// An order's reference, multiple, noise, prior or load scaling is invalid.
pub const SW_ERROR_ORDER: i32 = 5;
/// Sample rate, noise or initial variances, bias state, phase source or limits invalid.
pub const SW_ERROR_MODEL: i32 = 6;
/// Gear ratio not positive or `gear_fixed` unknown.
pub const SW_ERROR_GEAR: i32 = 7;
/// The calibration's kind, length, values or extrapolation is invalid.
pub const SW_ERROR_CALIBRATION: i32 = 8;
/// `channels` has unknown bits or lacks what the phase source needs.
pub const SW_ERROR_CHANNELS: i32 = 9;
/// The covariance went bad: the state was reset and the output is the calibrated torque.
pub const SW_ERROR_COVARIANCE: i32 = 10;
/// A guard threshold is negative or not finite, or `off` / `learned_prior` is not 0 or 1.
pub const SW_ERROR_GUARD: i32 = 11;

/// The text of a return code (a static NUL-terminated string).
pub(crate) fn text(code: i32) -> *const c_char {
    let s: &'static CStr = match code {
        SW_OK => c"ok",
        SW_ERROR_NULL => c"a pointer argument is null",
        SW_ERROR_NOT_INITIALIZED => c"the state was not initialised by a successful sw_init",
        SW_ERROR_VERSION => c"the model was exported for another version of strainwave.h (SW_MODEL_VERSION)",
        SW_ERROR_ORDER_COUNT => c"order_count must be 1 to SW_MAX_ORDERS",
        SW_ERROR_ORDER => c"an order's reference, multiple, process noise, prior or load_scaled is invalid",
        SW_ERROR_MODEL => c"sample rate, noise_nm, bias, initial variances, phase source or limits are invalid",
        SW_ERROR_GEAR => c"gear_ratio must be positive and gear_fixed a SW_GEAR_* value",
        SW_ERROR_CALIBRATION => c"the calibration's kind, len, values or extrapolation is invalid",
        SW_ERROR_CHANNELS => {
            c"channels has unknown bits or lacks the angles (angle phase) or motor velocity (velocity phase)"
        }
        SW_ERROR_COVARIANCE => c"the covariance went bad; the state was reset and the torque passed through",
        SW_ERROR_GUARD => c"a guard threshold is negative or not finite, or guard.off / learned_prior is not 0 or 1",
        _ => c"unknown strainwave error code",
    };
    s.as_ptr()
}
