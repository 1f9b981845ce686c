//! Fitting the compliance: linear solve or Levenberg–Marquardt on the estimator's residual.

use super::*;

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
            termination: None,
            friction: None,
            parameters: Vec::new(),
        }
    }

    /// The fitted parameters in their own units, by name.
    fn physical(&self, p: &[f64], opts: &ComplianceFitOptions) -> Vec<(String, f64)> {
        let fit = self.fit(p, opts, FitMetrics::of(&[], &[]), 0);
        let mut out = Vec::new();
        match fit.params {
            _ if matches!(self.form, ComplianceForm::Fixed(_)) => {}
            ComplianceParams::Linear { k_nm_per_rad } => out.push(("k_nm_per_rad".into(), k_nm_per_rad)),
            ComplianceParams::Cubic { k1_nm_per_rad, k3_nm_per_rad3 } => {
                out.push(("k1_nm_per_rad".into(), k1_nm_per_rad));
                out.push(("k3_nm_per_rad3".into(), k3_nm_per_rad3));
            }
            ComplianceParams::ThreeSlope { k1_nm_per_rad, k2_nm_per_rad, k3_nm_per_rad, .. } => {
                out.push(("k1_nm_per_rad".into(), k1_nm_per_rad));
                out.push(("k2_nm_per_rad".into(), k2_nm_per_rad));
                out.push(("k3_nm_per_rad".into(), k3_nm_per_rad));
            }
            ComplianceParams::Seed {
                flexspline_k0_nm_per_rad,
                flexspline_c_per_nm,
                wave_generator_k0_nm_per_rad,
                wave_generator_c_per_nm,
                ..
            } => {
                out.push(("flexspline_k0_nm_per_rad".into(), flexspline_k0_nm_per_rad));
                out.push(("flexspline_c_per_nm".into(), flexspline_c_per_nm));
                out.push(("wave_generator_k0_nm_per_rad".into(), wave_generator_k0_nm_per_rad));
                out.push(("wave_generator_c_per_nm".into(), wave_generator_c_per_nm));
            }
        }
        match &fit.hysteresis {
            FittedHysteresis::None => {}
            FittedHysteresis::Dahl { half_width_rad, memory_rad, .. } => {
                out.push(("dahl_half_width_rad".into(), *half_width_rad));
                out.push(("dahl_memory_rad".into(), *memory_rad));
            }
            FittedHysteresis::Plays { weights_rad, .. } => {
                for (i, b) in weights_rad.iter().enumerate() {
                    out.push((format!("play_weight_{}_rad", i + 1), *b));
                }
            }
        }
        if self.damping.is_some() {
            out.push(("damping_nm_s_per_rad".into(), fit.damping_nm_s_per_rad));
        }
        if self.offset.is_some() {
            out.push(("windup_offset_rad".into(), fit.windup_offset_rad));
        }
        out
    }

    /// Named parameters with standard errors by the delta method: `Cov(φ) = G Cov(p) Gᵀ`,
    /// `G = ∂φ/∂p` by central differences.
    fn parameters(&self, p: &[f64], cov: Option<&[f64]>, opts: &ComplianceFitOptions) -> Vec<ParamEstimate> {
        let base = self.physical(p, opts);
        let np = p.len();
        let g: Vec<Vec<f64>> = (0..np)
            .map(|j| {
                let h = 1e-6 * (1.0 + p[j].abs());
                let (mut a, mut b) = (p.to_vec(), p.to_vec());
                a[j] += h;
                b[j] -= h;
                let (fa, fb) = (self.physical(&a, opts), self.physical(&b, opts));
                fa.iter().zip(&fb).map(|(x, y)| (x.1 - y.1) / (2.0 * h)).collect()
            })
            .collect();
        base.iter()
            .enumerate()
            .map(|(i, (name, value))| {
                let se = cov.map_or(f64::NAN, |c| {
                    let mut v = 0.0;
                    for a in 0..np {
                        for b in 0..np {
                            v += g[a][i] * c[a * np + b] * g[b][i];
                        }
                    }
                    v.max(0.0).sqrt()
                });
                ParamEstimate::new(name, *value, se)
            })
            .collect()
    }
}

