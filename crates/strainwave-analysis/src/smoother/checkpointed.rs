//! The fixed-interval smoother over recordings too long to hold: the same result as
//! [`smooth`](super::smooth), bit for bit, in memory bounded by one block.
//!
//! The forward pass keeps only the filter's state at the start of every block of
//! `block_len` samples (a checkpoint). The backward pass then takes the blocks from the
//! last to the first: each is filtered again from its checkpoint, which rebuilds its
//! per-sample records exactly, and smoothed backward from the first sample of the block
//! after it (its record and smoothed mean are carried over). Cost: the forward filter
//! twice; memory: one block of records, plus one state per block in the
//! [`CheckpointStore`] (a `Vec` by default; a file keeps memory bounded by one block).

use strainwave_core::ripple::{step_traced, RippleInput, RippleModel, RippleOutput, RippleState, StepTrace};
use strainwave_core::Real;

use super::{backward, forward, samples, Record, Smoothed, SmootherError};

/// Where a [`CheckpointedSmoother`] keeps the state at the start of each block: in
/// memory (`Vec`), or elsewhere (a scratch file, say, through
/// [`RippleState::snapshot`]) so that memory stays bounded whatever the length.
pub trait CheckpointStore<T: Real, const M: usize> {
    /// Keeps the state at the start of `block` (blocks come in order: 0, 1, …).
    fn save(&mut self, block: usize, state: &RippleState<T, M>) -> Result<(), String>;
    /// The state kept for `block`.
    fn load(&mut self, block: usize) -> Result<RippleState<T, M>, String>;
}

impl<T: Real, const M: usize> CheckpointStore<T, M> for Vec<RippleState<T, M>> {
    fn save(&mut self, block: usize, state: &RippleState<T, M>) -> Result<(), String> {
        if block != self.len() {
            return Err(format!("saved out of order (expected block {})", self.len()));
        }
        self.push(*state);
        Ok(())
    }

    fn load(&mut self, block: usize) -> Result<RippleState<T, M>, String> {
        self.get(block).copied().ok_or_else(|| format!("not saved ({} blocks are)", self.len()))
    }
}

/// Forward pass sample by sample ([`push`](Self::push)), then the backward pass block by
/// block, the last first ([`smooth_block`](Self::smooth_block)); the caller keeps the
/// inputs (on disk, say) and gives each block's back.
///
/// ```
/// use strainwave_analysis::smoother::{smooth, CheckpointedSmoother};
/// use strainwave_core::ripple::{ReferenceValues, RippleInput, RippleModel};
/// let model = RippleModel::<f64, 2>::taghirad_4th_order(1000.0).unwrap();
/// let inputs: Vec<_> = (0..2500)
///     .map(|k| RippleInput::new(0.5 * (0.1 * k as f64).cos(), ReferenceValues::new(0.05 * k as f64, 0.0, 0.0)))
///     .collect();
/// let mut s = CheckpointedSmoother::new(&model, 1000).with_torque_state_sd();
/// for input in &inputs {
///     s.push(input).unwrap();
/// }
/// let whole = smooth(&model, &inputs).unwrap();
/// for b in (0..s.blocks()).rev() {
///     let range = s.block_range(b);
///     let part = s.smooth_block(b, &inputs[range.clone()]).unwrap();
///     assert_eq!(part.smoothed, whole.smoothed[range]);
/// }
/// ```
#[derive(Clone)]
pub struct CheckpointedSmoother<T: Real, const M: usize, S = Vec<RippleState<T, M>>> {
    model: RippleModel<T, M>,
    block_len: usize,
    state: RippleState<T, M>,
    trace: StepTrace<T, M>,
    /// The state before the first sample of each block.
    checkpoints: S,
    blocks: usize,
    len: usize,
    /// The block `smooth_block` takes next.
    next_block: Option<usize>,
    /// The first sample of the block smoothed last: its record, smoothed mean and
    /// smoothed covariance.
    after: Option<(Record, Vec<f64>, Option<Vec<f64>>)>,
    backward_began: bool,
    /// Whether the backward pass carries the smoothed covariance (for `torque_state_sd_nm`).
    state_sd: bool,
}

