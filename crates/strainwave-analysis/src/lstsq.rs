//! Linear least squares by Householder QR (never the normal equations), with rank detection.
//!
//! Solves `min ‖A x − b‖₂` for a tall `A` (`m ≥ n`) given row-major:
//!
//! ```text
//! A D⁻¹ P = Q R        D = diag(‖A_:j‖) column equilibration, P column pivoting
//! R z = (Qᵀ b)[0..n],  x = D⁻¹ P z
//! r = b − A x          residuals, computed from the original A
//! σ² = ‖r‖² / (m − n)  Cov(x) = σ² (AᵀA)⁻¹ = σ² D⁻¹ P R⁻¹ R⁻ᵀ Pᵀ D⁻¹
//! ```
//!
//! The covariance goes through `R⁻¹` (a triangular inverse), so `AᵀA` is never formed.
//!
//! **Rank.** With unit-norm columns and pivoting, `|R_kk|` does not increase with `k`;
//! the problem is declared rank-deficient (singular) when
//! `|R_kk| ≤ rtol · |R_00|` for some `k`, with the default
//! `rtol = max(1e-12, ε · max(m, n))`. The error names the first column found to be
//! a combination of the others. A problem with condition number near `1/rtol` or
//! above is refused: its solution would carry no trustworthy digits.
//!
//! Helpers: [`polyfit`] (centred and scaled internally, coefficients returned in the
//! original variable, lowest order first), [`fit_line`], [`fit_through_origin`].

use crate::AnalysisError;

/// Why a least-squares problem could not be solved.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum LstsqError {
    /// Fewer rows (equations) than unknowns.
    #[error("least squares: {rows} rows for {unknowns} unknowns; needs at least as many rows as unknowns")]
    TooFewRows {
        /// Rows given.
        rows: usize,
        /// Unknowns.
        unknowns: usize,
    },
    /// Inconsistent sizes.
    #[error("least squares: `{what}` has {len} entries, expected {expected}")]
    Shape {
        /// Which input.
        what: &'static str,
        /// Entries given.
        len: usize,
        /// Entries expected.
        expected: usize,
    },
    /// A NaN or infinite entry.
    #[error("least squares: `{what}` row {row} column {col} is not finite")]
    NonFinite {
        /// Which input (`"a"`, `"b"`, `"x"`, `"y"`).
        what: &'static str,
        /// Row index (0-based).
        row: usize,
        /// Column index (0 for a vector).
        col: usize,
    },
    /// The columns are linearly dependent to within the tolerance.
    #[error(
        "singular least-squares problem: rank {rank} < {unknowns} unknowns \
         (column {column} is a combination of the others at relative tolerance {rtol:e})"
    )]
    RankDeficient {
        /// Numerical rank found.
        rank: usize,
        /// Unknowns.
        unknowns: usize,
        /// Original index of the first column judged dependent.
        column: usize,
        /// Relative tolerance used.
        rtol: f64,
    },
    /// A tolerance outside `[0, 1)` or NaN.
    #[error("least squares: relative tolerance {0} must lie in [0, 1)")]
    BadTolerance(f64),
}

impl From<LstsqError> for AnalysisError {
    fn from(e: LstsqError) -> Self {
        match e {
            LstsqError::TooFewRows { rows, unknowns } => {
                AnalysisError::TooShort { what: "least-squares rows", needed: unknowns, got: rows }
            }
            LstsqError::NonFinite { what, row, .. } => AnalysisError::NonFinite { what, index: row },
            other => AnalysisError::Invalid { what: "least squares", why: other.to_string() },
        }
    }
}

/// The default relative tolerance on `R`'s diagonal: `max(1e-12, ε · max(m, n))`.
pub fn default_rtol(rows: usize, unknowns: usize) -> f64 {
    (1e-12f64).max(f64::EPSILON * rows.max(unknowns) as f64)
}

