//! Wheatstone bridge of strain gauges on the flexspline diaphragm (docs/physics.md §2).
//!
//! Strain field seen by a gauge at circumferential position `β`, radius `r` and
//! orientation `α` (from the radial direction; ±45° nominal), with `ψ = φ − β` and
//! `φ` the relative WG–FS angle:
//!
//! ```text
//! ε(α) = c + d cos 2α + (γ/2) sin 2α
//! γ/2  = ε_a(T) (r0/r)² + Σ_h S_h (r/r0) sin(2hψ + p_h)     torsion + interference shear
//! d    = Σ_h D_h (r/r0) cos(2hψ + p_h)                       (ε_r − ε_θ)/2 of the ellipse
//! c    = Σ_h C_h (r/r0) cos(2hψ + p_h)                       (ε_r + ε_θ)/2 of the ellipse
//! ```
//!
//! `h = 1` is the 2× component, `h = 2` the 4× component. Torsional shear falls as
//! `1/r²` (torsion of a disc); the elliptical interference is taken to grow linearly
//! with radius. At `α = ±45°`, `ε = c ± γ/2`: a rosette's difference keeps the
//! torsion and the interference shear, and gauges 90° apart cancel the 2× shear
//! (`sin(2ψ − π) = −sin 2ψ`) but not the 4× (`sin(4ψ − 2π) = sin 4ψ`).
//!
//! Bridge (arms 1..4, arm strain = mean of its series gauges, gauge factor `K`):
//!
//! ```text
//! small strain:  U/E = (K/4)(ε1 − ε2 + ε3 − ε4)
//! exact:         U/E = R1/(R1 + R2) − R4/(R3 + R4),  R_i = R0 (1 + K ε_i)
//! ```
//!
//! With the standard layouts and ideal placement `U = K ε_a E`. the embedded-sensor article writes
//! `4 K ε_a E`, dropping the bridge's 1/4; we follow the standard equation.

use crate::error::{positive, Error};
use crate::Real;

/// Torsional principal strain of a flexspline diaphragm per N·m (the embedded-sensor article):
/// `ε_a / T = (r1 + r2) / (8π a G r1² r2)`.
///
/// `r1_m` hub radius, `r2_m` outer radius, `thickness_m` diaphragm thickness `a`,
/// `shear_modulus_pa` `G`.
///
/// ```
/// use strainwave_core::bridge::diaphragm_strain_per_nm;
/// let e = diaphragm_strain_per_nm(0.008_f64, 0.020, 0.0014, 80e9).unwrap();
/// assert!(e > 7e-6 && e < 8e-6);
/// ```
pub fn diaphragm_strain_per_nm<T: Real>(r1_m: T, r2_m: T, thickness_m: T, shear_modulus_pa: T) -> Result<T, Error> {
    positive(r1_m, "r1_m")?;
    positive(r2_m, "r2_m")?;
    positive(thickness_m, "thickness_m")?;
    positive(shear_modulus_pa, "shear_modulus_pa")?;
    if r2_m <= r1_m {
        return Err(Error::NotIncreasing("r2_m"));
    }
    let eight_pi = T::from_f64(8.0) * T::PI;
    Ok((r1_m + r2_m) / (eight_pi * thickness_m * shear_modulus_pa * r1_m * r1_m * r2_m))
}

/// One harmonic of the elliptical interference, as strains (dimensionless).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Interference<T: Real> {
    /// Shear part `S_h`: survives a rosette's difference.
    pub shear: T,
    /// Normal-difference part `D_h`: leaks in through angular error.
    pub normal: T,
    /// Common part `C_h`: cancels in a rosette unless the arms are unbalanced.
    pub common: T,
    /// Phase `p_h`, rad.
    pub phase_rad: T,
}

/// The strain field of the flexspline diaphragm at the gauge radius.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StrainField<T: Real> {
    /// Torsional strain `ε_a` per N·m of flexspline torque at the nominal radius.
    pub torsion_strain_per_nm: T,
    /// Nominal gauge radius `r0`, m.
    pub nominal_radius_m: T,
    /// `[2×, 4×]` interference harmonics.
    pub interference: [Interference<T>; 2],
}

