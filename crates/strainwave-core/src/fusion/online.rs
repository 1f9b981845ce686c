//! Online model-corrected fusion: each path is corrected by the inverse of its bench model
//! inside a fourth-order complementary pair, per sample, in constant memory.
//!
//! The pair shares the denominator `(s + ω)⁴`:
//!
//! ```text
//! LP(s) = (4ω³ s + ω⁴) / (s + ω)⁴                      relative degree 3
//! HP(s) = s² (s² + 4ω s + 6ω²) / (s + ω)⁴ = 1 − LP(s)   double zero at s = 0
//! ```
//!
//! Each branch is the pair's filter times the inverse of its path (see the parent module
//! for `G_TS`, `G_ACC`):
//!
//! ```text
//! C_TS(s)  = LP(s) · g (s² + 2ζ ω_n s + ω_n²) / ω_n² · S(s)      ≈ LP / G_TS
//!            g = (J_B + J_R)/J_B,  ω_n² = k (1/J_R + 1/J_B),  2ζ ω_n = 2Γ (1/J_R + 1/J_B)
//! C_acc(s) = HP(s) / (J_S G_ACC) = (s² + 4ω s + 6ω²)(s² + (Γ_LS/J_S) s + k_S/J_S) / (s + ω)⁴
//! T        = C_TS T_TS + C_acc T_acc,   so that  C_TS G_TS + C_acc J_S G_ACC = LP + HP = 1
//! ```
//!
//! `C_TS` holds a notch at the shaft resonance (the zeros of `G_TS`'s poles) and rolls off
//! with `f⁻¹` above it; `C_acc` needs no integrator because `HP`'s double zero cancels the
//! double zero of the accelerometer path at `s = 0`. Both are proper and stable for any
//! positive model: their poles are those of the pair (and of `S`), whatever the mechanics.
//!
//! Left out of the inverse: the zero of `G_TS` at `s = −k/2Γ` (48 kHz on the KIT bench, so
//! `< 0.03 dB` where `LP` passes the shaft). `S(s) = (s + a/g)/(s + a)` returns the gain
//! from `g` to 1 below `a` (default 0.05 Hz): fluctuations split between rotor and brake as
//! `G_TS(0) = 1/g`, but a steady torque is carried by the brake, so the shaft sees all of it.
//!
//! Discretization: bilinear, every denominator prewarped at the crossover (so `LP + HP = 1`
//! holds exactly in discrete time); the numerators that invert a resonance are prewarped at
//! that resonance, so that the digital zeros sit exactly on the model's poles.
//!
//! `ω` sets the crossover `f_c` where `|LP| = |HP|`: with `x = 2π f_c / ω`, `u = x²`,
//! `u⁴ + 4u³ + 36u² − 16u − 1 = 0` (one positive root, `x ≈ 0.689`).

use crate::error::{finite, non_negative, positive, Error};
use crate::iir::{Biquad, BiquadState, Complex};
use crate::Real;

use super::{AccelerometerModel, TorsionShaftModel};

/// Design settings of [`OnlineCorrectedFusion`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OnlineCorrectionConfig<T: Real> {
    /// Crossover `f_c` (`|LP| = |HP|`), Hz.
    pub crossover_hz: T,
    /// Corner `a/2π` of the steady-torque section `S`, Hz; 0 leaves the gain at `g` down
    /// to DC.
    pub static_corner_hz: T,
}

impl<T: Real> OnlineCorrectionConfig<T> {
    /// 150 Hz crossover (the geometric middle of the housing's 24 Hz and the shaft's 829 Hz,
    /// where a ±10 % model error costs least), 0.05 Hz steady-torque corner.
    ///
    /// ```
    /// let c = strainwave_core::fusion::OnlineCorrectionConfig::<f64>::kit();
    /// assert_eq!((c.crossover_hz, c.static_corner_hz), (150.0, 0.05));
    /// ```
    pub fn kit() -> Self {
        Self { crossover_hz: T::from_f64(150.0), static_corner_hz: T::from_f64(0.05) }
    }
}

/// The online model-corrected fusion (see the module doc): three sections on the torsion
/// path, two on the accelerometer path.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OnlineCorrectedFusion<T: Real> {
    torsion: [Biquad<T>; 3],
    accel: [Biquad<T>; 2],
    crossover_hz: T,
    sample_rate_hz: T,
}

/// State of an [`OnlineCorrectedFusion`]: ten words.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct OnlineFusionState<T: Real> {
    /// Torsion-path sections.
    pub torsion: [BiquadState<T>; 3],
    /// Accelerometer-path sections.
    pub accel: [BiquadState<T>; 2],
}

