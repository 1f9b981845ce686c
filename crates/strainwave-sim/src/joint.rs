//! Rigid-body dynamics of a strain wave gear joint: motor, gear spring with catalogue
//! stiffness and hysteresis, friction, load, integrated by fixed-step RK4 with sub-steps.
//!
//! Coordinates: motor angle `θ_m`, output angle `θ_L`. With the signed ratio
//! `n_s` (−N with the circular spline fixed, N+1 with the flexspline fixed):
//!
//! ```text
//! twist            δ = θ_m / n_s − θ_L
//! transmitted      τ = K(δ + h z) + c δ̇                (K: three-slope curve, h: half loop width)
//! hysteresis       ż = (δ̇ / ℓ) (1 − z sgn δ̇),  ℓ = h/2   (Dahl-type, |z| ≤ 1)
//! gear friction    τ_g = b_g ω_k + c_g sgn(ω_k),  ω_k = ω_m / n_s
//! WG torque        T_wg = (τ + τ_g) / n_s
//! motor            J_m ω̇_m = K_t i − b_m ω_m − c_m sgn ω_m − T_wg
//! load             J_L ω̇_L = τ − b_L ω_L − c_L sgn ω_L + τ_ext
//! ```
//!
//! `sgn` is regularized as `tanh(ω/ε)` with `ε` large enough for the sub-step to stay
//! stable. The meshing ripple and the misalignment signature are sensor-side effects
//! here (see [`crate::sensors`]); they do not drive the dynamics, so `τ` is the clean
//! low-frequency transmitted torque a controller needs.

use strainwave_core::compliance::ThreeSlopeStiffness;
use strainwave_core::gear::{FixedElement, Gear};

use crate::error::SimError;
use crate::scenario::{FixedElementName, Scenario};

/// Mechanical state.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct JointState {
    /// Motor (WG) angle, rad.
    pub motor_angle_rad: f64,
    /// Motor speed, rad/s.
    pub motor_speed_rad_s: f64,
    /// Output angle, rad.
    pub output_angle_rad: f64,
    /// Output speed, rad/s.
    pub output_speed_rad_s: f64,
    /// Hysteresis state `z ∈ [−1, 1]`.
    pub hysteresis: f64,
}

impl JointState {
    fn axpy(&self, k: f64, d: &JointState) -> JointState {
        JointState {
            motor_angle_rad: self.motor_angle_rad + k * d.motor_angle_rad,
            motor_speed_rad_s: self.motor_speed_rad_s + k * d.motor_speed_rad_s,
            output_angle_rad: self.output_angle_rad + k * d.output_angle_rad,
            output_speed_rad_s: self.output_speed_rad_s + k * d.output_speed_rad_s,
            hysteresis: self.hysteresis + k * d.hysteresis,
        }
    }
}

/// Parameters of the joint dynamics in SI units.
#[derive(Debug, Clone)]
pub struct JointModel {
    /// The gear.
    pub gear: Gear<f64>,
    stiffness: ThreeSlopeStiffness<f64>,
    n_s: f64,
    hyst_half_rad: f64,
    hyst_len_rad: f64,
    damping: f64,
    gear_visc: f64,
    gear_coul: f64,
    jm: f64,
    kt: f64,
    bm: f64,
    cm: f64,
    jl: f64,
    bl: f64,
    cl: f64,
    eps_m: f64,
    eps_g: f64,
    eps_l: f64,
}

/// Regularized sign.
fn smooth_sign(w: f64, eps: f64) -> f64 {
    (w / eps).tanh()
}

impl JointModel {
    /// Builds the model from a validated scenario; `substep_s` sets the friction regularization.
    pub fn new(s: &Scenario, substep_s: f64) -> Result<Self, SimError> {
        let fixed = match s.gear.fixed {
            FixedElementName::CircularSpline => FixedElement::CircularSpline,
            FixedElementName::Flexspline => FixedElement::Flexspline,
        };
        let gear = Gear::new(s.gear.ratio, fixed)?;
        let stiffness = ThreeSlopeStiffness::new(
            s.gear.k1_nm_per_rad,
            s.gear.k2_nm_per_rad,
            s.gear.k3_nm_per_rad,
            s.gear.t1_nm,
            s.gear.t2_nm,
        )?;
        let n_s = gear.signed_ratio();
        let (jm, jl) = (s.motor.inertia_kg_m2, s.load.inertia_kg_m2);
        // ε ≥ 4 c h / J keeps the friction's local rate c/(ε J) below 1/(4h): stable in RK4.
        let floor: f64 = 1e-3;
        let eps_m = floor.max(4.0 * s.motor.coulomb_nm * substep_s / jm);
        let eps_g = floor.max(4.0 * s.gear.friction_coulomb_nm * substep_s / (jm * n_s * n_s));
        let eps_l = floor.max(4.0 * s.load.coulomb_nm * substep_s / jl);
        let hyst_half_rad = 0.5 * s.gear.hysteresis_rad;
        Ok(Self {
            gear,
            stiffness,
            n_s,
            hyst_half_rad,
            hyst_len_rad: (0.5 * hyst_half_rad).max(1e-12),
            damping: s.gear.damping_nm_s_per_rad,
            gear_visc: s.gear.friction_viscous_nm_s_per_rad,
            gear_coul: s.gear.friction_coulomb_nm,
            jm,
            kt: s.motor.torque_constant_nm_per_a,
            bm: s.motor.viscous_nm_s_per_rad,
            cm: s.motor.coulomb_nm,
            jl,
            bl: s.load.viscous_nm_s_per_rad,
            cl: s.load.coulomb_nm,
            eps_m,
            eps_g,
            eps_l,
        })
    }

