//! The measurement models of the bench (Stoß et al. (2022)): the torsion shaft's and the
//! accelerometers' transfer functions and the accelerometer torque; see the parent
//! module's doc for the equations.

use crate::error::{non_negative, positive, Error};
use crate::iir::{polyval, Complex};
use crate::Real;

/// Stoß et al. (2022) Table I and the accelerometer data, in SI units.
pub mod kit {
    /// Brake rotor inertia `J_B`, kg·m² (100 mg·m²).
    pub const BRAKE_INERTIA_KG_M2: f64 = 100e-6;
    /// DUT rotor inertia `J_R`, kg·m² (10.5 mg·m²).
    pub const ROTOR_INERTIA_KG_M2: f64 = 10.5e-6;
    /// DUT stator + housing inertia `J_S,tot`, kg·m² (1.305 g·m²).
    pub const STATOR_INERTIA_KG_M2: f64 = 1.305e-3;
    /// Rotor bearing damping `Γ_LP`, N·m·s/rad (424 µN·m·s).
    pub const BEARING_DAMPING_NM_S_PER_RAD: f64 = 424e-6;
    /// Rotor–brake stiffness without the torsion shaft `k_RB,Acc`, N·m/rad.
    pub const STIFFNESS_ACC_NM_PER_RAD: f64 = 549.0;
    /// Rotor–brake stiffness through the torsion shaft `k_RB,TS`, N·m/rad.
    pub const STIFFNESS_TS_NM_PER_RAD: f64 = 258.0;
    /// Helix coupling stiffness `k_S`, N·m/rad.
    pub const COUPLING_STIFFNESS_NM_PER_RAD: f64 = 29.0;
    /// Stator bearing damping `Γ_LS`, N·m·s/rad (4.24 mN·m·s).
    pub const STATOR_DAMPING_NM_S_PER_RAD: f64 = 4.24e-3;
    /// Accelerometer radius `R`, m. The paper does not state it; eq. 11 with the paper's
    /// `a_max` = 50 m/s² and its 97 mN·m implies `R = 50 J_S / 0.097 = 0.673 m`. That is ten
    /// times what a 59 mm motor's housing suggests (a typo in `a_max` or `R` is likely), but
    /// only `a / R` enters the torque, so the torque-domain figures are those of the paper.
    pub const ACCEL_RADIUS_M: f64 = 0.6727;
    /// Range of one sensor `a_max`, m/s² (Stoß et al. 2022: PCB 352B, 50 m/s²).
    pub const ACCEL_MAX_M_S2: f64 = 50.0;
    /// Resolution of one sensor `a_min`, m/s² (implied by eq. 10's 21 µN·m with this `R`).
    pub const ACCEL_MIN_M_S2: f64 = 0.0108;
    /// Crossover of the paper's fusion, Hz.
    pub const CROSSOVER_HZ: f64 = 250.0;
}

/// `s = j 2π f`.
fn jw<T: Real>(freq_hz: T) -> Complex<T> {
    Complex::new(T::ZERO, T::TAU * freq_hz)
}

/// The torsion-shaft measurement: DUT rotor and brake on a shaft (Stoß et al. 2022, eq. 1, Fig. 3).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TorsionShaftModel<T: Real> {
    /// `J_R`, kg·m².
    pub rotor_inertia_kg_m2: T,
    /// `J_B`, kg·m².
    pub brake_inertia_kg_m2: T,
    /// `k`, N·m/rad.
    pub stiffness_nm_per_rad: T,
    /// `Γ` (the shaft sees `2Γ`), N·m·s/rad.
    pub damping_nm_s_per_rad: T,
}

impl<T: Real> TorsionShaftModel<T> {
    /// Validates positive inertias and stiffness, damping ≥ 0.
    ///
    /// ```
    /// use strainwave_core::fusion::TorsionShaftModel;
    /// let m = TorsionShaftModel::new(10.5e-6_f64, 100e-6, 258.0, 424e-6).unwrap();
    /// assert!((m.resonance_hz() - 829.3).abs() < 0.05);
    /// assert!((m.dc_gain() - 0.905).abs() < 5e-4);
    /// ```
    pub fn new(
        rotor_inertia_kg_m2: T,
        brake_inertia_kg_m2: T,
        stiffness_nm_per_rad: T,
        damping_nm_s_per_rad: T,
    ) -> Result<Self, Error> {
        positive(rotor_inertia_kg_m2, "rotor_inertia_kg_m2")?;
        positive(brake_inertia_kg_m2, "brake_inertia_kg_m2")?;
        positive(stiffness_nm_per_rad, "stiffness_nm_per_rad")?;
        non_negative(damping_nm_s_per_rad, "damping_nm_s_per_rad")?;
        Ok(Self { rotor_inertia_kg_m2, brake_inertia_kg_m2, stiffness_nm_per_rad, damping_nm_s_per_rad })
    }