/// Which bridge arm a gauge is wired into.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Arm {
    /// Arm 1 (+ in `ε1 − ε2 + ε3 − ε4`).
    One,
    /// Arm 2 (−).
    Two,
    /// Arm 3 (+).
    Three,
    /// Arm 4 (−).
    Four,
}

impl Arm {
    fn index(self) -> usize {
        match self {
            Arm::One => 0,
            Arm::Two => 1,
            Arm::Three => 2,
            Arm::Four => 3,
        }
    }
}

/// A strain gauge: where it is and how it is oriented.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Gauge<T: Real> {
    /// Bridge arm.
    pub arm: Arm,
    /// Circumferential position `β`, rad.
    pub position_rad: T,
    /// Orientation `α` from the radial direction, rad (±π/4 nominal).
    pub orientation_rad: T,
    /// Radius `r`, m.
    pub radius_m: T,
}

/// Placement error of one gauge.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct PlacementError<T: Real> {
    /// Radial offset, m.
    pub radial_m: T,
    /// Circumferential offset `δβ`, rad.
    pub circumferential_rad: T,
    /// Orientation offset `Δα`, rad.
    pub angular_rad: T,
}

impl<T: Real> Gauge<T> {
    /// The gauge moved by a placement error.
    pub fn displaced(&self, e: &PlacementError<T>) -> Self {
        Self {
            arm: self.arm,
            position_rad: self.position_rad + e.circumferential_rad,
            orientation_rad: self.orientation_rad + e.angular_rad,
            radius_m: self.radius_m + e.radial_m,
        }
    }
}

/// Gauge layouts on the diaphragm.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Layout {
    /// Taghirad and Bélanger (1999): four rosettes (two perpendicular gauges each) at 0°, 90°, 180°, 270°.
    FourRosettes,
    /// the embedded-sensor article: eight gauges as four "T" pairs at 0°, 90°, 180°, 270°.
    EightGaugeT,
}

impl Layout {
    /// The eight gauges of the layout at radius `r`. Both layouts put a +45° and a
    /// −45° gauge at each of the four positions; arm 1 holds the +45° gauges at 0° and
    /// 180° in series, arm 2 the −45° ones there, arms 3 and 4 the same at 90° and 270°.
    /// The series pairs 180° apart cancel radial error and bending; the arms 90° apart
    /// cancel the 2× interference.
    pub fn gauges<T: Real>(self, radius_m: T) -> [Gauge<T>; 8] {
        let q = T::PI * T::HALF; // 90°
        let a45 = q * T::HALF;
        // The T-pair layout labels R1..R8 by position first; the wiring is the same.
        let mk = |arm, pos: T, ori: T| Gauge { arm, position_rad: pos, orientation_rad: ori, radius_m };
        [
            mk(Arm::One, T::ZERO, a45),
            mk(Arm::Two, T::ZERO, -a45),
            mk(Arm::Three, q, a45),
            mk(Arm::Four, q, -a45),
            mk(Arm::One, T::TWO * q, a45),
            mk(Arm::Two, T::TWO * q, -a45),
            mk(Arm::Three, T::from_f64(3.0) * q, a45),
            mk(Arm::Four, T::from_f64(3.0) * q, -a45),
        ]
    }
}

impl<T: Real> StrainField<T> {
    /// Strain seen by one gauge for a flexspline torque (N·m) at relative angle `φ` (rad).
    pub fn gauge_strain(&self, g: &Gauge<T>, fs_torque_nm: T, relative_angle_rad: T) -> T {
        let rr = g.radius_m / self.nominal_radius_m;
        let psi = relative_angle_rad - g.position_rad;
        let mut half_shear = self.torsion_strain_per_nm * fs_torque_nm / (rr * rr);
        let mut d = T::ZERO;
        let mut c = T::ZERO;
        let mut h = T::ONE;
        for w in &self.interference {
            let (s, co) = (T::TWO * h * psi + w.phase_rad).sin_cos();
            half_shear += w.shear * rr * s;
            d += w.normal * rr * co;
            c += w.common * rr * co;
            h += T::ONE;
        }
        let (s2a, c2a) = (T::TWO * g.orientation_rad).sin_cos();
        c + d * c2a + half_shear * s2a
    }
}