impl<T: Real, const M: usize> CheckpointedSmoother<T, M> {
    /// A smoother on `model` with blocks of `block_len` samples (at least 1), keeping
    /// its checkpoints in memory.
    pub fn new(model: &RippleModel<T, M>, block_len: usize) -> Self {
        Self::with_store(model, block_len, Vec::new())
    }
}

impl<T: Real, const M: usize, S: CheckpointStore<T, M>> CheckpointedSmoother<T, M, S> {
    /// A smoother on `model` with blocks of `block_len` samples (at least 1), keeping
    /// its checkpoints in `store` (empty).
    pub fn with_store(model: &RippleModel<T, M>, block_len: usize, store: S) -> Self {
        Self {
            model: *model,
            block_len: block_len.max(1),
            state: RippleState::new(model),
            trace: StepTrace::new(),
            checkpoints: store,
            blocks: 0,
            len: 0,
            next_block: None,
            after: None,
            backward_began: false,
            state_sd: false,
        }
    }

    /// Also carries the smoothed covariance backward, for `torque_state_sd_nm` (NaN
    /// without; the means are the same either way). It costs `n` more solves and two
    /// `n³` products per sample, `n` the state length.
    pub fn with_torque_state_sd(mut self) -> Self {
        self.state_sd = true;
        self
    }

    /// Forward pass: filters the next sample and returns the real-time output (the
    /// same as [`smooth_block`](Self::smooth_block) gives again in `filtered`).
    pub fn push(&mut self, input: &RippleInput<T>) -> Result<RippleOutput<T>, SmootherError> {
        if self.backward_began {
            return Err(SmootherError::PushAfterBackward);
        }
        if self.len.is_multiple_of(self.block_len) {
            let block = self.blocks;
            self.checkpoints
                .save(block, &self.state)
                .map_err(|message| SmootherError::Checkpoint { block, message })?;
            self.blocks += 1;
        }
        let out = step_traced(&self.model, &mut self.state, input, &mut self.trace)
            .map_err(|source| SmootherError::Filter { index: self.len, source })?;
        self.len += 1;
        self.next_block = self.blocks().checked_sub(1);
        Ok(out)
    }

    /// Samples pushed.
    pub fn len(&self) -> usize {
        self.len
    }

    /// Whether no sample was pushed.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Blocks of the samples pushed (the last may be shorter).
    pub fn blocks(&self) -> usize {
        self.blocks
    }

    /// The samples of block `b`.
    pub fn block_range(&self, b: usize) -> core::ops::Range<usize> {
        let start = b.saturating_mul(self.block_len).min(self.len);
        start..start.saturating_add(self.block_len).min(self.len)
    }

    /// Backward pass over block `b`, given its inputs (the ones pushed): its forward
    /// outputs and smoothed samples. Blocks go from the last to the first; once the
    /// first is smoothed, [`push`](Self::push) is refused.
    pub fn smooth_block(&mut self, b: usize, inputs: &[RippleInput<T>]) -> Result<Smoothed<T>, SmootherError> {
        let expected = self.next_block.map_or(0..0, |e| self.block_range(e));
        if self.next_block != Some(b) || inputs.len() != expected.len() {
            return Err(SmootherError::BlockMismatch {
                block: b,
                inputs: inputs.len(),
                expected_block: self.next_block.unwrap_or(usize::MAX),
                expected_inputs: expected.len(),
            });
        }
        self.backward_began = true;
        let mut state = self.checkpoints.load(b).map_err(|message| SmootherError::Checkpoint { block: b, message })?;
        let (filtered, mut records) = forward(&self.model, &mut state, inputs, expected.start)?;
        let after = self.after.as_ref().map(|(r, m, c)| (r, m.as_slice(), c.as_deref()));
        let mut back = backward::<M>(self.model.state_len(), &records, after, expected.start, self.state_sd)?;
        let smoothed = samples(&self.model, inputs, &records, &back);
        self.next_block = b.checked_sub(1);
        self.after =
            (!records.is_empty()).then(|| (records.swap_remove(0), back.means.swap_remove(0), back.first_cov.take()));
        Ok(Smoothed { filtered, smoothed })
    }
}