    /// Table I with the torsion shaft (`k_RB,TS` = 258 N·m/rad).
    ///
    /// ```
    /// let m = strainwave_core::fusion::TorsionShaftModel::<f32>::kit();
    /// assert!((m.resonance_hz() - 829.3).abs() < 0.1);
    /// ```
    pub fn kit() -> Self {
        Self {
            rotor_inertia_kg_m2: T::from_f64(kit::ROTOR_INERTIA_KG_M2),
            brake_inertia_kg_m2: T::from_f64(kit::BRAKE_INERTIA_KG_M2),
            stiffness_nm_per_rad: T::from_f64(kit::STIFFNESS_TS_NM_PER_RAD),
            damping_nm_s_per_rad: T::from_f64(kit::BEARING_DAMPING_NM_S_PER_RAD),
        }
    }

    /// `(numerator, denominator)` of `G_TS(s)`, descending powers of `s`.
    pub fn coefficients(&self) -> ([T; 2], [T; 3]) {
        let (jr, jb, k, g) =
            (self.rotor_inertia_kg_m2, self.brake_inertia_kg_m2, self.stiffness_nm_per_rad, self.damping_nm_s_per_rad);
        ([T::TWO * jb * g, jb * k], [jb * jr, T::TWO * g * (jb + jr), k * (jb + jr)])
    }

    /// `G_TS(j 2π f)`, dimensionless.
    pub fn response(&self, freq_hz: T) -> Complex<T> {
        let (n, d) = self.coefficients();
        let s = jw(freq_hz);
        polyval(&n, s) / polyval(&d, s)
    }

    /// `f_res,TS = √(k (1/J_B + 1/J_R)) / 2π`, Hz.
    pub fn resonance_hz(&self) -> T {
        (self.stiffness_nm_per_rad * (T::ONE / self.brake_inertia_kg_m2 + T::ONE / self.rotor_inertia_kg_m2)).sqrt()
            / T::TAU
    }

    /// `G_TS(0) = J_B / (J_B + J_R)`.
    pub fn dc_gain(&self) -> T {
        self.brake_inertia_kg_m2 / (self.brake_inertia_kg_m2 + self.rotor_inertia_kg_m2)
    }
}

/// The accelerometer measurement, simplified (Stoß et al. 2022, eq. 6): the housing on its coupling.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AccelerometerModel<T: Real> {
    /// `J_S`, kg·m².
    pub stator_inertia_kg_m2: T,
    /// `k_S`, N·m/rad.
    pub coupling_stiffness_nm_per_rad: T,
    /// `Γ_LS`, N·m·s/rad.
    pub stator_damping_nm_s_per_rad: T,
}

impl<T: Real> AccelerometerModel<T> {
    /// Validates positive inertia and stiffness, damping ≥ 0.
    ///
    /// ```
    /// use strainwave_core::fusion::AccelerometerModel;
    /// let m = AccelerometerModel::new(1.305e-3_f64, 29.0, 4.24e-3).unwrap();
    /// assert!((m.resonance_hz() - 23.73).abs() < 0.005);
    /// // Far above the resonance J_S·G_ACC → 1.
    /// assert!((m.torque_response(4000.0).norm() - 1.0).abs() < 1e-3);
    /// ```
    pub fn new(
        stator_inertia_kg_m2: T,
        coupling_stiffness_nm_per_rad: T,
        stator_damping_nm_s_per_rad: T,
    ) -> Result<Self, Error> {
        positive(stator_inertia_kg_m2, "stator_inertia_kg_m2")?;
        positive(coupling_stiffness_nm_per_rad, "coupling_stiffness_nm_per_rad")?;
        non_negative(stator_damping_nm_s_per_rad, "stator_damping_nm_s_per_rad")?;
        Ok(Self { stator_inertia_kg_m2, coupling_stiffness_nm_per_rad, stator_damping_nm_s_per_rad })
    }

