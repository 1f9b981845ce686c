//! Identification of the kinematic error and the compliance from recorded runs (SPEC §5).
//!
//! Two steps, as in seed 002:
//!
//! 1. **Kinematic error** from a no-load run: the torsion `θ_h = θ − θ_m/n_s` is regressed
//!    on a basis of the output angle (polynomial, the seed's form) or of the output and a
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
//!    catalogue three-slope, seed 002's pair, or known ones ([`ComplianceForm::Fixed`]);
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
    Compliance, CubicStiffness, FlexsplineStiffening, Hysteresis, PlayHysteresis, SeedCompliance, ThreeSlopeStiffness,
    WaveGeneratorSoftening, MAX_PLAYS,
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
// Householder QR least squares and Levenberg–Marquardt
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
    let mut a: Vec<Vec<f64>> = Vec::with_capacity(p);
    let mut scale = Vec::with_capacity(p);
    for (j, c) in columns.iter().enumerate() {
        check_finite("regressors", c)?;
        let norm = c.iter().map(|v| v * v).sum::<f64>().sqrt();
        if norm == 0.0 {
            return Err(invalid("regressors", format!("column {j} is all zeros (no excitation)")));
        }
        scale.push(norm);
        a.push(c.iter().map(|v| v / norm).collect());
    }
    let mut rhs = b.to_vec();
    let mut diag = vec![0.0; p];
    for k in 0..p {
        let alpha = a[k][k..].iter().map(|v| v * v).sum::<f64>().sqrt();
        let alpha = if a[k][k] > 0.0 { -alpha } else { alpha };
        diag[k] = alpha;
        if alpha == 0.0 {
            continue;
        }
        // v = x − α e1, stored in place of the column.
        a[k][k] -= alpha;
        let vnorm2 = a[k][k..].iter().map(|v| v * v).sum::<f64>();
        if vnorm2 == 0.0 {
            continue;
        }
        let (head, tail) = a.split_at_mut(k + 1);
        let v = &head[k][k..];
        for col in tail.iter_mut() {
            let dot: f64 = v.iter().zip(&col[k..]).map(|(x, y)| x * y).sum();
            let f = 2.0 * dot / vnorm2;
            for (c, vi) in col[k..].iter_mut().zip(v) {
                *c -= f * vi;
            }
        }
        let dot: f64 = v.iter().zip(&rhs[k..]).map(|(x, y)| x * y).sum();
        let f = 2.0 * dot / vnorm2;
        for (c, vi) in rhs[k..].iter_mut().zip(v) {
            *c -= f * vi;
        }
    }
    let dmax = diag.iter().fold(0.0_f64, |m, d| m.max(d.abs()));
    for (j, d) in diag.iter().enumerate() {
        if d.abs() <= 1e-11 * dmax {
            return Err(invalid("regressors", format!("rank deficient at column {j}: the data do not excite it")));
        }
    }
    let mut x = vec![0.0; p];
    for k in (0..p).rev() {
        let mut s = rhs[k];
        for (j, xj) in x.iter().enumerate().skip(k + 1) {
            s -= a[j][k] * xj;
        }
        x[k] = s / diag[k];
    }
    Ok(x.iter().zip(&scale).map(|(xi, s)| xi / s).collect())
}

/// Result of [`levenberg_marquardt`].
#[derive(Debug, Clone, PartialEq)]
pub struct LmResult {
    /// Parameters at the minimum.
    pub params: Vec<f64>,
    /// Final `½ Σ r²`.
    pub cost: f64,
    /// Iterations (Jacobian evaluations).
    pub iterations: usize,
}

/// Damped Gauss–Newton (Levenberg–Marquardt, Marquardt's diagonal scaling) with a
/// forward-difference Jacobian; each step solves the augmented least-squares problem
/// `[J; √λ D] δ = [−r; 0]` by QR. `residual(p, r)` fills `r` (length `n_residuals`) and
/// returns `false` where the model cannot be evaluated (the step is then rejected).
pub fn levenberg_marquardt<F>(
    p0: &[f64],
    n_residuals: usize,
    max_iterations: usize,
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
    for _ in 0..max_iterations {
        iterations += 1;
        // Jacobian by forward differences.
        let mut jac: Vec<Vec<f64>> = Vec::with_capacity(np);
        for j in 0..np {
            let h = 1e-6 * (1.0 + p[j].abs());
            let mut pj = p.clone();
            pj[j] += h;
            if !residual(&pj, &mut r_trial) {
                pj[j] = p[j] - h;
                if !residual(&pj, &mut r_trial) {
                    return Err(invalid("parameters", "the model cannot be evaluated near the current point"));
                }
                jac.push(r_trial.iter().zip(&r).map(|(a, b)| (b - a) / h).collect());
            } else {
                jac.push(r_trial.iter().zip(&r).map(|(a, b)| (a - b) / h).collect());
            }
        }
        let dscale: Vec<f64> = jac.iter().map(|c| c.iter().map(|v| v * v).sum::<f64>().sqrt().max(1e-300)).collect();
        let mut rhs: Vec<f64> = r.iter().map(|v| -v).collect();
        rhs.resize(n_residuals + np, 0.0);
        let mut improved = false;
        for _ in 0..12 {
            let cols: Vec<Vec<f64>> = jac
                .iter()
                .enumerate()
                .map(|(j, c)| {
                    let mut col = c.clone();
                    col.extend((0..np).map(|i| if i == j { lambda.sqrt() * dscale[j] } else { 0.0 }));
                    col
                })
                .collect();
            let delta = match lstsq_qr(&cols, &rhs) {
                Ok(d) => d,
                Err(_) => {
                    lambda *= 10.0;
                    continue;
                }
            };
            let trial: Vec<f64> = p.iter().zip(&delta).map(|(a, d)| a + d).collect();
            if residual(&trial, &mut r_trial) && r_trial.iter().all(|v| v.is_finite()) {
                let c = cost_of(&r_trial);
                if c < cost {
                    let rel = (cost - c) / cost.max(1e-300);
                    p = trial;
                    std::mem::swap(&mut r, &mut r_trial);
                    cost = c;
                    lambda = (lambda / 3.0).max(1e-12);
                    improved = true;
                    if rel < 1e-9 {
                        return Ok(LmResult { params: p, cost, iterations });
                    }
                    break;
                }
            }
            lambda *= 4.0;
        }
        if !improved {
            break;
        }
    }
    Ok(LmResult { params: p, cost, iterations })
}

// ---------------------------------------------------------------------------------------
// Kinematic error
// ---------------------------------------------------------------------------------------