/// A least-squares solution with what is needed for its covariance.
#[derive(Debug, Clone, PartialEq)]
pub struct LstsqSolution {
    /// The minimiser `x` (length n).
    pub x: Vec<f64>,
    /// `r = b − A x` (length m).
    pub residuals: Vec<f64>,
    /// `‖r‖₂`.
    pub residual_norm: f64,
    /// Rows m.
    pub rows: usize,
    /// Unknowns n.
    pub unknowns: usize,
    /// `R` of the equilibrated, pivoted problem, n×n row-major upper triangle.
    r: Vec<f64>,
    /// `perm[k]` = original column at pivoted position k.
    perm: Vec<usize>,
    /// Column norms used for equilibration.
    col_scale: Vec<f64>,
}

impl LstsqSolution {
    /// Residual variance `σ² = ‖r‖² / (m − n)`; `None` when `m = n`.
    pub fn sigma2(&self) -> Option<f64> {
        (self.rows > self.unknowns)
            .then(|| self.residual_norm * self.residual_norm / (self.rows - self.unknowns) as f64)
    }

    /// Parameter covariance `σ² (AᵀA)⁻¹`, n×n row-major, computed as
    /// `σ² D⁻¹ P R⁻¹ R⁻ᵀ Pᵀ D⁻¹` (no normal equations). `None` when `m = n`.
    pub fn covariance(&self) -> Option<Vec<f64>> {
        let s2 = self.sigma2()?;
        let n = self.unknowns;
        let rinv = upper_inverse(&self.r, n);
        let mut cov = vec![0.0; n * n];
        for i in 0..n {
            for j in 0..n {
                // (R⁻¹ R⁻ᵀ)_ij = Σ_k R⁻¹_ik R⁻¹_jk, k ≥ max(i, j).
                let c: f64 = (i.max(j)..n).map(|k| rinv[i * n + k] * rinv[j * n + k]).sum();
                let (pi, pj) = (self.perm[i], self.perm[j]);
                cov[pi * n + pj] = s2 * c / (self.col_scale[pi] * self.col_scale[pj]);
            }
        }
        Some(cov)
    }

    /// Standard errors `√diag(Cov)`; `None` when `m = n`.
    pub fn std_errors(&self) -> Option<Vec<f64>> {
        let n = self.unknowns;
        self.covariance().map(|c| (0..n).map(|i| c[i * n + i].sqrt()).collect())
    }

    /// `|R_nn| / |R_00|` of the equilibrated problem: a cheap reciprocal-condition estimate.
    pub fn rcond_estimate(&self) -> f64 {
        let n = self.unknowns;
        (self.r[(n - 1) * n + n - 1] / self.r[0]).abs()
    }
}

/// Inverse of an upper-triangular n×n row-major matrix with non-zero diagonal.
fn upper_inverse(r: &[f64], n: usize) -> Vec<f64> {
    let mut inv = vec![0.0; n * n];
    for j in 0..n {
        // Solve R v = e_j by back substitution; v is column j of R⁻¹.
        for i in (0..=j).rev() {
            let mut s = if i == j { 1.0 } else { 0.0 };
            for k in i + 1..=j {
                s -= r[i * n + k] * inv[k * n + j];
            }
            inv[i * n + j] = s / r[i * n + i];
        }
    }
    inv
}

/// Solves `min ‖A x − b‖₂` with the default tolerance ([`default_rtol`]).
///
/// `a` is row-major with `unknowns` columns; `b` has one entry per row.
///
/// ```
/// use strainwave_analysis::lstsq::lstsq;
/// // Fit y = c0 + c1 t to (0, 1), (1, 3), (2, 5): exact, c = (1, 2).
/// let a = [1.0, 0.0, 1.0, 1.0, 1.0, 2.0];
/// let s = lstsq(&a, 2, &[1.0, 3.0, 5.0]).unwrap();
/// assert!((s.x[0] - 1.0).abs() < 1e-14 && (s.x[1] - 2.0).abs() < 1e-14);
/// ```
pub fn lstsq(a: &[f64], unknowns: usize, b: &[f64]) -> Result<LstsqSolution, LstsqError> {
    let rows = a.len().checked_div(unknowns).unwrap_or(0);
    lstsq_rtol(a, unknowns, b, default_rtol(rows, unknowns))
}

