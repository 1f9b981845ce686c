//! The single-joint canceller: [`RippleState`], [`step`] and the traced step that the
//! offline smoother builds on.

use super::bank::{BankInput, BankOutput, RippleBank};
use super::io::{OrderStatus, ReferenceValues, RippleInput, RippleOutput, StepFlags};
use super::kernel::run;
use super::model::RippleModel;
use super::trace::StepTrace;
use crate::{Error, Real};

/// The state of one joint's canceller: estimate, covariance, phases, last angles.
/// The model is separate: see [`RippleModel`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RippleState<T: Real, const M: usize> {
    pub(super) bank: RippleBank<T, M, 1>,
}

impl<T: Real, const M: usize> RippleState<T, M> {
    /// The initial state of `model`: `x̂ = 0`, `P = diag(p0)`, no last angle.
    ///
    /// ```
    /// use strainwave_core::ripple::{RippleModel, RippleState};
    /// let model = RippleModel::<f64, 2>::taghirad_4th_order(1000.0).unwrap();
    /// let state = RippleState::new(&model);
    /// assert_eq!(state.estimate(&model, 0), Some(0.0));
    /// assert_eq!(state.covariance(&model, 1, 1), Some(1.0));
    /// ```
    pub fn new(model: &RippleModel<T, M>) -> Self {
        Self { bank: RippleBank::new(model) }
    }

    /// Back to the initial state.
    pub fn reset(&mut self, model: &RippleModel<T, M>) {
        self.bank.reset(model);
    }

    /// Element `index` of the posterior `x̂(k|k)` in the fixed frame (`x_{i,0}` at `2i`,
    /// `x_{i,1}` at `2i+1`, bias at `2M`).
    pub fn estimate(&self, model: &RippleModel<T, M>, index: usize) -> Option<T> {
        self.bank.estimate(model, 0, index)
    }

    /// Element `(row, col)` of the posterior covariance `P(k|k)` in the fixed frame.
    pub fn covariance(&self, model: &RippleModel<T, M>, row: usize, col: usize) -> Option<T> {
        self.bank.covariance(model, 0, row, col)
    }

    /// What order `order` has learned: its rotating-frame coefficients `[z₀, z₁]` (the
    /// contribution is `z₀ cos ψ + z₁ sin ψ`, times `|T̂|` for a load-scaled order) and
    /// the larger of their variances. Feed them back with [`RippleModel::with_priors`] so
    /// the next run starts where this one ended (see [`Order::with_prior`](super::Order::with_prior)).
    ///
    /// ```
    /// use strainwave_core::ripple::{RippleModel, RippleState};
    /// let model = RippleModel::<f64, 2>::taghirad_4th_order(1000.0).unwrap();
    /// let state = RippleState::new(&model);
    /// assert_eq!(state.learned(1), Some(([0.0, 0.0], 1.0)));
    /// assert_eq!(state.learned(2), None);
    /// ```
    pub fn learned(&self, order: usize) -> Option<([T; 2], T)> {
        let z = self.bank.z.get(order)?;
        let d = self.bank.p.get(order)?.get(order)?;
        Some(([z[0][0], z[1][0]], d[0][0][0].max(d[1][1][0])))
    }

    /// [`Self::learned`] for every order.
    pub fn learned_all(&self) -> [([T; 2], T); M] {
        core::array::from_fn(|i| self.learned(i).unwrap_or(([T::ZERO; 2], T::ONE)))
    }

    /// Status of order `order` after the last step.
    pub fn order_status(&self, order: usize) -> Option<OrderStatus> {
        self.bank.order_status(0, order)
    }

    /// Steps taken (skipped samples included; counts modulo 2⁶⁴).
    pub fn steps(&self) -> u64 {
        self.bank.steps(0).unwrap_or(0)
    }

    /// The last accepted reference values.
    pub fn last_references(&self) -> Option<ReferenceValues<T>> {
        self.bank.last_references(0)
    }
}

