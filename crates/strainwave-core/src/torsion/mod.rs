//! Encoder-based link torque: harmonic-drive torsion from motor and link angles, kinematic error, and the streaming estimator (docs/physics.md §5).
//!
//! Glossary: `θ_m` motor (= wave generator, WG) angle, `θ` link (output) angle, `n_s` the
//! signed ratio of [`Gear::signed_ratio`] (`−N` with the circular spline fixed, `N + 1`
//! with the flexspline fixed), `φ = θ_wg − θ_fs` the relative angle, `θ_k` the kinematic
//! error, `w` the wind-up the gear's springs carry, `τ` the link torque.
//!
//! ```text
//! torsion           θ_h = θ − θ_m / n_s          (CS fixed: θ + θ_m/N;  FS fixed: θ − θ_m/(N+1))
//! load torsion      Δθ  = θ_h − θ_k(θ, φ)
//! wind-up           w   = −Δθ = θ_k − θ_h
//! elastic twist     w_e = w + h z                 (optional hysteresis, see compliance::Hysteresis)
//! torque            τ   solves  θ_f(τ) + θ_w(τ/N)/N = w_e   (or any compliance::Compliance)
//!                         plus  c ẇ                (optional structural damping)
//! ```
//!
//! Sign convention: `θ_h` is the output angle minus the rigid (ideal) output angle, as in
//! docs/physics.md §5. The estimator reports the **link torque**: the torque the gear transmits to
//! the link, positive when it drives the link in its positive direction. Driving the link
//! forward makes it lag its rigid position, so `θ_h < 0` and the wind-up `w > 0`. In static
//! equilibrium the link torque is minus the external torque on the link (the HDA-arm paper's `τ`, which
//! solves `Δθ = θ_f + θ_w/N`, is that external torque).
//!
//! The motor angle here is the WG angle in the gear's own convention. An encoder mounted
//! the other way round is declared `reversed` in its [`EncoderConfig`].
//!
//! Precision: the torsion is a small difference of large angles (a 2^24-count motor
//! encoder reaches 10^9 counts). Counts are accumulated as `i64` and differenced in
//! `f64` before conversion to `T`, so `f32` users keep the torsion to encoder resolution.

use crate::compliance::{Compliance, Hysteresis, PlayHysteresis, MAX_PLAYS};
use crate::error::{finite, positive, Error};
use crate::gear::Gear;
use crate::Real;

const TAU_F64: f64 = core::f64::consts::TAU;

/// Harmonic-drive torsion `θ_h = θ − θ_m / n_s`, rad (output angle minus the rigid output angle).
///
/// ```
/// use strainwave_core::gear::{FixedElement, Gear};
/// use strainwave_core::torsion::torsion_rad;
/// let gear = Gear::new(100.0_f64, FixedElement::CircularSpline).unwrap();
/// // CS fixed: the output turns backwards; 10 rad of motor gives −0.1 rad of output.
/// assert!((torsion_rad(&gear, 10.0, -0.1 + 2e-4) - 2e-4).abs() < 1e-12);
/// ```
pub fn torsion_rad<T: Real>(gear: &Gear<T>, motor_angle_rad: T, link_angle_rad: T) -> T {
    link_angle_rad - gear.output_angle(motor_angle_rad)
}

/// `θ_h` computed in `f64` from `f64` angles, then converted (see the module doc).
fn torsion_f64(signed_ratio: f64, motor_angle_rad: f64, link_angle_rad: f64) -> f64 {
    link_angle_rad - motor_angle_rad / signed_ratio
}

/// `x mod 2π` in `[0, 2π)`.
fn reduce_tau(x: f64) -> f64 {
    let r = x - TAU_F64 * libm::floor(x / TAU_F64);
    if r >= TAU_F64 {
        0.0
    } else {
        r
    }
}

use encoder::{check_raw, unwrap_delta};
pub use encoder::{EncoderConfig, EncoderFlags, EncoderState};
pub use kinematic::{
    DefaultKinematic, GearAngles, KinematicError, KinematicFourier, KinematicPolynomial, MeshAngle, NoKinematicError,
};
pub use solver::{Solution, TorqueSolver};

/// Kinematic-error models: polynomial (the HDA-arm paper) and Fourier (output and mesh angle).
mod kinematic;

/// The bounded, bracketed Newton solver of the implicit torsion equation.
mod solver;

