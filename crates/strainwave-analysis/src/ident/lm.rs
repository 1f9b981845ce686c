//! Levenberg–Marquardt with stated termination and parameter standard errors.
//!
//! Damped Gauss–Newton with Marquardt's diagonal scaling and a forward-difference
//! Jacobian `J`; each step solves `[J; √λ D] δ = [−r; 0]` by QR. It stops on the first of
//!
//! - **gradient**: `max_j |J_jᵀ r| / (‖J_j‖ ‖r‖) ≤ gtol` (the residual is orthogonal to
//!   every column: a stationary point);
//! - **step**: `|δ_j| ≤ xtol (|p_j| + xtol)` for every parameter;
//! - **cost**: an accepted step lowers `½‖r‖²` by less than `ftol` relative (default
//!   1e-5: the RMS then moves by less than 5e-6 relative per step; on the arm twin's
//!   HDA-arm spring pair with plays the iteration otherwise crawls along a flat valley, the cost
//!   falling 0.05 % over twenty more iterations);
//! - the iteration cap, or no step lowering the cost even at a large damping.
//!
//! The first three are convergence; the last two are not ([`LmTermination::converged`]).
//! Standard errors come from the Jacobian at the end:
//! `Cov(p) = σ² (JᵀJ)⁻¹`, `σ² = ‖r‖² / (n − p)`, through the QR of `J` (no normal equations).

use super::*;

/// Why the iteration stopped.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum LmTermination {
    /// The gradient test passed (stationary point).
    Gradient,
    /// The step became negligible against the parameters.
    Step,
    /// The cost stopped decreasing (relative reduction below tolerance).
    Cost,
    /// The iteration cap was reached first.
    IterationLimit,
    /// No step lowered the cost, even heavily damped, before any test passed.
    NoDescent,
}

impl LmTermination {
    /// Whether this is a convergence (gradient, step or cost test).
    pub fn converged(self) -> bool {
        matches!(self, LmTermination::Gradient | LmTermination::Step | LmTermination::Cost)
    }

    /// A short phrase for messages.
    pub fn describe(self) -> &'static str {
        match self {
            LmTermination::Gradient => "converged (gradient test)",
            LmTermination::Step => "converged (step test)",
            LmTermination::Cost => "converged (cost test)",
            LmTermination::IterationLimit => "not converged: iteration limit reached",
            LmTermination::NoDescent => "not converged: no step lowers the cost",
        }
    }
}

/// Tolerances of [`levenberg_marquardt`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LmTolerances {
    /// Gradient (cosine) tolerance.
    pub gtol: f64,
    /// Relative step tolerance.
    pub xtol: f64,
    /// Relative cost-reduction tolerance.
    pub ftol: f64,
}

impl Default for LmTolerances {
    fn default() -> Self {
        Self { gtol: 1e-6, xtol: 1e-10, ftol: 1e-5 }
    }
}

/// Result of [`levenberg_marquardt`].
#[derive(Debug, Clone, PartialEq)]
pub struct LmResult {
    /// Parameters at the end.
    pub params: Vec<f64>,
    /// Final `½ Σ r²`.
    pub cost: f64,
    /// Iterations (Jacobian evaluations).
    pub iterations: usize,
    /// Why it stopped.
    pub termination: LmTermination,
    /// Standard errors of the parameters from the final Jacobian (`None` when it is
    /// rank deficient or there are no spare residuals).
    pub std_errors: Option<Vec<f64>>,
    /// Their covariance `σ² (JᵀJ)⁻¹`, row-major (`None` likewise).
    pub covariance: Option<Vec<f64>>,
}

