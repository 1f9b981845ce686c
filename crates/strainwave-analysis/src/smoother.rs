//! Fixed-interval (Rauch–Tung–Striebel) smoother on the ripple canceller's model.
//!
//! The forward pass is the real-time filter of `strainwave_core::ripple` itself
//! ([`step_traced`]), so the model, the resets, holds and load steps are exactly the
//! ones the controller would see. The backward pass runs in the filter's rotating frame
//! (`x_i = Φ(ψ_i) z_i`), where the transition from sample `k` to `k+1` is `z ← D z`
//! with `D = diag(kept)` (1, or 0 where an oscillator was reset):
//!
//! ```text
//! ẑ(k|k)   = ẑ(k|k−1) + g e / S,          P(k|k) = P(k|k−1) − g gᵀ / S
//! A(k)     = P(k|k) Dᵀ P(k+1|k)⁻¹
//! ẑ(k|N)   = ẑ(k|k) + A(k) [ẑ(k+1|N) − ẑ(k+1|k)]
//! ```
//!
//! (a load-step sample is the limit `Var(b) → ∞`: its bias row of `P(k+1|k)⁻¹` is 0).
//! The smoothed order waveforms `Σ h(k) ẑ(k|N)` are zero-phase: what Vold–Kalman order
//! tracking gives in batch. Memory: one prior mean and covariance per sample,
//! `O(N n²)` for `n = 2M + 1` states (about 1.2 kB per sample for the product model);
//! [`CheckpointedSmoother`] gives the same result in memory bounded by a block.

use strainwave_core::ripple::{
    step_traced, RippleInput, RippleModel, RippleOutput, RippleState, RotatingGaussian, StepTrace,
};
use strainwave_core::Real;

mod checkpointed;
pub use checkpointed::{CheckpointStore, CheckpointedSmoother};

/// Why the smoother stopped.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SmootherError {
    /// The forward filter reported an error at this sample.
    #[error("ripple filter at sample {index}: {source}")]
    Filter {
        /// Sample index.
        index: usize,
        /// The core error.
        source: strainwave_core::Error,
    },
    /// A prior covariance could not be factored (not positive definite).
    #[error("prior covariance at sample {index} is not positive definite")]
    NotPositiveDefinite {
        /// Sample index.
        index: usize,
    },
    /// [`CheckpointedSmoother::smooth_block`] was given blocks out of order (the last
    /// first) or a block with another number of inputs than were pushed.
    #[error("block {block} with {inputs} inputs: expected block {expected_block} with {expected_inputs}")]
    BlockMismatch {
        /// The block given.
        block: usize,
        /// Its inputs given.
        inputs: usize,
        /// The block expected next (`usize::MAX` when all are done).
        expected_block: usize,
        /// Its number of samples.
        expected_inputs: usize,
    },
    /// [`CheckpointedSmoother::push`] after the backward pass began.
    #[error("sample pushed after the backward pass began")]
    PushAfterBackward,
    /// The [`CheckpointStore`] could not keep or give back a block's state.
    #[error("checkpoint of block {block}: {message}")]
    Checkpoint {
        /// The block.
        block: usize,
        /// What the store reported.
        message: String,
    },
}

/// One smoothed sample, zero-phase.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SmoothedSample<T: Real> {
    /// Clean torque `T_meas − ripple − misalignment`, N·m.
    pub torque_nm: T,
    /// Smoothed ripple (Relative- and Motor-referenced orders), N·m.
    pub ripple_nm: T,
    /// Smoothed misalignment (Output-referenced orders), N·m.
    pub misalignment_nm: T,
    /// Smoothed bias-state torque `T_exp + b̂(k|N)` (the clean torque without bias state), N·m.
    pub torque_state_nm: T,
}

/// Forward filter outputs and smoothed samples, one each per input sample.
#[derive(Debug, Clone, PartialEq)]
pub struct Smoothed<T: Real> {
    /// The real-time filter's outputs (predictions, no delay).
    pub filtered: Vec<RippleOutput<T>>,
    /// The fixed-interval smoothed estimates.
    pub smoothed: Vec<SmoothedSample<T>>,
}

/// What the backward pass keeps of one forward step (f64, dense, rotating frame).
#[derive(Clone)]
pub(crate) struct Record {
    prior_mean: Vec<f64>,
    prior_cov: Vec<f64>,
    post_mean: Vec<f64>,
    post_cov: Vec<f64>,
    kept: Vec<bool>,
    load_step: bool,
    /// `(cos ψ_i, sin ψ_i)` and whether the order is in the prediction.
    phasor: Vec<(f64, f64, bool)>,
}