    /// Highest natural frequency of the two-mass system at the stiffest slope, rad/s.
    pub fn max_natural_frequency_rad_s(s: &Scenario) -> f64 {
        let k = s
            .gear
            .k1_nm_per_rad
            .max(s.gear.k2_nm_per_rad)
            .max(s.gear.k3_nm_per_rad);
        let jm_reflected = s.motor.inertia_kg_m2 * s.gear.ratio * s.gear.ratio;
        let w_spring = (k * (1.0 / s.load.inertia_kg_m2 + 1.0 / jm_reflected)).sqrt();
        // Damping sets a real eigenvalue c/J_eff; take the larger rate.
        let j_eff = 1.0 / (1.0 / s.load.inertia_kg_m2 + 1.0 / jm_reflected);
        w_spring.max(s.gear.damping_nm_s_per_rad / j_eff)
    }

    /// Signed ratio `n_s`.
    pub fn signed_ratio(&self) -> f64 {
        self.n_s
    }

    /// Motor torque constant, N·m/A.
    pub fn torque_constant(&self) -> f64 {
        self.kt
    }

    /// Reflected inertia at the motor, kg·m².
    pub fn total_inertia_at_motor(&self) -> f64 {
        self.jm + self.jl / (self.n_s * self.n_s)
    }

    /// Twist `δ = θ_m / n_s − θ_L`, rad.
    pub fn twist_rad(&self, x: &JointState) -> f64 {
        x.motor_angle_rad / self.n_s - x.output_angle_rad
    }

    fn twist_rate(&self, x: &JointState) -> f64 {
        x.motor_speed_rad_s / self.n_s - x.output_speed_rad_s
    }

    /// Transmitted torque on the load `τ = K(δ + h z) + c δ̇` (loading curve above unloading: the loop dissipates), N·m (output frame).
    pub fn transmitted_torque_nm(&self, x: &JointState) -> f64 {
        self.stiffness
            .torque_nm(self.twist_rad(x) + self.hyst_half_rad * x.hysteresis)
            + self.damping * self.twist_rate(x)
    }

    /// Gear friction at the output for a motor speed, N·m (output frame).
    pub fn gear_friction_nm(&self, motor_speed_rad_s: f64) -> f64 {
        let wk = motor_speed_rad_s / self.n_s;
        self.gear_visc * wk + self.gear_coul * smooth_sign(wk, self.eps_g)
    }

    /// Motor friction, N·m.
    pub fn motor_friction_nm(&self, motor_speed_rad_s: f64) -> f64 {
        self.bm * motor_speed_rad_s + self.cm * smooth_sign(motor_speed_rad_s, self.eps_m)
    }

    /// Load friction, N·m.
    pub fn load_friction_nm(&self, output_speed_rad_s: f64) -> f64 {
        self.bl * output_speed_rad_s + self.cl * smooth_sign(output_speed_rad_s, self.eps_l)
    }

    /// Wave-generator torque `T_wg = (τ + τ_g) / n_s`, N·m.
    pub fn wg_torque_nm(&self, x: &JointState) -> f64 {
        (self.transmitted_torque_nm(x) + self.gear_friction_nm(x.motor_speed_rad_s)) / self.n_s
    }

    fn derivative(&self, x: &JointState, current_a: f64, ext_nm: f64) -> JointState {
        let tau = self.transmitted_torque_nm(x);
        let t_wg = (tau + self.gear_friction_nm(x.motor_speed_rad_s)) / self.n_s;
        let dm =
            (self.kt * current_a - self.motor_friction_nm(x.motor_speed_rad_s) - t_wg) / self.jm;
        let dl = (tau - self.load_friction_nm(x.output_speed_rad_s) + ext_nm) / self.jl;
        let dz = if self.hyst_half_rad > 0.0 {
            let r = self.twist_rate(x);
            r / self.hyst_len_rad * (1.0 - x.hysteresis * smooth_sign(r, 1e-6))
        } else {
            0.0
        };
        JointState {
            motor_angle_rad: x.motor_speed_rad_s,
            motor_speed_rad_s: dm,
            output_angle_rad: x.output_speed_rad_s,
            output_speed_rad_s: dl,
            hysteresis: dz,
        }
    }