/// Forward-difference Jacobian by columns (backward where the forward point fails).
fn jacobian<F>(p: &[f64], r: &[f64], residual: &mut F) -> Result<Vec<Vec<f64>>, AnalysisError>
where
    F: FnMut(&[f64], &mut [f64]) -> bool,
{
    let mut r_trial = vec![0.0; r.len()];
    let mut jac = Vec::with_capacity(p.len());
    for j in 0..p.len() {
        let h = 1e-6 * (1.0 + p[j].abs());
        let mut pj = p.to_vec();
        pj[j] += h;
        if residual(&pj, &mut r_trial) && r_trial.iter().all(|v| v.is_finite()) {
            jac.push(r_trial.iter().zip(r).map(|(a, b)| (a - b) / h).collect());
        } else {
            pj[j] = p[j] - h;
            if !(residual(&pj, &mut r_trial) && r_trial.iter().all(|v| v.is_finite())) {
                return Err(invalid("parameters", "the model cannot be evaluated near the current point"));
            }
            jac.push(r_trial.iter().zip(r).map(|(a, b)| (b - a) / h).collect());
        }
    }
    Ok(jac)
}

/// `σ² (JᵀJ)⁻¹` from a column-major Jacobian and the residual (the least-squares
/// problem `J δ = −r`, whose residual at a minimum is `−r`).
fn covariance_of(jac: &[Vec<f64>], r: &[f64]) -> Option<Vec<f64>> {
    let np = jac.len();
    let a: Vec<f64> = (0..r.len()).flat_map(|i| jac.iter().map(move |c| c[i])).collect();
    let b: Vec<f64> = r.iter().map(|v| -v).collect();
    crate::lstsq::lstsq(&a, np, &b).ok()?.covariance()
}

