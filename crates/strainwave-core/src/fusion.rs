//! Hybrid torque sensing on a motor test bench (docs/physics.md §6, Stoß et al. (2022)): the transfer functions
//! of the torsion-shaft and the accelerometer measurement, the accelerometer torque, and
//! the real-time complementary fusion of the two.
//!
//! Glossary (Stoß et al. (2022) Table I; SI units):
//!
//! | symbol | field | meaning |
//! |---|---|---|
//! | `J_R`, `J_B` | `rotor_inertia_kg_m2`, `brake_inertia_kg_m2` | DUT rotor, brake rotor |
//! | `J_S` | `stator_inertia_kg_m2` | DUT stator + housing (`J_S,tot`) |
//! | `k` | `stiffness_nm_per_rad` | rotor–brake stiffness (`k_RB,TS` with the torsion shaft) |
//! | `Γ` | `damping_nm_s_per_rad` | bearing damping `Γ_LP` (the shaft sees `2Γ`) |
//! | `k_S`, `Γ_LS` | `coupling_stiffness_nm_per_rad`, `stator_damping_nm_s_per_rad` | helix coupling, stator bearings |
//! | `R` | `radius_m` | radius of the two accelerometers |
//!
//! ```text
//! G_TS(s)  = T_TS / T_e = (2 J_B Γ s + J_B k) / (J_B J_R s² + 2Γ (J_B + J_R) s + k (J_B + J_R))   (Stoß et al. 2022, eq. 1)
//! f_res,TS = √(k (1/J_B + 1/J_R)) / 2π                                                        (eq. 2)
//! G_ACC(s) = α_m / T_e = s² / (J_S s² + Γ_LS s + k_S)                                         (eq. 6)
//! G_ACC(s) = s (J_B J_R s³ + J_B Γ s² + k (J_B + J_R) s + k Γ)
//!            / ((J_B J_R s² + k (J_B + J_R)) (J_S s² + (Γ + Γ_LS) s + k_S))                   (eq. 5)
//! f_res,ACC = √(k_S / J_S) / 2π                                                               (eq. 7)
//! α_m = (a_1 + a_2) / (2R),   T_acc = J_S α_m                                                 (eqs. 8, 9)
//! ```
//!
//! Which stiffness is which: with Table I, `k = 258 N·m/rad` gives `f_res,TS = 829.3 Hz` (the
//! docs/physics.md §7 number), so 258 is the torsion-shaft stiffness `k_RB,TS`; `k = 549 N·m/rad`
//! (`k_RB,Acc`, the DUT coupled directly to the brake) gives the 1209.7 Hz DUT–brake resonance
//! the paper sees at ≈ 1.2 kHz in the accelerometer response (its Fig. 6).
//!
//! Fusion (HOKA principle): `T = LP(T_TS) + HP(T_acc)` with `LP + HP = 1` exactly. It is
//! computed as `T = T_acc + LP(T_TS − T_acc)`: one filter, complementary for any two inputs.
//! It leaves the shaft resonance in the fused torque (`LP` still passes part of it);
//! [`OnlineCorrectedFusion`] first multiplies each path by the inverse of its model, so
//! the fused response is flat through the resonance, still per sample.

use crate::error::{finite, positive, Error};
use crate::iir::{Biquad, BiquadState, Complex};
use crate::Real;

mod online;
mod sensors;
pub use online::{OnlineCorrectedFusion, OnlineCorrectionConfig, OnlineFusionState};
pub use sensors::{kit, AccelerometerModel, AccelerometerModelFull, AccelerometerPair, TorsionShaftModel};

/// Shape of the complementary pair.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum CrossoverOrder {
    /// `LP = ω / (s + ω)`, `HP = s / (s + ω)`; equal magnitudes (−3 dB) at `f_c`.
    First,
    /// `LP = (2ω s + ω²) / (s + ω)²`, `HP = s² / (s + ω)²`: the accelerometer path falls
    /// with `f²` below the crossover (its 24 Hz resonance is rejected), the torsion path with
    /// `f` above it. Equal magnitudes at `f_c`, so `ω = 2π f_c / √(2 + √5)`.
    #[default]
    Second,
}

/// Real-time complementary fusion `T = LP(T_TS) + HP(T_acc)`, `LP + HP = 1` (HOKA).
///
/// The low-pass is digital (bilinear, prewarped at the crossover); `HP = 1 − LP` holds
/// exactly in discrete time because the output is computed as `T_acc + LP(T_TS − T_acc)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ComplementaryFusion<T: Real> {
    lowpass: Biquad<T>,
    crossover_hz: T,
    sample_rate_hz: T,
    order: CrossoverOrder,
}

/// State of a [`ComplementaryFusion`].
pub type FusionState<T> = BiquadState<T>;