/// One sample: predicts the ripple and misalignment of sample `k` from `x̂(k|k−1)`,
/// outputs the clean torque, then updates with `y(k) = T_meas − T_exp`.
///
/// ```text
/// clean torque   T̂(k) = T_meas(k) − C_osc x̂(k|k−1)      (no added delay)
/// innovation     e(k) = y(k) − C x̂(k|k−1),   S = R + C P Cᵀ,   NIS = e² / S
/// ```
///
/// Returns `Err(Error::NotPositiveDefinite("ripple covariance"))` if the covariance
/// went bad; the state has then been reset to the initial one and the next sample
/// starts over. Never panics, whatever the input.
///
/// ```
/// use strainwave_core::ripple::{step, ReferenceValues, RippleInput, RippleModel, RippleState};
/// let model = RippleModel::<f64, 2>::taghirad_4th_order(1000.0)?;
/// let mut state = RippleState::new(&model);
/// let (w, load) = (0.05, 2.0); // relative angle per sample, N·m
/// let mut last = 0.0;
/// for k in 0..5000 {
///     let phi = w * k as f64;
///     let ripple = 0.5 * (2.0 * phi).cos() + 0.2 * (4.0 * phi + 1.0).cos();
///     let out = step(&model, &mut state, &RippleInput::new(load + ripple, ReferenceValues::new(phi, 0.0, 0.0)))?;
///     last = out.torque_nm;
/// }
/// assert!((last - load).abs() < 0.05);
/// # Ok::<(), strainwave_core::Error>(())
/// ```
pub fn step<T: Real, const M: usize>(
    model: &RippleModel<T, M>,
    state: &mut RippleState<T, M>,
    input: &RippleInput<T>,
) -> Result<RippleOutput<T>, Error> {
    let mut out = BankOutput::default();
    run::<T, M, 1, false>(model, &mut state.bank, &one_joint(input), &mut out, None);
    result(out)
}

/// [`step`] that also records the filter's intermediate quantities in `trace`
/// (for smoothers, golden data and tests). The step itself is [`step`]'s, bit for bit.
///
/// ```
/// use strainwave_core::ripple::{step_traced, ReferenceValues, RippleInput, RippleModel, RippleState, StepTrace};
/// let model = RippleModel::<f64, 3>::taghirad_6th_order(1000.0)?;
/// let mut state = RippleState::new(&model);
/// let mut trace = StepTrace::new();
/// step_traced(&model, &mut state, &RippleInput::new(1.0, ReferenceValues::new(0.0, 0.0, 0.0)), &mut trace)?;
/// assert_eq!(trace.measurement_nm, 1.0);
/// # Ok::<(), strainwave_core::Error>(())
/// ```
pub fn step_traced<T: Real, const M: usize>(
    model: &RippleModel<T, M>,
    state: &mut RippleState<T, M>,
    input: &RippleInput<T>,
    trace: &mut StepTrace<T, M>,
) -> Result<RippleOutput<T>, Error> {
    let mut out = BankOutput::default();
    run::<T, M, 1, true>(model, &mut state.bank, &one_joint(input), &mut out, Some(trace));
    result(out)
}

/// `input` as a bank input of one joint.
#[inline(always)]
fn one_joint<T: Real>(input: &RippleInput<T>) -> BankInput<T, 1> {
    let r = &input.references;
    BankInput {
        torque_nm: [input.torque_nm],
        expected_torque_nm: [input.expected_torque_nm],
        references: ReferenceValues::new([r.relative], [r.output], [r.motor]),
        dt_s: input.dt_s,
    }
}

/// The one joint's output, or the error of a covariance reset.
#[inline(always)]
fn result<T: Real>(out: BankOutput<T, 1>) -> Result<RippleOutput<T>, Error> {
    if out.flags[0].contains(StepFlags::COVARIANCE_RESET) {
        return Err(Error::NotPositiveDefinite("ripple covariance"));
    }
    Ok(out.into())
}