/// Fits the compliance from a loaded run against a reference torque (N·m, the link
/// torque's sign convention), with the kinematic error already known. With
/// [`ComplianceFitOptions::friction`] the reference is a motor-current torque and the
/// friction and rotor inertia are identified with the spring: in one least-squares solve
/// when the spring is linear without hysteresis, else alternately (spring on the
/// reference less friction, friction on the reference less the link torque, four rounds).
///
/// Errors: lengths differ, non-finite data, too short, no load variation (the wind-up or
/// the reference does not move), a negative stiffness (an encoder's direction or the
/// reference's sign is flipped), or a failed fit. A Levenberg–Marquardt fit that does not
/// converge is returned with its [`ComplianceFit::termination`]; check
/// [`ComplianceFit::converged`].
pub fn fit_compliance<K: KinematicError<f64> + Clone>(
    gear: &Gear<f64>,
    kinematic: &K,
    angles: &JointAngles,
    reference_torque_nm: &[f64],
    opts: &ComplianceFitOptions,
) -> Result<ComplianceFit, AnalysisError> {
    let Some(fopts) = opts.friction else {
        return fit_spring(gear, kinematic, angles, reference_torque_nm, opts, None);
    };
    check_friction_options(&fopts)?;
    let n = angles.check(20)?;
    if reference_torque_nm.len() != n {
        return Err(invalid("reference_torque_nm", "differs in length from the angles"));
    }
    check_finite("reference_torque_nm", reference_torque_nm)?;
    let rows = train_rows(opts, n)?;
    let (v, a) = motion_rates(&angles.link_side_motor_angle_rad(gear), angles.sample_rate_hz, fopts.rate_span)?;
    // Friction is only identifiable where the joint moves.
    let moving = rows.iter().filter(|&&k| v[k].abs() > 5.0 * fopts.smoothing_speed_rad_s).count();
    if moving * 10 < rows.len() {
        let vmax = rows.iter().map(|&k| v[k].abs()).fold(0.0, f64::max);
        return Err(invalid(
            "friction",
            format!(
                "not identifiable: the joint moves faster than {:.3} rad/s in {moving} of {} rows (max {vmax:.3} \
                 rad/s); fit the link torque alone",
                5.0 * fopts.smoothing_speed_rad_s,
                rows.len()
            ),
        ));
    }
    let spring_opts = ComplianceFitOptions { friction: None, ..opts.clone() };
    // The load-dependent term needs the link torque: the reference stands in for it at
    // first, then the model's own (where the solver gives none, the reference again).
    let mut link = reference_torque_nm.to_vec();
    let relink = |fit: &ComplianceFit| -> Result<Vec<f64>, AnalysisError> {
        let p = fit.predict(gear, kinematic.clone(), angles)?;
        Ok(p.iter().zip(reference_torque_nm).map(|(p, q)| if p.is_finite() { *p } else { *q }).collect())
    };
    // Joint solve: the spring's linear least squares with the friction columns alongside.
    let (fcols, _) = friction_columns(&fopts, &v, &a, &link);
    let mut joint = fit_spring(gear, kinematic, angles, reference_torque_nm, &spring_opts, Some((&fcols, fopts)))?;
    if joint.iterations == 0 && joint.termination.is_none() && joint.friction.is_some() {
        // Linear in every parameter: that solve is the answer (re-solved with the model's
        // link torque when friction depends on the load).
        if fopts.load_dependent {
            for _ in 0..4 {
                link = relink(&joint)?;
                let (fcols, _) = friction_columns(&fopts, &v, &a, &link);
                joint = fit_spring(gear, kinematic, angles, reference_torque_nm, &spring_opts, Some((&fcols, fopts)))?;
            }
        }
        return finish_with_friction(gear, kinematic, angles, reference_torque_nm, &rows, joint);
    }
    let mut friction = joint.friction.ok_or_else(|| invalid("friction", "the joint solve gave no friction"))?;
    let mut fit = joint;
    for _ in 0..4 {
        let shifted: Vec<f64> =
            (0..n).map(|k| reference_torque_nm[k] - friction.torque_nm(link[k], v[k], a[k])).collect();
        fit = fit_spring(gear, kinematic, angles, &shifted, &spring_opts, None)?;
        link = relink(&fit)?;
        let rest: Vec<f64> = reference_torque_nm.iter().zip(&link).map(|(q, t)| q - t).collect();
        let (f, est) = fit_friction(&fopts, &v, &a, &link, &rest, &rows)?;
        friction = f;
        fit.parameters.retain(|p| !est.iter().any(|e| e.name == p.name));
        fit.parameters.extend(est);
        fit.friction = Some(friction);
    }
    finish_with_friction(gear, kinematic, angles, reference_torque_nm, &rows, fit)
}

/// Metrics of the current-torque prediction on the training rows.
fn finish_with_friction<K: KinematicError<f64> + Clone>(
    gear: &Gear<f64>,
    kinematic: &K,
    angles: &JointAngles,
    reference_torque_nm: &[f64],
    rows: &[usize],
    fit: ComplianceFit,
) -> Result<ComplianceFit, AnalysisError> {
    let pred = fit.predict_reference(gear, kinematic.clone(), angles)?;
    let metrics = metrics_on(&pred, reference_torque_nm, rows);
    Ok(ComplianceFit { metrics, ..fit })
}

