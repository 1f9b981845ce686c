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
mod spd;
pub mod torque;
pub mod torque_ripple;
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
    /// Smoothed torque state `T_exp + b̂(k|N)`: the transmitted torque with the sensor's
    /// white noise averaged out (zero phase), steps the filter detected kept sharp; the
    /// clean torque `torque_nm` when the model has no bias state. N·m.
    pub torque_state_nm: T,
    /// Its standard deviation `√P_bb(k|N)`, N·m (0 without the bias state; NaN from a
    /// [`CheckpointedSmoother`] not asked for it, see
    /// [`with_torque_state_sd`](CheckpointedSmoother::with_torque_state_sd)).
    pub torque_state_sd_nm: T,
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

/// Cholesky factor `L` (row-major `m × m`) of the `n × n` row-major `a` restricted to
/// the indices `idx`; `None` when that part is not positive definite.
fn cholesky(a: &[f64], n: usize, idx: &[usize]) -> Option<Vec<f64>> {
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
    Some(l)
}

/// Solves `L Lᵀ y = rhs` (restricted to `idx`) in place of `y`; the other entries are 0.
fn cholesky_solve(l: &[f64], idx: &[usize], rhs: &[f64], out: &mut [f64]) {
    let m = idx.len();
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
    out.iter_mut().for_each(|v| *v = 0.0);
    for (p, &i) in idx.iter().enumerate() {
        out[i] = y[p];
    }
}

/// One backward step's smoothed mean and covariance of sample `k` (record `cur`), given
/// the record `next` of sample `k + 1` and its smoothed mean and covariance:
///
/// ```text
/// A(k)   = P(k|k) Dᵀ P(k+1|k)⁻¹
/// ẑ(k|N) = ẑ(k|k) + A(k) [ẑ(k+1|N) − ẑ(k+1|k)]
/// P(k|N) = P(k|k) + A(k) [P(k+1|N) − P(k+1|k)] A(k)ᵀ
/// ```
///
/// At a load step entering `k + 1` the bias row and column of `P(k+1|k)⁻¹` are 0
/// (`Var(b) → ∞`): nothing of the bias after the step reaches the bias before it, so the
/// step stays sharp. `None`: `P(k+1|k)` is not positive definite.
pub(crate) fn rts_step<const M: usize>(
    n: usize,
    cur: &Record,
    next: &Record,
    next_mean: &[f64],
    next_cov: Option<&[f64]>,
) -> Option<(Vec<f64>, Option<Vec<f64>>)> {
    let bias = (n > 2 * M).then_some(2 * M);
    let skip = if next.load_step { bias } else { None };
    let idx: Vec<usize> = (0..n).filter(|&i| Some(i) != skip).collect();
    let l = cholesky(&next.prior_cov, n, &idx)?;
    let kept = |i: usize| i >= 2 * M || next.kept[i / 2];
    // Mean: P(k|k) Dᵀ v with v = P(k+1|k)⁻¹ [ẑ(k+1|N) − ẑ(k+1|k)] (one solve).
    let diff: Vec<f64> = (0..n).map(|i| next_mean[i] - next.prior_mean[i]).collect();
    let mut v = vec![0.0; n];
    cholesky_solve(&l, &idx, &diff, &mut v);
    let dv: Vec<f64> = (0..n).map(|i| if kept(i) { v[i] } else { 0.0 }).collect();
    let mean: Vec<f64> =
        (0..n).map(|i| cur.post_mean[i] + (0..n).map(|j| cur.post_cov[i * n + j] * dv[j]).sum::<f64>()).collect();
    let Some(next_cov) = next_cov else { return Some((mean, None)) };
    // Aᵀ = P(k+1|k)⁻¹ D P(k|k): column j solves against D P(k|k)'s column j.
    let mut at = vec![0.0; n * n];
    let (mut col, mut sol) = (vec![0.0; n], vec![0.0; n]);
    for j in 0..n {
        for (i, c) in col.iter_mut().enumerate() {
            *c = if kept(i) { cur.post_cov[i * n + j] } else { 0.0 };
        }
        cholesky_solve(&l, &idx, &col, &mut sol);
        for (i, v) in sol.iter().enumerate() {
            at[i * n + j] = *v;
        }
    }
    // A(i, j) = at(j, i).
    let a = |i: usize, j: usize| at[j * n + i];
    // ΔP = P(k+1|N) − P(k+1|k); P(k|N) = P(k|k) + A ΔP Aᵀ.
    let dp: Vec<f64> = (0..n * n).map(|ij| next_cov[ij] - next.prior_cov[ij]).collect();
    let mut adp = vec![0.0; n * n];
    for i in 0..n {
        for j in 0..n {
            adp[i * n + j] = (0..n).map(|m| a(i, m) * dp[m * n + j]).sum();
        }
    }
    let mut cov = cur.post_cov.clone();
    for i in 0..n {
        for j in 0..=i {
            let v: f64 = (0..n).map(|m| adp[i * n + m] * a(j, m)).sum();
            cov[i * n + j] += v;
            if i != j {
                cov[j * n + i] = cov[i * n + j];
            }
        }
    }
    Some((mean, Some(cov)))
}