/// A full bridge of `G` gauges with gauge factor and excitation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Bridge<T: Real, const G: usize> {
    gauges: [Gauge<T>; G],
    gauge_factor: T,
    excitation_v: T,
    arm_counts: [usize; 4],
}

impl<T: Real, const G: usize> Bridge<T, G> {
    /// A bridge from its gauges; every arm needs at least one gauge.
    ///
    /// ```
    /// use strainwave_core::bridge::{Bridge, Layout};
    /// let b = Bridge::new(Layout::FourRosettes.gauges(0.015_f64), 2.0, 10.0).unwrap();
    /// assert_eq!(b.excitation_v(), 10.0);
    /// ```
    pub fn new(gauges: [Gauge<T>; G], gauge_factor: T, excitation_v: T) -> Result<Self, Error> {
        positive(gauge_factor, "gauge_factor")?;
        positive(excitation_v, "excitation_v")?;
        let mut arm_counts = [0usize; 4];
        for g in &gauges {
            positive(g.radius_m, "gauge radius_m")?;
            arm_counts[g.arm.index()] += 1;
        }
        if arm_counts.contains(&0) {
            return Err(Error::OutOfRange("gauges (every arm needs a gauge)"));
        }
        Ok(Self { gauges, gauge_factor, excitation_v, arm_counts })
    }

    /// The gauges.
    pub fn gauges(&self) -> &[Gauge<T>; G] {
        &self.gauges
    }

    /// Gauge factor `K`.
    pub fn gauge_factor(&self) -> T {
        self.gauge_factor
    }

    /// Excitation `E`, V.
    pub fn excitation_v(&self) -> T {
        self.excitation_v
    }

    /// The same bridge with each gauge displaced by its placement error.
    pub fn displaced(&self, errors: &[PlacementError<T>; G]) -> Self {
        let mut out = *self;
        for (g, e) in out.gauges.iter_mut().zip(errors.iter()) {
            *g = g.displaced(e);
        }
        out
    }

    /// Mean strain of each arm (series gauges of equal resistance average their strain).
    pub fn arm_strains(&self, field: &StrainField<T>, fs_torque_nm: T, relative_angle_rad: T) -> [T; 4] {
        let mut sum = [T::ZERO; 4];
        for g in &self.gauges {
            sum[g.arm.index()] += field.gauge_strain(g, fs_torque_nm, relative_angle_rad);
        }
        let mut out = [T::ZERO; 4];
        for i in 0..4 {
            out[i] = sum[i] / T::from_usize(self.arm_counts[i]);
        }
        out
    }

    /// Bridge output `U_out`, V (before amplification), small-strain or exact form.
    pub fn output_v(&self, field: &StrainField<T>, fs_torque_nm: T, relative_angle_rad: T, exact: bool) -> T {
        let e = self.arm_strains(field, fs_torque_nm, relative_angle_rad);
        let ratio = if exact {
            bridge_ratio_exact(self.gauge_factor, e)
        } else {
            bridge_ratio_small_strain(self.gauge_factor, e)
        };
        ratio * self.excitation_v
    }

    /// Torque sensitivity `U_out / T_fs`, V per N·m, of the small-strain bridge
    /// (independent of `φ`: only the torsion term is linear in torque).
    pub fn sensitivity_v_per_nm(&self, field: &StrainField<T>) -> T {
        let quiet = StrainField { interference: [Interference::default(); 2], ..*field };
        self.output_v(&quiet, T::ONE, T::ZERO, false) - self.output_v(&quiet, T::ZERO, T::ZERO, false)
    }
}

/// A bridge and strain field reduced to their linear form: each arm strain is
///
/// ```text
/// ε_arm(T, φ) = e0 + eT T + Σ_h (a_h sin 2hφ + b_h cos 2hφ)
/// ```
///
/// (the field is linear in the torque and in `sin/cos 2hφ`), so one sample costs two
/// `sin_cos` and 24 multiply-adds instead of three trigonometric calls per gauge.
/// Exactly equal to [`Bridge::arm_strains`] up to rounding.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BridgeKernel<T: Real> {
    /// Per arm: `[e0, eT, a_1, b_1, a_2, b_2]`.
    arm: [[T; 6]; 4],
    gauge_factor: T,
    excitation_v: T,
}

