//! The filter state of `J` joints that share one model, laid out as structure of
//! arrays (the joint index innermost) so one step vectorizes across joints. It is kept
//! in each oscillator's rotating frame `x_i = Φ(ψ_i) z_i` (see the kernel): `z` and `P_z`
//! are stored; [`RippleBank::estimate`] and [`RippleBank::covariance`] give `x` and `P`.

use super::io::{OrderStatus, ReferenceValues, StepFlags};
use super::model::RippleModel;
use crate::Real;

/// States of `J` joints for a model of `M` orders.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RippleBank<T: Real, const M: usize, const J: usize> {
    /// Rotating-frame oscillator states `z[i][component][joint]`, N·m.
    pub(crate) z: [[[T; J]; 2]; M],
    /// Bias state, N·m (0 without the bias state).
    pub(crate) b: [T; J],
    /// `p[i][j][r][c][joint] = Cov(z_i[r], z_j[c])`, only blocks `i ≤ j` are used.
    pub(crate) p: [[[[[T; J]; 2]; 2]; M]; M],
    /// `pb[i][r][joint] = Cov(z_i[r], b)`.
    pub(crate) pb: [[[T; J]; 2]; M],
    /// `Var(b)`.
    pub(crate) pbb: [T; J],
    /// `(cos ψ_i, sin ψ_i)`.
    pub(crate) phasor: [[[T; J]; 2]; M],
    /// Phase of each reference, wrapped: the angle itself (angle input) or the
    /// accumulated increments (velocity input), rad.
    pub(crate) psi: [[T; J]; 3],
    /// Accumulated phase of orders with a fractional multiple, wrapped, rad.
    pub(crate) order_psi: [[T; J]; M],
    pub(crate) status: [[OrderStatus; J]; M],
    pub(crate) last: [[T; J]; 3],
    pub(crate) has_last: [bool; J],
    /// Last accepted increment per sample of each reference, and whether it is known.
    pub(crate) last_delta: [[T; J]; 3],
    pub(crate) delta_known: [bool; J],
    /// Running mean of the increment per sample of each reference (decides holding).
    pub(crate) mean_delta: [[T; J]; 3],
    pub(crate) pending_samples: [T; J],
    pub(crate) pending_dt: [T; J],
    pub(crate) steps: [u64; J],
}

impl<T: Real, const M: usize, const J: usize> RippleBank<T, M, J> {
    /// Every joint at the model's initial state: `x = 0`, `P = diag(p0)`.
    ///
    /// ```
    /// use strainwave_core::ripple::{RippleBank, RippleModel};
    /// let model = RippleModel::<f32, 3>::taghirad_6th_order(1000.0).unwrap();
    /// let bank = RippleBank::<f32, 3, 8>::new(&model);
    /// assert_eq!(bank.covariance(&model, 0, 0, 0), Some(1.0));
    /// assert_eq!(bank.covariance(&model, 8, 0, 0), None);
    /// ```
    pub fn new(model: &RippleModel<T, M>) -> Self {
        let mut bank = Self {
            z: [[[T::ZERO; J]; 2]; M],
            b: [T::ZERO; J],
            p: [[[[[T::ZERO; J]; 2]; 2]; M]; M],
            pb: [[[T::ZERO; J]; 2]; M],
            pbb: [T::ZERO; J],
            phasor: [[[T::ZERO; J]; 2]; M],
            psi: [[T::ZERO; J]; 3],
            order_psi: [[T::ZERO; J]; M],
            status: [[OrderStatus::Active; J]; M],
            last: [[T::ZERO; J]; 3],
            has_last: [false; J],
            last_delta: [[T::ZERO; J]; 3],
            delta_known: [false; J],
            mean_delta: [[T::ZERO; J]; 3],
            pending_samples: [T::ZERO; J],
            pending_dt: [T::ZERO; J],
            steps: [0; J],
        };
        bank.reset(model);
        bank
    }

    /// Back to the initial state, forgetting the last angles too.
    pub fn reset(&mut self, model: &RippleModel<T, M>) {
        for l in 0..J {
            self.reset_lane(model, l);
            self.has_last[l] = false;
            self.delta_known[l] = false;
            for r in 0..3 {
                self.mean_delta[r][l] = T::ZERO;
                self.psi[r][l] = T::ZERO;
            }
            for i in 0..M {
                self.order_psi[i][l] = T::ZERO;
            }
            self.pending_samples[l] = T::ZERO;
            self.pending_dt[l] = T::ZERO;
            self.steps[l] = 0;
        }
    }

