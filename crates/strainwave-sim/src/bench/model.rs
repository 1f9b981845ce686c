//! Dynamics of the bench: three inertias, integrated by fixed-step RK4 with sub-steps.
//!
//! Angles `θ_R` (DUT rotor), `θ_B` (brake), `θ_S` (housing), positive in the rotor's
//! positive direction; `δ = θ_R − θ_B` the shaft twist; `θ_e = θ_R − θ_S` the rotor angle
//! in the housing (what the DUT's encoder reads), `γ = p θ_e` the electrical angle.
//!
//! ```text
//! air gap     T_e  = eq. 12 (ψ_d,q(γ, i_d, i_q)) + Σ c_N sin(N θ_e + φ_N)        (cogging)
//! shaft       T_sh = k δ + c δ̇
//! bearing     T_rb = Γ_rb (ω_R − ω_S)
//! brake       T_br = T_b(t) ω_B / √(ω_B² + ε²)             (hysteresis: no speed dependence)
//! rotor       J_R ω̇_R = T_e − T_sh − T_rb
//! brake       J_B ω̇_B = T_sh − T_br − Γ_bb ω_B
//! housing     J_S ω̇_S = −T_e + T_rb − Γ_LS ω_S − k_S θ_S
//! ```
//!
//! Flux linkages: `ψ_d = L_d i_d + Ψ_PM + Σ A_d cos(kγ + φ)`, `ψ_q = L_q i_q + Σ A_q sin(kγ + φ)`.
//! The torsion sensor reads `T_sh` (spring and damper, as eq. 1 of Stoß et al. 2022 does); the
//! accelerometers read `−R ω̇_S` (sign: see [`strainwave_core::fusion::AccelerometerPair`]).

use strainwave_core::pmsm::{torque_eq12, FluxMap, FluxSample};

use super::{BenchProfile, BenchScenario};
use crate::error::SimError;

/// Angle samples per electrical period of the "identified" flux map.
pub const MAP_ANGLE_POINTS: usize = 360;
/// The flux map type of the online eq.-12 torque (currents −20, 0, 20 A on both axes).
pub type BenchFluxMap = FluxMap<f64, MAP_ANGLE_POINTS, 3, 3>;

/// Mechanical state.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct BenchState {
    /// `θ_R`, rad.
    pub rotor_angle_rad: f64,
    /// `ω_R`, rad/s.
    pub rotor_speed_rad_s: f64,
    /// `θ_B`, rad.
    pub brake_angle_rad: f64,
    /// `ω_B`, rad/s.
    pub brake_speed_rad_s: f64,
    /// `θ_S`, rad.
    pub stator_angle_rad: f64,
    /// `ω_S`, rad/s.
    pub stator_speed_rad_s: f64,
}

impl BenchState {
    fn axpy(&self, k: f64, d: &BenchState) -> BenchState {
        BenchState {
            rotor_angle_rad: self.rotor_angle_rad + k * d.rotor_angle_rad,
            rotor_speed_rad_s: self.rotor_speed_rad_s + k * d.rotor_speed_rad_s,
            brake_angle_rad: self.brake_angle_rad + k * d.brake_angle_rad,
            brake_speed_rad_s: self.brake_speed_rad_s + k * d.brake_speed_rad_s,
            stator_angle_rad: self.stator_angle_rad + k * d.stator_angle_rad,
            stator_speed_rad_s: self.stator_speed_rad_s + k * d.stator_speed_rad_s,
        }
    }

    /// Rotor angle in the housing `θ_R − θ_S`, rad.
    pub fn rotor_in_housing_rad(&self) -> f64 {
        self.rotor_angle_rad - self.stator_angle_rad
    }
}

/// Rotor-frame currents, A.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Currents {
    /// `i_d`, A.
    pub d_a: f64,
    /// `i_q`, A.
    pub q_a: f64,
}

/// Raised-cosine ramp from 0 at `t = 0` to 1 at `t = len_s` (1 for `len_s = 0`).
pub fn engage(t_s: f64, len_s: f64) -> f64 {
    if t_s >= len_s {
        1.0
    } else if t_s <= 0.0 {
        0.0
    } else {
        0.5 - 0.5 * (std::f64::consts::PI * t_s / len_s).cos()
    }
}

/// Parameters of the dynamics in SI units.
#[derive(Debug, Clone)]
pub struct BenchModel {
    jr: f64,
    jb: f64,
    js: f64,
    k: f64,
    c: f64,
    g_rb: f64,
    g_bb: f64,
    k_s: f64,
    g_ls: f64,
    pole_pairs: f64,
    psi_pm: f64,
    ld: f64,
    lq: f64,
    /// `(k, A_d, A_q, φ)`.
    flux_harmonics: Vec<(f64, f64, f64, f64)>,
    /// `(N, c, φ)`.
    cogging: Vec<(f64, f64, f64)>,
    brake_nm: f64,
    engage_s: f64,
    eps_brake: f64,
}

