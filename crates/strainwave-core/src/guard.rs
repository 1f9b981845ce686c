//! Do no harm: a guard around the ripple canceller that applies an order's correction
//! only while the data support it, so that the cleaned torque is not made worse than
//! the raw one by a model that has not learned yet, has learned load, or does not fit.
//!
//! The canceller ([`crate::ripple`]) runs underneath unchanged and keeps learning; the
//! guard decides, per sample and per order, whether that order's predicted
//! contribution `c_i(k) = h_i(k) ẑ_i(k|k−1)` is subtracted:
//!
//! ```text
//! T̂(k) = T_meas(k) − Σ_{i applied at k} clamp(c_i(k))          (no added delay)
//! ```
//!
//! An order is applied while all of these hold (every test uses data up to `k−1`):
//!
//! - **evidence**: its amplitude is significant against its uncertainty,
//!   `χ²_i = ẑ_iᵀ P_ii⁻¹ ẑ_i` above [`GuardSettings::apply_chi2`] (2 degrees of freedom;
//!   it stops below [`GuardSettings::release_chi2`]). An estimate within a few σ of zero
//!   could add as much error as it removes. And it is steady: a periodic line has a
//!   constant estimate in the rotating frame, so one that wanders by more than
//!   [`GuardSettings::apply_wander`] of its amplitude is fitting load instead;
//! - **travel**: its line has turned through [`GuardSettings::min_cycles`] full cycles
//!   (all eight octants of its phase, each time), [`GuardSettings::min_cycles_output`] for
//!   output-angle orders, whose slow line is otherwise indistinguishable from load. A
//!   learned prior ([`GuardSettings::learned_prior`]) already carries that evidence;
//! - **health of the order**: removing it would not fit the data better. With `e` the
//!   innovation, running means of `e²` and `(e + c_i)²` are compared: for a line above
//!   the bias bandwidth `E(e + c_i)² − E e² ≈ E r_i² − E δ_i²` (true ripple `r_i`, error
//!   `δ_i`), so the order is stepped back exactly when applying it would hurt;
//! - **health of the model**: the running mean of the NIS (`χ²(1)`, mean 1 when the
//!   model is right) is below [`GuardSettings::nis_pass_through`]; above it every order
//!   steps back to pass-through (output = raw) until the mean falls below
//!   [`GuardSettings::nis_recover`]. In the first window of motion, before the model has a
//!   track record, a sample with NIS above [`GROSS_NIS`] passes the raw torque, and two in
//!   a row with innovations of one sign step the model back at once.
//!
//! At a standstill (order held) the contribution is clamped to the amplitude the order
//! had at its last moving sample (zero if it never moved), so what the filter removes
//! there is bounded by what it learned while moving. While the angles stand exactly still
//! no order is applied unless the torque is as steady as the model says (its running mean
//! NIS): where it ripples, the encoders are frozen on a turning joint, and a correction at
//! their stale phase would be worse than none.
//!
//! A load step (an innovation beyond the canceller's limit) that is a glitch puts the load
//! `|T_exp + b̂|` that scales the load-scaled orders far off: a jump of the expected torque
//! by more than the load (the glitch, and its undoing), or the bias that took a glitch of
//! the torque and gives it back (the load steps in a row from the one that undoes it).
//! Those orders are not applied there, and their statistics not updated. A real step's
//! innovations keep their sign while the bias takes it, and the orders stay applied.
//!
//! ```
//! use strainwave_core::guard::{Guard, GuardSettings};
//! use strainwave_core::ripple::{ReferenceValues, RippleInput, RippleModel};
//! let model = RippleModel::<f64, 3>::product(1000.0, 0.02)?;
//! let mut guard = Guard::new(&model, GuardSettings::default());
//! let (w, load) = (0.05, 2.0); // relative angle per sample, N·m
//! let mut out = None;
//! for k in 0..5000 {
//!     let phi = w * k as f64;
//!     let ripple = 0.5 * (2.0 * phi).cos();
//!     let refs = ReferenceValues::new(phi, phi / 100.0, phi);
//!     out = Some(guard.step(&model, &RippleInput::new(load + ripple, refs))?);
//! }
//! let out = out.unwrap();
//! // The 2× order is applied, the misalignment (output 1×, not one turn yet) is not.
//! assert!(out.applied[0] && !out.applied[2]);
//! assert!((out.output.torque_nm - load).abs() < 0.1);
//! # Ok::<(), strainwave_core::Error>(())
//! ```