    /// One RK4 step of `h_s` with current held and the external torque sampled by `ext(t)`.
    pub fn rk4_step(
        &self,
        x: &mut JointState,
        t_s: f64,
        h_s: f64,
        current_a: f64,
        ext: &dyn Fn(f64) -> f64,
    ) {
        let e0 = ext(t_s);
        let em = ext(t_s + 0.5 * h_s);
        let e1 = ext(t_s + h_s);
        let k1 = self.derivative(x, current_a, e0);
        let k2 = self.derivative(&x.axpy(0.5 * h_s, &k1), current_a, em);
        let k3 = self.derivative(&x.axpy(0.5 * h_s, &k2), current_a, em);
        let k4 = self.derivative(&x.axpy(h_s, &k3), current_a, e1);
        let mut next = *x;
        let w = h_s / 6.0;
        next = next
            .axpy(w, &k1)
            .axpy(2.0 * w, &k2)
            .axpy(2.0 * w, &k3)
            .axpy(w, &k4);
        next.hysteresis = next.hysteresis.clamp(-1.0, 1.0);
        *x = next;
    }
}

/// PI speed loop on the motor with acceleration feed-forward and anti-windup.
#[derive(Debug, Clone)]
pub struct SpeedController {
    kp: f64,
    ki: f64,
    inertia: f64,
    kt: f64,
    limit_a: f64,
    integral_nm: f64,
}

impl SpeedController {
    /// Tuned for a crossover `bandwidth_hz` on the reflected inertia.
    pub fn new(model: &JointModel, bandwidth_hz: f64, current_limit_a: f64) -> Self {
        let j = model.total_inertia_at_motor();
        let wc = std::f64::consts::TAU * bandwidth_hz;
        Self {
            kp: j * wc,
            ki: j * wc * wc / 4.0,
            inertia: j,
            kt: model.torque_constant(),
            limit_a: current_limit_a,
            integral_nm: 0.0,
        }
    }

    /// Current command for one sample period `dt_s`, A.
    pub fn current_a(&mut self, ref_speed: f64, ref_accel: f64, speed: f64, dt_s: f64) -> f64 {
        let e = ref_speed - speed;
        let torque = self.kp * e + self.integral_nm + self.inertia * ref_accel;
        let i = torque / self.kt;
        let clipped = i.clamp(-self.limit_a, self.limit_a);
        if clipped == i || (e > 0.0) != (i > 0.0) {
            self.integral_nm += self.ki * e * dt_s;
        }
        clipped
    }

    /// Forgets the integral (after an open-loop current segment).
    pub fn reset(&mut self) {
        self.integral_nm = 0.0;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Quasi-static twist cycles: at zero twist the loading branch lies above the
    /// unloading branch (the loop dissipates) and the loop width is the catalogue value.
    #[test]
    fn hysteresis_loop_dissipates_with_catalogue_width() {
        let s = crate::presets::preset("taghirad").unwrap();
        let m = JointModel::new(&s, 1e-4).unwrap();
        let n_s = m.signed_ratio();
        let mut x = JointState::default();
        let amp = 8e-4; // rad of twist, ≫ the Dahl length so z saturates
        let steps = 20_000; // per half cycle
        let dt = 1e-3;
        let (mut t_up, mut t_down) = (f64::NAN, f64::NAN);
        let mut prev_twist = 0.0;
        for k in 1..(4 * steps) {
            let phase = k as f64 / steps as f64 * std::f64::consts::PI;
            let twist = amp * phase.sin();
            let rate = (twist - prev_twist) / dt;
            let zdot = rate / m.hyst_len_rad * (1.0 - x.hysteresis * smooth_sign(rate, 1e-6));
            x.hysteresis = (x.hysteresis + zdot * dt).clamp(-1.0, 1.0);
            x.motor_angle_rad = twist * n_s;
            let tau = m
                .stiffness
                .torque_nm(m.twist_rad(&x) + m.hyst_half_rad * x.hysteresis);
            // Zero crossings: falling in the first cycle, rising in the second.
            if prev_twist > 0.0 && twist <= 0.0 && k < 2 * steps {
                t_down = tau;
            }
            if prev_twist < 0.0 && twist >= 0.0 && k > 2 * steps {
                t_up = tau;
            }
            prev_twist = twist;
        }
        assert!(
            t_up > t_down,
            "loading {t_up} must exceed unloading {t_down}"
        );
        let width_rad = (t_up - t_down) / s.gear.k1_nm_per_rad;
        assert!(
            (width_rad - s.gear.hysteresis_rad).abs() < 0.02 * s.gear.hysteresis_rad,
            "{width_rad}"
        );
    }
}