/// The backward pass's copy of one traced step: the filter's own prior and posterior
/// (its measurement update, load-step limit included, is not re-derived here).
fn record<T: Real, const M: usize>(tr: &StepTrace<T, M>, n: usize) -> Record {
    let f = |x: T| x.to_f64();
    let mean = |g: &RotatingGaussian<T, M>| -> Vec<f64> { (0..n).map(|i| g.mean(i).map_or(0.0, f)).collect() };
    let cov = |g: &RotatingGaussian<T, M>| -> Vec<f64> {
        (0..n * n).map(|ij| g.cov(ij / n, ij % n).map_or(0.0, f)).collect()
    };
    let phasor = (0..M).map(|i| (f(tr.phasor[i][0]), f(tr.phasor[i][1]), tr.predicted[i])).collect();
    Record {
        prior_mean: mean(&tr.prior),
        prior_cov: cov(&tr.prior),
        post_mean: mean(&tr.posterior),
        post_cov: cov(&tr.posterior),
        kept: tr.kept.to_vec(),
        load_step: tr.load_step,
        phasor,
    }
}

/// Cholesky factor of the `n × n` row-major `a` with the rows/columns in `skip` taken
/// out (they are treated as having infinite variance: their solution entries are 0).
fn solve_spd(a: &[f64], n: usize, skip: Option<usize>, rhs: &[f64]) -> Option<Vec<f64>> {
    let idx: Vec<usize> = (0..n).filter(|&i| Some(i) != skip).collect();
    let m = idx.len();
    let mut l = vec![0.0; m * m];
    for i in 0..m {
        for j in 0..=i {
            let mut sum = a[idx[i] * n + idx[j]];
            for k in 0..j {
                sum -= l[i * m + k] * l[j * m + k];
            }
            if i == j {
                if !sum.is_finite() || sum <= 0.0 {
                    return None;
                }
                l[i * m + i] = sum.sqrt();
            } else {
                l[i * m + j] = sum / l[j * m + j];
            }
        }
    }
    let mut y: Vec<f64> = idx.iter().map(|&i| rhs[i]).collect();
    for i in 0..m {
        for k in 0..i {
            y[i] -= l[i * m + k] * y[k];
        }
        y[i] /= l[i * m + i];
    }
    for i in (0..m).rev() {
        for k in i + 1..m {
            y[i] -= l[k * m + i] * y[k];
        }
        y[i] /= l[i * m + i];
    }
    let mut out = vec![0.0; n];
    for (p, &i) in idx.iter().enumerate() {
        out[i] = y[p];
    }
    Some(out)
}

/// Runs the real-time filter over `inputs`, then the RTS backward pass on the same
/// model. Both outputs have one entry per input.
///
/// ```
/// use strainwave_analysis::smoother::smooth;
/// use strainwave_core::ripple::{ReferenceValues, RippleInput, RippleModel};
/// let model = RippleModel::<f64, 2>::seed_4th_order(1000.0).unwrap();
/// let inputs: Vec<_> = (0..2000)
///     .map(|k| {
///         let phi = 0.05 * k as f64;
///         // Seed model: y = T_meas − T_exp is the ripple alone.
///         RippleInput::new(3.0 + 0.5 * (2.0 * phi).cos(), ReferenceValues::new(phi, 0.0, 0.0))
///             .with_expected_torque(3.0)
///     })
///     .collect();
/// let out = smooth(&model, &inputs).unwrap();
/// assert_eq!(out.smoothed.len(), 2000);
/// assert!((out.smoothed[1000].torque_nm - 3.0).abs() < 0.05);
/// ```
pub fn smooth<T: Real, const M: usize>(
    model: &RippleModel<T, M>,
    inputs: &[RippleInput<T>],
) -> Result<Smoothed<T>, SmootherError> {
    let mut state = RippleState::new(model);
    let (filtered, records) = forward(model, &mut state, inputs, 0)?;
    let means = backward::<M>(model.state_len(), &records, None, 0)?;
    let smoothed = samples(model, inputs, &records, &means);
    Ok(Smoothed { filtered, smoothed })
}

