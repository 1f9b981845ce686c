//! Accuracy of ripple/misalignment cancellers against a simulator's truth, side by side
//! with the simple alternatives (docs/physics.md §4).
//!
//! Figures, per method, over a run:
//! - **ripple + misalignment remaining**, dB below raw: `20 log10(rms(P) / rms(P_left))`
//!   with `P = true_ripple + true_misalignment`. For the Kalman cancellers
//!   `P_left = P − (raw − output)` (their output is raw minus their prediction, so no
//!   noise enters the figure); for the linear time-invariant baselines `P_left = F(P)`,
//!   exactly what the filter lets through.
//! - **RMS error** of the output against `true_torque`, N·m and % of full scale, after a
//!   warm-up.
//! - **step delay**: a torque step of 1 N·m fed through the method with the run's angles
//!   and no ripple; samples from the input's 50 % crossing to the output's.
//!
//! The full configuration runs as in a product: its coefficients are learned first on a
//! separate commissioning run of the same joint ([`commission`]), then it filters the
//! run under test starting from them. [`Method::FullCold`] is the same model learning
//! from nothing during the run itself.

use strainwave_core::gear::Gear;
use strainwave_core::iir::Biquad;
use strainwave_core::ripple::{
    step as ripple_step, PhaseSource, ReferenceValues, RippleInput, RippleModel, RippleOutput, RippleState, StepFlags,
};

use crate::error::AnalysisError;
use crate::smoother::smooth_with;
use crate::smoother::torque_ripple::{residual_orders, smooth_torque_with_ripple, MeanSpeed, RippleTorqueTrack};
use crate::stats::rms;

/// The signals of a run.
#[derive(Debug, Clone, Copy)]
pub struct RunSignals<'a> {
    /// Sample rate, Hz.
    pub sample_rate_hz: f64,
    /// Calibrated measured torque, N·m.
    pub measured_nm: &'a [f64],
    /// Motor encoder angle, rad.
    pub motor_angle_rad: &'a [f64],
    /// Output encoder angle, rad.
    pub output_angle_rad: &'a [f64],
    /// Tachometer, rad/s (the paper's phase source).
    pub motor_velocity_rad_s: &'a [f64],
    /// Truth: transmitted torque, N·m.
    pub true_torque_nm: &'a [f64],
    /// Truth: ripple, N·m.
    pub true_ripple_nm: &'a [f64],
    /// Truth: misalignment, N·m.
    pub true_misalignment_nm: &'a [f64],
}

/// The methods compared.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Method {
    /// The measurement as it is.
    Raw,
    /// 2nd-order Butterworth low-pass at this cutoff, Hz.
    LowPass(f64),
    /// Notch (Q = 2) at this frequency, Hz.
    Notch(f64),
    /// Taghirad and Bélanger (1999)'s 4th-order model (2×, 4× on the tachometer, Q = 1e-3 I, R = 1).
    Taghirad4th,
    /// Taghirad and Bélanger (1999)'s 6th-order model (plus 1× output).
    Taghirad6th,
    /// The full configuration (2×, 4× relative angle, the same scaled by load, 1×
    /// output, bias state) starting from what [`commission`] learned.
    Full,
    /// The full configuration without commissioning: learning from zero during the run.
    FullCold,
    /// The full configuration (commissioned) run offline: forward filter and
    /// Rauch–Tung–Striebel pass, its output the smoothed torque (`torque_smoothed`: the
    /// clean torque smoothed as a level-and-rate state, zero phase, steps kept sharp;
    /// see [`crate::smoother::torque`]).
    Smoothed,
}

/// What the full configuration learned: per order, rotating-frame coefficients and
/// their variance (see `RippleState::learned_all`).
pub type Learned = [([f64; 2], f64); 5];