#[cfg(test)]
mod tests {
    use super::super::smooth;
    use super::*;
    use strainwave_core::ripple::ReferenceValues;

    /// A loaded joint with ripple, misalignment, a load step, a standstill and a jump in
    /// angle, so that load steps, holds and resets fall inside and across blocks.
    fn inputs(n: usize) -> Vec<RippleInput<f64>> {
        let mut angle = 0.0;
        (0..n)
            .map(|k| {
                let w = if (3000..3600).contains(&k) { 0.0 } else { 0.08 };
                angle += w;
                if k == 5000 {
                    angle += 2.0;
                }
                let out = -angle / 100.0;
                let load = if k > 4200 { 12.0 } else { 2.0 };
                let y = load + (0.5 + 0.01 * load) * (2.0 * angle).cos() + 0.3 * (out + 0.2).cos();
                let wrap = |a: f64| a.rem_euclid(std::f64::consts::TAU);
                RippleInput::new(y + 0.01 * ((k * 7919) % 13) as f64, ReferenceValues::new(wrap(angle), wrap(out), 0.0))
            })
            .collect()
    }

    /// The same inputs in f32.
    fn single(ins: &[RippleInput<f64>]) -> Vec<RippleInput<f32>> {
        ins.iter()
            .map(|i| {
                let r = i.references;
                RippleInput::new(i.torque_nm as f32, ReferenceValues::new(r.relative as f32, r.output as f32, 0.0))
            })
            .collect()
    }

    fn blockwise<T: Real, const M: usize>(
        model: &RippleModel<T, M>,
        ins: &[RippleInput<T>],
        block: usize,
    ) -> Smoothed<T> {
        blockwise_in(model, ins, block, Vec::new())
    }

    fn blockwise_in<T: Real, const M: usize>(
        model: &RippleModel<T, M>,
        ins: &[RippleInput<T>],
        block: usize,
        store: impl CheckpointStore<T, M>,
    ) -> Smoothed<T> {
        let mut s = CheckpointedSmoother::with_store(model, block, store).with_torque_state_sd();
        let mut forward = Vec::new();
        for i in ins {
            forward.push(s.push(i).unwrap());
        }
        let mut out = Smoothed { filtered: vec![], smoothed: vec![] };
        for b in (0..s.blocks()).rev() {
            let part = s.smooth_block(b, &ins[s.block_range(b)]).unwrap();
            out.filtered.splice(0..0, part.filtered);
            out.smoothed.splice(0..0, part.smoothed);
        }
        assert_eq!(out.filtered, forward, "the blocks' forward outputs are the pushed ones");
        out
    }

    #[test]
    fn blockwise_is_the_whole_smoother_bit_for_bit() {
        let ins = inputs(7001);
        let product = RippleModel::<f64, 3>::product(1000.0, 0.05).unwrap();
        let whole = smooth(&product, &ins).unwrap();
        assert!(whole.filtered.iter().any(|o| o.flags.bits() != 0), "the run exercises resets and holds");
        for block in [1, 7, 1000, 4096, 7001, 10_000] {
            assert_eq!(blockwise(&product, &ins, block), whole, "block {block}");
        }
        let classic = RippleModel::<f32, 3>::taghirad_6th_order(1000.0).unwrap();
        let ins32 = single(&ins);
        assert_eq!(blockwise(&classic, &ins32, 333), smooth(&classic, &ins32).unwrap());
    }

    /// Checkpoints as snapshots in one flat buffer, as a scratch file keeps them.
    struct Flat<T: Real, const M: usize> {
        model: RippleModel<T, M>,
        values: Vec<f64>,
        /// Loads fail from this block on.
        lost_from: usize,
    }

    impl<T: Real, const M: usize> Flat<T, M> {
        fn new(model: &RippleModel<T, M>) -> Self {
            Self { model: *model, values: Vec::new(), lost_from: usize::MAX }
        }
    }

    impl<T: Real, const M: usize> CheckpointStore<T, M> for Flat<T, M> {
        fn save(&mut self, block: usize, state: &RippleState<T, M>) -> Result<(), String> {
            let n = RippleState::<T, M>::SNAPSHOT_LEN;
            assert_eq!(self.values.len(), block * n, "blocks are saved in order");
            self.values.resize((block + 1) * n, 0.0);
            state.snapshot(&mut self.values[block * n..]).map_err(|e| e.to_string())
        }