impl BenchModel {
    /// From a validated scenario.
    ///
    /// ```
    /// use strainwave_sim::bench::{model::BenchModel, preset};
    /// let m = BenchModel::new(&preset("kit-bench").unwrap()).unwrap();
    /// assert!((m.torque_constant_nm_per_a() - 0.05265).abs() < 1e-12);
    /// ```
    pub fn new(s: &BenchScenario) -> Result<Self, SimError> {
        s.validate()?;
        let m = &s.mechanics;
        let d = &s.dut;
        Ok(Self {
            jr: m.rotor_inertia_kg_m2,
            jb: m.brake_inertia_kg_m2,
            js: m.stator_inertia_kg_m2,
            k: m.shaft_stiffness_nm_per_rad,
            c: m.shaft_damping_nm_s_per_rad,
            g_rb: m.rotor_bearing_damping_nm_s_per_rad,
            g_bb: m.brake_bearing_damping_nm_s_per_rad,
            k_s: m.coupling_stiffness_nm_per_rad,
            g_ls: m.stator_damping_nm_s_per_rad,
            pole_pairs: d.pole_pairs as f64,
            psi_pm: d.pm_flux_linkage_vs,
            ld: d.d_inductance_h,
            lq: d.q_inductance_h,
            flux_harmonics: d
                .flux_harmonics
                .iter()
                .map(|h| (h.order_el as f64, h.d_amplitude_vs, h.q_amplitude_vs, h.phase_rad))
                .collect(),
            cogging: d.cogging.iter().map(|c| (c.order_mech as f64, c.amplitude_nm, c.phase_rad)).collect(),
            brake_nm: s.brake.torque_nm,
            engage_s: s.brake.engage_s,
            eps_brake: s.brake.speed_threshold_rad_s,
        })
    }

    /// Pole pairs `p`.
    pub fn pole_pairs(&self) -> f64 {
        self.pole_pairs
    }

    /// Eq.-13 torque constant `3/2 p Ψ_PM`, N·m/A.
    pub fn torque_constant_nm_per_a(&self) -> f64 {
        1.5 * self.pole_pairs * self.psi_pm
    }

    /// Rotor + brake inertia, kg·m².
    pub fn drive_inertia_kg_m2(&self) -> f64 {
        self.jr + self.jb
    }

    /// Housing inertia `J_S`, kg·m².
    pub fn stator_inertia_kg_m2(&self) -> f64 {
        self.js
    }

    /// Flux linkages and their angle derivatives at `(γ, i_d, i_q)` (exact).
    pub fn flux(&self, gamma_rad: f64, c: Currents) -> FluxSample<f64> {
        let mut s = FluxSample {
            psi_d_vs: self.ld * c.d_a + self.psi_pm,
            psi_q_vs: self.lq * c.q_a,
            dpsi_d_dgamma_vs: 0.0,
            dpsi_q_dgamma_vs: 0.0,
        };
        for &(k, ad, aq, ph) in &self.flux_harmonics {
            let (sn, cs) = (k * gamma_rad + ph).sin_cos();
            s.psi_d_vs += ad * cs;
            s.psi_q_vs += aq * sn;
            s.dpsi_d_dgamma_vs -= k * ad * sn;
            s.dpsi_q_dgamma_vs += k * aq * cs;
        }
        s
    }

    /// The flux map an identification would give (the model's flux on a grid): the bench's
    /// online eq.-12 torque uses it.
    pub fn flux_map(&self) -> Result<Box<BenchFluxMap>, SimError> {
        let grid = [-20.0, 0.0, 20.0];
        let map = BenchFluxMap::from_fn(std::f64::consts::TAU, grid, grid, |g, d, q| {
            let s = self.flux(g, Currents { d_a: d, q_a: q });
            (s.psi_d_vs, s.psi_q_vs)
        })?;
        Ok(Box::new(map))
    }

    /// Eq.-12 torque at rotor angle in the housing `θ_e`, N·m.
    pub fn inner_torque_nm(&self, rotor_in_housing_rad: f64, c: Currents) -> f64 {
        let f = self.flux(self.pole_pairs * rotor_in_housing_rad, c);
        torque_eq12(self.pole_pairs, &f, c.d_a, c.q_a)
    }

    /// Cogging torque, N·m.
    pub fn cogging_torque_nm(&self, rotor_in_housing_rad: f64) -> f64 {
        self.cogging.iter().map(|&(n, a, ph)| a * (n * rotor_in_housing_rad + ph).sin()).sum()
    }

    /// Air-gap torque `T_e` (eq. 12 + cogging), N·m.
    pub fn dut_torque_nm(&self, x: &BenchState, c: Currents) -> f64 {
        let th = x.rotor_in_housing_rad();
        self.inner_torque_nm(th, c) + self.cogging_torque_nm(th)
    }

