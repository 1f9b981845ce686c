//! Merging what runs learned about one order: Gaussians over its two coefficients
//! `z = [cos_nm, sin_nm]`, combined in information form.
//!
//! ```text
//! Λ = P⁻¹,  η = Λ z                               information matrix and vector
//! evidence of a run   Λ_e = Λ_post − Λ_prior,  η_e = η_post − η_prior
//! merged              Λ = Λ_file + Λ_e,         η = η_file + η_e,   z = Λ⁻¹ η
//! ```
//!
//! A run's posterior holds the prior it started from; subtracting the prior's
//! information leaves what the run's data said, so a weak prior of a cold start
//! (zero mean, 1 N·m², or the `full` model's misalignment prior) is not counted once per
//! run. The evidence is kept only where the data at least doubled the information
//! (`Λ_post − 2 Λ_prior` positive definite): an order the run barely saw (held at a
//! standstill, switched off above Nyquist) then adds nothing, rather than a mean made
//! large by dividing by a nearly zero information. The process noise of the
//! oscillators makes a long run's posterior forget its start; the evidence is then
//! that of the run's last stretch, which only understates it.
//!
//! Each order is merged on its own (its 2×2 covariance, not its correlation with other
//! orders).

/// A Gaussian over an order's two coefficients, N·m (N·m per N·m when load-scaled).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Gaussian2 {
    /// Mean `[cos, sin]`.
    pub mean_nm: [f64; 2],
    /// Covariance, symmetric positive definite, N·m².
    pub cov_nm2: [[f64; 2]; 2],
}

type Mat2 = [[f64; 2]; 2];

/// Inverse of a symmetric positive definite 2×2 matrix; `None` when it is not one.
fn inverse_spd(m: Mat2) -> Option<Mat2> {
    let off = 0.5 * (m[0][1] + m[1][0]);
    let det = m[0][0] * m[1][1] - off * off;
    let scale = m[0][0].abs().max(m[1][1].abs());
    if !(m[0][0] > 0.0 && m[1][1] > 0.0 && det > 1e-12 * scale * scale && det.is_finite()) {
        return None;
    }
    Some([[m[1][1] / det, -off / det], [-off / det, m[0][0] / det]])
}

fn mul_vec(m: Mat2, v: [f64; 2]) -> [f64; 2] {
    [m[0][0] * v[0] + m[0][1] * v[1], m[1][0] * v[0] + m[1][1] * v[1]]
}

fn sub(a: Mat2, b: Mat2) -> Mat2 {
    [[a[0][0] - b[0][0], a[0][1] - b[0][1]], [a[1][0] - b[1][0], a[1][1] - b[1][1]]]
}

fn is_positive_definite(m: Mat2) -> bool {
    let off = 0.5 * (m[0][1] + m[1][0]);
    m[0][0] > 0.0 && m[1][1] > 0.0 && m[0][0] * m[1][1] - off * off > 0.0
}

impl Gaussian2 {
    /// Mean `z`, variance `v` on each coefficient, no correlation.
    ///
    /// ```
    /// use strainwave_joint::merge::Gaussian2;
    /// let g = Gaussian2::isotropic([0.3, -0.1], 1e-4);
    /// assert_eq!(g.largest_variance_nm2(), 1e-4);
    /// ```
    pub fn isotropic(mean_nm: [f64; 2], variance_nm2: f64) -> Self {
        Self { mean_nm, cov_nm2: [[variance_nm2, 0.0], [0.0, variance_nm2]] }
    }

    /// Information matrix and vector `(Λ, η)`; `None` if the covariance is not positive definite.
    pub fn information(&self) -> Option<(Mat2, [f64; 2])> {
        let l = inverse_spd(self.cov_nm2)?;
        Some((l, mul_vec(l, self.mean_nm)))
    }

    /// The Gaussian of an information pair; `None` if `Λ` is not positive definite.
    pub fn from_information(info: Mat2, eta: [f64; 2]) -> Option<Self> {
        let cov = inverse_spd(info)?;
        let mean = mul_vec(cov, eta);
        (mean.iter().all(|v| v.is_finite())).then_some(Self { mean_nm: mean, cov_nm2: cov })
    }

    /// What a run's data said, its posterior without the prior it started from (see the
    /// module doc); `None` when the data did not at least double the information.
    ///
    /// ```
    /// use strainwave_joint::merge::Gaussian2;
    /// let prior = Gaussian2::isotropic([0.0, 0.0], 1.0);
    /// // Data worth information 3 at mean 0.5: posterior information 4, mean 0.375.
    /// let post = Gaussian2::isotropic([0.375, 0.0], 0.25);
    /// let e = Gaussian2::evidence(&post, &prior).unwrap();
    /// assert!((e.mean_nm[0] - 0.5).abs() < 1e-12 && (e.cov_nm2[0][0] - 1.0 / 3.0).abs() < 1e-12);
    /// assert!(Gaussian2::evidence(&Gaussian2::isotropic([0.1, 0.0], 0.9), &prior).is_none());
    /// ```
    pub fn evidence(posterior: &Self, prior: &Self) -> Option<Self> {
        let (lp, ep) = posterior.information()?;
        let (l0, e0) = prior.information()?;
        if !is_positive_definite(sub(lp, [[2.0 * l0[0][0], 2.0 * l0[0][1]], [2.0 * l0[1][0], 2.0 * l0[1][1]]])) {
            return None;
        }
        Self::from_information(sub(lp, l0), [ep[0] - e0[0], ep[1] - e0[1]])
    }