/// The real-time filter from `state` over `inputs` (the first being sample `first`),
/// with what the backward pass keeps of each step.
pub(crate) fn forward<T: Real, const M: usize>(
    model: &RippleModel<T, M>,
    state: &mut RippleState<T, M>,
    inputs: &[RippleInput<T>],
    first: usize,
) -> Result<(Vec<RippleOutput<T>>, Vec<Record>), SmootherError> {
    let n = model.state_len();
    let mut trace = StepTrace::new();
    let mut filtered = Vec::with_capacity(inputs.len());
    let mut records = Vec::with_capacity(inputs.len());
    for (k, input) in inputs.iter().enumerate() {
        let out = step_traced(model, state, input, &mut trace)
            .map_err(|source| SmootherError::Filter { index: first + k, source })?;
        filtered.push(out);
        records.push(record(&trace, n));
    }
    Ok((filtered, records))
}

/// The smoothed means `ẑ(k|N)` of `records` (the first being sample `first`), given the
/// record and smoothed mean of the sample after the last one (`None`: the last one is
/// the end of the recording).
pub(crate) fn backward<const M: usize>(
    n: usize,
    records: &[Record],
    after: Option<(&Record, &[f64])>,
    first: usize,
) -> Result<Vec<Vec<f64>>, SmootherError> {
    let bias = (n > 2 * M).then_some(2 * M);
    // ẑ(k|N) = ẑ(k|k) + P(k|k) Dᵀ P(k+1|k)⁻¹ [ẑ(k+1|N) − ẑ(k+1|k)].
    let step = |k: usize, cur: &Record, next: &Record, next_mean: &[f64]| -> Result<Vec<f64>, SmootherError> {
        let diff: Vec<f64> = (0..n).map(|i| next_mean[i] - next.prior_mean[i]).collect();
        let skip = if next.load_step { bias } else { None };
        let v = solve_spd(&next.prior_cov, n, skip, &diff)
            .ok_or(SmootherError::NotPositiveDefinite { index: first + k + 1 })?;
        // Dᵀ v: zero where the oscillator was reset entering k+1.
        let dv: Vec<f64> = (0..n).map(|i| if i < 2 * M && !next.kept[i / 2] { 0.0 } else { v[i] }).collect();
        Ok((0..n).map(|i| cur.post_mean[i] + (0..n).map(|j| cur.post_cov[i * n + j] * dv[j]).sum::<f64>()).collect())
    };
    let mut means = vec![Vec::new(); records.len()];
    let Some(last) = records.len().checked_sub(1) else {
        return Ok(means);
    };
    means[last] = match after {
        Some((next, next_mean)) => step(last, &records[last], next, next_mean)?,
        None => records[last].post_mean.clone(),
    };
    for k in (0..last).rev() {
        means[k] = step(k, &records[k], &records[k + 1], &means[k + 1])?;
    }
    Ok(means)
}

