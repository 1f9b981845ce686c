//! Rigid-body dynamics of a strain wave gear joint: motor, gear spring with catalogue
//! stiffness and hysteresis, friction, load, integrated by fixed-step RK4 with sub-steps.
//!
//! Coordinates: motor angle `θ_m`, output angle `θ_L`. With the signed ratio
//! `n_s` (−N with the circular spline fixed, N+1 with the flexspline fixed):
//!
//! ```text
//! twist            δ = θ_m / n_s − θ_L
//! transmitted      τ = K(δ + h z) + c δ̇                (K: three-slope curve, h: half loop width)
//! hysteresis       dz/dδ = (1 − z sgn δ̇) / ℓ,  ℓ = h     (Dahl-type, |z| ≤ 1)
//! gear friction    τ_g = b_g ω_k + c_g sgn(ω_k),  ω_k = ω_m / n_s
//! WG torque        T_wg = (τ + τ_g) / n_s
//! motor            J_m ω̇_m = K_t i − b_m ω_m − c_m sgn ω_m − T_wg
//! load             J_L ω̇_L = τ − b_L ω_L − c_L sgn ω_L + τ_ext
//! ```
//!
//! Along a monotone twist increment the hysteresis has the exact solution
//! `z = s + (z0 − s) e^(−|δ − δ0|/ℓ)`, `s = sgn(δ − δ0)`; every RK4 stage evaluates it from
//! the step's start, so the loop is integrated to the order of RK4 and never goes
//! unstable. While `z` flips, the tangent stiffness reaches `K (1 + 2h/ℓ) = 3K`; the
//! sub-step count accounts for it. `sgn` is regularized as `ω/√(ω² + ε²)` with `ε` large enough for the sub-step to stay
//! stable. The meshing ripple and the misalignment signature are sensor-side effects
//! here (see [`crate::sensors`]); they do not drive the dynamics, so `τ` is the clean
//! low-frequency transmitted torque a controller needs.

use strainwave_core::compliance::ThreeSlopeStiffness;
use strainwave_core::gear::Gear;

use crate::error::SimError;
use crate::scenario::Scenario;

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
    inv_n_s: f64,
    inv_jm: f64,
    inv_jl: f64,
    inv_hyst_len: f64,
    hyst_half_rad: f64,
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

/// Regularized sign `w / √(w² + ε²)`: odd, monotone, slope `1/ε` at zero (like
/// `tanh(w/ε)`, at a tenth of the cost), within 0.5 % of ±1 beyond `|w| = 10 ε`.
#[inline]
fn smooth_sign(w: f64, eps: f64) -> f64 {
    w / (w * w + eps * eps).sqrt()
}

