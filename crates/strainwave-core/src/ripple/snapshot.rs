//! A joint's whole filter state as a flat array of `f64` and back, exactly: for
//! smoothers that keep block-start states on disk, and for anything that must resume a
//! run bit for bit.
//!
//! Layout (fixed for a given `M`): the rotating-frame means and covariance, then the
//! phase bookkeeping, one `f64` per value; flags as 0/1, order statuses as 0/1/2
//! (active, held, off), the step counter as a whole number. `T` values are stored
//! widened to `f64`, which is exact for `f32`.

use super::bank::RippleBank;
use super::filter::RippleState;
use super::io::OrderStatus;
use super::model::RippleModel;
use crate::{Error, Real};

/// Largest step count stored exactly in an `f64`.
const MAX_COUNT: f64 = 9_007_199_254_740_992.0;

/// Walks every field of a one-joint bank in the snapshot's order.
trait Visit<T: Real> {
    fn real(&mut self, x: &mut T);
    fn flag(&mut self, x: &mut bool);
    fn status(&mut self, x: &mut OrderStatus);
    fn count(&mut self, x: &mut u64);
}

fn walk<T: Real, const M: usize>(b: &mut RippleBank<T, M, 1>, v: &mut impl Visit<T>) {
    for zi in &mut b.z {
        zi.iter_mut().for_each(|x| v.real(&mut x[0]));
    }
    v.real(&mut b.b[0]);
    for row in &mut b.p {
        for block in row {
            block.iter_mut().flatten().for_each(|x| v.real(&mut x[0]));
        }
    }
    b.pb.iter_mut().flatten().for_each(|x| v.real(&mut x[0]));
    v.real(&mut b.pbb[0]);
    b.phasor.iter_mut().flatten().for_each(|x| v.real(&mut x[0]));
    b.psi.iter_mut().for_each(|x| v.real(&mut x[0]));
    b.order_psi.iter_mut().for_each(|x| v.real(&mut x[0]));
    b.status.iter_mut().for_each(|x| v.status(&mut x[0]));
    b.last.iter_mut().for_each(|x| v.real(&mut x[0]));
    v.flag(&mut b.has_last[0]);
    b.last_delta.iter_mut().for_each(|x| v.real(&mut x[0]));
    v.flag(&mut b.delta_known[0]);
    b.mean_delta.iter_mut().for_each(|x| v.real(&mut x[0]));
    v.real(&mut b.pending_samples[0]);
    v.real(&mut b.pending_dt[0]);
    v.count(&mut b.steps[0]);
}

/// Writes the values in order.
struct Writer<'a> {
    out: &'a mut [f64],
    at: usize,
}

impl Writer<'_> {
    fn put(&mut self, x: f64) {
        if let Some(slot) = self.out.get_mut(self.at) {
            *slot = x;
        }
        self.at += 1;
    }
}

impl<T: Real> Visit<T> for Writer<'_> {
    fn real(&mut self, x: &mut T) {
        self.put(x.to_f64());
    }
    fn flag(&mut self, x: &mut bool) {
        self.put(f64::from(u8::from(*x)));
    }
    fn status(&mut self, x: &mut OrderStatus) {
        self.put(match x {
            OrderStatus::Active => 0.0,
            OrderStatus::Held => 1.0,
            OrderStatus::Off => 2.0,
        });
    }
    fn count(&mut self, x: &mut u64) {
        // Exact below 2^53 samples (285 000 years at 1 kHz).
        self.put(*x as f64);
    }
}

/// Reads the values in order; the first that is not what the field can hold is kept.
struct Reader<'a> {
    values: &'a [f64],
    at: usize,
    bad: Option<&'static str>,
}

impl Reader<'_> {
    fn take(&mut self) -> f64 {
        let x = self.values.get(self.at).copied().unwrap_or(f64::NAN);
        self.at += 1;
        x
    }

    fn fail(&mut self, what: &'static str) {
        self.bad.get_or_insert(what);
    }
}

impl<T: Real> Visit<T> for Reader<'_> {
    fn real(&mut self, x: &mut T) {
        let v = self.take();
        *x = T::from_f64(v);
        // A value `T` cannot hold exactly (a snapshot of f64 read as f32, say).
        if x.to_f64().to_bits() != v.to_bits() && !(v.is_nan() && x.to_f64().is_nan()) {
            self.fail("ripple snapshot: a value is not exact in this precision");
        }
    }
    fn flag(&mut self, x: &mut bool) {
        let v = self.take();
        *x = v == 1.0;
        if v != 0.0 && v != 1.0 {
            self.fail("ripple snapshot: a flag is not 0 or 1");
        }
    }
    fn status(&mut self, x: &mut OrderStatus) {
        let v = self.take();
        *x = if v == 1.0 {
            OrderStatus::Held
        } else if v == 2.0 {
            OrderStatus::Off
        } else {
            OrderStatus::Active
        };
        if v != 0.0 && v != 1.0 && v != 2.0 {
            self.fail("ripple snapshot: an order status is not 0, 1 or 2");
        }
    }
    fn count(&mut self, x: &mut u64) {
        let v = self.take();
        let whole = (0.0..=MAX_COUNT).contains(&v) && v == (v as u64) as f64;
        *x = if whole { v as u64 } else { 0 };
        if !whole {
            self.fail("ripple snapshot: the step count is not a whole number");
        }
    }
}

impl<T: Real, const M: usize> RippleState<T, M> {
    /// Number of values in a [`snapshot`](Self::snapshot): `4M² + 8M + 19`.
    pub const SNAPSHOT_LEN: usize = 4 * M * M + 8 * M + 19;