/// Encoder counts: offsets, direction, unwrapping of wrapping counters, jump detection.
mod encoder;

/// Streaming state of a [`TorsionEstimator`] (one per joint).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct EstimatorState<T: Real> {
    motor: EncoderState,
    link: EncoderState,
    motor_turn_offset: i64,
    last_torque_nm: T,
    last_windup_rad: T,
    hysteresis_extreme_rad: T,
    hysteresis_direction: T,
    hysteresis_z: T,
    plays: [T; MAX_PLAYS],
    started: bool,
    samples: u64,
    failures: u64,
    last_flags: EncoderFlags,
}

impl<T: Real> EstimatorState<T> {
    /// A fresh state.
    pub fn new() -> Self {
        Self::default()
    }
    /// Last good torque, N·m (held through failures).
    pub fn last_torque_nm(&self) -> T {
        self.last_torque_nm
    }
    /// Hysteresis state `z` (Dahl).
    pub fn hysteresis_state(&self) -> T {
        self.hysteresis_z
    }
    /// Play-operator states (play hysteresis), rad.
    pub fn plays(&self) -> &[T; MAX_PLAYS] {
        &self.plays
    }
    /// Samples processed.
    pub fn samples(&self) -> u64 {
        self.samples
    }
    /// Samples whose torque could not be solved.
    pub fn failures(&self) -> u64 {
        self.failures
    }
    /// Encoder flags of the last sample (also when it failed).
    pub fn last_flags(&self) -> EncoderFlags {
        self.last_flags
    }
    /// Motor encoder unwrapping state.
    pub fn motor_encoder(&self) -> &EncoderState {
        &self.motor
    }
    /// Link encoder unwrapping state.
    pub fn link_encoder(&self) -> &EncoderState {
        &self.link
    }
}

/// Everything the estimator computed for one sample.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Estimate<T: Real> {
    /// Link torque (transmitted to the link, see the module doc), N·m.
    pub link_torque_nm: T,
    /// Torsion `θ_h`, rad.
    pub torsion_rad: T,
    /// Kinematic error `θ_k`, rad.
    pub kinematic_error_rad: T,
    /// Wind-up `w = θ_k − θ_h`, rad.
    pub windup_rad: T,
    /// Output (link) angle, rad, unwrapped.
    pub output_angle_rad: T,
    /// Relative angle `φ`, rad in `[0, 2π)`.
    pub relative_angle_rad: T,
    /// Newton iterations used.
    pub iterations: u32,
    /// Encoder wraps and jumps.
    pub flags: EncoderFlags,
}

/// Link torque from a motor and a link encoder through the gear's compliance (docs/physics.md §5).
///
/// Configuration only (immutable); the per-joint [`EstimatorState`] is passed to each step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TorsionEstimator<T: Real, K, C> {
    gear: Gear<T>,
    motor_encoder: EncoderConfig,
    link_encoder: EncoderConfig,
    kinematic: K,
    compliance: C,
    solver: TorqueSolver<T>,
    hysteresis: Option<Hysteresis<T>>,
    hysteresis_deadband_rad: T,
    plays: Option<PlayHysteresis<T>>,
    damping_nm_s_per_rad: T,
    sample_rate_hz: T,
}

impl<T: Real, K: KinematicError<T>, C: Compliance<T>> TorsionEstimator<T, K, C> {
    /// An estimator with its gear, encoders, kinematic model, compliance and solver.
    ///
    /// ```
    /// use strainwave_core::compliance::ThreeSlopeStiffness;
    /// use strainwave_core::gear::{FixedElement, Gear};
    /// use strainwave_core::torsion::*;
    /// let gear = Gear::new(100.0_f64, FixedElement::CircularSpline).unwrap();
    /// let est = TorsionEstimator::new(
    ///     gear,
    ///     EncoderConfig::multi_turn(1 << 14).unwrap(),
    ///     EncoderConfig::single_turn(1 << 20).unwrap(),
    ///     NoKinematicError,
    ///     ThreeSlopeStiffness::linear(1.0e4).unwrap(),
    ///     TorqueSolver::for_rated_torque(40.0).unwrap(),
    /// );
    /// let mut state = EstimatorState::new();
    /// // Motor at +1600 counts (0.614 rad): the rigid output is −6.14 mrad = −1024 link counts.
    /// // The link lags that by 10 counts: a positive link torque of 1e4 × 10 × 2π/2^20 N·m.
    /// let e = est.step_counts(&mut state, 1600, (1 << 20) - 1024 - 10).unwrap();
    /// assert!((e.link_torque_nm - 0.5992).abs() < 1e-4);
    /// ```
    pub fn new(
        gear: Gear<T>,
        motor_encoder: EncoderConfig,
        link_encoder: EncoderConfig,
        kinematic: K,
        compliance: C,
        solver: TorqueSolver<T>,
    ) -> Self {
        Self {
            gear,
            motor_encoder,
            link_encoder,
            kinematic,
            compliance,
            solver,
            hysteresis: None,
            hysteresis_deadband_rad: T::ZERO,
            plays: None,
            damping_nm_s_per_rad: T::ZERO,
            sample_rate_hz: T::ONE,
        }
    }