/// Runs the real-time filter over `inputs`, then the RTS backward pass on the same
/// model. Both outputs have one entry per input.
///
/// ```
/// use strainwave_analysis::smoother::smooth;
/// use strainwave_core::ripple::{ReferenceValues, RippleInput, RippleModel};
/// let model = RippleModel::<f64, 2>::taghirad_4th_order(1000.0).unwrap();
/// let inputs: Vec<_> = (0..2000)
///     .map(|k| {
///         let phi = 0.05 * k as f64;
///         // Paper's model: y = T_meas − T_exp is the ripple alone.
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
    smooth_with(model, inputs, true)
}

/// [`smooth`], with the smoothed covariance (`torque_state_sd_nm`) or without it (NaN;
/// the rest is the same, and the backward pass much cheaper).
pub(crate) fn smooth_with<T: Real, const M: usize>(
    model: &RippleModel<T, M>,
    inputs: &[RippleInput<T>],
    state_sd: bool,
) -> Result<Smoothed<T>, SmootherError> {
    let mut state = RippleState::new(model);
    let (filtered, records) = forward(model, &mut state, inputs, 0)?;
    let back = backward::<M>(model.state_len(), &records, None, 0, state_sd)?;
    let smoothed = samples(model, inputs, &records, &back);
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

/// What the backward pass gives for a run of records: per sample, the smoothed mean
/// `ẑ(k|N)` and the bias variance `P_bb(k|N)` (0 without the bias state, NaN when the
/// covariance was not asked for); and the smoothed covariance of the first sample,
/// which the block before it needs.
pub(crate) struct Backward {
    pub(crate) means: Vec<Vec<f64>>,
    pub(crate) bias_var: Vec<f64>,
    pub(crate) first_cov: Option<Vec<f64>>,
}

/// The sample after a run of records: its record, smoothed mean and (if carried)
/// smoothed covariance.
pub(crate) type After<'a> = (&'a Record, &'a [f64], Option<&'a [f64]>);

/// The backward pass over `records` (the first being sample `first`), given the record,
/// smoothed mean and covariance of the sample after the last one (`None`: the last one
/// is the end of the recording). `with_cov`: also the smoothed covariance (`n` more
/// solves and two `n³` products per sample).
pub(crate) fn backward<const M: usize>(
    n: usize,
    records: &[Record],
    after: Option<After<'_>>,
    first: usize,
    with_cov: bool,
) -> Result<Backward, SmootherError> {
    let bias = (n > 2 * M).then_some(2 * M);
    let mut out =
        Backward { means: vec![Vec::new(); records.len()], bias_var: vec![f64::NAN; records.len()], first_cov: None };
    let Some(last) = records.len().checked_sub(1) else {
        return Ok(out);
    };
    let fail = |k: usize| SmootherError::NotPositiveDefinite { index: first + k + 1 };
    let (mut mean, mut cov) = match after {
        Some((next, next_mean, next_cov)) => {
            let next_cov = next_cov.filter(|_| with_cov);
            rts_step::<M>(n, &records[last], next, next_mean, next_cov).ok_or(fail(last))?
        }
        None => (records[last].post_mean.clone(), with_cov.then(|| records[last].post_cov.clone())),
    };
    for k in (0..=last).rev() {
        if k < last {
            (mean, cov) =
                rts_step::<M>(n, &records[k], &records[k + 1], &out.means[k + 1], cov.as_deref()).ok_or(fail(k))?;
        }
        if let Some(c) = &cov {
            out.bias_var[k] = bias.map_or(0.0, |b| c[b * n + b].max(0.0));
        }
        out.means[k] = core::mem::take(&mut mean);
    }
    out.first_cov = cov;
    Ok(out)
}