    /// The information-weighted combination of two independent Gaussians.
    ///
    /// ```
    /// use strainwave_joint::merge::Gaussian2;
    /// let a = Gaussian2::isotropic([1.0, 0.0], 1.0);
    /// let b = Gaussian2::isotropic([0.0, 0.0], 1.0 / 3.0);
    /// let m = a.fuse(&b).unwrap();
    /// assert!((m.mean_nm[0] - 0.25).abs() < 1e-12 && (m.cov_nm2[0][0] - 0.25).abs() < 1e-12);
    /// ```
    pub fn fuse(&self, other: &Self) -> Option<Self> {
        let (la, ea) = self.information()?;
        let (lb, eb) = other.information()?;
        let l = [[la[0][0] + lb[0][0], la[0][1] + lb[0][1]], [la[1][0] + lb[1][0], la[1][1] + lb[1][1]]];
        Self::from_information(l, [ea[0] + eb[0], ea[1] + eb[1]])
    }

    /// The larger eigenvalue of the covariance: the variance of a prior that claims no
    /// more than this Gaussian (what the canceller's isotropic prior takes).
    pub fn largest_variance_nm2(&self) -> f64 {
        let [[a, b], [_, d]] = self.cov_nm2;
        let half_trace = 0.5 * (a + d);
        let r = (0.25 * (a - d) * (a - d) + b * b).sqrt();
        half_trace + r
    }

    /// The covariance as the file writes it: `[P00, P01, P11]`.
    pub fn packed_cov(&self) -> [f64; 3] {
        [self.cov_nm2[0][0], 0.5 * (self.cov_nm2[0][1] + self.cov_nm2[1][0]), self.cov_nm2[1][1]]
    }

    /// From the file's `[P00, P01, P11]`.
    pub fn from_packed(mean_nm: [f64; 2], packed: [f64; 3]) -> Self {
        Self { mean_nm, cov_nm2: [[packed[0], packed[1]], [packed[1], packed[2]]] }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const TOL: f64 = 1e-12;

    /// Two runs' evidence merged equals one run with both runs' data.
    #[test]
    fn merging_evidence_equals_pooling_the_data() {
        let prior = Gaussian2::isotropic([0.0, 0.0], 1.0);
        // Data of run A: information [[40, 5], [5, 30]] at mean [0.2, -0.1]; run B [[20, 0], [0, 50]] at [0.3, 0.0].
        let la = [[40.0, 5.0], [5.0, 30.0]];
        let lb = [[20.0, 0.0], [0.0, 50.0]];
        let (ma, mb) = ([0.2, -0.1], [0.3, 0.0]);
        let post = |l: Mat2, m: [f64; 2]| {
            let (l0, e0) = prior.information().unwrap();
            let d = mul_vec(l, m);
            Gaussian2::from_information(
                [[l[0][0] + l0[0][0], l[0][1]], [l[1][0], l[1][1] + l0[1][1]]],
                [d[0] + e0[0], d[1] + e0[1]],
            )
            .unwrap()
        };
        let ea = Gaussian2::evidence(&post(la, ma), &prior).unwrap();
        let eb = Gaussian2::evidence(&post(lb, mb), &prior).unwrap();
        let merged = ea.fuse(&eb).unwrap();
        let pooled = Gaussian2::from_information(
            [[60.0, 5.0], [5.0, 80.0]],
            [mul_vec(la, ma)[0] + mul_vec(lb, mb)[0], mul_vec(la, ma)[1] + mul_vec(lb, mb)[1]],
        )
        .unwrap();
        for i in 0..2 {
            assert!((merged.mean_nm[i] - pooled.mean_nm[i]).abs() < TOL, "{merged:?} {pooled:?}");
            for j in 0..2 {
                assert!((merged.cov_nm2[i][j] - pooled.cov_nm2[i][j]).abs() < TOL);
            }
        }
        // Counting the prior once per run instead would pull the mean toward 0.
        let naive = post(la, ma).fuse(&post(lb, mb)).unwrap();
        assert!(naive.mean_nm[0] < merged.mean_nm[0] - 1e-3);
    }

    #[test]
    fn bad_covariances_are_none() {
        assert!(Gaussian2::isotropic([0.0; 2], 0.0).information().is_none());
        assert!(Gaussian2::isotropic([0.0; 2], f64::NAN).information().is_none());
        assert!(Gaussian2::from_packed([0.0; 2], [1.0, 2.0, 1.0]).information().is_none());
        let g = Gaussian2::from_packed([0.0; 2], [2.0, 1.0, 2.0]);
        assert!((g.largest_variance_nm2() - 3.0).abs() < TOL);
    }
}
