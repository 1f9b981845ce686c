//! The arm's equations: state, gear compliance with play hysteresis, kinematic error, derivatives.

use super::*;

/// Mechanical state.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ArmState {
    /// Motor angle `θ_m`, rad.
    pub motor_angle_rad: f64,
    /// Motor speed, rad/s.
    pub motor_speed_rad_s: f64,
    /// Link angle `θ`, rad.
    pub link_angle_rad: f64,
    /// Link speed, rad/s.
    pub link_speed_rad_s: f64,
    /// Play-operator outputs `p_i` of the hysteresis, rad.
    pub plays: [f64; PLAYS],
}

/// Number of play operators of the twin's hysteresis.
pub const PLAYS: usize = 4;
/// Play half-widths as multiples of `h`.
const PLAY_WIDTHS: [f64; PLAYS] = [0.25, 0.6, 1.2, 2.5];
/// Play weights (sum 1).
const PLAY_WEIGHTS: [f64; PLAYS] = [0.3, 0.3, 0.25, 0.15];

impl ArmState {
    fn axpy(&self, k: f64, d: &ArmState) -> ArmState {
        ArmState {
            motor_angle_rad: self.motor_angle_rad + k * d.motor_angle_rad,
            motor_speed_rad_s: self.motor_speed_rad_s + k * d.motor_speed_rad_s,
            link_angle_rad: self.link_angle_rad + k * d.link_angle_rad,
            link_speed_rad_s: self.link_speed_rad_s + k * d.link_speed_rad_s,
            plays: self.plays,
        }
    }
}

/// The arm's physics (no controller, no sensors).
#[derive(Debug, Clone)]
pub struct ArmModel {
    springs: HdaArmCompliance<f64>,
    half_width_rad: f64,
    solver: TorqueSolver<f64>,
    kinematic: ArmKinematicError,
    n_s: f64,
    damping: f64,
    jm: f64,
    rm: f64,
    jl: f64,
    bl: f64,
}

impl ArmModel {
    /// Builds the model from a scenario (parameters checked by the core).
    pub fn new(s: &ArmScenario) -> Result<Self, SimError> {
        let g = &s.gear;
        let springs = HdaArmCompliance::new(
            FlexsplineStiffening::new(g.flexspline_k0_nm_per_rad, g.flexspline_c_per_nm)?,
            WaveGeneratorSoftening::new(g.wave_generator_k0_nm_per_rad, g.wave_generator_c_per_nm)?,
            g.ratio,
        )?;

        // Truth is solved far tighter than any estimator, with a wide bracket.
        let solver = TorqueSolver::new(20.0 * g.rated_torque_nm, 1e-12 * g.rated_torque_nm, 120)?;
        Ok(Self {
            springs,
            half_width_rad: 0.5 * g.hysteresis_loss_rad,
            solver,
            kinematic: s.kinematic_error.clone(),
            n_s: -g.ratio,
            damping: g.damping_nm_s_per_rad,
            jm: s.motor.inertia_kg_m2,
            rm: s.motor.viscous_nm_s_per_rad(),
            jl: s.link.inertia_kg_m2,
            bl: s.link.viscous_nm_s_per_rad,
        })
    }

    /// The paper's springs.
    pub fn springs(&self) -> &HdaArmCompliance<f64> {
        &self.springs
    }

    /// Half loop width `h`, rad (0 = no hysteresis).
    pub fn hysteresis_half_width_rad(&self) -> f64 {
        self.half_width_rad
    }

    /// Hysteresis state `z = Σ α_i (w − p_i)/r_i ∈ [−1, 1]` at a state.
    pub fn hysteresis_state(&self, x: &ArmState) -> f64 {
        if self.half_width_rad <= 0.0 {
            return 0.0;
        }
        let w = self.windup_rad(x);
        (0..PLAYS).map(|i| PLAY_WEIGHTS[i] * (w - x.plays[i]) / (PLAY_WIDTHS[i] * self.half_width_rad)).sum()
    }

    /// The plays after moving the wind-up to `w` from `plays0` (exact for a monotone path).
    fn advance_plays(&self, plays0: &[f64; PLAYS], w: f64) -> [f64; PLAYS] {
        let mut p = *plays0;
        if self.half_width_rad > 0.0 {
            for (pi, r) in p.iter_mut().zip(PLAY_WIDTHS) {
                let r = r * self.half_width_rad;
                // Not `clamp`, which panics on a NaN bound: a state gone NaN is reported
                // by the caller.
                *pi = pi.max(w - r).min(w + r);
            }
        }
        p
    }