    /// Adds hysteresis loss: a Dahl state driven by the wind-up with a reversal deadband.
    ///
    /// The Dahl law integrates every reversal of `ẇ`; fed with raw encoder differences,
    /// quantization and noise chatter would drive `z` to 0 at standstill while the real
    /// gear keeps its branch. Here `z` advances only with travel beyond the last extreme
    /// of the wind-up in the current direction, and a reversal is accepted once the
    /// wind-up has come back by more than `deadband_rad` (choose the torsion resolution
    /// plus the noise, peak to peak); `z` then catches up with the whole travel since the
    /// extreme, so the only error is a lag of `deadband_rad` right after a reversal.
    pub fn with_hysteresis(mut self, hysteresis: Hysteresis<T>, deadband_rad: T) -> Result<Self, Error> {
        crate::error::non_negative(deadband_rad, "deadband_rad")?;
        self.hysteresis = Some(hysteresis);
        self.hysteresis_deadband_rad = deadband_rad;
        self.plays = None;
        Ok(self)
    }

    /// Adds rate-independent hysteresis as play operators (Maxwell-slip); it replaces a
    /// Dahl hysteresis set before, and vice versa.
    pub fn with_play_hysteresis(mut self, plays: PlayHysteresis<T>) -> Self {
        self.plays = Some(plays);
        self.hysteresis = None;
        self
    }

    /// Adds structural damping `c ẇ` with `ẇ` the wind-up difference times the sample rate.
    pub fn with_damping(mut self, damping_nm_s_per_rad: T, sample_rate_hz: T) -> Result<Self, Error> {
        crate::error::non_negative(damping_nm_s_per_rad, "damping_nm_s_per_rad")?;
        positive(sample_rate_hz, "sample_rate_hz")?;
        self.damping_nm_s_per_rad = damping_nm_s_per_rad;
        self.sample_rate_hz = sample_rate_hz;
        Ok(self)
    }

    /// The gear.
    pub fn gear(&self) -> &Gear<T> {
        &self.gear
    }
    /// The kinematic model.
    pub fn kinematic(&self) -> &K {
        &self.kinematic
    }
    /// The compliance model.
    pub fn compliance(&self) -> &C {
        &self.compliance
    }
    /// The solver.
    pub fn solver(&self) -> &TorqueSolver<T> {
        &self.solver
    }

