//! The kinematic-error fit: basis, design, cross-validation (first step of identification).

use super::*;

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
    pub(super) fn check(&self, min_len: usize) -> Result<usize, AnalysisError> {
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

    /// The motor angle referred to the link, `θ_m / n_s`, rad.
    pub fn link_side_motor_angle_rad(&self, gear: &Gear<f64>) -> Vec<f64> {
        let n_s = gear.signed_ratio();
        self.motor_angle_rad.iter().map(|m| m / n_s).collect()
    }

    pub(super) fn angles(&self, gear: &Gear<f64>, k: usize) -> GearAngles<f64> {
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
    /// `Σ_{i=0..order} a_i θ^i` in the output angle (the HDA-arm paper: order 5).
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
    let rows: Vec<usize> = (0..angles.motor_angle_rad.len()).collect();
    fit_kinematic_error_on(gear, angles, basis, opts, &rows)
}

/// [`fit_kinematic_error`] on some rows only (0-based, e.g. the training blocks of a
/// blocked holdout); the regressors are computed over the whole run.
pub fn fit_kinematic_error_on(
    gear: &Gear<f64>,
    angles: &JointAngles,
    basis: KinematicBasis,
    opts: &KinematicFitOptions,
    rows: &[usize],
) -> Result<KinematicFit, AnalysisError> {
    let n = angles.check(2 * (basis.n_terms() + opts.slow_trend_degree) + 2)?;
    if rows.len() < 2 * (basis.n_terms() + opts.slow_trend_degree) + 2 || rows.iter().any(|&k| k >= n) {
        return Err(invalid("rows", format!("need enough rows below {n}")));
    }
    check_motion(&basis, angles)?;
    if opts.slow_trend_degree > 0
        && !matches!(basis, KinematicBasis::Fourier { output_harmonics: 0, mesh_harmonics: 1.., .. })
    {
        return Err(invalid(
            "slow_trend_degree",
            "a slow trend is confounded with output-angle terms: use mesh harmonics only",
        ));
    }
    let mut design = kinematic_design(&basis, gear, angles, opts);
    let nt = basis.n_terms();
    if design.direction && rows.iter().all(|&k| design.columns[nt][k] == design.columns[nt][rows[0]]) {
        // The run turns both ways, but these rows only one: the term is the constant.
        design.columns.remove(nt);
        design.direction = false;
    }
    let (all, d) = solve_kinematic(basis, &design, rows)?;
    let fitted = predict_rows(&design, &all, rows);
    let target: Vec<f64> = rows.iter().map(|&k| design.torsion[k]).collect();
    let metrics = FitMetrics::of(&fitted, &target);
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