/// As [`lstsq`] with an explicit relative tolerance on `R`'s diagonal (`0 ≤ rtol < 1`).
pub fn lstsq_rtol(a: &[f64], unknowns: usize, b: &[f64], rtol: f64) -> Result<LstsqSolution, LstsqError> {
    if !(0.0..1.0).contains(&rtol) {
        return Err(LstsqError::BadTolerance(rtol));
    }
    let n = unknowns;
    if n == 0 {
        return Err(LstsqError::Shape { what: "unknowns", len: 0, expected: 1 });
    }
    let m = b.len();
    if a.len() != m * n {
        return Err(LstsqError::Shape { what: "a", len: a.len(), expected: m * n });
    }
    if m < n {
        return Err(LstsqError::TooFewRows { rows: m, unknowns: n });
    }
    for (idx, v) in a.iter().enumerate() {
        if !v.is_finite() {
            return Err(LstsqError::NonFinite { what: "a", row: idx / n, col: idx % n });
        }
    }
    if let Some(row) = b.iter().position(|v| !v.is_finite()) {
        return Err(LstsqError::NonFinite { what: "b", row, col: 0 });
    }

    // Column-major working copy, each column scaled to unit norm.
    let mut col_scale = vec![1.0; n];
    let mut w = vec![0.0; m * n];
    for j in 0..n {
        let norm = norm2((0..m).map(|i| a[i * n + j]));
        if norm > 0.0 && norm.is_finite() {
            col_scale[j] = norm;
        }
        for i in 0..m {
            w[j * m + i] = a[i * n + j] / col_scale[j];
        }
    }
    let mut perm: Vec<usize> = (0..n).collect();
    let mut qtb = b.to_vec();
    let mut r = vec![0.0; n * n];
    let mut r00 = 0.0f64;

    for k in 0..n {
        // Pivot: the remaining column with the largest norm below row k.
        let mut best = k;
        let mut best_norm = -1.0;
        for j in k..n {
            let nj = norm2(w[j * m + k..j * m + m].iter().copied());
            if nj > best_norm {
                best_norm = nj;
                best = j;
            }
        }
        if best != k {
            for i in 0..m {
                w.swap(k * m + i, best * m + i);
            }
            perm.swap(k, best);
            for i in 0..k {
                r.swap(i * n + k, i * n + best);
            }
        }
        if k == 0 {
            r00 = best_norm;
        }
        if best_norm <= rtol * r00 || best_norm == 0.0 {
            return Err(LstsqError::RankDeficient { rank: k, unknowns: n, column: perm[k], rtol });
        }
        // Householder reflector H = I − β v vᵀ mapping w[k.., k] to (α, 0, …).
        let x0 = w[k * m + k];
        let alpha = if x0 >= 0.0 { -best_norm } else { best_norm };
        let mut v: Vec<f64> = w[k * m + k..k * m + m].to_vec();
        v[0] -= alpha;
        let vnorm2: f64 = v.iter().map(|t| t * t).sum();
        let beta = if vnorm2 > 0.0 { 2.0 / vnorm2 } else { 0.0 };
        r[k * n + k] = alpha;
        for j in k + 1..n {
            let col = &mut w[j * m + k..j * m + m];
            let s: f64 = v.iter().zip(col.iter()).map(|(p, q)| p * q).sum::<f64>() * beta;
            for (c, vi) in col.iter_mut().zip(&v) {
                *c -= s * vi;
            }
            r[k * n + j] = col[0];
        }
        let tail = &mut qtb[k..];
        let s: f64 = v.iter().zip(tail.iter()).map(|(p, q)| p * q).sum::<f64>() * beta;
        for (c, vi) in tail.iter_mut().zip(&v) {
            *c -= s * vi;
        }
    }

    // Back substitution R z = (Qᵀ b)[0..n], then undo pivoting and scaling.
    let mut z = vec![0.0; n];
    for i in (0..n).rev() {
        let s: f64 = (i + 1..n).map(|k| r[i * n + k] * z[k]).sum();
        z[i] = (qtb[i] - s) / r[i * n + i];
    }
    let mut x = vec![0.0; n];
    for k in 0..n {
        x[perm[k]] = z[k] / col_scale[perm[k]];
    }
    let residuals: Vec<f64> = (0..m).map(|i| b[i] - (0..n).map(|j| a[i * n + j] * x[j]).sum::<f64>()).collect();
    let residual_norm = norm2(residuals.iter().copied());
    Ok(LstsqSolution { x, residuals, residual_norm, rows: m, unknowns: n, r, perm, col_scale })
}