impl<T: Real> ComplementaryFusion<T> {
    /// A fusion with its crossover at `crossover_hz` (must be below `sample_rate_hz / 2`:
    /// `Error::OutOfRange("crossover_hz")`).
    ///
    /// ```
    /// use strainwave_core::fusion::{ComplementaryFusion, CrossoverOrder};
    /// let f = ComplementaryFusion::new(250.0_f64, 20_000.0, CrossoverOrder::Second).unwrap();
    /// let mut st = Default::default();
    /// // Equal inputs pass unchanged, whatever their spectrum.
    /// for k in 0..100 {
    ///     let x = (k as f64 * 0.3).sin();
    ///     assert!((f.step(&mut st, x, x) - x).abs() < 1e-12);
    /// }
    /// assert!(ComplementaryFusion::new(12_000.0_f64, 20_000.0, CrossoverOrder::First).is_err());
    /// ```
    pub fn new(crossover_hz: T, sample_rate_hz: T, order: CrossoverOrder) -> Result<Self, Error> {
        positive(sample_rate_hz, "sample_rate_hz")?;
        positive(crossover_hz, "crossover_hz")?;
        if crossover_hz >= sample_rate_hz * T::HALF {
            return Err(Error::OutOfRange("crossover_hz"));
        }
        // Designed in f64 (the poles sit close to z = 1 at low crossovers), then rounded
        // to `T` with `b1` set so that the rounded coefficients keep a DC gain of 1.
        let (fc, fs) = (crossover_hz.to_f64(), sample_rate_hz.to_f64());
        let design = match order {
            CrossoverOrder::First => {
                let w = core::f64::consts::TAU * fc;
                Biquad::from_analog([0.0, 0.0, w], [0.0, 1.0, w], fc, fs)
            }
            CrossoverOrder::Second => {
                let w = core::f64::consts::TAU * fc / libm::sqrt(2.0 + libm::sqrt(5.0));
                Biquad::from_analog([0.0, 2.0 * w, w * w], [1.0, 2.0 * w, w * w], fc, fs)
            }
        }
        .map_err(|e| match e {
            Error::OutOfRange(_) => Error::OutOfRange("crossover_hz"),
            other => other,
        })?;
        let b0 = T::from_f64(design.b[0]);
        let b2 = T::from_f64(design.b[2]);
        let a = [T::from_f64(design.a[0]), T::from_f64(design.a[1])];
        let b1 = (T::ONE + a[0] + a[1]) - b0 - b2;
        let lowpass = Biquad { b: [b0, b1, b2], a };
        Ok(Self { lowpass, crossover_hz, sample_rate_hz, order })
    }

    /// The paper's 250 Hz crossover, second order.
    ///
    /// ```
    /// let f = strainwave_core::fusion::ComplementaryFusion::kit(20_000.0_f64).unwrap();
    /// assert_eq!(f.crossover_hz(), 250.0);
    /// ```
    pub fn kit(sample_rate_hz: T) -> Result<Self, Error> {
        Self::new(T::from_f64(kit::CROSSOVER_HZ), sample_rate_hz, CrossoverOrder::Second)
    }

    /// Crossover, Hz.
    pub fn crossover_hz(&self) -> T {
        self.crossover_hz
    }

    /// Sample rate, Hz.
    pub fn sample_rate_hz(&self) -> T {
        self.sample_rate_hz
    }

    /// Order of the pair.
    pub fn order(&self) -> CrossoverOrder {
        self.order
    }

    /// The low-pass of the torsion path.
    pub fn lowpass(&self) -> Biquad<T> {
        self.lowpass
    }

    /// The high-pass of the accelerometer path, `1 − LP`.
    pub fn highpass(&self) -> Biquad<T> {
        self.lowpass.complement()
    }

    /// A state as if both inputs had been constant for ever (no start-up transient).
    pub fn settled_state(&self, torsion_nm: T, accel_torque_nm: T) -> FusionState<T> {
        self.lowpass.settled_state(torsion_nm - accel_torque_nm)
    }

    /// One sample: `T = T_acc + LP(T_TS − T_acc)`, N·m.
    #[inline]
    pub fn step(&self, state: &mut FusionState<T>, torsion_nm: T, accel_torque_nm: T) -> T {
        accel_torque_nm + self.lowpass.step(state, torsion_nm - accel_torque_nm)
    }

    /// `(LP, HP)` responses at `freq_hz`.
    pub fn responses(&self, freq_hz: T) -> (Complex<T>, Complex<T>) {
        let lp = self.lowpass.response(freq_hz, self.sample_rate_hz);
        (lp, Complex::real(T::ONE) - lp)
    }
}

/// The whole online sensor: accelerometer pair plus complementary fusion.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HybridTorqueSensor<T: Real> {
    /// The accelerometers.
    pub pair: AccelerometerPair<T>,
    /// The fusion.
    pub fusion: ComplementaryFusion<T>,
}

impl<T: Real> HybridTorqueSensor<T> {
    /// From its parts.
    ///
    /// ```
    /// use strainwave_core::fusion::{AccelerometerPair, ComplementaryFusion, HybridTorqueSensor};
    /// let s = HybridTorqueSensor::new(AccelerometerPair::kit(), ComplementaryFusion::kit(20_000.0_f32).unwrap());
    /// let mut st = s.fusion.settled_state(0.1, 0.0);
    /// assert!((s.step(&mut st, 0.1, 0.0, 0.0).unwrap() - 0.1).abs() < 1e-5);
    /// ```
    pub fn new(pair: AccelerometerPair<T>, fusion: ComplementaryFusion<T>) -> Self {
        Self { pair, fusion }
    }

    /// One sample from the torsion torque (N·m) and the two accelerations (m/s²); a
    /// non-finite input gives `Err(NonFinite)` and leaves the state untouched.
    #[inline]
    pub fn step(
        &self,
        state: &mut FusionState<T>,
        torsion_nm: T,
        accel_1_m_s2: T,
        accel_2_m_s2: T,
    ) -> Result<T, Error> {
        finite(torsion_nm, "torsion_nm")?;
        finite(accel_1_m_s2, "accel_1_m_s2")?;
        finite(accel_2_m_s2, "accel_2_m_s2")?;
        Ok(self.fusion.step(state, torsion_nm, self.pair.torque_nm(accel_1_m_s2, accel_2_m_s2)))
    }
}

#[cfg(test)]
mod tests;