    /// Table I.
    ///
    /// ```
    /// let m = strainwave_core::fusion::AccelerometerModel::<f64>::kit();
    /// assert_eq!(m.coupling_stiffness_nm_per_rad, 29.0);
    /// ```
    pub fn kit() -> Self {
        Self {
            stator_inertia_kg_m2: T::from_f64(kit::STATOR_INERTIA_KG_M2),
            coupling_stiffness_nm_per_rad: T::from_f64(kit::COUPLING_STIFFNESS_NM_PER_RAD),
            stator_damping_nm_s_per_rad: T::from_f64(kit::STATOR_DAMPING_NM_S_PER_RAD),
        }
    }

    /// `(numerator, denominator)` of `G_ACC(s)`, descending powers.
    pub fn coefficients(&self) -> ([T; 3], [T; 3]) {
        (
            [T::ONE, T::ZERO, T::ZERO],
            [self.stator_inertia_kg_m2, self.stator_damping_nm_s_per_rad, self.coupling_stiffness_nm_per_rad],
        )
    }

    /// `G_ACC(j 2π f)`, rad/s² per N·m.
    pub fn response(&self, freq_hz: T) -> Complex<T> {
        let (n, d) = self.coefficients();
        let s = jw(freq_hz);
        polyval(&n, s) / polyval(&d, s)
    }

    /// `T_acc / T_e = J_S G_ACC`, dimensionless.
    pub fn torque_response(&self, freq_hz: T) -> Complex<T> {
        self.response(freq_hz).scale(self.stator_inertia_kg_m2)
    }

    /// `f_res,ACC = √(k_S / J_S) / 2π`, Hz.
    pub fn resonance_hz(&self) -> T {
        (self.coupling_stiffness_nm_per_rad / self.stator_inertia_kg_m2).sqrt() / T::TAU
    }
}

/// The accelerometer measurement with the rotor, brake and rotor bearings (Stoß et al. 2022, eq. 5).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AccelerometerModelFull<T: Real> {
    /// Housing part (`J_S`, `k_S`, `Γ_LS`).
    pub housing: AccelerometerModel<T>,
    /// Rotor and brake (`J_R`, `J_B`, `k` = `k_RB,Acc`, `Γ` = `Γ_LP`).
    pub drive: TorsionShaftModel<T>,
}

impl<T: Real> AccelerometerModelFull<T> {
    /// From the two parts.
    ///
    /// ```
    /// use strainwave_core::fusion::{AccelerometerModel, AccelerometerModelFull, TorsionShaftModel};
    /// let mut drive = TorsionShaftModel::<f64>::kit();
    /// drive.stiffness_nm_per_rad = 549.0; // k_RB,Acc
    /// let full = AccelerometerModelFull::new(AccelerometerModel::kit(), drive);
    /// assert!((full.rotor_brake_resonance_hz() - 1209.7).abs() < 0.05);
    /// ```
    pub fn new(housing: AccelerometerModel<T>, drive: TorsionShaftModel<T>) -> Self {
        Self { housing, drive }
    }

    /// Table I with `k_RB,Acc` = 549 N·m/rad.
    ///
    /// ```
    /// let m = strainwave_core::fusion::AccelerometerModelFull::<f64>::kit();
    /// assert_eq!(m.drive.stiffness_nm_per_rad, 549.0);
    /// ```
    pub fn kit() -> Self {
        let mut drive = TorsionShaftModel::kit();
        drive.stiffness_nm_per_rad = T::from_f64(kit::STIFFNESS_ACC_NM_PER_RAD);
        Self { housing: AccelerometerModel::kit(), drive }
    }

    /// `(numerator, denominator)` of eq. 5, descending powers (degree 4 over degree 4).
    pub fn coefficients(&self) -> ([T; 5], [T; 5]) {
        let d = &self.drive;
        let h = &self.housing;
        let (jr, jb, k, g) =
            (d.rotor_inertia_kg_m2, d.brake_inertia_kg_m2, d.stiffness_nm_per_rad, d.damping_nm_s_per_rad);
        let num = [jb * jr, jb * g, k * (jb + jr), k * g, T::ZERO];
        let (a, c) = (jb * jr, k * (jb + jr));
        let (dd, e, f) = (h.stator_inertia_kg_m2, g + h.stator_damping_nm_s_per_rad, h.coupling_stiffness_nm_per_rad);
        let den = [a * dd, a * e, a * f + c * dd, c * e, c * f];
        (num, den)
    }