fn metrics_on(pred: &[f64], reference: &[f64], rows: &[usize]) -> FitMetrics {
    let p: Vec<f64> = rows.iter().map(|&k| pred[k]).collect();
    let r: Vec<f64> = rows.iter().map(|&k| reference[k]).collect();
    FitMetrics::of(&p, &r)
}

/// The training rows: all, or the options' (checked: increasing, in range, enough).
fn train_rows(opts: &ComplianceFitOptions, n: usize) -> Result<Vec<usize>, AnalysisError> {
    match &opts.train_rows {
        None => Ok((0..n).collect()),
        Some(rows) => {
            if rows.windows(2).any(|w| w[0] >= w[1]) || rows.last().is_some_and(|&k| k >= n) {
                return Err(invalid("train_rows", format!("must increase and lie below {n}")));
            }
            if rows.len() < 20 {
                return Err(AnalysisError::TooShort { what: "training rows", needed: 20, got: rows.len() });
            }
            Ok(rows.clone())
        }
    }
}

/// The spring fit. `extra` columns (friction) join the linear least squares: their
/// coefficients land in `friction` when the model is linear in its parameters.
fn fit_spring<K: KinematicError<f64> + Clone>(
    gear: &Gear<f64>,
    kinematic: &K,
    angles: &JointAngles,
    reference_torque_nm: &[f64],
    opts: &ComplianceFitOptions,
    extra: Option<(&[Vec<f64>], FrictionFitOptions)>,
) -> Result<ComplianceFit, AnalysisError> {
    let n = angles.check(20)?;
    if reference_torque_nm.len() != n {
        return Err(invalid("reference_torque_nm", "differs in length from the angles"));
    }
    check_finite("reference_torque_nm", reference_torque_nm)?;
    if !(opts.rated_torque_nm.is_finite() && opts.rated_torque_nm > 0.0) {
        return Err(invalid("rated_torque_nm", format!("must be positive, got {}", opts.rated_torque_nm)));
    }
    let rows = train_rows(opts, n)?;
    let torsion = angles.torsion_rad(gear);
    let w: Vec<f64> = (0..n).map(|k| kinematic.kinematic_error_rad(&angles.angles(gear, k)) - torsion[k]).collect();
    let pick = |x: &[f64]| -> Vec<f64> { rows.iter().map(|&k| x[k]).collect() };
    let spread = |x: &[f64]| {
        let m = x.iter().sum::<f64>() / x.len() as f64;
        (x.iter().map(|v| (v - m) * (v - m)).sum::<f64>() / x.len() as f64).sqrt()
    };
    let ref_train = pick(reference_torque_nm);
    let ref_spread = spread(&ref_train);
    if ref_spread < 1e-3 * opts.rated_torque_nm {
        return Err(invalid(
            "reference_torque_nm",
            format!("varies by {ref_spread:.2e} N·m rms: no load to identify the compliance from"),
        ));
    }
    if spread(&pick(&w)) == 0.0 {
        return Err(invalid("windup_rad", "does not vary: the joint never twists"));
    }
    // Linear least squares: τ ≈ K w (+ c ẇ) (+ τ0) (+ friction): the start point and,
    // when the model is linear in its parameters, the answer.
    let fs = angles.sample_rate_hz;
    let wdot: Vec<f64> = (0..n)
        .map(|k| {
            let (a, b) = (k.saturating_sub(1), (k + 1).min(n - 1));
            (w[b] - w[a]) / (b - a) as f64 * fs
        })
        .collect();
    let mut cols = vec![w.clone()];
    let mut names = vec!["k_nm_per_rad"];
    if opts.form == ComplianceForm::Cubic {
        cols.push(w.iter().map(|v| v * v * v).collect());
        names[0] = "k1_nm_per_rad";
        names.push("k3_nm_per_rad3");
    }
    let i_damp = cols.len();
    if opts.damping {
        cols.push(wdot.clone());
        names.push("damping_nm_s_per_rad");
    }
    let i_off = cols.len();
    if opts.windup_offset {
        cols.push(vec![1.0; n]);
        names.push("windup_offset_rad");
    }
    let i_extra = cols.len();
    if let Some((extra, _)) = extra {
        cols.extend(extra.iter().cloned());
    }
    let design: Vec<f64> = rows.iter().flat_map(|&k| cols.iter().map(move |c| c[k])).collect();
    let lin_sol = crate::lstsq::lstsq_rtol(&design, cols.len(), &ref_train, 1e-11).map_err(|e| match e {
        crate::lstsq::LstsqError::RankDeficient { column, .. } => {
            invalid("regressors", format!("rank deficient at column {column}: the data do not excite it"))
        }
        e => invalid("regressors", e.to_string()),
    })?;
    let lin = &lin_sol.x;
    let lin_se = lin_sol.std_errors().unwrap_or_else(|| vec![f64::NAN; cols.len()]);
    let k_lin = lin[0];
    if k_lin.is_nan() || k_lin <= 0.0 {
        return Err(invalid(
            "reference_torque_nm",
            format!(
                "gives a negative stiffness {k_lin:.3e} N·m/rad against the wind-up: the torsion has the \
                 opposite sign to the reference torque (reverse both encoders' directions, or the reference's sign)"
            ),
        ));
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
        return Ok(ComplianceFit { metrics: metrics_on(&pred, reference_torque_nm, &rows), ..fit });
    }
    let linear_in_params = opts.hysteresis == HysteresisForm::None
        && (opts.form == ComplianceForm::Linear || (opts.form == ComplianceForm::Cubic && !opts.windup_offset));
    if linear_in_params {
        let mut p = vec![0.0; layout.len];
        p[0] = (k_lin / k_ref).ln();
        if opts.form == ComplianceForm::Cubic {
            p[1] = lin[1] * layout.theta_ref * layout.theta_ref / k_lin;
        }
        let mut fit = layout.fit(&p, opts, FitMetrics::of(&[], &[]), 0);
        if opts.damping {
            fit.damping_nm_s_per_rad = lin[i_damp].max(0.0);
        }
        if opts.windup_offset {
            // τ = K (w + w0): w0 = τ0 / K.
            fit.windup_offset_rad = lin[i_off] / k_lin;
        }
        fit.parameters = names
            .iter()
            .enumerate()
            .map(|(i, name)| {
                if i == i_off && opts.windup_offset {
                    ParamEstimate::new(name, lin[i] / k_lin, lin_se[i] / k_lin)
                } else {
                    ParamEstimate::new(name, lin[i], lin_se[i])
                }
            })
            .collect();
        if let Some((_, fopts)) = extra {
            let coef = &lin[i_extra..];
            let (_, fnames) = friction_columns(&fopts, &[], &[], &[]);
            fit.friction = Some(friction_params(&fopts, coef));
            for (j, name) in fnames.iter().enumerate() {
                fit.parameters.push(ParamEstimate::new(name, coef[j], lin_se[i_extra + j]));
            }
        }
        let pred = fit.predict(gear, kinematic.clone(), angles)?;
        let metrics = metrics_on(&pred, reference_torque_nm, &rows);
        return Ok(ComplianceFit { metrics, ..fit });
    }
    let mut p0 = layout.initial(k_lin);
    if let Some(i) = layout.damping {
        // c = c_ref e^p stays positive; start from the least-squares value (or 0.1 % of c_ref).
        p0[i] = (lin[i_damp] / layout.c_ref).max(1e-3).ln();
    }
    if let Some(i) = layout.offset {
        p0[i] = lin[i_off] / k_lin / layout.theta_ref;
    }
    let friction = extra.map(|(_, fopts)| friction_params(&fopts, &lin[i_extra..]));
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
        for (ri, &k) in r.iter_mut().zip(&rows) {
            *ri = pred[k] - reference_torque_nm[k];
        }
        r.iter().all(|v| v.is_finite())
    };
    let lm = if matches!(opts.hysteresis, HysteresisForm::Dahl { .. }) {
        levenberg_marquardt(&p0, rows.len(), opts.max_iterations, opts.tolerances, residual)?
    } else {
        let fit_rows: Vec<usize> = rows.iter().copied().step_by(opts.decimation.max(1)).collect();
        let count = fit_rows.len();
        let res = fast_residual(&layout, opts, &w, fs, reference_torque_nm, fit_rows);
        levenberg_marquardt(&p0, count, opts.max_iterations, opts.tolerances, res)?
    };
    let mut fit = layout.fit(&lm.params, opts, FitMetrics::of(&[], &[]), lm.iterations);
    fit.termination = Some(lm.termination);
    fit.parameters = layout.parameters(&lm.params, lm.covariance.as_deref(), opts);
    fit.friction = friction;
    let pred = fit.predict(gear, kinematic.clone(), angles)?;
    Ok(ComplianceFit { metrics: metrics_on(&pred, reference_torque_nm, &rows), ..fit })
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
    rows: Vec<usize>,
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