impl Method {
    /// Label for tables.
    pub fn label(&self) -> String {
        match self {
            Method::Raw => "raw measurement".into(),
            Method::LowPass(f) => format!("2nd-order low-pass {f:.1} Hz"),
            Method::Notch(f) => format!("notch at the 2× line {f:.1} Hz"),
            Method::Taghirad4th => "Taghirad 4th-order (2×, 4× tacho)".into(),
            Method::Taghirad6th => "Taghirad 6th-order (+1× output)".into(),
            Method::Full => "strainwave full (commissioned)".into(),
            Method::FullCold => "strainwave full, no commissioning".into(),
            Method::Smoothed => "strainwave full, smoothed (offline)".into(),
        }
    }
}

/// One row of the accuracy table.
#[derive(Debug, Clone, PartialEq)]
pub struct EvalRow {
    /// Method.
    pub method: Method,
    /// Ripple + misalignment remaining, dB below raw.
    pub suppression_db: f64,
    /// RMS error against `true_torque`, N·m.
    pub rms_error_nm: f64,
    /// Step delay, samples (`None`: the output did not reach 50 % before the run ended).
    pub step_delay_samples: Option<usize>,
}

fn check(s: &RunSignals) -> Result<usize, AnalysisError> {
    let n = s.measured_nm.len();
    for (what, v) in [
        ("motor_angle", s.motor_angle_rad),
        ("output_angle", s.output_angle_rad),
        ("motor_velocity", s.motor_velocity_rad_s),
        ("true_torque", s.true_torque_nm),
        ("true_ripple", s.true_ripple_nm),
        ("true_misalignment", s.true_misalignment_nm),
    ] {
        if v.len() != n {
            return Err(AnalysisError::Invalid { what, why: format!("has {} samples, measured torque {n}", v.len()) });
        }
    }
    if n < 16 {
        return Err(AnalysisError::TooShort { what: "run", needed: 16, got: n });
    }
    if !(s.sample_rate_hz.is_finite() && s.sample_rate_hz > 0.0) {
        return Err(AnalysisError::Invalid { what: "sample_rate_hz", why: "must be positive".into() });
    }
    Ok(n)
}

fn core_err(what: &'static str) -> impl Fn(strainwave_core::Error) -> AnalysisError {
    move |e| AnalysisError::Invalid { what, why: e.to_string() }
}

/// Runs a Kalman model over a signal; `velocity` selects the paper's tachometer phase.
fn run_kalman<const M: usize>(
    model: &RippleModel<f64, M>,
    gear: &Gear<f64>,
    y: &[f64],
    s: &RunSignals,
    velocity: bool,
) -> Result<Vec<RippleOutput<f64>>, AnalysisError> {
    let mut state = RippleState::new(model);
    let n_s = gear.signed_ratio();
    let mut out = Vec::with_capacity(y.len());
    for (k, &yk) in y.iter().enumerate() {
        let refs = if velocity {
            // The paper's phase source: 2×, 4× of the motor velocity, misalignment at velocity / ratio.
            let w = s.motor_velocity_rad_s[k];
            ReferenceValues::new(w, w / n_s, w)
        } else {
            ReferenceValues::from_gear(gear, s.motor_angle_rad[k], s.output_angle_rad[k])
        };
        out.push(ripple_step(model, &mut state, &RippleInput::new(yk, refs)).map_err(core_err("ripple filter"))?);
    }
    Ok(out)
}

fn lti(filter: &Biquad<f64>, x: &[f64]) -> Vec<f64> {
    let mut st = filter.settled_state(x[0]);
    x.iter().map(|v| filter.step(&mut st, *v)).collect()
}

fn notch(f0_hz: f64, fs: f64) -> Result<Biquad<f64>, AnalysisError> {
    let w0 = std::f64::consts::TAU * f0_hz;
    let q = 2.0;
    Biquad::from_analog([1.0, 0.0, w0 * w0], [1.0, w0 / q, w0 * w0], f0_hz, fs).map_err(core_err("notch"))
}

/// The full configuration learning from zero under the guard, as `strainwave filter` runs
/// it without a learned file (commissioning tuning, [`strainwave_core::guard::cold_start`]).
fn cold_full(fs: f64, noise_nm: f64) -> Result<RippleModel<f64, 5>, AnalysisError> {
    RippleModel::<f64, 5>::full_commissioning(fs, noise_nm)
        .and_then(strainwave_core::guard::cold_start)
        .map_err(core_err("full model"))
}