impl<T: Real, const G: usize> Bridge<T, G> {
    /// The linear kernel of this bridge on a strain field.
    ///
    /// ```
    /// use strainwave_core::bridge::{Bridge, Interference, Layout, StrainField};
    /// let b = Bridge::new(Layout::FourRosettes.gauges(0.015_f64), 2.0, 10.0).unwrap();
    /// let f = StrainField { torsion_strain_per_nm: 7.6e-6, nominal_radius_m: 0.015, interference: [Interference::default(); 2] };
    /// let k = b.kernel(&f);
    /// assert!((k.output_v(3.0, 0.4, false) - b.output_v(&f, 3.0, 0.4, false)).abs() < 1e-15);
    /// ```
    pub fn kernel(&self, field: &StrainField<T>) -> BridgeKernel<T> {
        let mut arm = [[T::ZERO; 6]; 4];
        for g in &self.gauges {
            let i = g.arm.index();
            let wgt = T::ONE / T::from_usize(self.arm_counts[i]);
            let rr = g.radius_m / field.nominal_radius_m;
            let (s2a, c2a) = (T::TWO * g.orientation_rad).sin_cos();
            let row = &mut arm[i];
            row[1] += wgt * field.torsion_strain_per_nm / (rr * rr) * s2a;
            let mut h = T::ONE;
            for (k, w) in field.interference.iter().enumerate() {
                // sin(2hφ − 2hβ + p) = sin 2hφ · cos(p − 2hβ) + cos 2hφ · sin(p − 2hβ)
                let (sd, cd) = (w.phase_rad - T::TWO * h * g.position_rad).sin_cos();
                let shear = w.shear * rr * s2a;
                let cosine = (w.normal * c2a + w.common) * rr;
                row[2 + 2 * k] += wgt * (shear * cd - cosine * sd);
                row[3 + 2 * k] += wgt * (shear * sd + cosine * cd);
                h += T::ONE;
            }
        }
        BridgeKernel { arm, gauge_factor: self.gauge_factor, excitation_v: self.excitation_v }
    }
}

impl<T: Real> BridgeKernel<T> {
    /// Arm strains for a flexspline torque (N·m) at relative angle `φ` (rad).
    #[inline]
    pub fn arm_strains(&self, fs_torque_nm: T, relative_angle_rad: T) -> [T; 4] {
        let (s1, c1) = (T::TWO * relative_angle_rad).sin_cos();
        // sin/cos 4φ from the double angle.
        let (s2, c2) = (T::TWO * s1 * c1, c1 * c1 - s1 * s1);
        let mut out = [T::ZERO; 4];
        for (o, a) in out.iter_mut().zip(self.arm.iter()) {
            *o = a[0] + a[1] * fs_torque_nm + a[2] * s1 + a[3] * c1 + a[4] * s2 + a[5] * c2;
        }
        out
    }

    /// Bridge output `U_out`, V, small-strain or exact form.
    #[inline]
    pub fn output_v(&self, fs_torque_nm: T, relative_angle_rad: T, exact: bool) -> T {
        let e = self.arm_strains(fs_torque_nm, relative_angle_rad);
        let ratio = if exact {
            bridge_ratio_exact(self.gauge_factor, e)
        } else {
            bridge_ratio_small_strain(self.gauge_factor, e)
        };
        ratio * self.excitation_v
    }

    /// Amplitude of the small-strain bridge output at `2h ×` the relative angle with no
    /// torque (`h = 1`: the 2× line, `h = 2`: the 4× line), V. Other `h` give 0.
    ///
    /// `U_h(φ) = (K E / 4) Σ_arms ±(a_h sin 2hφ + b_h cos 2hφ)`, amplitude `(K E/4) √(A² + B²)`.
    pub fn order_amplitude_v(&self, h: usize) -> T {
        if h == 0 || h > 2 {
            return T::ZERO;
        }
        let (i, j) = (2 * h, 2 * h + 1);
        let a = &self.arm;
        let sa = a[0][i] - a[1][i] + a[2][i] - a[3][i];
        let sb = a[0][j] - a[1][j] + a[2][j] - a[3][j];
        self.gauge_factor * T::from_f64(0.25) * self.excitation_v * (sa * sa + sb * sb).sqrt()
    }