    /// One sample from raw counts. Unwraps both counters (flagging wraps and implausible
    /// jumps), converts to angles and runs [`Self::step_angles`]. With a single-turn motor
    /// counter, its turn count is chosen on the first sample so that the torsion is
    /// smallest (valid while the twist stays under `π/N` of output).
    ///
    /// Errors: a count outside `0 … modulus − 1` (`OutOfRange("motor_counts")` /
    /// `("link_counts")`, state untouched), or the torque solve's error (state updated,
    /// last torque held).
    pub fn step_counts(
        &self,
        state: &mut EstimatorState<T>,
        motor_counts: i64,
        link_counts: i64,
    ) -> Result<Estimate<T>, Error> {
        check_raw(&self.motor_encoder, motor_counts, "motor_counts")?;
        check_raw(&self.link_encoder, link_counts, "link_counts")?;
        let mut flags = EncoderFlags::default();
        let (mc, lc) = (&self.motor_encoder, &self.link_encoder);
        if !state.started {
            let wrap0 = |cfg: &EncoderConfig, raw: i64| {
                let d = raw.wrapping_sub(cfg.offset_counts);
                if cfg.modulus_counts > 0 {
                    let m = cfg.modulus_counts as i64;
                    let r = d.rem_euclid(m);
                    if r >= m / 2 {
                        r - m
                    } else {
                        r
                    }
                } else {
                    d
                }
            };
            state.motor = EncoderState { last_raw: motor_counts, accumulated: wrap0(mc, motor_counts) };
            state.link = EncoderState { last_raw: link_counts, accumulated: wrap0(lc, link_counts) };
            state.motor_turn_offset = 0;
            if mc.modulus_counts > 0 {
                // Choose the motor turn count that makes the torsion smallest.
                let n_s = self.gear.signed_ratio().to_f64();
                let link = state.link.accumulated as f64 * lc.rad_per_count();
                let motor = state.motor.accumulated as f64 * mc.rad_per_count();
                let turns = libm::round((link * n_s - motor) / (mc.modulus_counts as f64 * mc.rad_per_count()));
                state.motor_turn_offset = (turns as i64).saturating_mul(mc.modulus_counts as i64);
            }
        } else {
            let (dm, wm, jm) = unwrap_delta(mc, &state.motor, motor_counts);
            let (dl, wl, jl) = unwrap_delta(lc, &state.link, link_counts);
            flags = EncoderFlags { motor_wrapped: wm, link_wrapped: wl, motor_jump: jm, link_jump: jl };
            state.motor.accumulated = state.motor.accumulated.wrapping_add(dm);
            state.motor.last_raw = motor_counts;
            state.link.accumulated = state.link.accumulated.wrapping_add(dl);
            state.link.last_raw = link_counts;
        }
        let motor_rad = (state.motor.accumulated.wrapping_add(state.motor_turn_offset)) as f64 * mc.rad_per_count();
        let link_rad = state.link.accumulated as f64 * lc.rad_per_count();
        let r = self.step_angles(state, motor_rad, link_rad);
        state.last_flags = flags;
        r.map(|mut e| {
            e.flags = flags;
            e
        })
    }