    /// Resets joint `l`'s estimate and covariance (keeps its last angles).
    pub(crate) fn reset_lane(&mut self, model: &RippleModel<T, M>, l: usize) {
        if l >= J {
            return;
        }
        for i in 0..M {
            let p0 = model.plan.p0_nm2[i];
            for r in 0..2 {
                self.z[i][r][l] = model.orders[i].prior_nm[r];
                self.pb[i][r][l] = T::ZERO;
                for j in 0..M {
                    for c in 0..2 {
                        self.p[i][j][r][c][l] = if i == j && r == c { p0 } else { T::ZERO };
                    }
                }
            }
            self.phasor[i][0][l] = T::ONE;
            self.phasor[i][1][l] = T::ZERO;
            self.status[i][l] = OrderStatus::Active;
        }
        self.b[l] = T::ZERO;
        self.pbb[l] = if model.bias_q_nm2.is_some() { model.p0_bias_nm2 } else { T::ZERO };
    }

    /// Steps taken by joint `joint` (skipped samples included; counts modulo 2⁶⁴).
    pub fn steps(&self, joint: usize) -> Option<u64> {
        self.steps.get(joint).copied()
    }

    /// Status of order `order` of joint `joint`.
    pub fn order_status(&self, joint: usize, order: usize) -> Option<OrderStatus> {
        self.status.get(order)?.get(joint).copied()
    }

    /// The last reference values accepted for `joint`, if any.
    pub fn last_references(&self, joint: usize) -> Option<ReferenceValues<T>> {
        if !*self.has_last.get(joint)? {
            return None;
        }
        let v = |r: usize| self.last[r][joint];
        Some(ReferenceValues::new(v(0), v(1), v(2)))
    }

    /// Element `index` of the fixed-frame posterior `x̂(k|k)` of `joint`: `x_{i,0}` at
    /// `2i`, `x_{i,1}` at `2i+1`, the bias at `2M`. `None` out of range.
    pub fn estimate(&self, model: &RippleModel<T, M>, joint: usize, index: usize) -> Option<T> {
        if joint >= J || index >= model.state_len() {
            return None;
        }
        if index == 2 * M {
            return Some(self.b[joint]);
        }
        let (i, r) = (index / 2, index % 2);
        let z = self.z.get(i)?;
        let (z0, z1) = (z[0][joint], z[1][joint]);
        let (c, s) = self.phasor_of(i, joint);
        Some(if r == 0 { c * z0 + s * z1 } else { c * z1 - s * z0 })
    }

    /// Element `(row, col)` of the fixed-frame covariance `P(k|k)` of `joint`
    /// (`P_x = Φ(ψ) P_z Φ(ψ)ᵀ`), indices as in [`Self::estimate`].
    pub fn covariance(&self, model: &RippleModel<T, M>, joint: usize, row: usize, col: usize) -> Option<T> {
        let n = model.state_len();
        if joint >= J || row >= n || col >= n {
            return None;
        }
        let bias = 2 * M;
        if row == bias && col == bias {
            return Some(self.pbb[joint]);
        }
        if row == bias || col == bias {
            let idx = if row == bias { col } else { row };
            let (i, r) = (idx / 2, idx % 2);
            let pb = self.pb.get(i)?;
            let v = [pb[0][joint], pb[1][joint]];
            return Some(rotate_vec(self.phasor_of(i, joint), v)[r]);
        }
        let (i, r, j, c) = (row / 2, row % 2, col / 2, col % 2);
        let blk = self.block(i, j, joint)?;
        // Φ_i B Φ_jᵀ
        let left = rotate_rows(self.phasor_of(i, joint), blk);
        let full = rotate_cols(self.phasor_of(j, joint), left);
        Some(full[r][c])
    }

    /// Rotating-frame block `Cov(z_i, z_j)` (2×2) of `joint`.
    pub(crate) fn block(&self, i: usize, j: usize, l: usize) -> Option<[[T; 2]; 2]> {
        let (a, bb, transpose) = if i <= j { (i, j, false) } else { (j, i, true) };
        let p = self.p.get(a)?.get(bb)?;
        let mut out = [[T::ZERO; 2]; 2];
        for (r, row) in out.iter_mut().enumerate() {
            for (c, v) in row.iter_mut().enumerate() {
                *v = if transpose { p[c][r].get(l).copied()? } else { p[r][c].get(l).copied()? };
            }
        }
        Some(out)
    }