/// Euclidean norm, scaled to avoid overflow and underflow.
fn norm2(it: impl Iterator<Item = f64> + Clone) -> f64 {
    let big = it.clone().fold(0.0f64, |acc, v| acc.max(v.abs()));
    if big == 0.0 || !big.is_finite() {
        return big;
    }
    big * it.map(|v| (v / big) * (v / big)).sum::<f64>().sqrt()
}

/// A polynomial fit `y ≈ Σ_k c_k x^k`.
#[derive(Debug, Clone, PartialEq)]
pub struct PolyFit {
    /// Coefficients in the original variable `x`, **lowest order first** (`c_0` = intercept).
    /// Note: `numpy.polyfit` returns the highest order first.
    pub coeffs: Vec<f64>,
    /// Covariance of `coeffs` (same order), row-major; `None` with no redundancy (m = n).
    pub covariance: Option<Vec<f64>>,
    /// `y_i − p(x_i)`.
    pub residuals: Vec<f64>,
    /// `‖residuals‖₂`.
    pub residual_norm: f64,
    /// Centre `c` of the internal variable `u = (x − c)/s`.
    pub center: f64,
    /// Scale `s` of the internal variable.
    pub scale: f64,
    /// Coefficients in `u`, lowest order first (better conditioned for evaluation).
    pub scaled_coeffs: Vec<f64>,
}

impl PolyFit {
    /// `p(x)`, evaluated in the internal variable `u` (Horner), which is more accurate
    /// than expanding `coeffs` when `|c|/s` is large.
    pub fn eval(&self, x: f64) -> f64 {
        let u = (x - self.center) / self.scale;
        self.scaled_coeffs.iter().rev().fold(0.0, |acc, c| acc * u + c)
    }

    /// Standard errors of `coeffs`.
    pub fn std_errors(&self) -> Option<Vec<f64>> {
        let n = self.coeffs.len();
        self.covariance.as_ref().map(|c| (0..n).map(|i| c[i * n + i].sqrt()).collect())
    }
}

/// Least-squares polynomial of degree `degree` through `(x_i, y_i)`.
///
/// Internally the fit is made in `u = (x − c)/s` with `c` the mid-range and `s` the
/// half-range of `x`, so `u ∈ [−1, 1]`; the coefficients are then expanded back to the
/// original variable, **lowest order first**:
///
/// ```text
/// c_j = Σ_{k ≥ j} p_k s^(−k) C(k, j) (−c)^(k−j),   Cov(c) = T Cov(p) Tᵀ with the same map T
/// ```
///
/// Errors: fewer points than `degree + 1`, non-finite `x`/`y` (naming the row), fewer
/// distinct `x` than `degree + 1` (rank-deficient).
///
/// ```
/// use strainwave_analysis::lstsq::polyfit;
/// let x = [1.0, 2.0, 3.0, 4.0];
/// let y: Vec<f64> = x.iter().map(|t| 2.0 - t + 0.5 * t * t).collect();
/// let p = polyfit(&x, &y, 2).unwrap();
/// assert!((p.coeffs[0] - 2.0).abs() < 1e-12);
/// assert!((p.coeffs[1] + 1.0).abs() < 1e-12);
/// assert!((p.coeffs[2] - 0.5).abs() < 1e-12);
/// ```
pub fn polyfit(x: &[f64], y: &[f64], degree: usize) -> Result<PolyFit, LstsqError> {
    if y.len() != x.len() {
        return Err(LstsqError::Shape { what: "y", len: y.len(), expected: x.len() });
    }
    let n = degree + 1;
    if x.len() < n {
        return Err(LstsqError::TooFewRows { rows: x.len(), unknowns: n });
    }
    for (row, (xi, yi)) in x.iter().zip(y).enumerate() {
        if !xi.is_finite() {
            return Err(LstsqError::NonFinite { what: "x", row, col: 0 });
        }
        if !yi.is_finite() {
            return Err(LstsqError::NonFinite { what: "y", row, col: 0 });
        }
    }
    let lo = x.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = x.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let center = 0.5 * lo + 0.5 * hi;
    let half = 0.5 * hi - 0.5 * lo;
    if half == 0.0 && degree > 0 {
        return Err(LstsqError::RankDeficient { rank: 1, unknowns: n, column: 1, rtol: default_rtol(x.len(), n) });
    }
    let scale = if half > 0.0 { half } else { 1.0 };
    let mut a = Vec::with_capacity(x.len() * n);
    for &xi in x {
        let u = (xi - center) / scale;
        let mut p = 1.0;
        for _ in 0..n {
            a.push(p);
            p *= u;
        }
    }
    let sol = lstsq(&a, n, y)?;
    let t = expansion_matrix(center, scale, n);
    let coeffs: Vec<f64> = (0..n).map(|j| (0..n).map(|k| t[j * n + k] * sol.x[k]).sum()).collect();
    let covariance = sol.covariance().map(|cp| transform_covariance(&t, &cp, n));
    Ok(PolyFit {
        coeffs,
        covariance,
        residual_norm: sol.residual_norm,
        residuals: sol.residuals,
        center,
        scale,
        scaled_coeffs: sol.x,
    })
}

