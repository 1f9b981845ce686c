//! Test support: a run of samples with the awkward cases (NaN torque, angle jumps, a
//! gap, load steps, unwrapped angles, two speeds), and the check that a step path
//! gives the general path's outputs and state bit for bit.

use super::bank::{BankInput, BankOutput, RippleBank};
use super::kernel::{general, run};
use super::model::{PhaseSource, RippleModel};
use super::ReferenceValues;
use crate::Real;

/// Sample `k` for `J` joints; angles are unwrapped from sample `unwrapped_after` on.
pub(crate) fn sample<T: Real, const M: usize, const J: usize>(
    model: &RippleModel<T, M>,
    k: usize,
    unwrapped_after: usize,
) -> BankInput<T, J> {
    let c = T::from_f64;
    let mut seed = 0x9E37_79B9_7F4A_7C15_u64 ^ (k as u64).wrapping_mul(0x2545_F491_4F6C_DD1D);
    seed ^= seed << 13;
    seed ^= seed >> 7;
    seed ^= seed << 17;
    let noise = (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5;
    let w = if k < 3000 { 0.08 } else { 0.3 };
    let theta = |j: usize| {
        let t = w * k as f64 + 0.3 * j as f64 + if k % 997 == 500 { 2.0 } else { 0.0 };
        if model.phase_source() == PhaseSource::Velocity {
            w * 1000.0
        } else if k >= unwrapped_after {
            t
        } else {
            t.rem_euclid(core::f64::consts::TAU)
        }
    };
    let load_step = if k % 1500 == 700 { 40.0 } else { 0.0 };
    let mut input = BankInput::new(
        core::array::from_fn(|j| c(2.0 + (2.0 * theta(j)).cos() + 0.1 * noise + load_step)),
        ReferenceValues::new(
            core::array::from_fn(|j| c(theta(j))),
            core::array::from_fn(|j| c(-theta(j) / 50.0)),
            core::array::from_fn(|j| c(theta(j) + 0.1)),
        ),
    );
    input.expected_torque_nm = core::array::from_fn(|j| c(1.5 - j as f64));
    if k % 611 == 3 {
        input.torque_nm[J - 1] = c(f64::NAN);
    }
    if k % 1777 == 900 {
        input.dt_s = Some(c(if k.is_multiple_of(2) { 0.01 } else { 0.0011 }));
    }
    input
}

/// Runs 6000 samples through `path` (falling back to the whole step when it declines)
/// and through the general path; asserts the same outputs and state, bit for bit, and
/// that a declined sample changed nothing. Returns how many samples `path` took.
pub(crate) fn against_general<T: Real, const M: usize, const J: usize>(
    model: &RippleModel<T, M>,
    unwrapped_after: usize,
    mut path: impl FnMut(&RippleModel<T, M>, &mut RippleBank<T, M, J>, &BankInput<T, J>) -> Option<BankOutput<T, J>>,
) -> usize {
    let mut a = RippleBank::<T, M, J>::new(model);
    let mut b = a;
    let mut took = 0;
    for k in 0..6000 {
        let input = sample::<T, M, J>(model, k, unwrapped_after);
        let before = a;
        let out = path(model, &mut a, &input);
        took += usize::from(out.is_some());
        if out.is_none() {
            assert_eq!(format!("{a:?}"), format!("{before:?}"), "k {k}: the check changed the state");
        }
        let out_a = out.unwrap_or_else(|| run(model, &mut a, &input, None));
        let out_b = general(model, &mut b, &input, None);
        // Debug prints every bit that matters (NaN compares unequal to itself).
        assert_eq!(format!("{out_a:?}"), format!("{out_b:?}"), "k {k}");
        assert_eq!(format!("{a:?}"), format!("{b:?}"), "k {k}");
    }
    took
}

/// Runs 6000 samples through `path` from its own state, and each sample also through
/// the general path from a copy of that state; asserts the same decisions (flags,
/// statuses, counters: every non-numeric part of the state and outputs) and every
/// number within `tol` relative to its magnitude (at least 1). For a build that rounds
/// differently (fused multiply–adds), where bit equality cannot hold.
pub(crate) fn close_to_general<T: Real, const M: usize, const J: usize>(
    model: &RippleModel<T, M>,
    tol: f64,
    mut path: impl FnMut(&RippleModel<T, M>, &mut RippleBank<T, M, J>, &BankInput<T, J>) -> BankOutput<T, J>,
) {
    let mut a = RippleBank::<T, M, J>::new(model);
    for k in 0..6000 {
        let input = sample::<T, M, J>(model, k, 5000);
        let mut b = a;
        let out_a = path(model, &mut a, &input);
        let out_b = general(model, &mut b, &input, None);
        close(&format!("{out_a:?}"), &format!("{out_b:?}"), tol, k);
        close(&format!("{a:?}"), &format!("{b:?}"), tol, k);
    }
}

/// Debug texts `a` and `b` equal but for their numbers, which agree within `tol`.
fn close(a: &str, b: &str, tol: f64, k: usize) {
    let split = |s: &str| -> (String, Vec<f64>) {
        let (mut text, mut numbers, mut cur) = (String::new(), Vec::new(), String::new());
        let flush = |cur: &mut String, text: &mut String, numbers: &mut Vec<f64>| {
            if !cur.is_empty() {
                match cur.parse::<f64>() {
                    Ok(v) => {
                        numbers.push(v);
                        text.push('#');
                    }
                    Err(_) => text.push_str(cur),
                }
                cur.clear();
            }
        };
        for ch in s.chars() {
            if ch.is_ascii_digit() || matches!(ch, '.' | '-' | 'e' | 'N' | 'a' | 'i' | 'n' | 'f') {
                cur.push(ch);
            } else {
                flush(&mut cur, &mut text, &mut numbers);
                text.push(ch);
            }
        }
        flush(&mut cur, &mut text, &mut numbers);
        (text, numbers)
    };
    let ((ta, na), (tb, nb)) = (split(a), split(b));
    assert_eq!(ta, tb, "k {k}: decisions differ");
    assert_eq!(na.len(), nb.len(), "k {k}");
    for (x, y) in na.iter().zip(&nb) {
        let same = x.to_bits() == y.to_bits() || (x - y).abs() <= tol * x.abs().max(y.abs()).max(1.0);
        assert!(same, "k {k}: {x} against {y}\n{a}\n{b}");
    }
}