/// The full configuration from `learned`.
fn full_model(fs: f64, noise_nm: f64, learned: Option<&Learned>) -> Result<RippleModel<f64, 5>, AnalysisError> {
    let learned = learned.ok_or(AnalysisError::Invalid {
        what: "full configuration",
        why: "needs learned coefficients: run `commission` first".into(),
    })?;
    RippleModel::<f64, 5>::full(fs, noise_nm).and_then(|m| m.with_priors(*learned)).map_err(core_err("full model"))
}

/// The smoothed full configuration over `y`: per sample, the smoothed torque
/// (`torque_smoothed`), its standard deviation and the smoothed ripple + misalignment, N·m.
fn run_smoothed(
    gear: &Gear<f64>,
    y: &[f64],
    s: &RunSignals,
    noise_nm: f64,
    learned: Option<&Learned>,
) -> Result<Vec<[f64; 3]>, AnalysisError> {
    let m = full_model(s.sample_rate_hz, noise_nm, learned)?;
    let inputs: Vec<RippleInput<f64>> = (0..y.len())
        .map(|k| RippleInput::new(y[k], ReferenceValues::from_gear(gear, s.motor_angle_rad[k], s.output_angle_rad[k])))
        .collect();
    let out =
        smooth_with(&m, &inputs, false).map_err(|e| AnalysisError::Invalid { what: "smoother", why: e.to_string() })?;
    let clean: Vec<f64> = out.smoothed.iter().map(|o| o.torque_nm).collect();
    let mut speed = MeanSpeed::default();
    inputs.iter().for_each(|i| speed.push(i.references.relative));
    let multiples = residual_orders(&m, speed.rad_per_s(s.sample_rate_hz));
    let phasors: Vec<Vec<[f64; 2]>> = inputs
        .iter()
        .map(|i| {
            multiples.iter().map(|n| [(n * i.references.relative).cos(), (n * i.references.relative).sin()]).collect()
        })
        .collect();
    let tracks = RippleTorqueTrack::pair(multiples.len(), m.noise_nm(), s.sample_rate_hz);
    let level = smooth_torque_with_ripple(&clean, &phasors, &[], tracks);
    Ok(out.smoothed.iter().zip(level).map(|(o, (t, sd))| [t, sd, o.ripple_nm + o.misalignment_nm]).collect())
}

/// Output of a method on `y`.
fn apply(
    method: Method,
    gear: &Gear<f64>,
    y: &[f64],
    s: &RunSignals,
    noise_nm: f64,
    learned: Option<&Learned>,
) -> Result<Vec<f64>, AnalysisError> {
    let fs = s.sample_rate_hz;
    Ok(match method {
        Method::Raw => y.to_vec(),
        Method::LowPass(fc) => {
            lti(&Biquad::lowpass(fc, std::f64::consts::FRAC_1_SQRT_2, fs).map_err(core_err("low-pass"))?, y)
        }
        Method::Notch(f0) => lti(&notch(f0, fs)?, y),
        Method::Taghirad4th => {
            let m = RippleModel::<f64, 2>::taghirad_4th_order(fs)
                .map_err(core_err("paper's model"))?
                .with_phase_source(PhaseSource::Velocity);
            run_kalman(&m, gear, y, s, true)?.iter().map(|o| o.torque_nm).collect()
        }
        Method::Taghirad6th => {
            let m = RippleModel::<f64, 3>::taghirad_6th_order(fs)
                .map_err(core_err("paper's model"))?
                .with_phase_source(PhaseSource::Velocity);
            run_kalman(&m, gear, y, s, true)?.iter().map(|o| o.torque_nm).collect()
        }
        Method::Full => {
            let m = full_model(fs, noise_nm, learned)?;
            run_kalman(&m, gear, y, s, false)?.iter().map(|o| o.torque_nm).collect()
        }
        Method::Smoothed => run_smoothed(gear, y, s, noise_nm, learned)?.iter().map(|o| o[0]).collect(),
        Method::FullCold => {
            let m = RippleModel::<f64, 5>::full_commissioning(fs, noise_nm).map_err(core_err("full model"))?;
            run_kalman(&m, gear, y, s, false)?.iter().map(|o| o.torque_nm).collect()
        }
    })
}