/// Motor and link angles of a run, in the gear's convention (rad, unwrapped).
#[derive(Debug, Clone, Copy)]
pub struct JointAngles<'a> {
    /// WG (motor) angle.
    pub motor_angle_rad: &'a [f64],
    /// Output (link) angle.
    pub link_angle_rad: &'a [f64],
    /// Sample rate, Hz.
    pub sample_rate_hz: f64,
}

impl JointAngles<'_> {
    fn check(&self, min_len: usize) -> Result<usize, AnalysisError> {
        let n = self.motor_angle_rad.len();
        if self.link_angle_rad.len() != n {
            return Err(invalid("link_angle_rad", "differs in length from motor_angle_rad"));
        }
        if n < min_len {
            return Err(AnalysisError::TooShort { what: "joint angles", needed: min_len, got: n });
        }
        if !(self.sample_rate_hz.is_finite() && self.sample_rate_hz > 0.0) {
            return Err(invalid("sample_rate_hz", format!("must be positive, got {}", self.sample_rate_hz)));
        }
        check_finite("motor_angle_rad", self.motor_angle_rad)?;
        check_finite("link_angle_rad", self.link_angle_rad)?;
        Ok(n)
    }

    /// Torsion `θ_h` per sample (f64 throughout), rad.
    pub fn torsion_rad(&self, gear: &Gear<f64>) -> Vec<f64> {
        let n_s = gear.signed_ratio();
        self.motor_angle_rad.iter().zip(self.link_angle_rad).map(|(m, l)| l - m / n_s).collect()
    }

    fn angles(&self, gear: &Gear<f64>, k: usize) -> GearAngles<f64> {
        GearAngles::from_f64(gear, self.motor_angle_rad[k], self.link_angle_rad[k])
    }

    /// Direction of the output, `sgn θ̇` over ±5 samples, 0 below `min_speed_rad_s`.
    fn direction(&self, min_speed_rad_s: f64) -> Vec<f64> {
        let l = self.link_angle_rad;
        let n = l.len();
        (0..n)
            .map(|k| {
                let (a, b) = (k.saturating_sub(5), (k + 5).min(n - 1));
                if b == a {
                    return 0.0;
                }
                let v = (l[b] - l[a]) / (b - a) as f64 * self.sample_rate_hz;
                if v.abs() < min_speed_rad_s {
                    0.0
                } else {
                    v.signum()
                }
            })
            .collect()
    }
}

/// The form of a kinematic-error model.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum KinematicBasis {
    /// `Σ_{i=0..order} a_i θ^i` in the output angle (seed 002: order 5).
    Polynomial {
        /// Highest power.
        order: usize,
    },
    /// `c0 + Σ_{h≤HO} (a_h cos hθ + b_h sin hθ) + Σ_{h≤HR} (c_h cos hψ + d_h sin hψ)`.
    Fourier {
        /// Output harmonics `HO`.
        output_harmonics: usize,
        /// Mesh harmonics `HR`.
        mesh_harmonics: usize,
        /// The mesh angle `ψ`.
        mesh_angle: MeshAngle,
    },
}

impl KinematicBasis {
    /// Number of coefficients.
    pub fn n_terms(&self) -> usize {
        match *self {
            KinematicBasis::Polynomial { order } => order + 1,
            KinematicBasis::Fourier { output_harmonics, mesh_harmonics, .. } => {
                1 + 2 * (output_harmonics + mesh_harmonics)
            }
        }
    }

    fn fill(&self, a: &GearAngles<f64>, out: &mut Vec<f64>) {
        out.clear();
        match *self {
            KinematicBasis::Polynomial { order } => {
                let mut x = 1.0;
                for _ in 0..=order {
                    out.push(x);
                    x *= a.output_rad;
                }
            }
            KinematicBasis::Fourier { output_harmonics, mesh_harmonics, mesh_angle } => {
                out.push(1.0);
                let psi = match mesh_angle {
                    MeshAngle::Relative => a.relative_rad,
                    MeshAngle::Motor => a.motor_rad,
                };
                for (angle, count) in [(a.output_rad, output_harmonics), (psi, mesh_harmonics)] {
                    for h in 1..=count {
                        let (s, c) = (h as f64 * angle).sin_cos();
                        out.push(c);
                        out.push(s);
                    }
                }
            }
        }
    }
}

/// Options of the kinematic fit.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct KinematicFitOptions {
    /// Fit a direction term `d sgn θ̇` (friction and hysteresis wind-up while turning);
    /// dropped when the run turns one way only.
    pub direction_offset: bool,
    /// Below this output speed the direction is taken as 0, rad/s.
    pub min_speed_rad_s: f64,
    /// Degree of a slow trend (Legendre polynomial in time, degrees 1 ..= d) fitted
    /// alongside and discarded: it takes up a slowly varying load, so that the mesh
    /// harmonics can be identified from a loaded run when there is no no-load run.
    /// Mesh harmonics only (output-angle terms would be confounded with it); not for
    /// cross-validation (a trend does not extrapolate into a held-out fold). 0 = none.
    pub slow_trend_degree: usize,
}

impl Default for KinematicFitOptions {
    fn default() -> Self {
        Self { direction_offset: true, min_speed_rad_s: 0.02, slow_trend_degree: 0 }
    }
}

/// A fitted kinematic error. Implements the core's [`KinematicError`], so an estimator can use it directly.
#[derive(Debug, Clone, PartialEq)]
pub struct KinematicFit {
    /// The basis.
    pub basis: KinematicBasis,
    /// Coefficients in the basis order (see [`KinematicBasis`]), rad.
    pub coefficients: Vec<f64>,
    /// Direction term `d`, rad (0 when not fitted).
    pub direction_offset_rad: f64,
    /// Fit of the torsion on the identification run.
    pub metrics: FitMetrics,
}

impl KinematicFit {
    /// `θ_k` at the given angles, rad.
    pub fn eval(&self, angles: &GearAngles<f64>) -> f64 {
        let mut row = Vec::with_capacity(self.coefficients.len());
        self.basis.fill(angles, &mut row);
        row.iter().zip(&self.coefficients).map(|(a, c)| a * c).sum()
    }

    /// `θ_k` along a run, rad.
    pub fn eval_run(&self, gear: &Gear<f64>, angles: &JointAngles) -> Vec<f64> {
        (0..angles.motor_angle_rad.len()).map(|k| self.eval(&angles.angles(gear, k))).collect()
    }