    /// `G_ACC(j 2π f)` of eq. 5, rad/s² per N·m.
    pub fn response(&self, freq_hz: T) -> Complex<T> {
        let (n, d) = self.coefficients();
        let s = jw(freq_hz);
        polyval(&n, s) / polyval(&d, s)
    }

    /// `J_S G_ACC`, dimensionless.
    pub fn torque_response(&self, freq_hz: T) -> Complex<T> {
        self.response(freq_hz).scale(self.housing.stator_inertia_kg_m2)
    }

    /// DUT–brake resonance `√(k (1/J_B + 1/J_R)) / 2π`, Hz.
    pub fn rotor_brake_resonance_hz(&self) -> T {
        self.drive.resonance_hz()
    }
}

/// Two accelerometers at radius `R` on the housing, sensitive axes opposed so that their
/// sum is twice the tangential acceleration and a translational vibration cancels (eq. 9).
///
/// Sign: a positive reading means the housing accelerates against the positive rotor
/// direction, i.e. the reaction to a positive DUT torque, so `T_acc` has the sign of `T_e`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AccelerometerPair<T: Real> {
    /// `R`, m.
    pub radius_m: T,
    /// `J_S`, kg·m².
    pub stator_inertia_kg_m2: T,
}

impl<T: Real> AccelerometerPair<T> {
    /// Validates positive radius and inertia.
    ///
    /// ```
    /// use strainwave_core::fusion::AccelerometerPair;
    /// let p = AccelerometerPair::new(0.07_f64, 1.305e-3).unwrap();
    /// // A vibration of 3 m/s² cancels; 1 m/s² tangential remains.
    /// assert!((p.angular_accel_rad_s2(1.0 + 3.0, 1.0 - 3.0) - 1.0 / 0.07).abs() < 1e-12);
    /// ```
    pub fn new(radius_m: T, stator_inertia_kg_m2: T) -> Result<Self, Error> {
        positive(radius_m, "radius_m")?;
        positive(stator_inertia_kg_m2, "stator_inertia_kg_m2")?;
        Ok(Self { radius_m, stator_inertia_kg_m2 })
    }

    /// The KIT bench ([`kit::ACCEL_RADIUS_M`], Table I `J_S`).
    ///
    /// ```
    /// let p = strainwave_core::fusion::AccelerometerPair::<f32>::kit();
    /// assert!((p.torque_nm(1.0, 1.0) - 1.305e-3 / 0.6727).abs() < 1e-6);
    /// ```
    pub fn kit() -> Self {
        Self {
            radius_m: T::from_f64(kit::ACCEL_RADIUS_M),
            stator_inertia_kg_m2: T::from_f64(kit::STATOR_INERTIA_KG_M2),
        }
    }

    /// `α_m = (a_1 + a_2) / (2R)`, rad/s² (inputs m/s²).
    #[inline]
    pub fn angular_accel_rad_s2(&self, accel_1_m_s2: T, accel_2_m_s2: T) -> T {
        (accel_1_m_s2 + accel_2_m_s2) / (T::TWO * self.radius_m)
    }

    /// `T_acc = J_S α_m`, N·m.
    #[inline]
    pub fn torque_nm(&self, accel_1_m_s2: T, accel_2_m_s2: T) -> T {
        self.stator_inertia_kg_m2 * self.angular_accel_rad_s2(accel_1_m_s2, accel_2_m_s2)
    }

    /// Measurable ripple amplitude `T = a J_S / R` for one sensor's `a_min`, `a_max`
    /// (eqs. 10, 11), N·m.
    ///
    /// ```
    /// use strainwave_core::fusion::{kit, AccelerometerPair};
    /// let (lo, hi) = AccelerometerPair::<f64>::kit().torque_range_nm(kit::ACCEL_MIN_M_S2, kit::ACCEL_MAX_M_S2);
    /// assert!((lo - 21e-6).abs() < 0.5e-6 && (hi - 97e-3).abs() < 0.5e-3);
    /// ```
    pub fn torque_range_nm(&self, accel_min_m_s2: T, accel_max_m_s2: T) -> (T, T) {
        let k = self.stator_inertia_kg_m2 / self.radius_m;
        (accel_min_m_s2 * k, accel_max_m_s2 * k)
    }
}