/// The smoothed outputs of `inputs` from their records and smoothed means.
pub(crate) fn samples<T: Real, const M: usize>(
    model: &RippleModel<T, M>,
    inputs: &[RippleInput<T>],
    records: &[Record],
    back: &Backward,
) -> Vec<SmoothedSample<T>> {
    let bias = (model.state_len() > 2 * M).then_some(2 * M);
    inputs
        .iter()
        .zip(records)
        .zip(back.means.iter().zip(&back.bias_var))
        .map(|((input, rec), (z, bias_var))| {
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
                torque_state_sd_nm: T::from_f64(bias_var.sqrt()),
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
        let model = RippleModel::<f64, 2>::taghirad_4th_order(1000.0).unwrap();
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

    /// A model that is exactly the truth (a constant 2× ripple, a random-walk torque,
    /// white noise): the smoothed torque state's error matches its σ, covers the truth
    /// 68 % of the time, and is well below the noise.
    #[test]
    fn smoothed_torque_state_sd_is_honest_when_the_model_is_right() {
        use strainwave_core::ripple::{Order, Reference};
        let (r_nm2, q_nm2) = (0.01, 1e-4);
        let order = Order::new(Reference::Relative, 2.0).unwrap();
        let model = RippleModel::<f64, 1>::new([order], r_nm2.sqrt(), 1000.0).unwrap().with_bias_state(q_nm2).unwrap();
        let mut seed = 99u64;
        let mut uniform = move || {
            seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            ((seed >> 11) as f64 + 0.5) / (1u64 << 53) as f64
        };
        let mut gauss = move || (-2.0 * uniform().ln()).sqrt() * (std::f64::consts::TAU * uniform()).cos();
        let (n, mut b) = (40_000, 3.0);
        let (mut inputs, mut truth) = (Vec::with_capacity(n), Vec::with_capacity(n));
        for k in 0..n {
            let phi = 0.07 * k as f64;
            let y = b + 0.4 * (2.0 * phi + 0.3).cos() + r_nm2.sqrt() * gauss();
            inputs.push(RippleInput::new(y, ReferenceValues::new(phi.rem_euclid(std::f64::consts::TAU), 0.0, 0.0)));
            truth.push(b);
            b += q_nm2.sqrt() * gauss();
        }
        let out = smooth(&model, &inputs).unwrap();
        let from = 2000;
        let s = &out.smoothed[from..];
        let err = rms(s.iter().zip(&truth[from..]).map(|(o, t)| o.torque_state_nm - t));
        let sd = (s.iter().map(|o| o.torque_state_sd_nm.powi(2)).sum::<f64>() / s.len() as f64).sqrt();
        let covered =
            s.iter().zip(&truth[from..]).filter(|(o, t)| (o.torque_state_nm - *t).abs() <= o.torque_state_sd_nm);
        let coverage = covered.count() as f64 / s.len() as f64;
        assert!((err / sd - 1.0).abs() < 0.05, "RMS error {err} vs σ {sd}");
        assert!((coverage - 0.683).abs() < 0.02, "coverage {coverage}");
        // Random walk q = 1e-4, r = 1e-2: the smoothed σ is about √(√(q r)/2) = 0.024.
        assert!(err < 0.3 * r_nm2.sqrt(), "RMS error {err} vs noise {}", r_nm2.sqrt());
        let filtered = rms(out.filtered[from..].iter().zip(&truth[from..]).map(|(o, t)| o.torque_state_nm - t));
        assert!(err < 0.8 * filtered, "smoothed {err} vs filtered state {filtered}");
    }

    /// A load step the filter detects is in the smoothed torque state at its sample: the
    /// backward pass does not carry the level after it to the samples before.
    #[test]
    fn detected_load_steps_stay_sharp() {
        let model = RippleModel::<f64, 3>::product(1000.0, 0.05).unwrap();
        let (n, k0) = (6000, 4000);
        let inputs: Vec<_> = (0..n)
            .map(|k| {
                let phi = 0.05 * k as f64;
                let load = if k >= k0 { 6.0 } else { 2.0 };
                let noise = 0.05 * (((k * 7919) % 23) as f64 / 11.0 - 1.0);
                let refs = ReferenceValues::new(phi.rem_euclid(std::f64::consts::TAU), 0.0, 0.0);
                RippleInput::new(load + 0.3 * (2.0 * phi).cos() + noise, refs)
            })
            .collect();
        let out = smooth(&model, &inputs).unwrap();
        assert!(out.filtered[k0].flags.contains(strainwave_core::ripple::StepFlags::LOAD_STEP));
        for k in k0 - 50..k0 {
            assert!((out.smoothed[k].torque_state_nm - 2.0).abs() < 0.1, "sample {k}: {:?}", out.smoothed[k]);
        }
        for k in k0..k0 + 50 {
            assert!((out.smoothed[k].torque_state_nm - 6.0).abs() < 0.1, "sample {k}: {:?}", out.smoothed[k]);
        }
    }

    #[test]
    fn works_in_f32_and_reports_filter_errors() {
        let model = RippleModel::<f32, 2>::taghirad_4th_order(1000.0).unwrap();
        let inputs: Vec<_> =
            (0..500).map(|k| RippleInput::new(1.0f32, ReferenceValues::new(0.05 * k as f32, 0.0, 0.0))).collect();
        assert_eq!(smooth(&model, &inputs).unwrap().smoothed.len(), 500);
        // A load that overflows the load-scaled orders' innovation variance (an expected
        // torque of 10³⁰ N·m, matched by the torque): the filter's error, at its index.
        let full = RippleModel::<f32, 5>::full(1000.0, 0.01).unwrap();
        let mut bad: Vec<_> = (0..500)
            .map(|k| RippleInput::new(1.0f32, ReferenceValues::new(0.05 * k as f32, 0.0, 0.05 * k as f32)))
            .collect();
        bad[2] = bad[2].with_expected_torque(1e30);
        bad[2].torque_nm = 1e30;
        let e = smooth(&full, &bad).map(|_| ()).unwrap_err();
        assert!(matches!(e, SmootherError::Filter { index: 2, .. }), "{e:?}");
        assert!(smooth(&model, &[]).unwrap().smoothed.is_empty());
    }
}