        fn load(&mut self, block: usize) -> Result<RippleState<T, M>, String> {
            if block >= self.lost_from {
                return Err("unreadable".into());
            }
            let n = RippleState::<T, M>::SNAPSHOT_LEN;
            let values = self.values.get(block * n..(block + 1) * n).ok_or("not saved")?;
            RippleState::from_snapshot(&self.model, values).map_err(|e| e.to_string())
        }
    }

    #[test]
    fn checkpoints_kept_as_snapshots_give_the_same_result() {
        let ins = inputs(7001);
        let product = RippleModel::<f64, 3>::product(1000.0, 0.05).unwrap();
        let whole = smooth(&product, &ins).unwrap();
        for block in [1, 1000, 4096] {
            assert_eq!(blockwise_in(&product, &ins, block, Flat::new(&product)), whole, "block {block}");
        }
        let full = RippleModel::<f32, 5>::full(1000.0, 0.05).unwrap();
        let ins32 = single(&ins);
        assert_eq!(blockwise_in(&full, &ins32, 333, Flat::new(&full)), smooth(&full, &ins32).unwrap());

        // A store that loses a block: the smoother says which, and stops.
        let mut s = CheckpointedSmoother::with_store(&product, 1000, Flat { lost_from: 2, ..Flat::new(&product) });
        for i in &ins[..2500] {
            s.push(i).unwrap();
        }
        let err = s.smooth_block(2, &ins[2000..2500]).unwrap_err();
        assert_eq!(err, SmootherError::Checkpoint { block: 2, message: "unreadable".into() });
        assert_eq!(err.to_string(), "checkpoint of block 2: unreadable");
    }

    #[test]
    fn without_the_state_sd_the_means_are_the_same() {
        let ins = inputs(3001);
        let product = RippleModel::<f64, 3>::product(1000.0, 0.05).unwrap();
        let whole = smooth(&product, &ins).unwrap();
        let mut s = CheckpointedSmoother::new(&product, 1000);
        for i in &ins {
            s.push(i).unwrap();
        }
        for b in (0..s.blocks()).rev() {
            let range = s.block_range(b);
            let part = s.smooth_block(b, &ins[range.clone()]).unwrap();
            for (p, w) in part.smoothed.iter().zip(&whole.smoothed[range]) {
                assert_eq!(
                    (p.torque_nm, p.ripple_nm, p.torque_state_nm),
                    (w.torque_nm, w.ripple_nm, w.torque_state_nm)
                );
                assert!(p.torque_state_sd_nm.is_nan() && w.torque_state_sd_nm > 0.0);
            }
        }
    }

    #[test]
    fn blocks_out_of_order_or_of_the_wrong_length_are_refused() {
        let ins = inputs(2500);
        let model = RippleModel::<f64, 2>::taghirad_4th_order(1000.0).unwrap();
        let mut s = CheckpointedSmoother::new(&model, 1000);
        assert!(s.is_empty() && s.blocks() == 0);
        assert!(matches!(s.smooth_block(0, &[]), Err(SmootherError::BlockMismatch { expected_block: usize::MAX, .. })));
        for i in &ins {
            s.push(i).unwrap();
        }
        assert_eq!((s.len(), s.blocks(), s.block_range(2)), (2500, 3, 2000..2500));
        let first = s.smooth_block(0, &ins[..1000]);
        assert!(matches!(first, Err(SmootherError::BlockMismatch { block: 0, expected_block: 2, .. })));
        let short = s.smooth_block(2, &ins[2000..2400]);
        assert!(matches!(short, Err(SmootherError::BlockMismatch { inputs: 400, expected_inputs: 500, .. })));
        assert!(s.smooth_block(2, &ins[2000..]).is_ok());
        assert!(s.smooth_block(1, &ins[1000..2000]).is_ok());
        assert!(s.smooth_block(0, &ins[..1000]).is_ok());
        assert!(s.smooth_block(0, &ins[..1000]).is_err(), "all blocks done");
        assert_eq!(s.push(&ins[0]), Err(SmootherError::PushAfterBackward));
    }
}