    /// The core's const-generic Fourier model (harmonics beyond the fit are zero).
    pub fn to_fourier<const HO: usize, const HR: usize>(&self) -> Result<KinematicFourier<f64, HO, HR>, AnalysisError> {
        let KinematicBasis::Fourier { output_harmonics, mesh_harmonics, mesh_angle } = self.basis else {
            return Err(invalid("basis", "not a Fourier fit"));
        };
        if output_harmonics > HO || mesh_harmonics > HR {
            return Err(invalid("basis", format!("{output_harmonics}/{mesh_harmonics} harmonics exceed {HO}/{HR}")));
        }
        let c = &self.coefficients;
        let mut out = [[0.0; 2]; HO];
        let mut mesh = [[0.0; 2]; HR];
        for h in 0..output_harmonics {
            out[h] = [c[1 + 2 * h], c[2 + 2 * h]];
        }
        let base = 1 + 2 * output_harmonics;
        for h in 0..mesh_harmonics {
            mesh[h] = [c[base + 2 * h], c[base + 1 + 2 * h]];
        }
        KinematicFourier::new(c[0], out, mesh, mesh_angle).map_err(|e| invalid("coefficients", e.to_string()))
    }

    /// The core's polynomial model (`D` ≥ order + 1; higher coefficients zero).
    pub fn to_polynomial<const D: usize>(&self) -> Result<KinematicPolynomial<f64, D>, AnalysisError> {
        let KinematicBasis::Polynomial { order } = self.basis else {
            return Err(invalid("basis", "not a polynomial fit"));
        };
        if order + 1 > D {
            return Err(invalid("basis", format!("order {order} needs {} coefficients, have {D}", order + 1)));
        }
        let mut a = [0.0; D];
        a[..=order].copy_from_slice(&self.coefficients);
        KinematicPolynomial::new(a).map_err(|e| invalid("coefficients", e.to_string()))
    }
}

impl KinematicError<f64> for KinematicFit {
    fn kinematic_error_rad(&self, angles: &GearAngles<f64>) -> f64 {
        self.eval(angles)
    }
}

/// Checks that the run moves enough for the basis.
fn check_motion(basis: &KinematicBasis, angles: &JointAngles) -> Result<(), AnalysisError> {
    let span = |x: &[f64]| {
        let (lo, hi) = x.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| (a.min(*v), b.max(*v)));
        hi - lo
    };
    let out_span = span(angles.link_angle_rad);
    let motor_span = span(angles.motor_angle_rad);
    match *basis {
        KinematicBasis::Polynomial { order } => {
            if out_span < 1e-3 * order.max(1) as f64 {
                return Err(invalid(
                    "link_angle_rad",
                    format!("spans {out_span:.2e} rad: no motion to fit a polynomial of order {order} on"),
                ));
            }
        }
        KinematicBasis::Fourier { output_harmonics, mesh_harmonics, .. } => {
            if output_harmonics > 0 && out_span < 0.95 * TAU {
                return Err(invalid(
                    "link_angle_rad",
                    format!("spans {out_span:.3} rad; output harmonics need a full revolution ({TAU:.3} rad)"),
                ));
            }
            if mesh_harmonics > 0 && motor_span < TAU {
                return Err(invalid(
                    "motor_angle_rad",
                    format!("spans {motor_span:.3} rad; mesh harmonics need a full motor revolution"),
                ));
            }
        }
    }
    Ok(())
}

struct KinematicDesign {
    columns: Vec<Vec<f64>>,
    torsion: Vec<f64>,
    /// Whether the last column is the direction term (dropped when the run turns one way
    /// only: it would duplicate the constant).
    direction: bool,
}

fn kinematic_design(
    basis: &KinematicBasis,
    gear: &Gear<f64>,
    angles: &JointAngles,
    opts: &KinematicFitOptions,
) -> KinematicDesign {
    let n = angles.motor_angle_rad.len();
    let nt = basis.n_terms();
    let mut columns = vec![Vec::with_capacity(n); nt];
    let mut row = Vec::with_capacity(nt);
    for k in 0..n {
        basis.fill(&angles.angles(gear, k), &mut row);
        for (c, v) in columns.iter_mut().zip(&row) {
            c.push(*v);
        }
    }
    let mut direction = false;
    if opts.direction_offset {
        let d = angles.direction(opts.min_speed_rad_s);
        if d.iter().any(|v| *v != d[0]) {
            columns.push(d);
            direction = true;
        }
    }
    if opts.slow_trend_degree > 0 && n > 1 {
        let mut prev: Vec<f64> = vec![1.0; n];
        let mut cur: Vec<f64> = (0..n).map(|k| 2.0 * k as f64 / (n - 1) as f64 - 1.0).collect();
        for deg in 1..=opts.slow_trend_degree {
            columns.push(cur.clone());
            let m = deg as f64;
            let next: Vec<f64> = (0..n)
                .map(|k| {
                    let t = 2.0 * k as f64 / (n - 1) as f64 - 1.0;
                    ((2.0 * m + 1.0) * t * cur[k] - m * prev[k]) / (m + 1.0)
                })
                .collect();
            prev = std::mem::replace(&mut cur, next);
        }
    }
    KinematicDesign { columns, torsion: angles.torsion_rad(gear), direction }
}

fn solve_kinematic(
    basis: KinematicBasis,
    design: &KinematicDesign,
    rows: &[usize],
) -> Result<(Vec<f64>, f64), AnalysisError> {
    let cols: Vec<Vec<f64>> = design.columns.iter().map(|c| rows.iter().map(|&k| c[k]).collect()).collect();
    let b: Vec<f64> = rows.iter().map(|&k| design.torsion[k]).collect();
    let x = lstsq_qr(&cols, &b)?;
    let nt = basis.n_terms();
    let d = if design.direction { x[nt] } else { 0.0 };
    Ok((x, d))
}

/// Fitted torsion on `rows`; `coef` holds every column's coefficient (basis, direction, trend).
fn predict_rows(design: &KinematicDesign, coef: &[f64], rows: &[usize]) -> Vec<f64> {
    rows.iter().map(|&k| design.columns.iter().zip(coef).map(|(c, x)| c[k] * x).sum()).collect()
}