/// Ripple + misalignment the method leaves, per sample.
fn remaining(method: Method, output: &[f64], s: &RunSignals, periodic: &[f64]) -> Result<Vec<f64>, AnalysisError> {
    let fs = s.sample_rate_hz;
    Ok(match method {
        Method::Raw => periodic.to_vec(),
        Method::LowPass(fc) => {
            lti(&Biquad::lowpass(fc, std::f64::consts::FRAC_1_SQRT_2, fs).map_err(core_err("low-pass"))?, periodic)
        }
        Method::Notch(f0) => lti(&notch(f0, fs)?, periodic),
        _ => (0..output.len()).map(|k| periodic[k] - (s.measured_nm[k] - output[k])).collect(),
    })
}

/// Samples from the input step's 50 % crossing to the output's, for a 1 N·m step added
/// to the run's measurement at its middle: the response is the difference between the
/// method's outputs with and without the step, so what the method removes from the run
/// itself does not count as delay.
fn step_delay(
    method: Method,
    gear: &Gear<f64>,
    s: &RunSignals,
    noise_nm: f64,
    learned: Option<&Learned>,
) -> Result<Option<usize>, AnalysisError> {
    let n = s.measured_nm.len();
    let k0 = n / 2;
    let stepped: Vec<f64> = (0..n).map(|k| s.measured_nm[k] + if k >= k0 { 1.0 } else { 0.0 }).collect();
    let with = apply(method, gear, &stepped, s, noise_nm, learned)?;
    let without = apply(method, gear, s.measured_nm, s, noise_nm, learned)?;
    Ok((k0..n).position(|k| with[k] - without[k] >= 0.5))
}

/// Learns the full configuration's coefficients on a commissioning run (the
/// commissioning tuning, forward pass; the final state is what was learned). A canceller
/// locked by its load-step test starts again ([`crate::step_lock`]).
pub fn commission(s: &RunSignals, gear: &Gear<f64>, noise_nm: f64) -> Result<Learned, AnalysisError> {
    check(s)?;
    let m = RippleModel::<f64, 5>::full_commissioning(s.sample_rate_hz, noise_nm).map_err(core_err("full model"))?;
    let mut state = RippleState::new(&m);
    let mut lock = crate::step_lock::StepLock::new(s.sample_rate_hz);
    for k in 0..s.measured_nm.len() {
        let refs = ReferenceValues::from_gear(gear, s.motor_angle_rad[k], s.output_angle_rad[k]);
        let out = ripple_step(&m, &mut state, &RippleInput::new(s.measured_nm[k], refs))
            .map_err(core_err("ripple filter"))?;
        if lock.locked(out.flags.contains(StepFlags::LOAD_STEP)) {
            state.reset(&m);
        }
    }
    Ok(state.learned_all())
}

