//! The caller-owned state: fixed-size storage for one joint's canceller (model, filter
//! state, do-no-harm guard, gear, calibration), tagged with a magic word so that a state never given to a
//! successful `sw_init` is refused.
//!
//! The storage holds the core model and state of the largest order count; its size is a
//! literal (C needs one) and a compile-time check keeps it large and aligned enough for
//! the core's types. A state is plain data: it may be copied with `memcpy`.

#![allow(non_camel_case_types)]

use core::mem::{align_of, size_of, MaybeUninit};

use strainwave_core::Real;

use crate::engine::Instance;

/// 64-bit words of storage in [`sw_state`].
pub const SW_STATE_WORDS: usize = 1536;
/// 64-bit words of storage in [`sw32_state`].
pub const SW32_STATE_WORDS: usize = 768;

/// `magic` of an initialised double-precision state ("swstate8" in ASCII).
pub(crate) const MAGIC_F64: u64 = u64::from_le_bytes(*b"swstate8");
/// `magic` of an initialised single-precision state ("swstate4" in ASCII).
pub(crate) const MAGIC_F32: u64 = u64::from_le_bytes(*b"swstate4");

/// One joint's canceller state (double precision): fixed size, no heap, owned by the
/// caller (static, stack or a struct member). Opaque: set it up with `sw_init`.
#[repr(C)]
pub struct sw_state {
    /// Private: set by `sw_init`.
    pub magic: u64,
    /// Private: the model and filter state.
    pub storage: [u64; SW_STATE_WORDS],
}

/// One joint's canceller state (single precision); see [`sw_state`].
#[repr(C)]
pub struct sw32_state {
    /// Private: set by `sw32_init`.
    pub magic: u64,
    /// Private: the model and filter state.
    pub storage: [u64; SW32_STATE_WORDS],
}

const _: () = {
    assert!(size_of::<Instance<f64>>() <= SW_STATE_WORDS * 8);
    assert!(size_of::<Instance<f32>>() <= SW32_STATE_WORDS * 8);
    assert!(align_of::<Instance<f64>>() <= align_of::<u64>());
    assert!(align_of::<Instance<f32>>() <= align_of::<u64>());
};

/// Access to a state's fields without naming its precision.
pub(crate) trait Slot {
    /// The precision.
    type Real: Real;
    /// `magic` of an initialised state.
    const MAGIC: u64;
    /// The magic word.
    fn magic(&mut self) -> &mut u64;
    /// The start of the storage.
    fn storage(&mut self) -> *mut u64;
}

impl Slot for sw_state {
    type Real = f64;
    const MAGIC: u64 = MAGIC_F64;
    fn magic(&mut self) -> &mut u64 {
        &mut self.magic
    }
    fn storage(&mut self) -> *mut u64 {
        self.storage.as_mut_ptr()
    }
}

impl Slot for sw32_state {
    type Real = f32;
    const MAGIC: u64 = MAGIC_F32;
    fn magic(&mut self) -> &mut u64 {
        &mut self.magic
    }
    fn storage(&mut self) -> *mut u64 {
        self.storage.as_mut_ptr()
    }
}

/// Builds an instance in the slot's storage with `build` (in place) and marks the slot
/// initialised if that succeeds; else leaves it uninitialised and returns the error.
pub(crate) fn init<S: Slot>(
    slot: &mut S,
    build: impl FnOnce(&mut MaybeUninit<Instance<S::Real>>) -> Result<(), i32>,
) -> Result<(), i32> {
    *slot.magic() = 0;
    // SAFETY: the storage is large and aligned enough for an `Instance` (checked at
    // compile time above) and exclusively borrowed through `slot`; as `MaybeUninit` it
    // may hold anything.
    let dest = unsafe { &mut *slot.storage().cast::<MaybeUninit<Instance<S::Real>>>() };
    build(dest)?;
    *slot.magic() = S::MAGIC;
    Ok(())
}

/// The instance of an initialised slot.
pub(crate) fn get<S: Slot>(slot: &mut S) -> Option<&mut Instance<S::Real>> {
    if *slot.magic() != S::MAGIC {
        return None;
    }
    // SAFETY: the magic word is only set by `init`, right after a valid instance was
    // built in this storage (a copied state carries its instance with it: it is plain data
    // without pointers). Size and alignment are checked at compile time.
    Some(unsafe { &mut *slot.storage().cast::<Instance<S::Real>>() })
}