/// Fits the kinematic error from a no-load run: `θ_h ≈ θ_k(θ, ψ) + d sgn θ̇`.
///
/// Errors: too few samples, non-finite angles, a run that does not move enough for the
/// basis (a Fourier output series needs a full output revolution), or a rank-deficient basis.
pub fn fit_kinematic_error(
    gear: &Gear<f64>,
    angles: &JointAngles,
    basis: KinematicBasis,
    opts: &KinematicFitOptions,
) -> Result<KinematicFit, AnalysisError> {
    let n = angles.check(2 * (basis.n_terms() + opts.slow_trend_degree) + 2)?;
    check_motion(&basis, angles)?;
    if opts.slow_trend_degree > 0
        && !matches!(basis, KinematicBasis::Fourier { output_harmonics: 0, mesh_harmonics: 1.., .. })
    {
        return Err(invalid(
            "slow_trend_degree",
            "a slow trend is confounded with output-angle terms: use mesh harmonics only",
        ));
    }
    let design = kinematic_design(&basis, gear, angles, opts);
    let rows: Vec<usize> = (0..n).collect();
    let (all, d) = solve_kinematic(basis, &design, &rows)?;
    let fitted = predict_rows(&design, &all, &rows);
    let metrics = FitMetrics::of(&fitted, &design.torsion);
    let coefficients = all[..basis.n_terms()].to_vec();
    Ok(KinematicFit { basis, coefficients, direction_offset_rad: d, metrics })
}

/// k-fold cross-validation RMS (contiguous folds) of each candidate basis, rad; a
/// candidate that cannot be fitted on some training set gets `∞`.
pub fn cross_validate_kinematic(
    gear: &Gear<f64>,
    angles: &JointAngles,
    candidates: &[KinematicBasis],
    folds: usize,
    opts: &KinematicFitOptions,
) -> Result<Vec<f64>, AnalysisError> {
    if folds < 2 {
        return Err(invalid("folds", format!("must be ≥ 2, got {folds}")));
    }
    if opts.slow_trend_degree > 0 {
        return Err(invalid("slow_trend_degree", "a slow trend cannot be cross-validated"));
    }
    let n = angles.check(4 * folds)?;
    let mut out = Vec::with_capacity(candidates.len());
    for basis in candidates {
        check_motion(basis, angles)?;
        let design = kinematic_design(basis, gear, angles, opts);
        let mut sse = 0.0;
        let mut ok = true;
        for f in 0..folds {
            let (a, b) = (f * n / folds, (f + 1) * n / folds);
            let train: Vec<usize> = (0..a).chain(b..n).collect();
            let test: Vec<usize> = (a..b).collect();
            match solve_kinematic(*basis, &design, &train) {
                Ok((c, _)) => {
                    let p = predict_rows(&design, &c, &test);
                    sse += p.iter().zip(&test).map(|(p, &k)| (p - design.torsion[k]).powi(2)).sum::<f64>();
                }
                Err(_) => {
                    ok = false;
                    break;
                }
            }
        }
        out.push(if ok { (sse / n as f64).sqrt() } else { f64::INFINITY });
    }
    Ok(out)
}

/// Chooses the candidate with the smallest cross-validated RMS and fits it on the whole run.
pub fn select_kinematic_basis(
    gear: &Gear<f64>,
    angles: &JointAngles,
    candidates: &[KinematicBasis],
    folds: usize,
    opts: &KinematicFitOptions,
) -> Result<(KinematicFit, Vec<f64>), AnalysisError> {
    let cv = cross_validate_kinematic(gear, angles, candidates, folds, opts)?;
    let best = cv
        .iter()
        .enumerate()
        .filter(|(_, v)| v.is_finite())
        .min_by(|a, b| a.1.total_cmp(b.1))
        .map(|(i, _)| i)
        .ok_or_else(|| invalid("candidates", "none could be fitted"))?;
    Ok((fit_kinematic_error(gear, angles, candidates[best], opts)?, cv))
}

// ---------------------------------------------------------------------------------------
// Compliance
// ---------------------------------------------------------------------------------------

/// A kinematic model plus a constant wind-up offset (`θ_k + w0`).
#[derive(Debug, Clone, PartialEq)]
pub struct WithOffset<K> {
    /// The model.
    pub inner: K,
    /// Added offset, rad.
    pub offset_rad: f64,
}

impl<K: KinematicError<f64>> KinematicError<f64> for WithOffset<K> {
    fn kinematic_error_rad(&self, angles: &GearAngles<f64>) -> f64 {
        self.inner.kinematic_error_rad(angles) + self.offset_rad
    }
}

/// The compliance model to fit.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ComplianceForm {
    /// `τ = K w`.
    Linear,
    /// `τ = k1 w + k3 w³`.
    Cubic,
    /// Catalogue three-slope curve with the break torques fixed.
    ThreeSlope {
        /// First break torque, N·m.
        t1_nm: f64,
        /// Second break torque, N·m.
        t2_nm: f64,
    },
    /// Seed 002: stiffening flexspline and wave generator in series, with this ratio.
    Seed {
        /// Ratio `N`.
        ratio: f64,
    },
    /// Known springs (e.g. the catalogue's): only the zero, the hysteresis and the damping
    /// are fitted. Without any of those the fit only evaluates the model.
    Fixed(ComplianceParams),
}

/// Fitted compliance parameters (plain values; SI units).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ComplianceParams {
    /// Linear stiffness, N·m/rad.
    Linear {
        /// `K`.
        k_nm_per_rad: f64,
    },
    /// Cubic stiffness.
    Cubic {
        /// `k1`, N·m/rad.
        k1_nm_per_rad: f64,
        /// `k3`, N·m/rad³.
        k3_nm_per_rad3: f64,
    },
    /// Three-slope stiffness.
    ThreeSlope {
        /// `K1`, N·m/rad.
        k1_nm_per_rad: f64,
        /// `K2`, N·m/rad.
        k2_nm_per_rad: f64,
        /// `K3`, N·m/rad.
        k3_nm_per_rad: f64,
        /// `T1`, N·m.
        t1_nm: f64,
        /// `T2`, N·m.
        t2_nm: f64,
    },
    /// Seed 002 springs.
    Seed {
        /// `K_f0`, N·m/rad.
        flexspline_k0_nm_per_rad: f64,
        /// `C_f`, 1/(N·m).
        flexspline_c_per_nm: f64,
        /// `K_w0` at the WG, N·m/rad.
        wave_generator_k0_nm_per_rad: f64,
        /// `c_w`, 1/(N·m).
        wave_generator_c_per_nm: f64,
        /// `N`.
        ratio: f64,
    },
}

/// Any of the core's compliance models (dispatch by `match`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum AnyCompliance {
    /// Three-slope (also the linear case).
    ThreeSlope(ThreeSlopeStiffness<f64>),
    /// Cubic.
    Cubic(CubicStiffness<f64>),
    /// Seed 002.
    Seed(SeedCompliance<f64>),
}

