//! The single-joint canceller: [`RippleState`], [`step`] and the traced step that the
//! offline smoother builds on.

use super::bank::{BankInput, BankOutput, RippleBank};
use super::io::{OrderStatus, ReferenceValues, RippleInput, RippleOutput, StepFlags};
use super::kernel::run;
use super::model::RippleModel;
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

/// Mean and covariance of the rotating-frame state `[z_1, …, z_M, b]` (length `2M+1`;
/// the bias entries are 0 for a model without bias state).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RotatingGaussian<T: Real, const M: usize> {
    /// Oscillator means `z_i`.
    pub z: [[T; 2]; M],
    /// Bias mean.
    pub bias: T,
    /// Full (both triangles) oscillator covariance blocks `Cov(z_i, z_j)`.
    pub p: [[[[T; 2]; 2]; M]; M],
    /// `Cov(z_i, b)`.
    pub pb: [[T; 2]; M],
    /// `Var(b)`.
    pub pbb: T,
}

impl<T: Real, const M: usize> RotatingGaussian<T, M> {
    /// All zeros.
    ///
    /// ```
    /// let g = strainwave_core::ripple::RotatingGaussian::<f64, 2>::zeros();
    /// assert_eq!((g.mean(4), g.cov(4, 4), g.mean(5)), (Some(0.0), Some(0.0), None));
    /// ```
    pub fn zeros() -> Self {
        Self {
            z: [[T::ZERO; 2]; M],
            bias: T::ZERO,
            p: [[[[T::ZERO; 2]; 2]; M]; M],
            pb: [[T::ZERO; 2]; M],
            pbb: T::ZERO,
        }
    }

    /// Mean element `index` (`2i + r`, bias at `2M`).
    pub fn mean(&self, index: usize) -> Option<T> {
        if index == 2 * M {
            return Some(self.bias);
        }
        self.z.get(index / 2).map(|z| z[index % 2])
    }

    /// Covariance element `(row, col)`.
    pub fn cov(&self, row: usize, col: usize) -> Option<T> {
        let bias = 2 * M;
        match (row == bias, col == bias) {
            (true, true) => Some(self.pbb),
            (true, false) => self.pb.get(col / 2).map(|v| v[col % 2]),
            (false, true) => self.pb.get(row / 2).map(|v| v[row % 2]),
            (false, false) => self.p.get(row / 2).and_then(|b| b.get(col / 2)).map(|blk| blk[row % 2][col % 2]),
        }
    }
}

/// What one traced step did, in the rotating frame (see [`step_traced`]).
///
/// The time update from `k−1` to `k` was `ẑ(k|k−1) = D ẑ(k−1|k−1)` with
/// `D = diag(kept)` and `P(k|k−1)` = the decoupled `P(k−1|k−1)` + `Q`; the update was
/// `ẑ(k|k) = ẑ(k|k−1) + g e / S`, `P(k|k) = P(k|k−1) − g gᵀ / S`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepTrace<T: Real, const M: usize> {
    /// Applied phase increments `a_i = n_i Δθ`, rad (0 for reset or off orders).
    pub increment_rad: [T; M],
    /// Process noise added to each oscillator component, N·m².
    pub q_nm2: [T; M],
    /// Process noise added to the bias, N·m².
    pub q_bias_nm2: T,
    /// `false` where the oscillator was reset to its prior this step.
    pub kept: [bool; M],
    /// Whether the bias variance was reinflated (time gap).
    pub bias_reinflated: bool,
    /// Whether this sample was a load step: the update was the limit `Var(b) → ∞`
    /// (bias takes the innovation, oscillators untouched).
    pub load_step: bool,
    /// Whether each order entered the prediction `ŷ`.
    pub predicted: [bool; M],
    /// `(cos ψ_i, sin ψ_i)` at sample `k`.
    pub phasor: [[T; 2]; M],
    /// `ẑ(k|k−1)`, `P(k|k−1)`.
    pub prior: RotatingGaussian<T, M>,
    /// `ẑ(k|k)`, `P(k|k)`: the filter's own measurement update (with its variance
    /// floor and, on a load step, the limit `Var(b) → ∞`), before any health reset.
    pub posterior: RotatingGaussian<T, M>,
    /// Measurement row `h` over the oscillators (zero where not updated).
    pub update_row: [[T; 2]; M],
    /// Measurement row entry of the bias (1 or 0).
    pub update_row_bias: T,
    /// `g = P(k|k−1) hᵀ` over the oscillators.
    pub gain_numerator: [[T; 2]; M],
    /// `g` entry of the bias.
    pub gain_numerator_bias: T,
    /// `S = R + h g`, N·m².
    pub innovation_variance_nm2: T,
    /// Innovation used in the update (0 when the update was skipped), N·m.
    pub innovation_used_nm: T,
    /// `y = T_meas − T_exp`, N·m.
    pub measurement_nm: T,
}

impl<T: Real, const M: usize> Default for StepTrace<T, M> {
    fn default() -> Self {
        Self::new()
    }
}

impl<T: Real, const M: usize> StepTrace<T, M> {
    /// An empty trace to pass to [`step_traced`].
    ///
    /// ```
    /// let t = strainwave_core::ripple::StepTrace::<f32, 2>::new();
    /// assert_eq!(t.kept, [true; 2]);
    /// ```
    pub fn new() -> Self {
        Self {
            increment_rad: [T::ZERO; M],
            q_nm2: [T::ZERO; M],
            q_bias_nm2: T::ZERO,
            kept: [true; M],
            bias_reinflated: false,
            load_step: false,
            predicted: [true; M],
            phasor: [[T::ZERO; 2]; M],
            prior: RotatingGaussian::zeros(),
            posterior: RotatingGaussian::zeros(),
            update_row: [[T::ZERO; 2]; M],
            update_row_bias: T::ZERO,
            gain_numerator: [[T::ZERO; 2]; M],
            gain_numerator_bias: T::ZERO,
            innovation_variance_nm2: T::ZERO,
            innovation_used_nm: T::ZERO,
            measurement_nm: T::ZERO,
        }
    }
}