/// Evaluates the methods on a run. `warmup_s` is left out of the RMS error; `learned`
/// (from [`commission`]) is needed by [`Method::Full`].
pub fn evaluate(
    s: &RunSignals,
    gear: &Gear<f64>,
    noise_nm: f64,
    methods: &[Method],
    warmup_s: f64,
    learned: Option<&Learned>,
) -> Result<Vec<EvalRow>, AnalysisError> {
    let n = check(s)?;
    let periodic: Vec<f64> = (0..n).map(|k| s.true_ripple_nm[k] + s.true_misalignment_nm[k]).collect();
    let p_rms = rms(&periodic);
    let k_warm = ((warmup_s * s.sample_rate_hz) as usize).min(n - 1);
    let mut rows = Vec::with_capacity(methods.len());
    for &m in methods {
        let (out, left) = if m == Method::Smoothed {
            // The smoothed torque is not `raw − prediction`: what is left of the
            // periodic part is the truth minus the smoothed ripple and misalignment.
            let sm = run_smoothed(gear, s.measured_nm, s, noise_nm, learned)?;
            (sm.iter().map(|o| o[0]).collect(), (0..n).map(|k| periodic[k] - sm[k][2]).collect())
        } else {
            let out = apply(m, gear, s.measured_nm, s, noise_nm, learned)?;
            let left = remaining(m, &out, s, &periodic)?;
            (out, left)
        };
        let err: Vec<f64> = (k_warm..n).map(|k| out[k] - s.true_torque_nm[k]).collect();
        rows.push(EvalRow {
            method: m,
            suppression_db: 20.0 * (p_rms / rms(&left[k_warm..])).log10(),
            rms_error_nm: rms(&err),
            step_delay_samples: step_delay(m, gear, s, noise_nm, learned)?,
        });
    }
    Ok(rows)
}

/// The smoothed torque (`torque_smoothed`) against the truth over a run (see
/// [`smoothed_accuracy`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SmoothedAccuracy {
    /// RMS error of the smoothed torque against `true_torque` after the warm-up, N·m.
    pub rms_error_nm: f64,
    /// Fraction of the samples after the warm-up whose truth lies within ±1σ
    /// (`torque_smoothed_sd`) of the smoothed torque (0.683 when honest).
    pub coverage_1sd: f64,
    /// A 1 N·m step added at sample `k0`: the first sample from `k0 − 50` on where the
    /// smoothed response reaches 0.5 N·m, minus `k0` (negative: it rises early). `None`:
    /// never.
    pub step_offset_samples: Option<i64>,
    /// The largest response before `k0 − 2`, N·m (how much the step smears backwards).
    pub step_smear_before_nm: f64,
    /// The smallest response from `k0 + 2` on over 50 samples, N·m (1 when the step is
    /// complete within 2 samples).
    pub step_level_after_nm: f64,
}

/// The full configuration's smoothed torque on a run, from `learned`: RMS error,
/// coverage of its 1σ band and the response to a 1 N·m step added at `step_at` (the
/// run's middle when `None`).
pub fn smoothed_accuracy(
    s: &RunSignals,
    gear: &Gear<f64>,
    noise_nm: f64,
    learned: &Learned,
    warmup_s: f64,
    step_at: Option<usize>,
) -> Result<SmoothedAccuracy, AnalysisError> {
    let n = check(s)?;
    let k_warm = ((warmup_s * s.sample_rate_hz) as usize).min(n - 1);
    let sm = run_smoothed(gear, s.measured_nm, s, noise_nm, Some(learned))?;
    let err: Vec<f64> = (k_warm..n).map(|k| sm[k][0] - s.true_torque_nm[k]).collect();
    let covered = (k_warm..n).filter(|&k| (sm[k][0] - s.true_torque_nm[k]).abs() <= sm[k][1]).count();
    let k0 = step_at.unwrap_or(n / 2).clamp(52, n.saturating_sub(52).max(52));
    if k0 + 52 > n {
        return Err(AnalysisError::TooShort { what: "run for the step", needed: k0 + 52, got: n });
    }
    let stepped: Vec<f64> = (0..n).map(|k| s.measured_nm[k] + if k >= k0 { 1.0 } else { 0.0 }).collect();
    let with = run_smoothed(gear, &stepped, s, noise_nm, Some(learned))?;
    let response = |k: usize| with[k][0] - sm[k][0];
    Ok(SmoothedAccuracy {
        rms_error_nm: rms(&err),
        coverage_1sd: covered as f64 / (n - k_warm) as f64,
        step_offset_samples: (k0 - 50..n).find(|&k| response(k) >= 0.5).map(|k| k as i64 - k0 as i64),
        step_smear_before_nm: (k0 - 50..k0 - 2).map(|k| response(k).abs()).fold(0.0, f64::max),
        step_level_after_nm: (k0 + 2..k0 + 52).map(response).fold(f64::INFINITY, f64::min),
    })
}