impl Compliance<f64> for AnyCompliance {
    fn twist_rad(&self, torque_nm: f64) -> f64 {
        match self {
            AnyCompliance::ThreeSlope(m) => Compliance::twist_rad(m, torque_nm),
            AnyCompliance::Cubic(m) => m.twist_rad(torque_nm),
            AnyCompliance::Seed(m) => m.twist_rad(torque_nm),
        }
    }
    fn compliance_rad_per_nm(&self, torque_nm: f64) -> f64 {
        match self {
            AnyCompliance::ThreeSlope(m) => m.compliance_rad_per_nm(torque_nm),
            AnyCompliance::Cubic(m) => m.compliance_rad_per_nm(torque_nm),
            AnyCompliance::Seed(m) => m.compliance_rad_per_nm(torque_nm),
        }
    }
    fn max_twist_rad(&self) -> Option<f64> {
        match self {
            AnyCompliance::ThreeSlope(m) => m.max_twist_rad(),
            AnyCompliance::Cubic(m) => m.max_twist_rad(),
            AnyCompliance::Seed(m) => m.max_twist_rad(),
        }
    }
}

impl ComplianceParams {
    /// The core model.
    pub fn model(&self) -> Result<AnyCompliance, AnalysisError> {
        let core = |e: strainwave_core::Error| invalid("compliance parameters", e.to_string());
        Ok(match *self {
            ComplianceParams::Linear { k_nm_per_rad } => {
                AnyCompliance::ThreeSlope(ThreeSlopeStiffness::linear(k_nm_per_rad).map_err(core)?)
            }
            ComplianceParams::Cubic { k1_nm_per_rad, k3_nm_per_rad3 } => {
                AnyCompliance::Cubic(CubicStiffness::new(k1_nm_per_rad, k3_nm_per_rad3).map_err(core)?)
            }
            ComplianceParams::ThreeSlope { k1_nm_per_rad, k2_nm_per_rad, k3_nm_per_rad, t1_nm, t2_nm } => {
                AnyCompliance::ThreeSlope(
                    ThreeSlopeStiffness::new(k1_nm_per_rad, k2_nm_per_rad, k3_nm_per_rad, t1_nm, t2_nm)
                        .map_err(core)?,
                )
            }
            ComplianceParams::Seed {
                flexspline_k0_nm_per_rad,
                flexspline_c_per_nm,
                wave_generator_k0_nm_per_rad,
                wave_generator_c_per_nm,
                ratio,
            } => AnyCompliance::Seed(
                SeedCompliance::new(
                    FlexsplineStiffening::new(flexspline_k0_nm_per_rad, flexspline_c_per_nm).map_err(core)?,
                    WaveGeneratorSoftening::new(wave_generator_k0_nm_per_rad, wave_generator_c_per_nm).map_err(core)?,
                    ratio,
                )
                .map_err(core)?,
            ),
        })
    }
}

/// The hysteresis model to fit.
#[derive(Debug, Clone, PartialEq)]
pub enum HysteresisForm {
    /// None.
    None,
    /// Dahl law (half width `h`, memory `λ`) with the core's reversal deadband, rad.
    Dahl {
        /// Reversal deadband, rad.
        deadband_rad: f64,
    },
    /// Play operators of these half-widths (rad, at most `MAX_PLAYS`); their weights are fitted.
    Plays {
        /// Half-widths `r_i`, rad.
        half_widths_rad: Vec<f64>,
    },
}

impl HysteresisForm {
    /// Plays with half-widths in a geometric series from `narrowest_rad` (choose it above
    /// the torsion noise, peak to peak) by `factor`.
    pub fn geometric_plays(narrowest_rad: f64, factor: f64, count: usize) -> Self {
        HysteresisForm::Plays { half_widths_rad: (0..count).map(|i| narrowest_rad * factor.powi(i as i32)).collect() }
    }

    fn n_params(&self) -> usize {
        match self {
            HysteresisForm::None => 0,
            HysteresisForm::Dahl { .. } => 2,
            HysteresisForm::Plays { half_widths_rad } => half_widths_rad.len(),
        }
    }
}

/// Fitted hysteresis.
#[derive(Debug, Clone, PartialEq)]
pub enum FittedHysteresis {
    /// None.
    None,
    /// Dahl law.
    Dahl {
        /// Half loop width `h`, rad.
        half_width_rad: f64,
        /// Memory `λ`, rad.
        memory_rad: f64,
        /// Reversal deadband, rad.
        deadband_rad: f64,
    },
    /// Play operators.
    Plays {
        /// Half-widths `r_i`, rad.
        half_widths_rad: Vec<f64>,
        /// Weights `β_i`, rad.
        weights_rad: Vec<f64>,
    },
}

/// Options of the compliance fit.
#[derive(Debug, Clone, PartialEq)]
pub struct ComplianceFitOptions {
    /// The model.
    pub form: ComplianceForm,
    /// The hysteresis model.
    pub hysteresis: HysteresisForm,
    /// Fit structural damping `c ẇ`.
    pub damping: bool,
    /// Fit a wind-up offset `w0` (when no no-load run fixed the zero).
    pub windup_offset: bool,
    /// Rated torque, N·m: scales the parameters and sets the solver (bracket 4 × rated).
    pub rated_torque_nm: f64,
    /// Levenberg–Marquardt iteration cap.
    pub max_iterations: usize,
    /// Fit on every `decimation`-th sample (≥ 1). Play states and rates are still
    /// computed at the full rate, so the fit stays that of the full-rate estimator; use it
    /// when the load changes slowly against the sample rate (a Dahl fit ignores it).
    pub decimation: usize,
}

impl ComplianceFitOptions {
    /// Defaults for a form and rated torque: no hysteresis, no damping, no offset, 40 iterations.
    pub fn new(form: ComplianceForm, rated_torque_nm: f64) -> Self {
        Self {
            form,
            hysteresis: HysteresisForm::None,
            damping: false,
            windup_offset: false,
            rated_torque_nm,
            max_iterations: 40,
            decimation: 1,
        }
    }
}

/// A fitted compliance, ready to build an estimator.
#[derive(Debug, Clone, PartialEq)]
pub struct ComplianceFit {
    /// Spring parameters.
    pub params: ComplianceParams,
    /// Hysteresis.
    pub hysteresis: FittedHysteresis,
    /// Structural damping, N·m·s/rad.
    pub damping_nm_s_per_rad: f64,
    /// Wind-up offset `w0`, rad.
    pub windup_offset_rad: f64,
    /// Rated torque the solver is set for, N·m.
    pub rated_torque_nm: f64,
    /// Estimate against the reference on the identification run.
    pub metrics: FitMetrics,
    /// Levenberg–Marquardt iterations (0 for a linear least-squares fit).
    pub iterations: usize,
}

