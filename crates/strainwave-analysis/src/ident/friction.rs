//! The torque a motor-current reference sees: link torque plus friction plus the rotor's
//! inertial torque, and the rates it needs.
//!
//! Arms without torque sensors log the torque computed from the motor current. Referred
//! to the link it is
//!
//! ```text
//! τ_current = τ_link + (F_c + μ |τ_link| + F_s e^{−(v/v_s)²}) tanh(v/ε) + F_v v + J a
//! ```
//!
//! with `v`, `a` the link-side speed and acceleration of the motor (`θ_m / n_s`),
//! Coulomb `F_c`, optional load-dependent friction `μ` (a strain wave gear's mesh
//! friction grows with the torque it carries), optional Stribeck excess `F_s` (decay
//! speed `v_s` fixed), viscous `F_v`, rotor inertia referred to the link `J`, and `ε` a
//! small smoothing speed. All are linear in the parameters once `v_s`, `ε` and the link
//! torque are fixed, so they are identified by least squares, jointly with the spring
//! (re-solved with the updated link torque) or alternately with a nonlinear one
//! ([`fit_compliance`]).
//!
//! Rates are causal differences over `span` samples (the same in identification and in
//! streaming): `v_k = (x_k − x_{k−h}) f_s / h`, `a_k = (v_k − v_{k−h}) f_s / h`.

use super::*;

/// Streaming link-side speed and acceleration by causal differences over `span` samples.
#[derive(Debug, Clone)]
pub struct RateTracker {
    span: usize,
    sample_rate_hz: f64,
    x: Vec<f64>,
    v: Vec<f64>,
    seen: usize,
}

impl RateTracker {
    /// Largest span.
    pub const MAX_SPAN: usize = 64;

    /// A tracker; `span` in 1 ..= [`Self::MAX_SPAN`].
    pub fn new(span: usize, sample_rate_hz: f64) -> Result<Self, AnalysisError> {
        if !(1..=Self::MAX_SPAN).contains(&span) {
            return Err(invalid("rate span", format!("must be 1 ..= {}, got {span}", Self::MAX_SPAN)));
        }
        if !(sample_rate_hz.is_finite() && sample_rate_hz > 0.0) {
            return Err(invalid("sample_rate_hz", format!("must be positive, got {sample_rate_hz}")));
        }
        Ok(Self { span, sample_rate_hz, x: vec![0.0; span + 1], v: vec![0.0; span + 1], seen: 0 })
    }

    /// Takes the next angle (rad) and returns `(v, a)` (rad/s, rad/s²); zero until
    /// enough samples have been seen.
    pub fn step(&mut self, angle_rad: f64) -> (f64, f64) {
        let m = self.span + 1;
        let i = self.seen % m;
        self.x[i] = angle_rad;
        let h = self.span;
        let scale = self.sample_rate_hz / h as f64;
        let v = if self.seen >= h { (angle_rad - self.x[(self.seen - h) % m]) * scale } else { 0.0 };
        self.v[i] = v;
        let a = if self.seen >= 2 * h { (v - self.v[(self.seen - h) % m]) * scale } else { 0.0 };
        self.seen += 1;
        (v, a)
    }
}

/// `(v, a)` along a run (see [`RateTracker`]).
pub fn motion_rates(
    angle_rad: &[f64],
    sample_rate_hz: f64,
    span: usize,
) -> Result<(Vec<f64>, Vec<f64>), AnalysisError> {
    let mut t = RateTracker::new(span, sample_rate_hz)?;
    Ok(angle_rad.iter().map(|x| t.step(*x)).unzip())
}

/// Which friction and inertia terms to identify.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FrictionFitOptions {
    /// Coulomb `F_c`.
    pub coulomb: bool,
    /// Viscous `F_v`.
    pub viscous: bool,
    /// Stribeck excess with this decay speed `v_s`, rad/s (`None`: no Stribeck term).
    pub stribeck_speed_rad_s: Option<f64>,
    /// Load-dependent friction `μ |τ_link|`.
    pub load_dependent: bool,
    /// Rotor inertia `J`.
    pub inertia: bool,
    /// Smoothing speed `ε` of the sign, rad/s.
    pub smoothing_speed_rad_s: f64,
    /// Difference span of the rates, samples.
    pub rate_span: usize,
}

impl Default for FrictionFitOptions {
    fn default() -> Self {
        Self {
            coulomb: true,
            viscous: true,
            stribeck_speed_rad_s: None,
            load_dependent: false,
            inertia: true,
            smoothing_speed_rad_s: 0.01,
            rate_span: 4,
        }
    }
}