    /// Signed ratio `n_s = −N`.
    pub fn signed_ratio(&self) -> f64 {
        self.n_s
    }

    /// Kinematic error at a state, rad.
    pub fn kinematic_error_rad(&self, x: &ArmState) -> f64 {
        self.kinematic.eval(x.link_angle_rad, x.motor_angle_rad - x.link_angle_rad)
    }

    /// Wind-up `w = θ_m/n_s + θ_k − θ`, rad.
    pub fn windup_rad(&self, x: &ArmState) -> f64 {
        x.motor_angle_rad / self.n_s + self.kinematic_error_rad(x) - x.link_angle_rad
    }

    /// Torsion `θ_h = θ − θ_m/n_s`, rad.
    pub fn torsion_rad(&self, x: &ArmState) -> f64 {
        x.link_angle_rad - x.motor_angle_rad / self.n_s
    }

    /// Spring torque for an elastic twist, N·m (clamped at the bracket if beyond it).
    fn spring_torque_nm(&self, elastic_rad: f64, guess_nm: f64) -> f64 {
        match self.solver.solve(&self.springs, elastic_rad, guess_nm) {
            Ok(s) => s.torque_nm,
            Err(_) => self.solver.torque_limit_nm() * elastic_rad.signum(),
        }
    }

    /// Link torque `τ = τ_s(w + h z) + c ẇ`, N·m.
    pub fn link_torque_nm(&self, x: &ArmState, guess_nm: f64) -> f64 {
        let w = self.windup_rad(x);
        let elastic = w + self.half_width_rad * self.hysteresis_state(x);
        let rate = x.motor_speed_rad_s / self.n_s - x.link_speed_rad_s;
        self.spring_torque_nm(elastic, guess_nm) + self.damping * rate
    }

    fn derivative(&self, x: &ArmState, motor_torque_nm: f64, ext_nm: f64, guess: &mut f64) -> ArmState {
        let tau = self.link_torque_nm(x, *guess);
        *guess = tau;
        ArmState {
            motor_angle_rad: x.motor_speed_rad_s,
            motor_speed_rad_s: (motor_torque_nm - self.rm * x.motor_speed_rad_s - tau / self.n_s) / self.jm,
            link_angle_rad: x.link_speed_rad_s,
            link_speed_rad_s: (tau - self.bl * x.link_speed_rad_s + ext_nm) / self.jl,
            plays: [0.0; PLAYS],
        }
    }

    /// One RK4 step with the motor torque held and `τ_d` sampled at mid-step; the
    /// plays are advanced exactly from the step's start in every stage.
    pub fn rk4_step(&self, x: &mut ArmState, h_s: f64, motor_torque_nm: f64, ext_nm: f64, guess: &mut f64) {
        let plays0 = x.plays;
        let stage = |y: ArmState| ArmState { plays: self.advance_plays(&plays0, self.windup_rad(&y)), ..y };
        let k1 = self.derivative(x, motor_torque_nm, ext_nm, guess);
        let k2 = self.derivative(&stage(x.axpy(0.5 * h_s, &k1)), motor_torque_nm, ext_nm, guess);
        let k3 = self.derivative(&stage(x.axpy(0.5 * h_s, &k2)), motor_torque_nm, ext_nm, guess);
        let k4 = self.derivative(&stage(x.axpy(h_s, &k3)), motor_torque_nm, ext_nm, guess);
        let w = h_s / 6.0;
        let next = x.axpy(w, &k1).axpy(2.0 * w, &k2).axpy(2.0 * w, &k3).axpy(w, &k4);
        *x = stage(next);
    }

    /// Highest natural frequency (stiffest tangent at 3 × rated torque, raised by the
    /// plays' slopes `1 + Σ α_i h / r_i` while they stick), or the damping rate if larger, rad/s.
    pub fn max_rate_rad_s(&self, rated_torque_nm: f64) -> f64 {
        let k = 1.0 / self.springs.compliance_rad_per_nm(3.0 * rated_torque_nm);
        let stick: f64 = if self.half_width_rad > 0.0 {
            PLAY_WEIGHTS.iter().zip(PLAY_WIDTHS).map(|(a, r)| a / r).sum()
        } else {
            0.0
        };
        let k = (1.0 + stick) * k;
        let inv_j = 1.0 / self.jl + 1.0 / (self.jm * self.n_s * self.n_s);
        (k * inv_j).sqrt().max(self.damping * inv_j)
    }
}