/// An estimator built from fitted models, fed with angles.
pub type FittedEstimator<K> = TorsionEstimator<f64, WithOffset<K>, AnyCompliance>;

impl ComplianceFit {
    /// The streaming estimator with these parameters and a kinematic model.
    pub fn estimator<K: KinematicError<f64>>(
        &self,
        gear: Gear<f64>,
        kinematic: K,
        sample_rate_hz: f64,
    ) -> Result<FittedEstimator<K>, AnalysisError> {
        // Angles are fed directly (`step_angles`); the encoder configurations are unused.
        let enc = EncoderConfig::multi_turn(1 << 20).map_err(|e| invalid("estimator", e.to_string()))?;
        self.estimator_for_counts(gear, enc, enc, kinematic, sample_rate_hz)
    }

    /// The streaming estimator fed with raw encoder counts (see [`EncoderConfig`]).
    pub fn estimator_for_counts<K: KinematicError<f64>>(
        &self,
        gear: Gear<f64>,
        motor_encoder: EncoderConfig,
        link_encoder: EncoderConfig,
        kinematic: K,
        sample_rate_hz: f64,
    ) -> Result<FittedEstimator<K>, AnalysisError> {
        let core = |e: strainwave_core::Error| invalid("estimator", e.to_string());
        let mut est = TorsionEstimator::new(
            gear,
            motor_encoder,
            link_encoder,
            WithOffset { inner: kinematic, offset_rad: self.windup_offset_rad },
            self.params.model()?,
            TorqueSolver::for_rated_torque(self.rated_torque_nm).map_err(core)?,
        );
        match &self.hysteresis {
            FittedHysteresis::None => {}
            FittedHysteresis::Dahl { half_width_rad, memory_rad, deadband_rad } => {
                est = est
                    .with_hysteresis(Hysteresis::new(*half_width_rad, *memory_rad).map_err(core)?, *deadband_rad)
                    .map_err(core)?;
            }
            FittedHysteresis::Plays { half_widths_rad, weights_rad } => {
                est = est.with_play_hysteresis(PlayHysteresis::new(half_widths_rad, weights_rad).map_err(core)?);
            }
        }
        if self.damping_nm_s_per_rad != 0.0 {
            est = est.with_damping(self.damping_nm_s_per_rad, sample_rate_hz).map_err(core)?;
        }
        Ok(est)
    }

    /// The estimated link torque along a run (NaN where the solver fails), N·m.
    pub fn predict<K: KinematicError<f64>>(
        &self,
        gear: &Gear<f64>,
        kinematic: K,
        angles: &JointAngles,
    ) -> Result<Vec<f64>, AnalysisError> {
        let est = self.estimator(*gear, kinematic, angles.sample_rate_hz)?;
        Ok(run_estimator(&est, angles))
    }
}

/// Runs an estimator over a run (NaN where a sample fails).
pub fn run_estimator<K: KinematicError<f64>, C: Compliance<f64>>(
    est: &TorsionEstimator<f64, K, C>,
    angles: &JointAngles,
) -> Vec<f64> {
    let mut st = EstimatorState::new();
    angles
        .motor_angle_rad
        .iter()
        .zip(angles.link_angle_rad)
        .map(|(m, l)| est.step_angles(&mut st, *m, *l).map_or(f64::NAN, |e| e.link_torque_nm))
        .collect()
}

/// Layout of the LM parameter vector.
/// Bound of the log-stiffness parameters (1e3 either way).
const LOG_STIFFNESS_RANGE: f64 = 6.907_755_278_982_137;

struct Layout {
    form: ComplianceForm,
    dahl: bool,
    hyst: Option<usize>,
    offset: Option<usize>,
    damping: Option<usize>,
    len: usize,
    theta_ref: f64,
    k_ref: f64,
    c_ref: f64,
}

impl Layout {
    fn new(opts: &ComplianceFitOptions, k_ref: f64, sample_rate_hz: f64) -> Self {
        let n_form = match opts.form {
            ComplianceForm::Linear => 1,
            ComplianceForm::Cubic => 2,
            ComplianceForm::ThreeSlope { .. } => 3,
            ComplianceForm::Seed { .. } => 4,
            ComplianceForm::Fixed(_) => 0,
        };
        let mut len = n_form;
        let mut take = |on: bool, k: usize| {
            if on {
                len += k;
                Some(len - k)
            } else {
                None
            }
        };
        let n_h = opts.hysteresis.n_params();
        let hyst = take(n_h > 0, n_h);
        let offset = take(opts.windup_offset, 1);
        let damping = take(opts.damping, 1);
        let theta_ref = opts.rated_torque_nm / k_ref;
        Self {
            form: opts.form,
            dahl: matches!(opts.hysteresis, HysteresisForm::Dahl { .. }),
            hyst,
            offset,
            damping,
            len,
            theta_ref,
            k_ref,
            c_ref: k_ref / (TAU * 10.0_f64.min(0.1 * sample_rate_hz)),
        }
    }

    fn params(&self, p: &[f64], rated: f64) -> ComplianceParams {
        // Stiffnesses stay within 1e-3 … 1e3 of the linear least-squares value (a slope
        // running off to infinity would turn the curve into a dead band).
        let k = |x: f64| self.k_ref * x.clamp(-LOG_STIFFNESS_RANGE, LOG_STIFFNESS_RANGE).exp();
        match self.form {
            ComplianceForm::Linear => ComplianceParams::Linear { k_nm_per_rad: k(p[0]) },
            ComplianceForm::Cubic => {
                let k1 = k(p[0]);
                ComplianceParams::Cubic {
                    k1_nm_per_rad: k1,
                    k3_nm_per_rad3: p[1] * k1 / (self.theta_ref * self.theta_ref),
                }
            }
            ComplianceForm::ThreeSlope { t1_nm, t2_nm } => ComplianceParams::ThreeSlope {
                k1_nm_per_rad: k(p[0]),
                k2_nm_per_rad: k(p[1]),
                k3_nm_per_rad: k(p[2]),
                t1_nm,
                t2_nm,
            },
            ComplianceForm::Seed { ratio } => ComplianceParams::Seed {
                flexspline_k0_nm_per_rad: k(p[0]),
                flexspline_c_per_nm: p[1].clamp(-40.0, 40.0).exp() / rated,
                wave_generator_k0_nm_per_rad: k(p[2]) / (ratio * ratio),
                wave_generator_c_per_nm: p[3] * ratio / rated,
                ratio,
            },
            ComplianceForm::Fixed(params) => params,
        }
    }