/// Identified friction and rotor inertia, referred to the link (SI units).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FrictionParams {
    /// `F_c`, N·m.
    pub coulomb_nm: f64,
    /// `F_v`, N·m·s/rad.
    pub viscous_nm_s_per_rad: f64,
    /// `F_s`, N·m (0 without a Stribeck term).
    pub stribeck_nm: f64,
    /// `v_s`, rad/s.
    pub stribeck_speed_rad_s: f64,
    /// `J`, kg·m².
    pub inertia_kg_m2: f64,
    /// `μ`, load-dependent friction per N·m of link torque (0 without it).
    #[serde(default)]
    pub load_coefficient: f64,
    /// `ε`, rad/s.
    pub smoothing_speed_rad_s: f64,
    /// Difference span of the rates, samples.
    pub rate_span: usize,
}

impl FrictionParams {
    /// Friction plus inertial torque at link torque `τ_link`, speed `v` and acceleration `a`, N·m.
    pub fn torque_nm(&self, link_torque_nm: f64, v: f64, a: f64) -> f64 {
        let s = (v / self.smoothing_speed_rad_s).tanh();
        let strib = if self.stribeck_speed_rad_s > 0.0 {
            self.stribeck_nm * (-(v / self.stribeck_speed_rad_s).powi(2)).exp()
        } else {
            0.0
        };
        (self.coulomb_nm + self.load_coefficient * link_torque_nm.abs() + strib) * s
            + self.viscous_nm_s_per_rad * v
            + self.inertia_kg_m2 * a
    }

    /// Checks the values a model file may carry.
    pub fn validate(&self) -> Result<(), AnalysisError> {
        let all = [
            self.coulomb_nm,
            self.viscous_nm_s_per_rad,
            self.stribeck_nm,
            self.stribeck_speed_rad_s,
            self.inertia_kg_m2,
            self.smoothing_speed_rad_s,
            self.load_coefficient,
        ];
        if all.iter().any(|v| !v.is_finite()) {
            return Err(invalid("friction", "every value must be finite"));
        }
        if self.smoothing_speed_rad_s <= 0.0 || self.stribeck_speed_rad_s < 0.0 {
            return Err(invalid("friction", "smoothing_speed_rad_s must be positive, stribeck_speed_rad_s ≥ 0"));
        }
        RateTracker::new(self.rate_span, 1.0).map(|_| ())
    }
}

/// Regressor columns of the friction terms, in the order coulomb, viscous, stribeck,
/// inertia, load (the last from the link torque `link`).
pub(super) fn friction_columns(
    opts: &FrictionFitOptions,
    v: &[f64],
    a: &[f64],
    link: &[f64],
) -> (Vec<Vec<f64>>, Vec<&'static str>) {
    let eps = opts.smoothing_speed_rad_s;
    let mut cols = Vec::new();
    let mut names = Vec::new();
    if opts.coulomb {
        cols.push(v.iter().map(|v| (v / eps).tanh()).collect());
        names.push("coulomb_nm");
    }
    if opts.viscous {
        cols.push(v.to_vec());
        names.push("viscous_nm_s_per_rad");
    }
    if let Some(vs) = opts.stribeck_speed_rad_s {
        cols.push(v.iter().map(|v| (v / eps).tanh() * (-(v / vs).powi(2)).exp()).collect());
        names.push("stribeck_nm");
    }
    if opts.inertia {
        cols.push(a.to_vec());
        names.push("inertia_kg_m2");
    }
    if opts.load_dependent {
        cols.push(v.iter().zip(link).map(|(v, t)| (v / eps).tanh() * t.abs()).collect());
        names.push("load_coefficient");
    }
    (cols, names)
}

/// Friction parameters from the coefficients of [`friction_columns`].
pub(super) fn friction_params(opts: &FrictionFitOptions, coef: &[f64]) -> FrictionParams {
    let mut it = coef.iter().copied();
    let mut take = |on: bool| if on { it.next().unwrap_or(0.0) } else { 0.0 };
    FrictionParams {
        coulomb_nm: take(opts.coulomb),
        viscous_nm_s_per_rad: take(opts.viscous),
        stribeck_nm: take(opts.stribeck_speed_rad_s.is_some()),
        inertia_kg_m2: take(opts.inertia),
        load_coefficient: take(opts.load_dependent),
        stribeck_speed_rad_s: opts.stribeck_speed_rad_s.unwrap_or(0.0),
        smoothing_speed_rad_s: opts.smoothing_speed_rad_s,
        rate_span: opts.rate_span,
    }
}