    pub(crate) fn phasor_of(&self, i: usize, l: usize) -> (T, T) {
        match self.phasor.get(i) {
            Some(ph) => (ph[0].get(l).copied().unwrap_or(T::ONE), ph[1].get(l).copied().unwrap_or(T::ZERO)),
            None => (T::ONE, T::ZERO),
        }
    }
}

/// `Φ(ψ) v` with `Φ = [[c, s], [−s, c]]`.
fn rotate_vec<T: Real>((c, s): (T, T), v: [T; 2]) -> [T; 2] {
    [c * v[0] + s * v[1], c * v[1] - s * v[0]]
}

/// `Φ(ψ) B`.
fn rotate_rows<T: Real>(cs: (T, T), b: [[T; 2]; 2]) -> [[T; 2]; 2] {
    let c0 = rotate_vec(cs, [b[0][0], b[1][0]]);
    let c1 = rotate_vec(cs, [b[0][1], b[1][1]]);
    [[c0[0], c1[0]], [c0[1], c1[1]]]
}

/// `B Φ(ψ)ᵀ`.
fn rotate_cols<T: Real>(cs: (T, T), b: [[T; 2]; 2]) -> [[T; 2]; 2] {
    [rotate_vec(cs, b[0]), rotate_vec(cs, b[1])]
}

/// One sample for `J` joints, structure of arrays.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BankInput<T: Real, const J: usize> {
    /// Measured torques, N·m.
    pub torque_nm: [T; J],
    /// Expected torques, N·m (zeros if none).
    pub expected_torque_nm: [T; J],
    /// Reference angles (rad) or velocities (rad/s) per joint.
    pub references: ReferenceValues<[T; J]>,
    /// Time since the previous sample, shared by the joints, s; `None` = nominal.
    pub dt_s: Option<T>,
}

impl<T: Real, const J: usize> BankInput<T, J> {
    /// A sample with no expected torque and the nominal interval.
    ///
    /// ```
    /// use strainwave_core::ripple::{BankInput, ReferenceValues};
    /// let s = BankInput::new([1.0_f32; 4], ReferenceValues::new([0.1; 4], [0.001; 4], [0.099; 4]));
    /// assert_eq!(s.expected_torque_nm, [0.0; 4]);
    /// ```
    pub fn new(torque_nm: [T; J], references: ReferenceValues<[T; J]>) -> Self {
        Self { torque_nm, expected_torque_nm: [T::ZERO; J], references, dt_s: None }
    }
}

/// Per-joint results of one bank step (see [`RippleOutput`](super::RippleOutput)).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BankOutput<T: Real, const J: usize> {
    /// Clean torque, N·m.
    pub torque_nm: [T; J],
    /// Predicted ripple, N·m.
    pub ripple_nm: [T; J],
    /// Predicted misalignment, N·m.
    pub misalignment_nm: [T; J],
    /// Bias-state torque estimate (or the clean torque without bias state), N·m.
    pub torque_state_nm: [T; J],
    /// Innovation, N·m.
    pub innovation_nm: [T; J],
    /// Innovation variance, N·m².
    pub innovation_variance_nm2: [T; J],
    /// Normalized innovation squared.
    pub nis: [T; J],
    /// Flags; [`StepFlags::COVARIANCE_RESET`] marks a joint whose state was reset.
    pub flags: [StepFlags; J],
}

impl<T: Real, const J: usize> Default for BankOutput<T, J> {
    /// All zero, no flags: the buffer [`step_many`](super::step_many) fills.
    #[inline]
    fn default() -> Self {
        Self {
            torque_nm: [T::ZERO; J],
            ripple_nm: [T::ZERO; J],
            misalignment_nm: [T::ZERO; J],
            torque_state_nm: [T::ZERO; J],
            innovation_nm: [T::ZERO; J],
            innovation_variance_nm2: [T::ZERO; J],
            nis: [T::ZERO; J],
            flags: [StepFlags::empty(); J],
        }
    }
}

impl<T: Real> From<BankOutput<T, 1>> for super::RippleOutput<T> {
    /// The single joint of a one-joint bank step.
    fn from(o: BankOutput<T, 1>) -> Self {
        Self {
            torque_nm: o.torque_nm[0],
            ripple_nm: o.ripple_nm[0],
            misalignment_nm: o.misalignment_nm[0],
            torque_state_nm: o.torque_state_nm[0],
            innovation_nm: o.innovation_nm[0],
            innovation_variance_nm2: o.innovation_variance_nm2[0],
            nis: o.nis[0],
            flags: o.flags[0],
        }
    }
}