    /// Shaft torque `k δ + c δ̇`, N·m.
    pub fn shaft_torque_nm(&self, x: &BenchState) -> f64 {
        self.k * (x.rotor_angle_rad - x.brake_angle_rad) + self.c * (x.rotor_speed_rad_s - x.brake_speed_rad_s)
    }

    /// Brake torque at time `t_s` and brake speed, N·m.
    pub fn brake_torque_nm(&self, t_s: f64, brake_speed_rad_s: f64) -> f64 {
        let w = brake_speed_rad_s;
        self.brake_nm * engage(t_s, self.engage_s) * w / (w * w + self.eps_brake * self.eps_brake).sqrt()
    }

    /// State derivative at time `t_s` with currents `c`.
    pub fn derivative(&self, x: &BenchState, t_s: f64, c: Currents) -> BenchState {
        let te = self.dut_torque_nm(x, c);
        let tsh = self.shaft_torque_nm(x);
        let trb = self.g_rb * (x.rotor_speed_rad_s - x.stator_speed_rad_s);
        let tbr = self.brake_torque_nm(t_s, x.brake_speed_rad_s);
        BenchState {
            rotor_angle_rad: x.rotor_speed_rad_s,
            rotor_speed_rad_s: (te - tsh - trb) / self.jr,
            brake_angle_rad: x.brake_speed_rad_s,
            brake_speed_rad_s: (tsh - tbr - self.g_bb * x.brake_speed_rad_s) / self.jb,
            stator_angle_rad: x.stator_speed_rad_s,
            stator_speed_rad_s: (-te + trb - self.g_ls * x.stator_speed_rad_s - self.k_s * x.stator_angle_rad)
                / self.js,
        }
    }

    /// One RK4 step of `h_s` from `t_s`; `currents(t)` is evaluated at the stage times.
    pub fn rk4_step(&self, x: &mut BenchState, t_s: f64, h_s: f64, currents: &dyn Fn(f64) -> Currents) {
        let (c0, c1, c2) = (currents(t_s), currents(t_s + 0.5 * h_s), currents(t_s + h_s));
        let k1 = self.derivative(x, t_s, c0);
        let k2 = self.derivative(&x.axpy(0.5 * h_s, &k1), t_s + 0.5 * h_s, c1);
        let k3 = self.derivative(&x.axpy(0.5 * h_s, &k2), t_s + 0.5 * h_s, c1);
        let k4 = self.derivative(&x.axpy(h_s, &k3), t_s + h_s, c2);
        let w = h_s / 6.0;
        *x = x.axpy(w, &k1).axpy(2.0 * w, &k2).axpy(2.0 * w, &k3).axpy(w, &k4);
    }

    /// The fastest rate the integration must resolve, rad/s: the shaft mode, the housing
    /// mode, the damping and brake rates, and the fastest forcing of the profile.
    pub fn max_rate_rad_s(&self, s: &BenchScenario) -> f64 {
        let shaft = (self.k * (1.0 / self.jr + 1.0 / self.jb)).sqrt();
        let housing = (self.k_s / self.js).sqrt();
        let damping = (self.c + self.g_rb) / self.jr + self.g_ls / self.js + self.g_bb / self.jb;
        let brake = self.brake_nm / (self.eps_brake * self.jb);
        let forcing = match &s.profile {
            BenchProfile::SpeedRamp { to_rpm, .. } => {
                let flux = self.flux_harmonics.iter().map(|h| h.0 * self.pole_pairs).fold(self.pole_pairs, f64::max);
                let cog = self.cogging.iter().map(|c| c.0).fold(0.0, f64::max);
                flux.max(cog) * to_rpm * std::f64::consts::TAU / 60.0
            }
            BenchProfile::CurrentSweep { to_hz, .. } => std::f64::consts::TAU * to_hz,
        };
        shaft.max(housing).max(damping).max(brake).max(forcing)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn flux_map_reproduces_the_exact_torque() {
        let s = super::super::preset("kit-bench").unwrap();
        let m = BenchModel::new(&s).unwrap();
        let map = m.flux_map().unwrap();
        let c = Currents { d_a: -4.0, q_a: 2.0 };
        let mut worst: f64 = 0.0;
        for k in 0..200 {
            let th = 0.0123 * k as f64;
            let exact = m.inner_torque_nm(th, c);
            let online = map.torque_nm(m.pole_pairs(), m.pole_pairs() * th, c.d_a, c.q_a);
            worst = worst.max((exact - online).abs());
        }
        // The map's spline error, far below the harmonics (mN·m).
        assert!(worst < 2e-5, "{worst}");
        // Eq. 13 of the mean flux: Table II at i_q = 2 A.
        assert!((map.fundamental_torque_nm(3.0, 0.0, 2.0) - 0.1053).abs() < 1e-9);
    }
}