/// Checks the options.
pub(super) fn check_friction_options(opts: &FrictionFitOptions) -> Result<(), AnalysisError> {
    if !(opts.coulomb || opts.viscous || opts.stribeck_speed_rad_s.is_some() || opts.inertia || opts.load_dependent) {
        return Err(invalid("friction", "no term to identify"));
    }
    if !(opts.smoothing_speed_rad_s.is_finite() && opts.smoothing_speed_rad_s > 0.0) {
        return Err(invalid("friction", "smoothing speed must be positive"));
    }
    if let Some(vs) = opts.stribeck_speed_rad_s {
        if !(vs.is_finite() && vs > 0.0) {
            return Err(invalid("friction", "Stribeck speed must be positive"));
        }
    }
    RateTracker::new(opts.rate_span, 1.0).map(|_| ())
}

/// Fits the friction terms to `torque_nm` (the reference minus the link torque `link`)
/// on `rows`; returns the parameters and their standard errors (named).
pub fn fit_friction(
    opts: &FrictionFitOptions,
    v: &[f64],
    a: &[f64],
    link: &[f64],
    torque_nm: &[f64],
    rows: &[usize],
) -> Result<(FrictionParams, Vec<ParamEstimate>), AnalysisError> {
    check_friction_options(opts)?;
    let (cols, names) = friction_columns(opts, v, a, link);
    let p = cols.len();
    let design: Vec<f64> = rows.iter().flat_map(|&k| cols.iter().map(move |c| c[k])).collect();
    let b: Vec<f64> = rows.iter().map(|&k| torque_nm[k]).collect();
    let sol = crate::lstsq::lstsq(&design, p, &b).map_err(|e| {
        invalid("friction", format!("{e}: the run does not excite the friction terms (does the joint move?)"))
    })?;
    let se = sol.std_errors().unwrap_or_else(|| vec![f64::NAN; p]);
    let params = friction_params(opts, &sol.x);
    let est = names.iter().zip(&sol.x).zip(&se).map(|((n, v), s)| ParamEstimate::new(n, *v, *s)).collect();
    Ok((params, est))
}

/// A named parameter with its standard error.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct ParamEstimate {
    /// Name, with its unit.
    pub name: String,
    /// Value.
    pub value: f64,
    /// Standard error (NaN when not available).
    pub std_error: f64,
}

impl ParamEstimate {
    /// A parameter.
    pub fn new(name: &str, value: f64, std_error: f64) -> Self {
        Self { name: name.to_string(), value, std_error }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rates_of_a_parabola_are_exact_after_the_warm_up() {
        let fs = 100.0;
        let x: Vec<f64> = (0..50).map(|k| 0.5 * 3.0 * (k as f64 / fs).powi(2)).collect();
        let (v, a) = motion_rates(&x, fs, 4).unwrap();
        // Causal differences lag by span/2 samples: v_k = 3 (t_k − 2/fs), a = 3.
        for k in 8..50 {
            assert!((v[k] - 3.0 * (k as f64 - 2.0) / fs).abs() < 1e-9, "{k}: {}", v[k]);
            assert!((a[k] - 3.0).abs() < 1e-9, "{k}: {}", a[k]);
        }
        assert!(motion_rates(&x, fs, 0).is_err() && motion_rates(&x, fs, 65).is_err());
    }

    #[test]
    fn friction_fit_recovers_known_terms() {
        let fs = 250.0;
        let n = 2000;
        let x: Vec<f64> = (0..n).map(|k| (k as f64 / fs * 1.3).sin() + 0.3 * (k as f64 / fs * 4.1).sin()).collect();
        let (v, a) = motion_rates(&x, fs, 4).unwrap();
        let truth = FrictionParams {
            coulomb_nm: 4.0,
            viscous_nm_s_per_rad: 9.0,
            stribeck_nm: 0.0,
            stribeck_speed_rad_s: 0.0,
            inertia_kg_m2: 0.8,
            load_coefficient: 0.0,
            smoothing_speed_rad_s: 0.01,
            rate_span: 4,
        };
        let tq: Vec<f64> = v.iter().zip(&a).map(|(v, a)| truth.torque_nm(0.0, *v, *a)).collect();
        let rows: Vec<usize> = (10..n).collect();
        let (p, se) = fit_friction(&FrictionFitOptions::default(), &v, &a, &tq, &tq, &rows).unwrap();
        assert!((p.coulomb_nm - 4.0).abs() < 1e-9 && (p.viscous_nm_s_per_rad - 9.0).abs() < 1e-9, "{p:?}");
        assert!((p.inertia_kg_m2 - 0.8).abs() < 1e-9, "{p:?}");
        assert_eq!(se.len(), 3);
        // A still joint does not excite friction: an error, not a made-up value.
        let still = vec![0.0; n];
        assert!(fit_friction(&FrictionFitOptions::default(), &still, &still, &tq, &tq, &rows).is_err());
    }
}