impl JointModel {
    /// Builds the model from a validated scenario; `substep_s` sets the friction regularization.
    pub fn new(s: &Scenario, substep_s: f64) -> Result<Self, SimError> {
        let gear = Gear::new(s.gear.ratio, s.gear.fixed)?;
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
            inv_n_s: 1.0 / n_s,
            inv_jm: 1.0 / jm,
            inv_jl: 1.0 / jl,
            inv_hyst_len: 1.0 / hyst_half_rad.max(1e-12),
            hyst_half_rad,
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

    /// Highest natural frequency of the two-mass system at the stiffest slope
    /// (tripled while the hysteresis state flips), rad/s.
    pub fn max_natural_frequency_rad_s(s: &Scenario) -> f64 {
        let hyst_factor = if s.gear.hysteresis_rad > 0.0 { 3.0 } else { 1.0 };
        let k = hyst_factor * s.gear.k1_nm_per_rad.max(s.gear.k2_nm_per_rad).max(s.gear.k3_nm_per_rad);
        let jm_reflected = s.motor.inertia_kg_m2 * s.gear.ratio * s.gear.ratio;
        let w_spring = (k * (1.0 / s.load.inertia_kg_m2 + 1.0 / jm_reflected)).sqrt();
        // Damping sets a real eigenvalue c/J_eff; take the larger rate.
        let j_eff = 1.0 / (1.0 / s.load.inertia_kg_m2 + 1.0 / jm_reflected);
        w_spring.max(s.gear.damping_nm_s_per_rad / j_eff)
    }

    /// The scenario key that sets [`JointModel::max_natural_frequency_rad_s`], and its value:
    /// the damping when its rate is the larger, else the stiffest spring slope.
    pub fn stiffest_mode_key(s: &Scenario) -> (&'static str, f64) {
        let jm_reflected = s.motor.inertia_kg_m2 * s.gear.ratio * s.gear.ratio;
        let inv_j = 1.0 / s.load.inertia_kg_m2 + 1.0 / jm_reflected;
        let g = &s.gear;
        let slopes = [
            ("gear.k1_nm_per_rad", g.k1_nm_per_rad),
            ("gear.k2_nm_per_rad", g.k2_nm_per_rad),
            ("gear.k3_nm_per_rad", g.k3_nm_per_rad),
        ];
        let (key, k) = slopes.into_iter().fold(slopes[0], |a, b| if b.1 > a.1 { b } else { a });
        let hyst_factor = if g.hysteresis_rad > 0.0 { 3.0 } else { 1.0 };
        if g.damping_nm_s_per_rad * inv_j > (hyst_factor * k * inv_j).sqrt() {
            ("gear.damping_nm_s_per_rad", g.damping_nm_s_per_rad)
        } else {
            (key, k)
        }
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
        x.motor_angle_rad * self.inv_n_s - x.output_angle_rad
    }

    fn twist_rate(&self, x: &JointState) -> f64 {
        x.motor_speed_rad_s * self.inv_n_s - x.output_speed_rad_s
    }

    /// Transmitted torque on the load `τ = K(δ + h z) + c δ̇` (loading curve above unloading: the loop dissipates), N·m (output frame).
    pub fn transmitted_torque_nm(&self, x: &JointState) -> f64 {
        self.stiffness.torque_nm(self.twist_rad(x) + self.hyst_half_rad * x.hysteresis)
            + self.damping * self.twist_rate(x)
    }

    /// Gear friction at the output for a motor speed, N·m (output frame).
    pub fn gear_friction_nm(&self, motor_speed_rad_s: f64) -> f64 {
        let wk = motor_speed_rad_s * self.inv_n_s;
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

    /// Hysteresis state after a monotone twist increment `d_twist_rad` from `z0`.
    #[inline]
    pub fn hysteresis_after(&self, z0: f64, d_twist_rad: f64) -> f64 {
        if self.hyst_half_rad <= 0.0 || d_twist_rad == 0.0 {
            return z0;
        }
        let s = d_twist_rad.signum();
        s + (z0 - s) * (-d_twist_rad.abs() * self.inv_hyst_len).exp()
    }

    /// State derivative; `x.hysteresis` must already hold `z` for this stage.
    fn derivative(&self, x: &JointState, current_a: f64, ext_nm: f64) -> JointState {
        let tau = self.transmitted_torque_nm(x);
        let t_wg = (tau + self.gear_friction_nm(x.motor_speed_rad_s)) * self.inv_n_s;
        let dm = (self.kt * current_a - self.motor_friction_nm(x.motor_speed_rad_s) - t_wg) * self.inv_jm;
        let dl = (tau - self.load_friction_nm(x.output_speed_rad_s) + ext_nm) * self.inv_jl;
        // z is advanced exactly after the step (see `rk4_step`), not by RK4.
        let dz = 0.0;
        JointState {
            motor_angle_rad: x.motor_speed_rad_s,
            motor_speed_rad_s: dm,
            output_angle_rad: x.output_speed_rad_s,
            output_speed_rad_s: dl,
            hysteresis: dz,
        }
    }

    /// One RK4 step of `h_s` with the current and the external torque held over the
    /// step (`ext` sampled at the step's midpoint, so a step in the external torque on a
    /// step boundary acts the same whatever the step size).
    pub fn rk4_step(&self, x: &mut JointState, t_s: f64, h_s: f64, current_a: f64, ext: &dyn Fn(f64) -> f64) {
        let e = ext(t_s + 0.5 * h_s);
        let (z0, d0) = (x.hysteresis, self.twist_rad(x));
        let stage = |y: JointState| JointState { hysteresis: self.hysteresis_after(z0, self.twist_rad(&y) - d0), ..y };
        let k1 = self.derivative(x, current_a, e);
        let k2 = self.derivative(&stage(x.axpy(0.5 * h_s, &k1)), current_a, e);
        let k3 = self.derivative(&stage(x.axpy(0.5 * h_s, &k2)), current_a, e);
        let k4 = self.derivative(&stage(x.axpy(h_s, &k3)), current_a, e);
        let mut next = *x;
        let w = h_s / 6.0;
        next = next.axpy(w, &k1).axpy(2.0 * w, &k2).axpy(2.0 * w, &k3).axpy(w, &k4);
        next.hysteresis = self.hysteresis_after(z0, self.twist_rad(&next) - d0);
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
        let amp = 1.5e-3; // rad of twist, ≫ the Dahl length so z saturates
        let steps = 20_000; // per half cycle
        let (mut t_up, mut t_down) = (f64::NAN, f64::NAN);
        let mut prev_twist = 0.0;
        for k in 1..(4 * steps) {
            let phase = k as f64 / steps as f64 * std::f64::consts::PI;
            let twist = amp * phase.sin();
            x.hysteresis = m.hysteresis_after(x.hysteresis, twist - prev_twist);
            x.motor_angle_rad = twist * n_s;
            let tau = m.stiffness.torque_nm(m.twist_rad(&x) + m.hyst_half_rad * x.hysteresis);
            // Zero crossings: falling in the first cycle, rising in the second.
            if prev_twist > 0.0 && twist <= 0.0 && k < 2 * steps {
                t_down = tau;
            }
            if prev_twist < 0.0 && twist >= 0.0 && k > 2 * steps {
                t_up = tau;
            }
            prev_twist = twist;
        }
        assert!(t_up > t_down, "loading {t_up} must exceed unloading {t_down}");
        let width_rad = (t_up - t_down) / s.gear.k1_nm_per_rad;
        assert!((width_rad - s.gear.hysteresis_rad).abs() < 0.02 * s.gear.hysteresis_rad, "{width_rad}");
    }
}