mod order;
mod stats;

use crate::ripple::{
    step_traced, OrderStatus, Reference, RippleInput, RippleModel, RippleOutput, RippleState, StepFlags, StepTrace,
};
use crate::{Error, Real};
use order::OrderGuard;
pub use stats::GuardStats;

/// NIS of a sample (a thousand σ) that, while the model has run under one window
/// ([`GuardSettings::window_s`]) in motion, passes the raw torque on that sample; two such
/// samples in a row with innovations of one sign put the model in pass-through. With no
/// track record yet, they say the model is wrong; one alone, or two of opposite signs, is
/// a glitch. (Later a load step or a collision can give them; the running mean decides.)
pub const GROSS_NIS: f64 = 1e6;

/// While the angles stand exactly still, the running mean NIS that decides whether the
/// encoders are frozen averages over this share of [`GuardSettings::window_s`] (0.125 s by
/// default): short, as a stale correction adds to the error at once; not shorter, as a
/// real standstill's load changes raise it for a moment.
pub const STILL_WINDOW_SHARE: f64 = 0.5;

/// A line starts to be applied only while the running mean NIS over this share of
/// [`GuardSettings::window_s`] (16 ms by default, a few cycles of a line) is at most
/// [`GuardSettings::nis_recover`]: at a moment the data contradict the model (a load
/// transient the oscillators took, in a model without a bias state), an estimate that
/// just passed its tests is not yet trusted.
pub const ADMIT_WINDOW_SHARE: f64 = 1.0 / 16.0;

/// Initial variance of each component of an order learned from zero, N·m² (1σ 0.1 N·m).
/// With a larger one (the models' 1 N·m²) the ripple orders take the torque of a first
/// acceleration, while their line is still slow, for ripple, and confidently: the misfit
/// keeps the innovation beyond the load-step threshold, which skips their updates, so a
/// cold start stays wrong for seconds and the guard can only pass the raw torque through.
pub const COLD_OSCILLATOR_VARIANCE_NM2: f64 = 0.01;

/// `model` for learning from zero (cold, under the guard or not): its orders without a
/// learned prior start at [`COLD_OSCILLATOR_VARIANCE_NM2`]; the bias is unchanged.
///
/// ```
/// use strainwave_core::guard::cold_start;
/// use strainwave_core::ripple::RippleModel;
/// let m = cold_start(RippleModel::<f32, 5>::full_commissioning(1000.0, 0.0162)?)?;
/// assert!((m.initial_variance_nm2().0 - 0.01).abs() < 1e-9);
/// # Ok::<(), strainwave_core::Error>(())
/// ```
pub fn cold_start<T: Real, const M: usize>(model: RippleModel<T, M>) -> Result<RippleModel<T, M>, Error> {
    let (_, bias_nm2) = model.initial_variance_nm2();
    model.with_initial_variance(T::from_f64(COLD_OSCILLATOR_VARIANCE_NM2), bias_nm2)
}

