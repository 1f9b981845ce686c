//! Identification of the kinematic error and the compliance from recorded runs.
//!
//! Two steps, as in the HDA-arm paper:
//!
//! 1. **Kinematic error** from a no-load run: the torsion `θ_h = θ − θ_m/n_s` is regressed
//!    on a basis of the output angle (polynomial, the paper's form) or of the output and a
//!    mesh angle (Fourier, periodic), plus an optional direction term `d sgn θ̇` that takes
//!    up the constant wind-up of friction and hysteresis while turning. Linear least
//!    squares by Householder QR. The basis is chosen by the user or by k-fold
//!    cross-validation over contiguous folds ([`select_kinematic_basis`]).
//! 2. **Compliance** from a loaded run against a reference torque: the wind-up
//!    `w = θ_k − θ_h` and the reference torque give the spring's parameters. Where the
//!    model is linear in its parameters (linear or cubic stiffness, damping, no
//!    hysteresis, no offset) this is one QR solve; otherwise a Levenberg–Marquardt
//!    iteration whose residual is exactly what the core's streaming estimator computes
//!    (the estimator itself for a Dahl hysteresis; the same play operators and solver,
//!    with the parameter-free parts computed once, otherwise). Springs: linear, cubic,
//!    catalogue three-slope, the HDA-arm paper's pair, or known ones ([`ComplianceForm::Fixed`]);
//!    hysteresis: none, Dahl or play operators; optional damping and zero offset.
//!
//! When there is no no-load run (a real log), the mesh harmonics of the kinematic error
//! can be fitted from a loaded run with a slow trend taking up the load
//! ([`KinematicFitOptions::slow_trend_degree`]).
//!
//! Every fit reports R², RMS, mean and max |error| ([`FitMetrics`]).
//!
//! Angles are in the gear's convention (WG angle and output angle, rad, unwrapped); see
//! [`strainwave_core::torsion`] for the signs.

use strainwave_core::compliance::{
    Compliance, CubicStiffness, FlexsplineStiffening, HdaArmCompliance, Hysteresis, PlayHysteresis,
    ThreeSlopeStiffness, WaveGeneratorSoftening, MAX_PLAYS,
};
use strainwave_core::gear::Gear;
use strainwave_core::torsion::{
    EncoderConfig, EstimatorState, GearAngles, KinematicError, KinematicFourier, KinematicPolynomial, MeshAngle,
    NoKinematicError, TorqueSolver, TorsionEstimator,
};

use crate::error::AnalysisError;

const TAU: f64 = std::f64::consts::TAU;

fn invalid(what: &'static str, why: impl Into<String>) -> AnalysisError {
    AnalysisError::Invalid { what, why: why.into() }
}

fn check_finite(what: &'static str, x: &[f64]) -> Result<(), AnalysisError> {
    match x.iter().position(|v| !v.is_finite()) {
        Some(index) => Err(AnalysisError::NonFinite { what, index }),
        None => Ok(()),
    }
}

// ---------------------------------------------------------------------------------------
// Metrics
// ---------------------------------------------------------------------------------------

/// Goodness of a fit or of an estimate against a reference.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FitMetrics {
    /// `1 − Σe² / Σ(y − ȳ)²` (negative when worse than the reference's mean).
    pub r_squared: f64,
    /// RMS of the error.
    pub rms: f64,
    /// Mean |error|.
    pub mean_abs: f64,
    /// Max |error|.
    pub max_abs: f64,
    /// Samples compared.
    pub samples: usize,
}

