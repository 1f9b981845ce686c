//! A model's orders as one number, so that the one-loop bank step (`fused`) can be
//! compiled for the presets' layouts with each order's reference, power and load
//! scaling known at compile time: no selects in the loop, one squaring per power.
//!
//! Four bits per order `i` at bit `4i`: the power code (1, 2, 3 for a multiple of 1, 2,
//! 4; 0 ends the list), bit 2 the output reference, bit 3 load scaling. Bit 28: the
//! bias state. [`RUNTIME`] (no order) means "read the model at run time".

use super::model::{Reference, RippleModel};
use crate::Real;

/// Read the model at run time.
pub(super) const RUNTIME: u32 = 0;
const BIAS: u32 = 1 << 28;
const OUTPUT: u32 = 1 << 2;
const SCALED: u32 = 1 << 3;
const MAX_ORDERS: usize = 7;

const fn order(power_code: u32, flags: u32, i: u32) -> u32 {
    (power_code | flags) << (4 * i)
}

/// The seed's 4th-order model: 2× and 4× the relative angle.
pub(super) const SEED_4TH: u32 = order(2, 0, 0) | order(3, 0, 1);
/// The seed's 6th-order model: and 1× the output angle.
pub(super) const SEED_6TH: u32 = SEED_4TH | order(1, OUTPUT, 2);
/// The product default: the 6th-order orders and the bias state.
pub(super) const PRODUCT: u32 = SEED_6TH | BIAS;
/// The full model: 2×, 4×, 2× and 4× load-scaled, 1× output, bias.
pub(super) const FULL: u32 = SEED_4TH | order(2, SCALED, 2) | order(3, SCALED, 3) | order(1, OUTPUT, 4) | BIAS;

const fn nibble(layout: u32, i: usize) -> u32 {
    if i >= MAX_ORDERS {
        0
    } else {
        (layout >> (4 * i)) & 0xf
    }
}

/// Number of orders.
pub(super) const fn orders(layout: u32) -> usize {
    let mut n = 0;
    while nibble(layout, n) & 3 != 0 {
        n += 1;
    }
    n
}

/// Whole multiple of order `i` (1, 2 or 4).
pub(super) const fn power(layout: u32, i: usize) -> u8 {
    match nibble(layout, i) & 3 {
        1 => 1,
        2 => 2,
        _ => 4,
    }
}

/// Whether order `i` is on the output angle (else the relative one).
pub(super) const fn on_output(layout: u32, i: usize) -> bool {
    nibble(layout, i) & OUTPUT != 0
}

/// Whether order `i` is scaled by the load.
pub(super) const fn load_scaled(layout: u32, i: usize) -> bool {
    nibble(layout, i) & SCALED != 0
}

/// Everything the bank step reads of a layout, for order `i < 7`; evaluate it in a
/// `const` block so that it costs nothing per sample.
pub(super) struct Table {
    pub(super) power: [u8; MAX_ORDERS],
    pub(super) on_output: [bool; MAX_ORDERS],
    pub(super) load_scaled: [bool; MAX_ORDERS],
}

/// The [`Table`] of `layout`.
pub(super) const fn table(layout: u32) -> Table {
    let mut t = Table { power: [1; MAX_ORDERS], on_output: [false; MAX_ORDERS], load_scaled: [false; MAX_ORDERS] };
    let mut i = 0;
    while i < MAX_ORDERS {
        t.power[i] = power(layout, i);
        t.on_output[i] = on_output(layout, i);
        t.load_scaled[i] = load_scaled(layout, i);
        i += 1;
    }
    t
}

/// The [`Table`] of layout `L`: a constant in the binary, so that reading it with a
/// known order index folds away.
#[inline(always)]
pub(super) fn table_of<const L: u32>() -> &'static Table {
    const { &table(L) }
}

/// The layout code of `model`, or [`RUNTIME`] if it has none: only models whose
/// orders are whole multiples 1, 2 or 4 of the relative or output angle have one.
pub(super) fn of<T: Real, const M: usize>(model: &RippleModel<T, M>) -> u32 {
    if M == 0 || M > MAX_ORDERS {
        return RUNTIME;
    }
    let mut code = if model.bias_q_nm2.is_some() { BIAS } else { 0 };
    for (i, (o, &p)) in model.orders.iter().zip(model.power.iter()).enumerate() {
        let power_code = match p {
            1 => 1,
            2 => 2,
            4 => 3,
            _ => return RUNTIME,
        };
        let reference = match o.reference {
            Reference::Relative => 0,
            Reference::Output => OUTPUT,
            Reference::Motor => return RUNTIME,
        };
        let scaled = if o.load_scaled { SCALED } else { 0 };
        code |= order(power_code, reference | scaled, i as u32);
    }
    code
}

#[cfg(test)]
mod tests {
    use super::super::RippleModel;
    use super::*;

    #[test]
    fn presets_have_their_layouts() {
        assert_eq!(of(&RippleModel::<f64, 2>::seed_4th_order(1000.0).unwrap()), SEED_4TH);
        assert_eq!(of(&RippleModel::<f32, 3>::seed_6th_order(1000.0).unwrap()), SEED_6TH);
        assert_eq!(of(&RippleModel::<f32, 3>::product(1000.0, 0.05).unwrap()), PRODUCT);
        assert_eq!(of(&RippleModel::<f64, 5>::full(1000.0, 0.05).unwrap()), FULL);
        assert_eq!(
            (orders(SEED_4TH), orders(SEED_6TH), orders(PRODUCT), orders(FULL), orders(RUNTIME)),
            (2, 3, 3, 5, 0)
        );
        assert_eq!(
            (power(FULL, 1), on_output(FULL, 4), load_scaled(FULL, 2), load_scaled(FULL, 4)),
            (4, true, true, false)
        );
    }

    #[test]
    fn other_layouts_are_read_at_run_time() {
        use super::super::{Order, Reference};
        let motor = [Order::new(Reference::Motor, 1.0_f64).unwrap()];
        assert_eq!(of(&RippleModel::new(motor, 1.0, 1000.0).unwrap()), RUNTIME);
        let third = [Order::new(Reference::Relative, 3.0_f64).unwrap()];
        assert_eq!(of(&RippleModel::new(third, 1.0, 1000.0).unwrap()), RUNTIME);
        let one = [Order::new(Reference::Relative, 1.0_f64).unwrap()];
        assert_eq!(orders(of(&RippleModel::new(one, 1.0, 1000.0).unwrap())), 1);
    }
}