/// Thresholds of the guard (see the [module documentation](self)).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GuardSettings<T: Real> {
    /// `χ²` (2 degrees of freedom) of an order's amplitude above which it is applied.
    /// Default 25: `P(χ²₂ > 25) ≈ 4·10⁻⁶` for an order that is not there.
    pub apply_chi2: T,
    /// `χ²` below which an applied order stops. Default 9.
    pub release_chi2: T,
    /// The estimate must also be steady: the RMS of its wander about its running mean
    /// (over [`Self::window_s`]) at most this fraction of its amplitude to apply.
    /// Default 0.2.
    pub apply_wander: T,
    /// Wander fraction above which an applied order stops. Default 0.4.
    pub release_wander: T,
    /// Full cycles of the line before a ripple (relative- or motor-angle) order may be
    /// applied. Default 3.
    pub min_cycles: T,
    /// Full cycles of the line before an output-angle order may be applied. Default 3.
    pub min_cycles_output: T,
    /// The orders start from learned priors (a commissioning run's coefficients): the
    /// travel is taken as shown, and the standstill bound starts at the prior amplitude.
    pub learned_prior: bool,
    /// Time constant of the running means (NIS, and `e²` against `(e + c_i)²`), s.
    /// Default 0.25 s.
    pub window_s: T,
    /// Running mean NIS above which the whole model steps back to pass-through.
    /// Default 6.
    pub nis_pass_through: T,
    /// Running mean NIS below which it comes back. Default 3.
    pub nis_recover: T,
    /// An order is stepped back when `mean (e + c_i)² < (1 − margin) mean e²`, and comes
    /// back when `mean (e + c_i)² > (1 + margin) mean e²`. Default 0.1.
    pub contradiction_margin: T,
    /// Each sample's NIS enters the running mean clipped to this (a load step or a
    /// glitch is one sample, not a misfit). Default 25.
    pub nis_clip: T,
    /// Unless the model is complete and fits (every order passes its tests, and the
    /// running mean NIS over [`Self::standstill_window_s`] is at most
    /// [`Self::complete_max_nis`]), an order is applied only when it is moving (not
    /// held) with its line at or above this, Hz: over a 1 s
    /// window such a line is nearly orthogonal to the slow or constant error of the
    /// withheld orders, so removing it cannot raise the window's error by adding to
    /// theirs. Default 5 Hz.
    pub partial_min_line_hz: T,
    /// See [`Self::partial_min_line_hz`]. Default 4.
    pub complete_max_nis: T,
    /// Held orders (standstill) are applied only while the model is complete and the
    /// running mean NIS of the motion before, over [`Self::standstill_window_s`], is at
    /// most this. While the angles stand exactly still, no order is applied unless the
    /// running mean NIS since they stopped, over half of [`Self::window_s`], is at most this too
    /// (frozen encoders on a turning joint fail it). Default 2.
    pub standstill_max_nis: T,
    /// Time constant of that running mean, s (long: the fit of the model, not of the
    /// last transient). Default 2 s.
    pub standstill_window_s: T,
}

impl<T: Real> Default for GuardSettings<T> {
    fn default() -> Self {
        let c = T::from_f64;
        Self {
            apply_chi2: c(25.0),
            release_chi2: c(9.0),
            apply_wander: c(0.2),
            release_wander: c(0.4),
            min_cycles: c(3.0),
            min_cycles_output: c(3.0),
            learned_prior: false,
            window_s: c(0.25),
            nis_pass_through: c(6.0),
            nis_recover: c(3.0),
            contradiction_margin: c(0.1),
            nis_clip: c(25.0),
            partial_min_line_hz: c(10.0),
            standstill_max_nis: c(2.0),
            complete_max_nis: c(3.0),
            standstill_window_s: c(2.0),
        }
    }
}

/// What the guard did on a sample. Several flags can be set at once.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Hash)]
pub struct GuardFlags(u16);

impl GuardFlags {
    /// The model does not fit (running mean NIS too high): output = raw.
    pub const PASS_THROUGH: Self = Self(1);
    /// At least one order was not applied for lack of evidence or travel.
    pub const WITHHELD: Self = Self(1 << 1);
    /// At least one order was stepped back because removing it fits the data better.
    pub const CONTRADICTED: Self = Self(1 << 2);
    /// At least one held order's contribution was clamped to its moving amplitude.
    pub const STANDSTILL_BOUND: Self = Self(1 << 3);
    /// At least one load-scaled order was not applied: the sample is a load step that is
    /// a glitch (of the torque or the expected torque), so the load that scales the order
    /// is not known.
    pub const LOAD_STEP_WITHHELD: Self = Self(1 << 4);