/// Minimizes `½ Σ r(p)²` from `p0` (see the module doc). `residual(p, r)` fills `r`
/// (length `n_residuals`) and returns `false` where the model cannot be evaluated (the
/// step is then rejected). Errors only when the start point or its neighbourhood cannot
/// be evaluated; a fit that does not converge is reported by its termination.
pub fn levenberg_marquardt<F>(
    p0: &[f64],
    n_residuals: usize,
    max_iterations: usize,
    tolerances: LmTolerances,
    mut residual: F,
) -> Result<LmResult, AnalysisError>
where
    F: FnMut(&[f64], &mut [f64]) -> bool,
{
    let np = p0.len();
    if np == 0 {
        return Err(invalid("parameters", "nothing to fit"));
    }
    if n_residuals < np {
        return Err(AnalysisError::TooShort { what: "residuals", needed: np, got: n_residuals });
    }
    let mut p = p0.to_vec();
    let mut r = vec![0.0; n_residuals];
    if !residual(&p, &mut r) || r.iter().any(|v| !v.is_finite()) {
        return Err(invalid("initial parameters", "the model cannot be evaluated at the starting point"));
    }
    let cost_of = |r: &[f64]| 0.5 * r.iter().map(|v| v * v).sum::<f64>();
    let mut cost = cost_of(&r);
    let mut lambda: f64 = 1e-3;
    let mut r_trial = vec![0.0; n_residuals];
    let mut iterations = 0;
    let mut termination = LmTermination::IterationLimit;
    let mut jac = jacobian(&p, &r, &mut residual)?;
    while iterations < max_iterations {
        iterations += 1;
        let r_norm = r.iter().map(|v| v * v).sum::<f64>().sqrt();
        let col_norm: Vec<f64> = jac.iter().map(|c| c.iter().map(|v| v * v).sum::<f64>().sqrt()).collect();
        // Gradient test.
        let gmax = jac
            .iter()
            .zip(&col_norm)
            .map(|(c, n)| {
                let g = c.iter().zip(&r).map(|(a, b)| a * b).sum::<f64>().abs();
                if *n > 0.0 && r_norm > 0.0 {
                    g / (n * r_norm)
                } else {
                    0.0
                }
            })
            .fold(0.0, f64::max);
        if gmax <= tolerances.gtol {
            termination = LmTermination::Gradient;
            break;
        }
        let dscale: Vec<f64> = col_norm.iter().map(|v| v.max(1e-300)).collect();
        let mut rhs: Vec<f64> = r.iter().map(|v| -v).collect();
        rhs.resize(n_residuals + np, 0.0);
        let mut accepted = None;
        for _ in 0..16 {
            let cols: Vec<Vec<f64>> = jac
                .iter()
                .enumerate()
                .map(|(j, c)| {
                    let mut col = c.clone();
                    col.extend((0..np).map(|i| if i == j { lambda.sqrt() * dscale[j] } else { 0.0 }));
                    col
                })
                .collect();
            let Ok(delta) = lstsq_qr(&cols, &rhs) else {
                lambda *= 10.0;
                continue;
            };
            let trial: Vec<f64> = p.iter().zip(&delta).map(|(a, d)| a + d).collect();
            if residual(&trial, &mut r_trial) && r_trial.iter().all(|v| v.is_finite()) {
                let c = cost_of(&r_trial);
                if c < cost {
                    accepted = Some((trial, delta, c));
                    break;
                }
            }
            lambda *= 4.0;
        }
        let Some((trial, delta, c)) = accepted else {
            termination = LmTermination::NoDescent;
            break;
        };
        let rel = (cost - c) / cost.max(1e-300);
        let small_step = delta.iter().zip(&p).all(|(d, x)| d.abs() <= tolerances.xtol * (x.abs() + tolerances.xtol));
        p = trial;
        std::mem::swap(&mut r, &mut r_trial);
        cost = c;
        lambda = (lambda / 3.0).max(1e-12);
        jac = jacobian(&p, &r, &mut residual)?;
        if small_step {
            termination = LmTermination::Step;
            break;
        }
        if rel < tolerances.ftol {
            termination = LmTermination::Cost;
            break;
        }
    }
    let covariance = covariance_of(&jac, &r);
    let std_errors = covariance.as_ref().map(|c| (0..np).map(|i| c[i * np + i].sqrt()).collect());
    Ok(LmResult { params: p, cost, iterations, termination, std_errors, covariance })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn exp_problem() -> (Vec<f64>, Vec<f64>) {
        let t: Vec<f64> = (0..40).map(|i| i as f64 * 0.1).collect();
        // A small deterministic disturbance so that the standard errors are not zero.
        let y: Vec<f64> =
            t.iter().enumerate().map(|(i, t)| 3.0 * (-0.7 * t).exp() + 1e-3 * (i as f64 * 1.7).sin()).collect();
        (t, y)
    }

    #[test]
    fn fits_an_exponential_and_reports_convergence_and_errors() {
        let (t, y) = exp_problem();
        let r = levenberg_marquardt(&[1.0, 0.0], t.len(), 100, LmTolerances::default(), |p, r| {
            for ((ri, ti), yi) in r.iter_mut().zip(&t).zip(&y) {
                *ri = p[0] * (p[1] * ti).exp() - yi;
            }
            true
        })
        .unwrap();
        assert!((r.params[0] - 3.0).abs() < 1e-2 && (r.params[1] + 0.7).abs() < 1e-2, "{r:?}");
        assert!(r.termination.converged(), "{r:?}");
        let se = r.std_errors.as_ref().unwrap();
        // The errors are of the disturbance's size, and bracket the truth within a few σ.
        assert!(se.iter().all(|s| *s > 1e-6 && *s < 1e-2), "{se:?}");
        assert!((r.params[0] - 3.0).abs() < 6.0 * se[0] && (r.params[1] + 0.7).abs() < 6.0 * se[1], "{r:?}");
    }

    #[test]
    fn iteration_limit_is_not_convergence() {
        let (t, y) = exp_problem();
        let r = levenberg_marquardt(&[1.0, 0.0], t.len(), 2, LmTolerances::default(), |p, r| {
            for ((ri, ti), yi) in r.iter_mut().zip(&t).zip(&y) {
                *ri = p[0] * (p[1] * ti).exp() - yi;
            }
            true
        })
        .unwrap();
        assert_eq!(r.termination, LmTermination::IterationLimit);
        assert!(!r.termination.converged());
    }
}