    /// Torque sensitivity of the small-strain bridge `U_out / T_fs`, V per N·m.
    pub fn sensitivity_v_per_nm(&self) -> T {
        let a = &self.arm;
        self.gauge_factor * T::from_f64(0.25) * (a[0][1] - a[1][1] + a[2][1] - a[3][1]) * self.excitation_v
    }
}

/// `U/E = (K/4)(ε1 − ε2 + ε3 − ε4)`.
pub fn bridge_ratio_small_strain<T: Real>(gauge_factor: T, arm_strain: [T; 4]) -> T {
    gauge_factor * T::from_f64(0.25) * (arm_strain[0] - arm_strain[1] + arm_strain[2] - arm_strain[3])
}

/// `U/E = R1/(R1 + R2) − R4/(R3 + R4)` with `R_i/R0 = 1 + K ε_i`.
pub fn bridge_ratio_exact<T: Real>(gauge_factor: T, arm_strain: [T; 4]) -> T {
    let r = |e: T| T::ONE + gauge_factor * e;
    let (r1, r2, r3, r4) = (r(arm_strain[0]), r(arm_strain[1]), r(arm_strain[2]), r(arm_strain[3]));
    r1 / (r1 + r2) - r4 / (r3 + r4)
}

/// Amplifier and ADC after the bridge.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SignalChain<T: Real> {
    /// Amplifier gain, V/V.
    pub amplifier_gain: T,
    /// ADC resolution, bits (1..=32).
    pub adc_bits: u32,
    /// ADC input range: `±adc_range_v`, V.
    pub adc_range_v: T,
}

impl<T: Real> SignalChain<T> {
    /// Checks the fields.
    ///
    /// ```
    /// use strainwave_core::bridge::SignalChain;
    /// let c = SignalChain { amplifier_gain: 1000.0_f64, adc_bits: 12, adc_range_v: 10.0 }.validated().unwrap();
    /// assert!((c.lsb_v() - 20.0 / 4096.0).abs() < 1e-15);
    /// ```
    pub fn validated(self) -> Result<Self, Error> {
        positive(self.amplifier_gain, "amplifier_gain")?;
        positive(self.adc_range_v, "adc_range_v")?;
        if self.adc_bits == 0 || self.adc_bits > 32 {
            return Err(Error::OutOfRange("adc_bits"));
        }
        Ok(self)
    }

    /// One ADC step, V.
    pub fn lsb_v(&self) -> T {
        T::TWO * self.adc_range_v / T::from_f64((1u64 << self.adc_bits) as f64)
    }

    /// Quantizes an amplified voltage to the ADC grid (mid-tread), clipping at the
    /// range. Returns the value and whether it clipped.
    pub fn quantize(&self, v: T) -> (T, bool) {
        let lsb = self.lsb_v();
        let max = self.adc_range_v - lsb;
        let clipped = v > max || v < -self.adc_range_v || !v.is_finite();
        let v = if v.is_finite() { v.clamp(-self.adc_range_v, max) } else { T::ZERO };
        ((v / lsb).round() * lsb, clipped)
    }

    /// Full-scale torque for a bridge sensitivity `V/N·m` (before the amplifier), N·m.
    pub fn full_scale_nm(&self, sensitivity_v_per_nm: T) -> T {
        self.adc_range_v / (sensitivity_v_per_nm * self.amplifier_gain).abs()
    }

    /// Torque per ADC step for a bridge sensitivity, N·m.
    pub fn torque_per_lsb_nm(&self, sensitivity_v_per_nm: T) -> T {
        self.lsb_v() / (sensitivity_v_per_nm * self.amplifier_gain).abs()
    }
}

#[cfg(test)]
mod tests;