    /// No flag.
    pub const fn empty() -> Self {
        Self(0)
    }
    /// Raw bits.
    pub const fn bits(self) -> u16 {
        self.0
    }
    /// Whether every flag of `other` is set.
    pub const fn contains(self, other: Self) -> bool {
        self.0 & other.0 == other.0
    }
    fn set(&mut self, other: Self, on: bool) {
        if on {
            self.0 |= other.0;
        }
    }
}

/// One guarded sample.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GuardedOutput<T: Real, const M: usize> {
    /// The canceller's output with `torque_nm`, `ripple_nm` and `misalignment_nm`
    /// replaced by what the guard applied (innovation, NIS, flags: the canceller's).
    pub output: RippleOutput<T>,
    /// The canceller's own clean torque, every order applied, N·m.
    pub unguarded_torque_nm: T,
    /// Each order's predicted contribution `c_i(k)`, N·m (0 for an order off).
    pub contribution_nm: [T; M],
    /// Whether each order was applied.
    pub applied: [bool; M],
    /// What the guard did.
    pub flags: GuardFlags,
    /// Running mean of the NIS after this sample.
    pub mean_nis: T,
}

impl<T: Real, const M: usize> GuardedOutput<T, M> {
    /// Bit `i` set when order `i` was not applied.
    pub fn withheld_mask(&self) -> u16 {
        self.applied.iter().enumerate().filter(|(_, a)| !**a).fold(0, |m, (i, _)| m | (1 << i.min(15)))
    }
}

/// The canceller of one joint under the guard: its state, and per order the evidence,
/// travel, health and standstill bound. No allocation; `f32` or `f64`.
#[derive(Debug, Clone)]
pub struct Guard<T: Real, const M: usize> {
    settings: GuardSettings<T>,
    state: RippleState<T, M>,
    trace: StepTrace<T, M>,
    orders: [OrderGuard<T>; M],
    /// The first order on the same line (reference and multiple) as each order: a line's
    /// orders (plain and load-scaled) are judged and applied together, as only their sum
    /// is well determined while the load is steady.
    group: [usize; M],
    /// Weight of the newest sample in the running means.
    alpha: T,
    mean_nis: T,
    /// Running mean NIS over [`GuardSettings::standstill_window_s`].
    slow_mean_nis: T,
    /// Running mean NIS while the angles stand exactly still (0 when they last moved),
    /// over [`STILL_WINDOW_SHARE`] of [`GuardSettings::window_s`]: high where the torque
    /// ripples under frozen encoders.
    still_mean_nis: T,
    still_alpha: T,
    slow_alpha: T,
    /// Running mean NIS over [`ADMIT_WINDOW_SHARE`] of [`GuardSettings::window_s`] (load
    /// steps left out: the bias takes them): a line not applied on the sample before
    /// starts only while it is at most [`GuardSettings::nis_recover`] (the model fits the
    /// last few samples).
    recent_nis: T,
    recent_alpha: T,
    /// The lines applied on the sample before.
    applied: [bool; M],
    mean_e2: T,
    pass_through: bool,
    /// Measured samples in motion so far (saturating): the track record of the model.
    moving_samples: u32,
    /// The last load known to scale the load-scaled orders, N·m.
    load_nm: T,
    /// The expected torque of the sample before, N·m.
    expected_nm: T,
    /// The innovation of the sample before if it was a load step, else 0, N·m.
    step_innovation_nm: T,
    /// In a run of load steps since one that undid the step before (a glitch).
    undoing: bool,
    /// The innovation of the sample before if it was a gross misfit, else 0, N·m.
    gross_innovation_nm: T,
    stats: GuardStats<M>,
}