    /// Writes the whole state into `out` (length [`SNAPSHOT_LEN`](Self::SNAPSHOT_LEN));
    /// [`from_snapshot`](Self::from_snapshot) gives it back bit for bit.
    ///
    /// ```
    /// use strainwave_core::ripple::{step, ReferenceValues, RippleInput, RippleModel, RippleState};
    /// let model = RippleModel::<f32, 2>::taghirad_4th_order(1000.0)?;
    /// let mut state = RippleState::new(&model);
    /// step(&model, &mut state, &RippleInput::new(1.5, ReferenceValues::new(0.3, 0.0, 0.0)))?;
    /// let mut values = [0.0; RippleState::<f32, 2>::SNAPSHOT_LEN];
    /// state.snapshot(&mut values)?;
    /// assert_eq!(RippleState::from_snapshot(&model, &values)?, state);
    /// # Ok::<(), strainwave_core::Error>(())
    /// ```
    pub fn snapshot(&self, out: &mut [f64]) -> Result<(), Error> {
        if out.len() != Self::SNAPSHOT_LEN {
            return Err(Error::OutOfRange("ripple snapshot length"));
        }
        let mut bank = self.bank;
        walk(&mut bank, &mut Writer { out, at: 0 });
        Ok(())
    }

    /// The state a [`snapshot`](Self::snapshot) holds. `Err` names what is wrong when
    /// `values` has another length or a value its field cannot hold (a flag other than
    /// 0/1, a fractional step count, an `f64` that is not exact in `T`).
    pub fn from_snapshot(model: &RippleModel<T, M>, values: &[f64]) -> Result<Self, Error> {
        if values.len() != Self::SNAPSHOT_LEN {
            return Err(Error::OutOfRange("ripple snapshot length"));
        }
        let mut state = Self::new(model);
        let mut reader = Reader { values, at: 0, bad: None };
        walk(&mut state.bank, &mut reader);
        match reader.bad {
            Some(what) => Err(Error::OutOfRange(what)),
            None => Ok(state),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::kernel::tests::sample;
    use super::super::{step, RippleInput, RippleModel, RippleState};
    use crate::Real;

    /// Runs `model` through the awkward samples, snapshotting and restoring at every
    /// step: the restored copy must be the state bit for bit and step on identically.
    fn round_trip<T: Real, const M: usize>(model: RippleModel<T, M>) {
        let mut state = RippleState::new(&model);
        let mut values = vec![0.0; RippleState::<T, M>::SNAPSHOT_LEN];
        let mut walked = 0;
        for k in 0..3000 {
            let b = sample::<T, M, 1>(&model, k, usize::MAX);
            let r = &b.references;
            let mut input = RippleInput::new(
                b.torque_nm[0],
                super::super::ReferenceValues::new(r.relative[0], r.output[0], r.motor[0]),
            );
            input.expected_torque_nm = b.expected_torque_nm[0];
            input.dt_s = b.dt_s;
            state.snapshot(&mut values).unwrap();
            let mut back = RippleState::from_snapshot(&model, &values).unwrap();
            assert_eq!(format!("{back:?}"), format!("{state:?}"), "k {k}");
            let (a, c) = (step(&model, &mut state, &input), step(&model, &mut back, &input));
            assert_eq!(format!("{a:?}"), format!("{c:?}"), "k {k}");
            walked += 1;
        }
        assert_eq!(walked, 3000);
    }

    #[test]
    fn snapshot_round_trips_bit_for_bit() {
        round_trip(RippleModel::<f64, 3>::taghirad_6th_order(1000.0).unwrap());
        round_trip(RippleModel::<f32, 3>::product(1000.0, 0.05).unwrap());
        round_trip(RippleModel::<f64, 5>::full(1000.0, 0.05).unwrap());
    }

    #[test]
    fn snapshot_length_matches_its_fields() {
        // Every slot is written: a sentinel left anywhere means the formula is wrong.
        let model = RippleModel::<f64, 5>::full(1000.0, 0.05).unwrap();
        let mut values = vec![f64::MAX; RippleState::<f64, 5>::SNAPSHOT_LEN];
        RippleState::new(&model).snapshot(&mut values).unwrap();
        assert!(values.iter().all(|&v| v != f64::MAX));
        let mut walker = super::Writer { out: &mut [], at: 0 };
        super::walk(&mut RippleState::new(&model).bank, &mut walker);
        assert_eq!(walker.at, RippleState::<f64, 5>::SNAPSHOT_LEN);
    }

    #[test]
    fn bad_snapshots_are_refused_by_name() {
        let model = RippleModel::<f32, 2>::taghirad_4th_order(1000.0).unwrap();
        let n = RippleState::<f32, 2>::SNAPSHOT_LEN;
        let mut values = vec![0.0; n];
        RippleState::new(&model).snapshot(&mut values).unwrap();
        let err = |v: &[f64]| RippleState::from_snapshot(&model, v).unwrap_err().to_string();
        assert!(err(&values[..n - 1]).contains("snapshot length"));
        assert!(RippleState::new(&model).snapshot(&mut vec![0.0; n + 1]).is_err());
        let mut v = values.clone();
        v[0] = 0.1; // not an f32
        assert!(err(&v).contains("not exact"));
        let mut v = values.clone();
        v[n - 1] = 2.5; // the step count
        assert!(err(&v).contains("step count"));
        // From the end: step count, pending dt and samples, mean increments (3), then
        // `delta_known`; the order statuses sit before the last angles (3), `has_last`
        // and the last increments (3).
        let mut v = values.clone();
        v[n - 7] = 0.5;
        assert!(err(&v).contains("flag"), "{}", err(&v));
        let mut v = values.clone();
        v[n - 15] = 3.0;
        assert!(err(&v).contains("order status"), "{}", err(&v));
    }
}