/// `ω / 2π f_c` of the pair (the positive root of the module doc's quartic, by bisection).
fn pair_omega_ratio() -> f64 {
    let p = |u: f64| (((u + 4.0) * u + 36.0) * u - 16.0) * u - 1.0;
    let (mut lo, mut hi) = (0.0_f64, 1.0_f64);
    for _ in 0..100 {
        let mid = 0.5 * (lo + hi);
        if p(mid) < 0.0 {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    1.0 / libm::sqrt(0.5 * (lo + hi))
}

/// Bilinear constant prewarped at `freq_hz`, or `fallback` when that is at or above Nyquist.
fn prewarp_or(freq_hz: f64, fs: f64, fallback: f64) -> f64 {
    if freq_hz > 0.0 && freq_hz < 0.45 * fs {
        let w = core::f64::consts::TAU * freq_hz;
        w / libm::tan(w / (2.0 * fs))
    } else {
        fallback
    }
}

/// `(n2 s² + n1 s + n0)` under `s = c (z − 1)/(z + 1)`, times `(z + 1)²`, in powers of `z⁻¹`.
fn bilinear_poly(p: [f64; 3], c: f64) -> [f64; 3] {
    let c2 = c * c;
    [p[0] * c2 + p[1] * c + p[2], 2.0 * (p[2] - p[0] * c2), p[0] * c2 - p[1] * c + p[2]]
}

/// A biquad with the numerator transformed with `c_num` and the denominator with `c_den`.
fn section<T: Real>(num: [f64; 3], c_num: f64, den: [f64; 3], c_den: f64) -> Result<Biquad<T>, Error> {
    let nb = bilinear_poly(num, c_num);
    let da = bilinear_poly(den, c_den);
    let a0 = da[0];
    if a0 == 0.0 || !a0.is_finite() {
        return Err(Error::OutOfRange("denominator"));
    }
    let q = Biquad {
        b: [T::from_f64(nb[0] / a0), T::from_f64(nb[1] / a0), T::from_f64(nb[2] / a0)],
        a: [T::from_f64(da[1] / a0), T::from_f64(da[2] / a0)],
    };
    for v in q.b.iter().chain(q.a.iter()) {
        finite(*v, "coefficient")?;
    }
    Ok(q)
}

/// Largest pole radius of one section (`z² + a1 z + a2`).
fn pole_radius<T: Real>(q: &Biquad<T>) -> f64 {
    let (a1, a2) = (q.a[0].to_f64(), q.a[1].to_f64());
    let disc = a1 * a1 - 4.0 * a2;
    if disc < 0.0 {
        libm::sqrt(a2)
    } else {
        let r = libm::sqrt(disc);
        libm::fabs(-a1 + r).max(libm::fabs(-a1 - r)) * 0.5
    }
}

impl<T: Real> OnlineCorrectedFusion<T> {
    /// Designs the fusion from the torsion-shaft model (`Γ` as in `G_TS`, the shaft
    /// sees `2Γ`), the housing model and `cfg`. Errors: `crossover_hz` not in
    /// `(0, 0.45 fs)` → `OutOfRange("crossover_hz")`; a `static_corner_hz` negative, at or
    /// above a tenth of the crossover, or positive but below `1e-9 fs`.
    ///
    /// ```
    /// use strainwave_core::fusion::{AccelerometerModel, OnlineCorrectedFusion, OnlineCorrectionConfig, TorsionShaftModel};
    /// let (ts, acc) = (TorsionShaftModel::<f64>::kit(), AccelerometerModel::<f64>::kit());
    /// let f = OnlineCorrectedFusion::new(&ts, &acc, &OnlineCorrectionConfig::kit(), 20_000.0).unwrap();
    /// // The fused response of the model paths is 1 at the shaft resonance, where the plain
    /// // complementary filter leaves the +20 dB peak.
    /// let r = f.fused_response(829.3, ts.response(829.3), acc.torque_response(829.3));
    /// assert!((r.norm() - 1.0).abs() < 0.01 && r.arg().abs() < 0.01);
    /// let mut cfg = OnlineCorrectionConfig::kit();
    /// cfg.crossover_hz = 9_500.0;
    /// assert!(OnlineCorrectedFusion::new(&ts, &acc, &cfg, 20_000.0).is_err());
    /// ```
    pub fn new(
        torsion: &TorsionShaftModel<T>,
        housing: &AccelerometerModel<T>,
        cfg: &OnlineCorrectionConfig<T>,
        sample_rate_hz: T,
    ) -> Result<Self, Error> {
        let fs = positive(sample_rate_hz, "sample_rate_hz")?.to_f64();
        let fc = positive(cfg.crossover_hz, "crossover_hz")?.to_f64();
        if fc >= 0.45 * fs {
            return Err(Error::OutOfRange("crossover_hz"));
        }
        let corner = non_negative(cfg.static_corner_hz, "static_corner_hz")?.to_f64();
        // 0 switches the steady correction off; a corner below a billionth of the sample
        // rate (a time constant of hours) leaves the section's pole and zero at 1 in
        // rounding, and its output not finite.
        if corner >= 0.1 * fc || (corner > 0.0 && corner < 1e-9 * fs) {
            return Err(Error::OutOfRange("static_corner_hz"));
        }
        // Re-validate the models (their fields are public).
        let ts = TorsionShaftModel::new(
            torsion.rotor_inertia_kg_m2.to_f64(),
            torsion.brake_inertia_kg_m2.to_f64(),
            torsion.stiffness_nm_per_rad.to_f64(),
            torsion.damping_nm_s_per_rad.to_f64(),
        )?;
        let acc = AccelerometerModel::new(
            housing.stator_inertia_kg_m2.to_f64(),
            housing.coupling_stiffness_nm_per_rad.to_f64(),
            housing.stator_damping_nm_s_per_rad.to_f64(),
        )?;
        let tau = core::f64::consts::TAU;
        let w = tau * fc * pair_omega_ratio();
        let cx = prewarp_or(fc, fs, 2.0 * fs);
        let den = [1.0, 2.0 * w, w * w];
        // Torsion: LP's numerator, the inverse of the shaft resonance, the steady section.
        let inv_j = 1.0 / ts.rotor_inertia_kg_m2 + 1.0 / ts.brake_inertia_kg_m2;
        let wn2 = ts.stiffness_nm_per_rad * inv_j;
        let two_zeta_wn = 2.0 * ts.damping_nm_s_per_rad * inv_j;
        let g = 1.0 / ts.dc_gain();
        let cn = prewarp_or(ts.resonance_hz(), fs, cx);
        let k = g * w * w / wn2;
        let t1 = section([0.0, 4.0 * w, w * w], cx, den, cx)?;
        let t2 = section([k, k * two_zeta_wn, k * wn2], cn, den, cx)?;
        let t3 = if corner > 0.0 {
            let a = tau * corner;
            Biquad::from_analog([0.0, 1.0, a / g], [0.0, 1.0, a], fc, fs)?
        } else {
            Biquad::identity()
        };
        let t3 = Biquad {
            b: [T::from_f64(t3.b[0]), T::from_f64(t3.b[1]), T::from_f64(t3.b[2])],
            a: [T::from_f64(t3.a[0]), T::from_f64(t3.a[1])],
        };
        // Accelerometers: HP's numerator over s², the inverse of the housing resonance.
        let js = acc.stator_inertia_kg_m2;
        let cs = prewarp_or(acc.resonance_hz(), fs, cx);
        let a1 = section([1.0, 4.0 * w, 6.0 * w * w], cx, den, cx)?;
        let a2 =
            section([1.0, acc.stator_damping_nm_s_per_rad / js, acc.coupling_stiffness_nm_per_rad / js], cs, den, cx)?;
        Ok(Self { torsion: [t3, t1, t2], accel: [a1, a2], crossover_hz: cfg.crossover_hz, sample_rate_hz })
    }

    /// Crossover, Hz.
    pub fn crossover_hz(&self) -> T {
        self.crossover_hz
    }

    /// Sample rate, Hz.
    pub fn sample_rate_hz(&self) -> T {
        self.sample_rate_hz
    }

    /// The torsion-path sections (steady, `LP` numerator, resonance inverse), in order.
    pub fn torsion_sections(&self) -> &[Biquad<T>; 3] {
        &self.torsion
    }

    /// The accelerometer-path sections, in order.
    pub fn accel_sections(&self) -> &[Biquad<T>; 2] {
        &self.accel
    }

    /// Largest pole radius of all sections (< 1: stable).
    ///
    /// ```
    /// use strainwave_core::fusion::{AccelerometerModel, OnlineCorrectedFusion, OnlineCorrectionConfig, TorsionShaftModel};
    /// let f = OnlineCorrectedFusion::new(&TorsionShaftModel::<f32>::kit(), &AccelerometerModel::kit(),
    ///     &OnlineCorrectionConfig::kit(), 20_000.0).unwrap();
    /// assert!(f.max_pole_radius() < 1.0);
    /// ```
    pub fn max_pole_radius(&self) -> f64 {
        self.torsion.iter().chain(self.accel.iter()).map(pole_radius).fold(0.0, f64::max)
    }

    /// The state after both inputs were constant for ever (no start-up transient).
    pub fn settled_state(&self, torsion_nm: T, accel_torque_nm: T) -> OnlineFusionState<T> {
        let mut st = OnlineFusionState::default();
        let mut x = torsion_nm;
        for (q, s) in self.torsion.iter().zip(st.torsion.iter_mut()) {
            *s = q.settled_state(x);
            x = q.dc_gain() * x;
        }
        let mut x = accel_torque_nm;
        for (q, s) in self.accel.iter().zip(st.accel.iter_mut()) {
            *s = q.settled_state(x);
            x = q.dc_gain() * x;
        }
        st
    }

    /// One sample: `T = C_TS T_TS + C_acc T_acc`, N·m.
    #[inline]
    pub fn step(&self, state: &mut OnlineFusionState<T>, torsion_nm: T, accel_torque_nm: T) -> T {
        let mut t = torsion_nm;
        for (q, s) in self.torsion.iter().zip(state.torsion.iter_mut()) {
            t = q.step(s, t);
        }
        let mut a = accel_torque_nm;
        for (q, s) in self.accel.iter().zip(state.accel.iter_mut()) {
            a = q.step(s, a);
        }
        t + a
    }

    /// One sample with the inputs checked: a non-finite input gives `Err(NonFinite)` and
    /// leaves the state untouched.
    #[inline]
    pub fn try_step(&self, state: &mut OnlineFusionState<T>, torsion_nm: T, accel_torque_nm: T) -> Result<T, Error> {
        finite(torsion_nm, "torsion_nm")?;
        finite(accel_torque_nm, "accel_torque_nm")?;
        Ok(self.step(state, torsion_nm, accel_torque_nm))
    }

    /// `(C_TS, C_acc)` at `freq_hz`.
    pub fn responses(&self, freq_hz: T) -> (Complex<T>, Complex<T>) {
        let fs = self.sample_rate_hz;
        let prod = |qs: &[Biquad<T>]| qs.iter().fold(Complex::real(T::ONE), |acc, q| acc * q.response(freq_hz, fs));
        (prod(&self.torsion), prod(&self.accel))
    }

    /// Fused response `C_TS h_ts + C_acc h_acc` for path responses `h_ts = T_TS/T_e` and
    /// `h_acc = T_acc/T_e` at `freq_hz` (1 when the model is exact).
    pub fn fused_response(&self, freq_hz: T, h_ts: Complex<T>, h_acc: Complex<T>) -> Complex<T> {
        let (c_ts, c_acc) = self.responses(freq_hz);
        c_ts * h_ts + c_acc * h_acc
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pair_ratio_gives_equal_magnitudes() {
        let x = 1.0 / pair_omega_ratio();
        let s = Complex::new(0.0, x);
        let one = Complex::real(1.0);
        let p = (s + one) * (s + one) * (s + one) * (s + one);
        let lp = (s.scale(4.0) + one) / p;
        let hp = one - lp;
        assert!((lp.norm() - hp.norm()).abs() < 1e-12, "{lp:?} {hp:?}");
        assert!((x - 0.6891).abs() < 1e-4, "{x}");
    }

    #[test]
    fn model_paths_fuse_flat() {
        let (ts, acc) = (TorsionShaftModel::<f64>::kit(), AccelerometerModel::<f64>::kit());
        let f = OnlineCorrectedFusion::new(&ts, &acc, &OnlineCorrectionConfig::kit(), 20_000.0).unwrap();
        let mut fr = 1.0;
        while fr < 4000.0 {
            let r = f.fused_response(fr, ts.response(fr), acc.torque_response(fr));
            // The uninverted shaft-damping zero and the steady section: well below 0.1 dB / 0.5°.
            assert!((20.0 * r.norm().log10()).abs() < 0.1 && r.arg().to_degrees().abs() < 0.5, "{fr}: {r:?}");
            fr *= 1.02;
        }
    }

    #[test]
    fn rejects_bad_settings() {
        let (ts, acc) = (TorsionShaftModel::<f64>::kit(), AccelerometerModel::<f64>::kit());
        let mut c = OnlineCorrectionConfig::kit();
        c.static_corner_hz = -1.0;
        assert_eq!(OnlineCorrectedFusion::new(&ts, &acc, &c, 20_000.0), Err(Error::OutOfRange("static_corner_hz")));
        for tiny in [1e-320, 1e-6] {
            c.static_corner_hz = tiny;
            assert_eq!(OnlineCorrectedFusion::new(&ts, &acc, &c, 20_000.0), Err(Error::OutOfRange("static_corner_hz")));
        }
        c.static_corner_hz = 1e-4;
        assert!(OnlineCorrectedFusion::new(&ts, &acc, &c, 20_000.0).is_ok());
        c = OnlineCorrectionConfig::kit();
        c.crossover_hz = f64::NAN;
        assert_eq!(OnlineCorrectedFusion::new(&ts, &acc, &c, 20_000.0), Err(Error::NonPositive("crossover_hz")));
        let mut bad = ts;
        bad.stiffness_nm_per_rad = 0.0;
        assert!(OnlineCorrectedFusion::new(&bad, &acc, &OnlineCorrectionConfig::kit(), 20_000.0).is_err());
    }
}