impl<T: Real, const M: usize> Guard<T, M> {
    /// A guard with the canceller of `model` in its initial state.
    pub fn new(model: &RippleModel<T, M>, settings: GuardSettings<T>) -> Self {
        let samples = (settings.window_s * model.sample_rate_hz()).max(T::ONE);
        Self {
            settings,
            state: RippleState::new(model),
            trace: StepTrace::new(),
            orders: core::array::from_fn(|i| OrderGuard::new(&model.orders()[i], &settings, model.r_nm2)),
            group: core::array::from_fn(|i| {
                let o = &model.orders()[i];
                let same = |p: &crate::ripple::Order<T>| p.reference() == o.reference() && p.multiple() == o.multiple();
                model.orders().iter().position(same).unwrap_or(i)
            }),
            alpha: T::ONE / samples,
            mean_nis: T::ONE,
            slow_mean_nis: T::ONE,
            still_mean_nis: T::ZERO,
            still_alpha: (T::from_f64(1.0 / STILL_WINDOW_SHARE) / samples).min(T::ONE),
            slow_alpha: T::ONE / (settings.standstill_window_s * model.sample_rate_hz()).max(T::ONE),
            recent_nis: T::ONE,
            recent_alpha: (T::from_f64(1.0 / ADMIT_WINDOW_SHARE) / samples).min(T::ONE),
            applied: [false; M],
            mean_e2: model.r_nm2,
            pass_through: false,
            moving_samples: 0,
            load_nm: T::ZERO,
            expected_nm: T::ZERO,
            step_innovation_nm: T::ZERO,
            undoing: false,
            gross_innovation_nm: T::ZERO,
            stats: GuardStats::new(),
        }
    }

    /// The canceller's state (what it learned: see [`RippleState::learned_all`]).
    pub fn state(&self) -> &RippleState<T, M> {
        &self.state
    }

    /// The settings.
    pub fn settings(&self) -> &GuardSettings<T> {
        &self.settings
    }

    /// The figures of the run so far.
    pub fn stats(&self) -> &GuardStats<M> {
        &self.stats
    }

