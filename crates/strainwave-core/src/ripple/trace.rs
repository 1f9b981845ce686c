//! What a traced step shows: the state in the rotating frame and one step's time and
//! measurement update.

use crate::Real;

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

/// What one traced step did, in the rotating frame (see [`step_traced`](super::step_traced)).
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
    /// An empty trace to pass to [`step_traced`](super::step_traced).
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
