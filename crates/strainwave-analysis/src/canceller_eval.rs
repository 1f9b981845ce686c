//! Accuracy of ripple/misalignment cancellers against a simulator's truth, side by side
//! with the simple alternatives (issue: the real-time canceller; SPEC §4).
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
    step as ripple_step, PhaseSource, ReferenceValues, RippleInput, RippleModel, RippleOutput, RippleState,
};

use crate::error::AnalysisError;
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
    /// Tachometer, rad/s (the seed's phase source).
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
    /// Seed 000's 4th-order model (2×, 4× on the tachometer, Q = 1e-3 I, R = 1).
    Seed4th,
    /// Seed 000's 6th-order model (plus 1× output).
    Seed6th,
    /// The full configuration (2×, 4× relative angle, the same scaled by load, 1×
    /// output, bias state) starting from what [`commission`] learned.
    Full,
    /// The full configuration without commissioning: learning from zero during the run.
    FullCold,
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
            Method::Seed4th => "seed 4th-order (2×, 4× tacho)".into(),
            Method::Seed6th => "seed 6th-order (+1× output)".into(),
            Method::Full => "strainwave full (commissioned)".into(),
            Method::FullCold => "strainwave full, no commissioning".into(),
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

/// Runs a Kalman model over a signal; `velocity` selects the seed's tachometer phase.
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
            // The seed: 2×, 4× of the motor velocity, misalignment at velocity / ratio.
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

/// Output of a method on `y` (and, for the Kalman methods, their prediction).
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
        Method::Seed4th => {
            let m = RippleModel::<f64, 2>::seed_4th_order(fs)
                .map_err(core_err("seed model"))?
                .with_phase_source(PhaseSource::Velocity);
            run_kalman(&m, gear, y, s, true)?.iter().map(|o| o.torque_nm).collect()
        }
        Method::Seed6th => {
            let m = RippleModel::<f64, 3>::seed_6th_order(fs)
                .map_err(core_err("seed model"))?
                .with_phase_source(PhaseSource::Velocity);
            run_kalman(&m, gear, y, s, true)?.iter().map(|o| o.torque_nm).collect()
        }
        Method::Full => {
            let learned = learned.ok_or(AnalysisError::Invalid {
                what: "full configuration",
                why: "needs learned coefficients: run `commission` first".into(),
            })?;
            let m = RippleModel::<f64, 5>::full(fs, noise_nm)
                .and_then(|m| m.with_priors(*learned))
                .map_err(core_err("full model"))?;
            run_kalman(&m, gear, y, s, false)?.iter().map(|o| o.torque_nm).collect()
        }
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
/// commissioning tuning, forward pass; the final state is what was learned).
pub fn commission(s: &RunSignals, gear: &Gear<f64>, noise_nm: f64) -> Result<Learned, AnalysisError> {
    check(s)?;
    let m = RippleModel::<f64, 5>::full_commissioning(s.sample_rate_hz, noise_nm).map_err(core_err("full model"))?;
    let mut state = RippleState::new(&m);
    for k in 0..s.measured_nm.len() {
        let refs = ReferenceValues::from_gear(gear, s.motor_angle_rad[k], s.output_angle_rad[k]);
        ripple_step(&m, &mut state, &RippleInput::new(s.measured_nm[k], refs)).map_err(core_err("ripple filter"))?;
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
        let out = apply(m, gear, s.measured_nm, s, noise_nm, learned)?;
        let left = remaining(m, &out, s, &periodic)?;
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