    /// One sample: the canceller's step (see [`crate::ripple::step`]), then the guard's
    /// choice of the orders applied. Errors are the canceller's (its state was then reset,
    /// and so is the guard's evidence).
    #[allow(clippy::needless_range_loop)] // per-order arrays side by side
    pub fn step(&mut self, model: &RippleModel<T, M>, input: &RippleInput<T>) -> Result<GuardedOutput<T, M>, Error> {
        let out = match step_traced(model, &mut self.state, input, &mut self.trace) {
            Ok(o) => o,
            Err(e) => {
                self.orders =
                    core::array::from_fn(|i| OrderGuard::new(&model.orders()[i], &self.settings, model.r_nm2));
                self.step_innovation_nm = T::ZERO;
                return Err(e);
            }
        };
        let s = self.settings;
        let tr = &self.trace;
        let dt_rad_to_hz = model.sample_rate_hz() / T::TAU;
        // The decisions use what was known before this sample: the prediction
        // `ẑ(k|k−1)`, `P(k|k−1)` and the phase at `k` (evidence, steadiness, travel), and
        // the fit of the innovations up to `k−1`. The model is complete when every line
        // not off passes its own tests.
        let mut contribution = [T::ZERO; M];
        for i in 0..M {
            let [c, sn] = tr.phasor[i];
            let z = tr.prior.z[i];
            contribution[i] = if tr.predicted[i] { c * z[0] + sn * z[1] } else { T::ZERO };
        }
        // The load `|T_exp + b̂(k|k−1)|` that scales the load-scaled lines is not known on a
        // load step that is a glitch: the expected torque jumped by more than the last load
        // known (the glitch, or its undoing), or the load steps in a row since one whose
        // innovation undid the one before (a glitch in the torque, which the bias took and
        // gives back). Those lines are neither applied nor observed there (a glitch would
        // sway their wander for seconds). A real step's innovations keep their sign.
        let load_step = out.flags.contains(StepFlags::LOAD_STEP);
        let e = out.innovation_nm;
        #[allow(clippy::neg_cmp_op_on_partial_ord)] // a NaN counts as a jump
        let expected_jumped = !((input.expected_torque_nm - self.expected_nm).abs() <= self.load_nm);
        self.undoing = load_step && (self.undoing || self.step_innovation_nm * e < T::ZERO);
        let load_jumped = load_step && (expected_jumped || self.undoing);
        self.step_innovation_nm = if load_step { e } else { T::ZERO };
        self.expected_nm = input.expected_torque_nm;
        if !load_jumped {
            self.load_nm = (input.expected_torque_nm + tr.prior.bias).abs();
        }
        let load_unknown: [bool; M] = core::array::from_fn(|lead| {
            load_jumped && (lead..M).any(|i| self.group[i] == lead && model.orders()[i].is_load_scaled())
        });
        let mut status = [OrderStatus::Off; M];
        let mut lines = [None; M];
        for i in 0..M {
            status[i] = self.state.order_status(i).unwrap_or(OrderStatus::Off);
            if self.group[i] == i {
                let line = group_line(tr, &self.group, i, &contribution);
                let g = &mut self.orders[i];
                if !load_unknown[i] {
                    g.observe(&s, self.alpha, &line.p, line.z, line.unit_phasor, status[i]);
                }
                g.observe_line(self.alpha, tr.increment_rad[i]);
                lines[i] = Some(line);
            }
        }
        let mut complete = true;
        for i in 0..M {
            let v = self.orders[i].verdict(false);
            complete &= self.group[i] != i || status[i] == OrderStatus::Off || v.apply;
        }
        // Early in a run there is no track record: a misfit of a thousand σ passes the raw
        // torque on that sample, and two in a row with one sign (not a glitch and its
        // undoing) say the model is wrong (a learned file of another joint, or a damaged
        // one): it passes through from there.
        let early = T::from_f64(f64::from(self.moving_samples)) * self.alpha < T::ONE;
        let gross = early && out.nis > T::from_f64(GROSS_NIS);
        if gross && self.gross_innovation_nm * out.innovation_nm > T::ZERO {
            self.pass_through = true;
            self.mean_nis = self.mean_nis.max(s.nis_clip);
        }
        self.gross_innovation_nm = if gross { out.innovation_nm } else { T::ZERO };
        let pass_through = self.pass_through || gross;
        let moving = status.contains(&OrderStatus::Active);
        let measured = e.is_finite() && out.nis.is_finite();
        // Held orders are applied only when the model fitted well while it moved: at a
        // standstill a partial or wrong correction is a constant that nothing can check.
        let standstill_ok = self.slow_mean_nis <= s.standstill_max_nis;
        // While the angles stand exactly still, no order is applied unless the torque is
        // as steady as the model says: encoders frozen on a turning joint leave the
        // torque rippling, and the phase they give is stale.
        let still = (0..M).all(|i| tr.increment_rad[i] == T::ZERO);
        if !still {
            self.still_mean_nis = T::ZERO;
        } else if measured {
            self.still_mean_nis += self.still_alpha * (out.nis.min(s.nis_clip) - self.still_mean_nis);
        }
        let steady = self.still_mean_nis <= s.standstill_max_nis;
        let fits = self.slow_mean_nis <= s.complete_max_nis;
        let verdict: [_; M] = core::array::from_fn(|i| Some(self.orders[i].verdict(pass_through)));
        let mut flags = GuardFlags::empty();
        let (mut ripple, mut mis) = (T::ZERO, T::ZERO);
        let mut applied = [false; M];
        for lead in 0..M {
            if self.group[lead] != lead {
                continue;
            }
            let (Some(verdict), Some(line)) = (verdict[lead], lines[lead]) else { continue };
            let status = status[lead];
            let g = &mut self.orders[lead];
            let alone = (complete && fits)
                || (status == OrderStatus::Active && g.line_hz(dt_rad_to_hz) >= s.partial_min_line_hz);
            flags.set(GuardFlags::WITHHELD, !verdict.evidence || !verdict.travelled);
            flags.set(GuardFlags::CONTRADICTED, verdict.contradicted);
            let (value, bounded) = g.bounded(line.contribution_nm, status);
            let held_ok = (status != OrderStatus::Held || (complete && standstill_ok)) && steady;
            let bounded = bounded || !held_ok;
            let load_unknown = load_unknown[lead];
            flags.set(GuardFlags::LOAD_STEP_WITHHELD, load_unknown && verdict.apply);
            let admitted = self.applied[lead] || self.recent_nis <= s.nis_recover;
            let apply = verdict.apply && alone && held_ok && admitted && status != OrderStatus::Off && !load_unknown;
            flags.set(GuardFlags::STANDSTILL_BOUND, bounded && verdict.apply && alone);
            for i in lead..M {
                applied[i] |= apply && self.group[i] == lead;
            }
            if apply {
                if model.orders()[lead].reference() == Reference::Output {
                    mis += value;
                } else {
                    ripple += value;
                }
            }
            // Then this sample's innovation for the next decision (a load step's is the
            // bias's: it says nothing of the orders' fit).
            if measured && !load_step {
                g.observe_fit(self.alpha, e, line.contribution_nm);
            }
        }
        // Only motion can confirm or contradict the orders: at a standstill the bias takes
        // whatever they leave, so the verdicts of the last motion stand.
        if measured && moving {
            self.moving_samples = self.moving_samples.saturating_add(1);
            let nis = out.nis.min(s.nis_clip);
            self.mean_nis += self.alpha * (nis - self.mean_nis);
            self.slow_mean_nis += self.slow_alpha * (nis - self.slow_mean_nis);
            if !load_step {
                self.recent_nis += self.recent_alpha * (nis - self.recent_nis);
                self.mean_e2 += self.alpha * (e * e - self.mean_e2);
            }
            for g in &mut self.orders {
                g.judge_fit(&s, self.mean_e2);
            }
            let was = self.pass_through;
            self.pass_through = if was { self.mean_nis > s.nis_recover } else { self.mean_nis > s.nis_pass_through };
        }
        flags.set(GuardFlags::PASS_THROUGH, pass_through);
        self.applied = applied;
        self.stats.record(&applied, flags, out.nis.min(s.nis_clip).to_f64(), measured, self.mean_nis.to_f64());
        let unguarded_torque_nm = out.torque_nm;
        let mut output = out;
        output.ripple_nm = ripple;
        output.misalignment_nm = mis;
        output.torque_nm = input.torque_nm - ripple - mis;
        Ok(GuardedOutput {
            output,
            unguarded_torque_nm,
            contribution_nm: contribution,
            applied,
            flags,
            mean_nis: self.mean_nis,
        })
    }
}