    /// One sample from angles in the gear's convention (WG angle and output angle, rad,
    /// unwrapped, `f64` so that the torsion survives large motor angles).
    pub fn step_angles(
        &self,
        state: &mut EstimatorState<T>,
        motor_angle_rad: f64,
        link_angle_rad: f64,
    ) -> Result<Estimate<T>, Error> {
        state.last_flags = EncoderFlags::default();
        if !(motor_angle_rad.is_finite() && link_angle_rad.is_finite()) {
            state.failures += 1;
            return Err(Error::NonFinite(if motor_angle_rad.is_finite() {
                "link_angle_rad"
            } else {
                "motor_angle_rad"
            }));
        }
        state.samples += 1;
        let torsion = T::from_f64(torsion_f64(self.gear.signed_ratio().to_f64(), motor_angle_rad, link_angle_rad));
        let angles = GearAngles::from_f64(&self.gear, motor_angle_rad, link_angle_rad);
        let kin = self.kinematic.kinematic_error_rad(&angles);
        let windup = kin - torsion;
        let first = !state.started;
        state.started = true;
        let delta = if first { T::ZERO } else { windup - state.last_windup_rad };
        let elastic = match &self.hysteresis {
            Some(h) => {
                if first {
                    state.hysteresis_extreme_rad = windup;
                    state.hysteresis_direction = T::ZERO;
                } else {
                    // Noise-tolerant Dahl: z follows travel beyond the last extreme in the
                    // current direction; a reversal counts once the wind-up has come back
                    // more than the deadband, and then with its full travel (exact catch-up).
                    let d = windup - state.hysteresis_extreme_rad;
                    let s = d.signum0();
                    let dir = state.hysteresis_direction;
                    let advance = (dir != T::ZERO && s == dir) || d.abs() > self.hysteresis_deadband_rad;
                    if advance && s != T::ZERO {
                        state.hysteresis_z = h.update(state.hysteresis_z, d);
                        state.hysteresis_extreme_rad = windup;
                        state.hysteresis_direction = s;
                    }
                }
                h.elastic_twist_rad(windup, state.hysteresis_z)
            }
            None => match &self.plays {
                Some(p) => {
                    if first {
                        state.plays = p.initial_state(windup);
                    } else {
                        p.advance(&mut state.plays, windup);
                    }
                    windup + p.offset_rad(&state.plays, windup)
                }
                None => windup,
            },
        };
        state.last_windup_rad = windup;
        let solved = self.solver.solve(&self.compliance, elastic, state.last_torque_nm);
        match solved {
            Ok(s) => {
                let damping = self.damping_nm_s_per_rad * delta * self.sample_rate_hz;
                state.last_torque_nm = s.torque_nm;
                Ok(Estimate {
                    link_torque_nm: s.torque_nm + damping,
                    torsion_rad: torsion,
                    kinematic_error_rad: kin,
                    windup_rad: windup,
                    output_angle_rad: angles.output_rad,
                    relative_angle_rad: angles.relative_rad,
                    iterations: s.iterations,
                    flags: EncoderFlags::default(),
                })
            }
            Err(e) => {
                state.failures += 1;
                Err(e)
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::kinematic::fourier_sum;
    use super::*;
    use crate::compliance::{FlexsplineStiffening, HdaArmCompliance, ThreeSlopeStiffness, WaveGeneratorSoftening};
    use crate::gear::FixedElement;

    const TORQUE_TOL_NM: f64 = 1e-6;

    #[test]
    fn torsion_sign_per_configuration() {
        let cs = Gear::new(100.0, FixedElement::CircularSpline).unwrap();
        let fs = Gear::new(100.0, FixedElement::Flexspline).unwrap();
        assert!((torsion_rad(&cs, 1.0, -0.01) - 0.0).abs() < 1e-15);
        assert!((torsion_rad(&fs, 1.01, 0.01) - 0.0).abs() < 1e-15);
        assert!((torsion_rad(&cs, 1.0, -0.0099) - 1e-4).abs() < 1e-12);
    }

    #[test]
    fn fourier_recurrence_matches_direct() {
        let coefs = [[0.3, -0.2], [0.1, 0.05], [-0.07, 0.02], [0.01, 0.0]];
        for i in 0..50 {
            let x = i as f64 * 0.37;
            let direct: f64 = coefs
                .iter()
                .enumerate()
                .map(|(h, c)| c[0] * ((h + 1) as f64 * x).cos() + c[1] * ((h + 1) as f64 * x).sin())
                .sum();
            assert!((fourier_sum(x, &coefs) - direct).abs() < 1e-12);
        }
    }

    #[test]
    fn solver_inverts_hda_arm_model_f32_f64() {
        fn case<T: Real>(tol: f64) {
            let m = HdaArmCompliance::new(
                FlexsplineStiffening::new(T::from_f64(2.0e4), T::from_f64(0.015)).unwrap(),
                WaveGeneratorSoftening::new(T::from_f64(2.5), T::from_f64(1.5)).unwrap(),
                T::from_f64(100.0),
            )
            .unwrap();
            let s = TorqueSolver::for_rated_torque(T::from_f64(40.0)).unwrap();
            for i in -12..=12 {
                let tau = T::from_f64(i as f64 * 10.0);
                let sol = s.solve(&m, m.twist_rad(tau), T::ZERO).unwrap();
                assert!((sol.torque_nm - tau).to_f64().abs() < tol * (1.0 + tau.to_f64().abs()), "{tau:?} {sol:?}");
            }
        }
        case::<f64>(TORQUE_TOL_NM);
        case::<f32>(1e-3);
    }

    #[test]
    fn encoder_single_turn_wraps_are_flagged() {
        let gear = Gear::new(50.0, FixedElement::CircularSpline).unwrap();
        let est = TorsionEstimator::new(
            gear,
            EncoderConfig::single_turn(4096).unwrap(),
            EncoderConfig::single_turn(1 << 16).unwrap(),
            NoKinematicError,
            ThreeSlopeStiffness::linear(1e4).unwrap(),
            TorqueSolver::for_rated_torque(50.0).unwrap(),
        );
        let mut st = EstimatorState::<f64>::new();
        est.step_counts(&mut st, 4090, 0).unwrap();
        let e = est.step_counts(&mut st, 5, 0).unwrap();
        assert!(e.flags.motor_wrapped && !e.flags.motor_jump);
        assert_eq!(st.motor_encoder().accumulated_counts(), -6 + 11);
        let e = est.step_counts(&mut st, 2100, 0);
        assert!(st.last_flags().motor_jump, "{e:?}");
        assert_eq!(est.step_counts(&mut st, 4096, 0), Err(Error::OutOfRange("motor_counts")));
    }
}