/// The n×n map `T` from coefficients in `u = (x − c)/s` to coefficients in `x`:
/// `T[j][k] = s^(−k) C(k, j) (−c)^(k−j)` for `k ≥ j`, else 0.
pub(crate) fn expansion_matrix(center: f64, scale: f64, n: usize) -> Vec<f64> {
    let mut t = vec![0.0; n * n];
    for k in 0..n {
        let sk = scale.powi(-(k as i32));
        let mut binom = 1.0; // C(k, j), built up from j = 0
        for j in 0..=k {
            t[j * n + k] = sk * binom * (-center).powi((k - j) as i32);
            binom = binom * (k - j) as f64 / (j + 1) as f64;
        }
    }
    t
}

/// `T C Tᵀ` for n×n row-major matrices.
pub(crate) fn transform_covariance(t: &[f64], c: &[f64], n: usize) -> Vec<f64> {
    let mut tc = vec![0.0; n * n];
    for i in 0..n {
        for j in 0..n {
            tc[i * n + j] = (0..n).map(|k| t[i * n + k] * c[k * n + j]).sum();
        }
    }
    let mut out = vec![0.0; n * n];
    for i in 0..n {
        for j in 0..n {
            out[i * n + j] = (0..n).map(|k| tc[i * n + k] * t[j * n + k]).sum();
        }
    }
    out
}

/// Straight line `y ≈ slope · x + intercept`; returns `(slope, intercept)`.
///
/// ```
/// use strainwave_analysis::lstsq::fit_line;
/// let (k, c) = fit_line(&[0.0, 1.0, 2.0], &[0.5, 2.5, 4.5]).unwrap();
/// assert!((k - 2.0).abs() < 1e-14 && (c - 0.5).abs() < 1e-14);
/// ```
pub fn fit_line(x: &[f64], y: &[f64]) -> Result<(f64, f64), LstsqError> {
    let p = polyfit(x, y, 1)?;
    Ok((p.coeffs[1], p.coeffs[0]))
}

/// Line through the origin `y ≈ g · x`; returns `g`. Singular when every `x` is 0.
///
/// ```
/// use strainwave_analysis::lstsq::fit_through_origin;
/// let g = fit_through_origin(&[1.0, 2.0], &[6.6, 13.2]).unwrap();
/// assert!((g - 6.6).abs() < 1e-14);
/// ```
pub fn fit_through_origin(x: &[f64], y: &[f64]) -> Result<f64, LstsqError> {
    if y.len() != x.len() {
        return Err(LstsqError::Shape { what: "y", len: y.len(), expected: x.len() });
    }
    for (row, (xi, yi)) in x.iter().zip(y).enumerate() {
        if !xi.is_finite() {
            return Err(LstsqError::NonFinite { what: "x", row, col: 0 });
        }
        if !yi.is_finite() {
            return Err(LstsqError::NonFinite { what: "y", row, col: 0 });
        }
    }
    Ok(lstsq(x, 1, y)?.x[0])
}

#[cfg(test)]
mod tests;