impl FitMetrics {
    /// Metrics of `predicted` against `reference` over the pairs where both are finite.
    ///
    /// ```
    /// use strainwave_analysis::ident::FitMetrics;
    /// let m = FitMetrics::of(&[1.0, 2.0, 3.5], &[1.0, 2.0, 3.0]);
    /// assert_eq!(m.max_abs, 0.5);
    /// assert!((m.r_squared - (1.0 - 0.25 / 2.0)).abs() < 1e-12);
    /// ```
    pub fn of(predicted: &[f64], reference: &[f64]) -> FitMetrics {
        let pairs: Vec<(f64, f64)> = predicted
            .iter()
            .zip(reference)
            .filter(|(p, r)| p.is_finite() && r.is_finite())
            .map(|(p, r)| (*p, *r))
            .collect();
        let n = pairs.len();
        if n == 0 {
            return FitMetrics {
                r_squared: f64::NAN,
                rms: f64::NAN,
                mean_abs: f64::NAN,
                max_abs: f64::NAN,
                samples: 0,
            };
        }
        let mean_ref = pairs.iter().map(|p| p.1).sum::<f64>() / n as f64;
        let (mut sse, mut sst, mut sae, mut mae) = (0.0, 0.0, 0.0, 0.0_f64);
        for (p, r) in &pairs {
            let e = p - r;
            sse += e * e;
            sst += (r - mean_ref) * (r - mean_ref);
            sae += e.abs();
            mae = mae.max(e.abs());
        }
        FitMetrics {
            r_squared: if sst > 0.0 { 1.0 - sse / sst } else { f64::NAN },
            rms: (sse / n as f64).sqrt(),
            mean_abs: sae / n as f64,
            max_abs: mae,
            samples: n,
        }
    }
}

// ---------------------------------------------------------------------------------------
// Householder QR least squares (Levenberg–Marquardt in `lm`)
// ---------------------------------------------------------------------------------------

/// Solves `min ‖A x − b‖` by Householder QR with column scaling (no normal equations).
/// `columns` holds A by columns. A column of zeros or a rank-deficient A is an error.
///
/// ```
/// use strainwave_analysis::ident::lstsq_qr;
/// let x = lstsq_qr(&[vec![1.0, 1.0, 1.0], vec![0.0, 1.0, 2.0]], &[1.0, 3.0, 5.0]).unwrap();
/// assert!((x[0] - 1.0).abs() < 1e-12 && (x[1] - 2.0).abs() < 1e-12);
/// ```
pub fn lstsq_qr(columns: &[Vec<f64>], b: &[f64]) -> Result<Vec<f64>, AnalysisError> {
    let p = columns.len();
    let n = b.len();
    if p == 0 {
        return Err(invalid("regressors", "no columns"));
    }
    if n < p {
        return Err(AnalysisError::TooShort { what: "least squares rows", needed: p, got: n });
    }
    if columns.iter().any(|c| c.len() != n) {
        return Err(invalid("regressors", "columns and right-hand side differ in length"));
    }
    check_finite("right-hand side", b)?;
    for (j, c) in columns.iter().enumerate() {
        check_finite("regressors", c)?;
        if c.iter().all(|v| *v == 0.0) {
            return Err(invalid("regressors", format!("column {j} is all zeros (no excitation)")));
        }
    }
    // The shared column-scaled, column-pivoted Householder QR of `lstsq`, row-major.
    let a: Vec<f64> = (0..n).flat_map(|i| columns.iter().map(move |c| c[i])).collect();
    match crate::lstsq::lstsq_rtol(&a, p, b, 1e-11) {
        Ok(sol) => Ok(sol.x),
        Err(crate::lstsq::LstsqError::RankDeficient { column, .. }) => {
            Err(invalid("regressors", format!("rank deficient at column {column}: the data do not excite it")))
        }
        Err(e) => Err(invalid("regressors", e.to_string())),
    }
}

mod compliance;
mod compliance_fit;
mod friction;
mod holdout;
mod kinematic;
mod lm;

pub use compliance::*;
pub use compliance_fit::*;
pub use friction::*;
pub use holdout::*;
pub use kinematic::*;
pub use lm::*;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn qr_matches_exact_solution_and_flags_rank() {
        let n = 50;
        let x: Vec<f64> = (0..n).map(|i| i as f64 * 0.1).collect();
        let cols = vec![vec![1.0; n], x.clone(), x.iter().map(|v| v * v).collect()];
        let b: Vec<f64> = x.iter().map(|v| 2.0 - 0.5 * v + 0.25 * v * v).collect();
        let c = lstsq_qr(&cols, &b).unwrap();
        assert!((c[0] - 2.0).abs() < 1e-10 && (c[1] + 0.5).abs() < 1e-10 && (c[2] - 0.25).abs() < 1e-10);
        let dup = vec![x.clone(), x.iter().map(|v| 2.0 * v).collect()];
        assert!(lstsq_qr(&dup, &b).is_err());
        assert!(lstsq_qr(&[vec![0.0; n]], &b).is_err());
    }
}