/// One line's orders taken together: `h_i = s_i u` with the unit phasor `u` and each
/// order's scale `s_i` (1, or `|load|`), so the line is `u (Σ s_i z_i)` with covariance
/// `Σ_ij s_i s_j P_ij`.
#[derive(Clone, Copy)]
struct Line<T: Real> {
    contribution_nm: T,
    z: [T; 2],
    p: [[T; 2]; 2],
    unit_phasor: [T; 2],
}

fn group_line<T: Real, const M: usize>(
    tr: &StepTrace<T, M>,
    group: &[usize; M],
    lead: usize,
    contribution: &[T; M],
) -> Line<T> {
    let scale = |i: usize| {
        let [c, s] = tr.phasor[i];
        (c * c + s * s).sqrt()
    };
    let mut line = Line { contribution_nm: T::ZERO, z: [T::ZERO; 2], p: [[T::ZERO; 2]; 2], unit_phasor: [T::ZERO; 2] };
    let mut widest = T::ZERO;
    for i in (lead..M).filter(|&i| group[i] == lead) {
        let si = scale(i);
        line.contribution_nm += contribution[i];
        if si > widest {
            widest = si;
            line.unit_phasor = [tr.phasor[i][0] / si, tr.phasor[i][1] / si];
        }
        for r in 0..2 {
            line.z[r] += si * tr.prior.z[i][r];
        }
        for j in (lead..M).filter(|&j| group[j] == lead) {
            let w = si * scale(j);
            for (r, row) in line.p.iter_mut().enumerate() {
                for (q, v) in row.iter_mut().enumerate() {
                    *v += w * tr.prior.p[i][j][r][q];
                }
            }
        }
    }
    line
}

#[cfg(test)]
mod tests;