/// The smoothed outputs of `inputs` from their records and smoothed means.
pub(crate) fn samples<T: Real, const M: usize>(
    model: &RippleModel<T, M>,
    inputs: &[RippleInput<T>],
    records: &[Record],
    means: &[Vec<f64>],
) -> Vec<SmoothedSample<T>> {
    let bias = (model.state_len() > 2 * M).then_some(2 * M);
    inputs
        .iter()
        .zip(records)
        .zip(means)
        .map(|((input, rec), z)| {
            let (mut ripple, mut mis) = (0.0, 0.0);
            for (i, o) in model.orders().iter().enumerate() {
                let (c, s, on) = rec.phasor[i];
                if on {
                    let v = c * z[2 * i] + s * z[2 * i + 1];
                    if o.reference().is_ripple() {
                        ripple += v;
                    } else {
                        mis += v;
                    }
                }
            }
            let torque = input.torque_nm.to_f64() - ripple - mis;
            let state_torque = bias.map_or(torque, |b| input.expected_torque_nm.to_f64() + z[b]);
            SmoothedSample {
                torque_nm: T::from_f64(torque),
                ripple_nm: T::from_f64(ripple),
                misalignment_nm: T::from_f64(mis),
                torque_state_nm: T::from_f64(state_torque),
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use strainwave_core::ripple::ReferenceValues;

    /// The smoother's ripple error must be below this fraction of the filter's.
    const GAIN_OVER_FILTER: f64 = 0.7;

    fn rms(v: impl Iterator<Item = f64>) -> f64 {
        let (s, n) = v.fold((0.0, 0usize), |(s, n), x| (s + x * x, n + 1));
        (s / n.max(1) as f64).sqrt()
    }

    /// Ripple whose amplitude follows the load (ramps and a step), misalignment, noise.
    /// (load, ripple, misalignment) of one sample.
    type Truth = (f64, f64, f64);

    fn synthetic(n: usize) -> (Vec<RippleInput<f64>>, Vec<Truth>) {
        let mut seed = 12345u64;
        let mut noise = move || {
            seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            ((seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 0.05 * 12f64.sqrt()
        };
        let mut inputs = Vec::with_capacity(n);
        let mut truth = Vec::with_capacity(n);
        for k in 0..n {
            let t = k as f64 / 1000.0;
            let motor = 150.0 * t;
            let out = -motor / 100.0;
            let rel = motor - out;
            let load = 5.0 + 40.0 * ((t - 20.0) / 5.0).clamp(0.0, 1.0) - if t > 35.0 { 30.0 } else { 0.0 };
            let ripple = (0.5 + 0.01 * load) * (2.0 * rel + 0.3).cos() + (0.2 + 0.004 * load) * (4.0 * rel - 1.1).cos();
            let mis = (out + 0.7).cos();
            let refs =
                ReferenceValues::new(rel.rem_euclid(std::f64::consts::TAU), out.rem_euclid(std::f64::consts::TAU), 0.0);
            inputs.push(RippleInput::new(load + ripple + mis + noise(), refs));
            truth.push((load, ripple, mis));
        }
        (inputs, truth)
    }

    #[test]
    fn smoother_beats_the_forward_filter() {
        let (inputs, truth) = synthetic(50_000);
        let model = RippleModel::<f64, 3>::product(1000.0, 0.05).unwrap();
        let out = smooth(&model, &inputs).unwrap();
        let from = 15_000;
        let filt = rms(out.filtered[from..].iter().zip(&truth[from..]).map(|(o, t)| o.ripple_nm - t.1));
        let smo = rms(out.smoothed[from..].iter().zip(&truth[from..]).map(|(o, t)| o.ripple_nm - t.1));
        assert!(smo < GAIN_OVER_FILTER * filt, "ripple RMS error: smoothed {smo} vs filtered {filt}");
        let filt_t = rms(out.filtered[from..].iter().zip(&truth[from..]).map(|(o, t)| o.torque_nm - t.0));
        let smo_t = rms(out.smoothed[from..].iter().zip(&truth[from..]).map(|(o, t)| o.torque_nm - t.0));
        assert!(smo_t <= filt_t, "clean torque RMS error: smoothed {smo_t} vs filtered {filt_t}");
    }

    #[test]
    fn smoothed_waveform_is_zero_phase() {
        // A pure 2× ripple of growing amplitude: the smoothed estimate has no lag, so its
        // error is not correlated with the amplitude's rate of change.
        let model = RippleModel::<f64, 2>::seed_4th_order(1000.0).unwrap();
        let inputs: Vec<_> = (0..20_000)
            .map(|k| {
                let phi = 0.05 * k as f64;
                let amp = 0.5 + 0.5 * (k as f64 / 20_000.0);
                RippleInput::new(amp * (2.0 * phi).cos(), ReferenceValues::new(phi, 0.0, 0.0))
            })
            .collect();
        let out = smooth(&model, &inputs).unwrap();
        let err = |pick: &dyn Fn(usize) -> f64| {
            rms((5_000..15_000).map(|k| pick(k) - (0.5 + 0.5 * (k as f64 / 20_000.0)) * (2.0 * 0.05 * k as f64).cos()))
        };
        let smo = err(&|k| out.smoothed[k].ripple_nm);
        let filt = err(&|k| out.filtered[k].ripple_nm);
        assert!(smo < 0.5 * filt, "smoothed {smo} vs filtered {filt}");
    }

    #[test]
    fn works_in_f32_and_reports_filter_errors() {
        let model = RippleModel::<f32, 2>::seed_4th_order(1000.0).unwrap();
        let inputs: Vec<_> =
            (0..500).map(|k| RippleInput::new(1.0f32, ReferenceValues::new(0.05 * k as f32, 0.0, 0.0))).collect();
        assert_eq!(smooth(&model, &inputs).unwrap().smoothed.len(), 500);
        let bad = RippleModel::<f32, 2>::seed_4th_order(1000.0).unwrap().with_initial_variance(f32::MAX, 1.0).unwrap();
        assert!(matches!(smooth(&bad, &inputs), Err(SmootherError::Filter { index: 0, .. })));
        assert!(smooth(&model, &[]).unwrap().smoothed.is_empty());
    }
}
