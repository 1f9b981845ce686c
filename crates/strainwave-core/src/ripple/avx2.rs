//! The joint bank's step compiled for AVX2, chosen at run time on x86-64 CPUs that have
//! it (std builds only; `no_std` builds use what the target enables at compile time).
//!
//! The same source as [`step_many`](super::step_many): no fused multiply–add is
//! formed (Rust never contracts `a * b + c`), so the results are bit for bit those
//! of the portable build; only the vector width and the instruction encoding change.

// The one place the project uses `unsafe`: calling a function compiled for a CPU
// feature, after checking that the CPU has it.
#![allow(unsafe_code)]

use super::bank::{BankInput, BankOutput, RippleBank};
use super::kernel::fill;
use super::model::RippleModel;
use crate::Real;

/// Whether this CPU runs [`step`] (checked once, then cached by the standard library).
#[inline]
pub(crate) fn available() -> bool {
    std::is_x86_feature_detected!("avx2")
}

/// [`fill`] for banks, with AVX2 enabled. Call only when [`available`] is true.
#[inline]
pub(crate) fn step<T: Real, const M: usize, const J: usize>(
    model: &RippleModel<T, M>,
    bank: &mut RippleBank<T, M, J>,
    input: &BankInput<T, J>,
    out: &mut BankOutput<T, J>,
) {
    debug_assert!(available());
    // SAFETY: callers check `available()`, so the CPU executes AVX2 instructions.
    unsafe { step_avx2(model, bank, input, out) }
}

#[target_feature(enable = "avx2")]
fn step_avx2<T: Real, const M: usize, const J: usize>(
    model: &RippleModel<T, M>,
    bank: &mut RippleBank<T, M, J>,
    input: &BankInput<T, J>,
    out: &mut BankOutput<T, J>,
) {
    fill(model, bank, input, None, out);
}

#[cfg(test)]
mod tests {
    use super::super::path_check::against_general;
    use super::super::{BankOutput, RippleModel};
    use super::{available, step};
    use crate::Real;

    /// The AVX2 build against the portable general path, bit for bit.
    fn same<T: Real, const M: usize, const J: usize>(model: RippleModel<T, M>) {
        let took = against_general::<T, M, J>(&model, 5000, |m, b, i| {
            let mut out = BankOutput::default();
            step(m, b, i, &mut out);
            Some(out)
        });
        assert_eq!(took, 6000);
    }

    #[test]
    fn avx2_build_is_the_portable_build() {
        if !available() {
            eprintln!("this CPU has no AVX2: nothing to compare");
            return;
        }
        same::<f32, 3, 8>(RippleModel::seed_6th_order(1000.0).unwrap());
        same::<f32, 3, 16>(RippleModel::product(1000.0, 0.05).unwrap());
        same::<f64, 5, 4>(RippleModel::full(1000.0, 0.05).unwrap());
        same::<f32, 2, 3>(RippleModel::seed_4th_order(1000.0).unwrap());
    }
}