    fn initial(&self, k_lin: f64) -> Vec<f64> {
        let mut p = vec![0.0; self.len];
        let lk = (k_lin / self.k_ref).ln();
        match self.form {
            ComplianceForm::Linear => p[0] = lk,
            ComplianceForm::Cubic => p[0] = lk,
            ComplianceForm::ThreeSlope { .. } => {
                p[0] = lk;
                p[1] = lk;
                p[2] = lk;
            }
            ComplianceForm::Seed { .. } => {
                // Two equal springs in series, each twice the linear stiffness, mildly stiffening.
                p[0] = lk + 2f64.ln();
                p[1] = 0.3f64.ln();
                p[2] = lk + 2f64.ln();
                p[3] = 0.3;
            }
            ComplianceForm::Fixed(_) => {}
        }
        if let (Some(i), true) = (self.hyst, self.dahl) {
            p[i] = (0.05f64).ln();
            p[i + 1] = (0.05f64).ln();
        }
        p
    }

    fn fit(&self, p: &[f64], opts: &ComplianceFitOptions, metrics: FitMetrics, iterations: usize) -> ComplianceFit {
        ComplianceFit {
            params: self.params(p, opts.rated_torque_nm),
            hysteresis: match (&opts.hysteresis, self.hyst) {
                (HysteresisForm::Dahl { deadband_rad }, Some(i)) => FittedHysteresis::Dahl {
                    half_width_rad: self.theta_ref * p[i].exp(),
                    memory_rad: self.theta_ref * p[i + 1].exp(),
                    deadband_rad: *deadband_rad,
                },
                (HysteresisForm::Plays { half_widths_rad }, Some(i)) => FittedHysteresis::Plays {
                    half_widths_rad: half_widths_rad.clone(),
                    weights_rad: p[i..i + half_widths_rad.len()].iter().map(|b| 0.01 * self.theta_ref * b).collect(),
                },
                _ => FittedHysteresis::None,
            },
            damping_nm_s_per_rad: self.damping.map_or(0.0, |i| self.c_ref * p[i].exp()),
            windup_offset_rad: self.offset.map_or(0.0, |i| self.theta_ref * p[i]),
            rated_torque_nm: opts.rated_torque_nm,
            metrics,
            iterations,
        }
    }
}

/// Fits the compliance from a loaded run against a reference torque (N·m, the link
/// torque's sign convention), with the kinematic error already known.
///
/// Errors: lengths differ, non-finite data, too short, no load variation (the wind-up or
/// the reference does not move), or a failed fit.
pub fn fit_compliance<K: KinematicError<f64> + Clone>(
    gear: &Gear<f64>,
    kinematic: &K,
    angles: &JointAngles,
    reference_torque_nm: &[f64],
    opts: &ComplianceFitOptions,
) -> Result<ComplianceFit, AnalysisError> {
    let n = angles.check(20)?;
    if reference_torque_nm.len() != n {
        return Err(invalid("reference_torque_nm", "differs in length from the angles"));
    }
    check_finite("reference_torque_nm", reference_torque_nm)?;
    if !(opts.rated_torque_nm.is_finite() && opts.rated_torque_nm > 0.0) {
        return Err(invalid("rated_torque_nm", format!("must be positive, got {}", opts.rated_torque_nm)));
    }
    let torsion = angles.torsion_rad(gear);
    let w: Vec<f64> = (0..n).map(|k| kinematic.kinematic_error_rad(&angles.angles(gear, k)) - torsion[k]).collect();
    let spread = |x: &[f64]| {
        let m = x.iter().sum::<f64>() / x.len() as f64;
        (x.iter().map(|v| (v - m) * (v - m)).sum::<f64>() / x.len() as f64).sqrt()
    };
    let ref_spread = spread(reference_torque_nm);
    if ref_spread < 1e-3 * opts.rated_torque_nm {
        return Err(invalid(
            "reference_torque_nm",
            format!("varies by {ref_spread:.2e} N·m rms: no load to identify the compliance from"),
        ));
    }
    if spread(&w) == 0.0 {
        return Err(invalid("windup_rad", "does not vary: the joint never twists"));
    }
    // Linear least squares: τ ≈ K w (+ c ẇ) (+ τ0): the start point and, when the model
    // is linear in its parameters, the answer.
    let fs = angles.sample_rate_hz;
    let wdot: Vec<f64> = (0..n)
        .map(|k| {
            let (a, b) = (k.saturating_sub(1), (k + 1).min(n - 1));
            (w[b] - w[a]) / (b - a) as f64 * fs
        })
        .collect();
    let mut cols = vec![w.clone()];
    if opts.form == ComplianceForm::Cubic {
        cols.push(w.iter().map(|v| v * v * v).collect());
    }
    if opts.damping {
        cols.push(wdot.clone());
    }
    if opts.windup_offset {
        cols.push(vec![1.0; n]);
    }
    let lin = lstsq_qr(&cols, reference_torque_nm)?;
    let k_lin = lin[0];
    if k_lin.is_nan() || k_lin <= 0.0 {
        return Err(invalid("reference_torque_nm", format!("gives a non-positive stiffness {k_lin:.3e} N·m/rad")));
    }
    let k_ref = k_lin;
    let layout = Layout::new(opts, k_ref, fs);
    if let HysteresisForm::Plays { half_widths_rad } = &opts.hysteresis {
        if half_widths_rad.is_empty() || half_widths_rad.len() > MAX_PLAYS {
            return Err(invalid("hysteresis", format!("needs 1 ..= {MAX_PLAYS} plays, got {}", half_widths_rad.len())));
        }
        if half_widths_rad.iter().any(|r| !(r.is_finite() && *r > 0.0)) {
            return Err(invalid("hysteresis", "play half-widths must be positive"));
        }
    }
    if layout.len == 0 {
        // Nothing to fit: evaluate the known model.
        let fit = layout.fit(&[], opts, FitMetrics::of(&[], &[]), 0);
        let pred = fit.predict(gear, kinematic.clone(), angles)?;
        return Ok(ComplianceFit { metrics: FitMetrics::of(&pred, reference_torque_nm), ..fit });
    }
    let linear_in_params = opts.hysteresis == HysteresisForm::None
        && !opts.windup_offset
        && matches!(opts.form, ComplianceForm::Linear | ComplianceForm::Cubic);
    if linear_in_params {
        let mut p = vec![0.0; layout.len];
        p[0] = (k_lin / k_ref).ln();
        if opts.form == ComplianceForm::Cubic {
            p[1] = lin[1] * layout.theta_ref * layout.theta_ref / k_lin;
        }
        let mut fit = layout.fit(&p, opts, FitMetrics::of(&[], &[]), 0);
        if opts.damping {
            fit.damping_nm_s_per_rad = lin[cols.len() - 1].max(0.0);
        }
        let pred = fit.predict(gear, kinematic.clone(), angles)?;
        let metrics = FitMetrics::of(&pred, reference_torque_nm);
        return Ok(ComplianceFit { metrics, ..fit });
    }
    let mut p0 = layout.initial(k_lin);
    if let Some(i) = layout.damping {
        // c = c_ref e^p stays positive; start from the least-squares value (or 0.1 % of c_ref).
        p0[i] = (lin[1 + usize::from(opts.form == ComplianceForm::Cubic)] / layout.c_ref).max(1e-3).ln();
    }
    if let Some(i) = layout.offset {
        let tau0 = *lin.last().unwrap_or(&0.0);
        p0[i] = tau0 / k_lin / layout.theta_ref;
    }
    // θ_k does not depend on the compliance parameters: fold it into the link angle once
    // (θ' = θ − θ_k gives w = −θ_h' with no kinematic model) so that each evaluation of
    // the residual runs only the springs.
    let shifted: Vec<f64> = angles.link_angle_rad.iter().zip(&torsion).zip(&w).map(|((l, th), w)| l - th - w).collect();
    let shifted_angles = JointAngles { link_angle_rad: &shifted, ..*angles };
    let residual = |p: &[f64], r: &mut [f64]| -> bool {
        let fit = layout.fit(p, opts, FitMetrics::of(&[], &[]), 0);
        let Ok(est) = fit.estimator(*gear, NoKinematicError, fs) else {
            return false;
        };
        let pred = run_estimator(&est, &shifted_angles);
        for ((ri, pi), yi) in r.iter_mut().zip(&pred).zip(reference_torque_nm) {
            *ri = pi - yi;
        }
        pred.iter().all(|v| v.is_finite())
    };
    let lm = if matches!(opts.hysteresis, HysteresisForm::Dahl { .. }) {
        levenberg_marquardt(&p0, n, opts.max_iterations, residual)?
    } else {
        let rows = n.div_ceil(opts.decimation.max(1));
        levenberg_marquardt(&p0, rows, opts.max_iterations, fast_residual(&layout, opts, &w, fs, reference_torque_nm))?
    };
    let fit = layout.fit(&lm.params, opts, FitMetrics::of(&[], &[]), lm.iterations);
    let pred = fit.predict(gear, kinematic.clone(), angles)?;
    Ok(ComplianceFit { metrics: FitMetrics::of(&pred, reference_torque_nm), ..fit })
}