/// The cutoff of a 2nd-order low-pass that removes `target_db` of the run's ripple +
/// misalignment (bisection on a log scale between 0.1 Hz and 0.45 fs).
pub fn lowpass_cutoff_for(s: &RunSignals, target_db: f64) -> Result<f64, AnalysisError> {
    let n = check(s)?;
    let periodic: Vec<f64> = (0..n).map(|k| s.true_ripple_nm[k] + s.true_misalignment_nm[k]).collect();
    let p_rms = rms(&periodic);
    let db = |fc: f64| -> Result<f64, AnalysisError> {
        let left = remaining(Method::LowPass(fc), &[], s, &periodic)?;
        Ok(20.0 * (p_rms / rms(&left)).log10())
    };
    let (mut lo, mut hi) = (0.1f64.ln(), (0.45 * s.sample_rate_hz).ln());
    for _ in 0..40 {
        let mid = 0.5 * (lo + hi);
        if db(mid.exp())? > target_db {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    Ok((0.5 * (lo + hi)).exp())
}

/// The full configuration's clean torque over a run, from `learned`.
pub fn filtered(s: &RunSignals, gear: &Gear<f64>, noise_nm: f64, learned: &Learned) -> Result<Vec<f64>, AnalysisError> {
    check(s)?;
    apply(Method::Full, gear, s.measured_nm, s, noise_nm, Some(learned))
}

/// The full configuration's smoothed torque (`torque_smoothed`) over a run, from
/// `learned` (offline, zero phase), N·m.
pub fn smoothed(s: &RunSignals, gear: &Gear<f64>, noise_nm: f64, learned: &Learned) -> Result<Vec<f64>, AnalysisError> {
    check(s)?;
    apply(Method::Smoothed, gear, s.measured_nm, s, noise_nm, Some(learned))
}

/// The worst 1 s window after the first second of the clean torque's RMS error against
/// `true_torque` over the raw measurement's in the same window (the "never worse than
/// raw" figure: at most 1 when nothing is made worse).
pub fn worst_window_ratio(clean: &[f64], s: &RunSignals) -> Result<f64, AnalysisError> {
    let n = check(s)?;
    if clean.len() != n {
        return Err(AnalysisError::Invalid {
            what: "clean torque",
            why: format!("has {} samples, not {n}", clean.len()),
        });
    }
    let w = (s.sample_rate_hz.round() as usize).max(1);
    let mut worst = f64::NAN;
    for k in 1..n / w {
        let range = k * w..(k + 1) * w;
        let err = |x: &[f64]| range.clone().map(|i| (x[i] - s.true_torque_nm[i]).powi(2)).sum::<f64>();
        let ratio = (err(clean) / err(s.measured_nm)).sqrt();
        worst = if worst.is_nan() { ratio } else { worst.max(ratio) };
    }
    Ok(worst)
}

/// The full configuration under the do-no-harm guard, as `strainwave filter` runs it:
/// from `learned` (operating tuning, learned priors) or, with `None`, cold
/// (commissioning tuning learning from zero). The clean torque per sample.
pub fn guarded(
    s: &RunSignals,
    gear: &Gear<f64>,
    noise_nm: f64,
    learned: Option<&Learned>,
) -> Result<Vec<f64>, AnalysisError> {
    use strainwave_core::guard::{Guard, GuardSettings};
    check(s)?;
    let model = match learned {
        Some(_) => full_model(s.sample_rate_hz, noise_nm, learned)?,
        None => cold_full(s.sample_rate_hz, noise_nm)?,
    };
    let mut guard = Guard::new(&model, GuardSettings { learned_prior: learned.is_some(), ..GuardSettings::default() });
    (0..s.measured_nm.len())
        .map(|k| {
            let refs = ReferenceValues::from_gear(gear, s.motor_angle_rad[k], s.output_angle_rad[k]);
            let input = RippleInput::new(s.measured_nm[k], refs);
            guard.step(&model, &input).map(|o| o.output.torque_nm).map_err(core_err("guarded filter"))
        })
        .collect()
}