/// The residual of a fit without a Dahl state, evaluated without the estimator loop: the
/// play deflections `ζ_i` and the wind-up rate depend only on the wind-up, so they are
/// computed once (with the core's own play operators, exactly as the estimator does);
/// each evaluation then solves `θ(τ) = w + w0 + Σ β_i ζ_i` per sample, warm-started from
/// the previous evaluation's torque at that sample.
fn fast_residual<'a>(
    layout: &'a Layout,
    opts: &'a ComplianceFitOptions,
    w: &'a [f64],
    fs: f64,
    reference_torque_nm: &'a [f64],
) -> impl FnMut(&[f64], &mut [f64]) -> bool + 'a {
    let n = w.len();
    let widths: Vec<f64> = match &opts.hysteresis {
        HysteresisForm::Plays { half_widths_rad } => half_widths_rad.clone(),
        _ => Vec::new(),
    };
    let m = widths.len();
    let mut zeta = vec![0.0; n * m];
    if m > 0 {
        if let Ok(ph) = PlayHysteresis::new(&widths, &vec![0.0; m]) {
            let mut plays = ph.initial_state(w[0]);
            let mut d = [0.0; MAX_PLAYS];
            for (k, wk) in w.iter().enumerate() {
                ph.advance(&mut plays, *wk);
                ph.deflections(&plays, *wk, &mut d);
                zeta[k * m..(k + 1) * m].copy_from_slice(&d[..m]);
            }
        }
    }
    let wdot: Vec<f64> = (0..n).map(|k| if k == 0 { 0.0 } else { (w[k] - w[k - 1]) * fs }).collect();
    let step = opts.decimation.max(1);
    let rows: Vec<usize> = (0..n).step_by(step).collect();
    let mut guess = vec![0.0; rows.len()];
    move |p: &[f64], r: &mut [f64]| -> bool {
        let fit = layout.fit(p, opts, FitMetrics::of(&[], &[]), 0);
        let (Ok(model), Ok(solver)) = (fit.params.model(), TorqueSolver::for_rated_torque(opts.rated_torque_nm)) else {
            return false;
        };
        let weights: &[f64] = match &fit.hysteresis {
            FittedHysteresis::Plays { weights_rad, .. } => weights_rad,
            _ => &[],
        };
        for (j, &k) in rows.iter().enumerate() {
            let mut e = w[k] + fit.windup_offset_rad;
            for (b, z) in weights.iter().zip(&zeta[k * m..(k + 1) * m]) {
                e += b * z;
            }
            match solver.solve(&model, e, guess[j]) {
                Ok(s) => {
                    guess[j] = s.torque_nm;
                    r[j] = s.torque_nm + fit.damping_nm_s_per_rad * wdot[k] - reference_torque_nm[k];
                }
                Err(_) => return false,
            }
        }
        true
    }
}

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

    #[test]
    fn lm_fits_an_exponential() {
        let t: Vec<f64> = (0..40).map(|i| i as f64 * 0.1).collect();
        let y: Vec<f64> = t.iter().map(|t| 3.0 * (-0.7 * t).exp()).collect();
        let r = levenberg_marquardt(&[1.0, 0.0], t.len(), 100, |p, r| {
            for ((ri, ti), yi) in r.iter_mut().zip(&t).zip(&y) {
                *ri = p[0] * (p[1] * ti).exp() - yi;
            }
            true
        })
        .unwrap();
        assert!((r.params[0] - 3.0).abs() < 1e-6 && (r.params[1] + 0.7).abs() < 1e-6, "{r:?}");
    }
}
