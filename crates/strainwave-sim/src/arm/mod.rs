//! The harmonic-drive arm model of the HDA-arm paper (docs/physics.md §5): motor, wave-generator and flexspline compliance, link, external torque.
//!
//! ```text
//! motor      J_m θ̈_m + r_m θ̇_m = τ_m − τ / n_s,        r_m = k_m I_0 / ω_0,  ω_0 = 2π n_0 / 60
//! link       J θ̈ = τ − b_L θ̇ + τ_d
//! wind-up    w = θ_m / n_s + θ_k(θ, φ) − θ            (the rigid output plus the kinematic error, minus the link)
//! springs    w + h z = θ_f(τ_s) + θ_w(τ_s / N) / N    (paper App. B, solved for τ_s by the core's Newton solver)
//! hysteresis z = Σ_i α_i (w − p_i) / r_i,  p_i = clamp(p_i, w − r_i, w + r_i)   (Maxwell-slip / Prandtl–Ishlinskii)
//! torque     τ = τ_s + c ẇ,  ẇ ≈ θ̇_m / n_s − θ̇         (structural damping; θ̇_k neglected in the damping)
//! ```
//!
//! Hysteresis: `h` is half the catalogue loss (loop width `2h` once every slip element
//! slides). The twin uses four play operators (Jenkin spring–slider elements) with
//! half-widths `r_i = h · (0.25, 0.6, 1.2, 2.5)` and weights `α_i = (0.3, 0.3, 0.25, 0.15)`,
//! the friction model of strain wave gear hysteresis in the literature. Unlike a Dahl
//! law, small vibrations inside the plays leave the branch alone (a Dahl state relaxes
//! towards 0 under any dither), and the estimator's Dahl model is only an approximation
//! of it: the comparison is not an inverse crime. Each play is advanced exactly from the
//! step's start in every RK4 stage.
//!
//! The circular spline is fixed (`n_s = −N`): the link turns opposite to the motor. `τ` is
//! the link torque, the torque the gear transmits to the link, positive when it drives the
//! link forward (`true_link_torque`); in static equilibrium it is `−τ_d`. The torsion
//! `θ_h = θ − θ_m/n_s = θ_k − w` is docs/physics.md §5's. The kinematic error is periodic (output
//! and relative-angle harmonics) plus an optional polynomial in the output angle.
//!
//! The motor is either held by a digital PID on its angle (the paper's first experiment),
//! driven along a position ramp (a no-load run for identification), or given an
//! open-loop torque: constant (the paper's second experiment), a step or a sinusoid
//! (the paper's Fig. 4 simulations). A hand applies the external torque `τ_d`: smooth
//! steps and sinusoids. [`ArmExperiment`] builds each of the paper's runs from the preset.
//!
//! Encoders count `floor(θ/step + noise)`; with `single_turn` the counters wrap every
//! revolution, with the zero offsets added. The reference torque stands in for the paper's
//! six-axis sensor at the flange: `τ` plus white noise.

use serde::{Deserialize, Serialize};
use strainwave_core::compliance::{Compliance, FlexsplineStiffening, HdaArmCompliance, WaveGeneratorSoftening};
use strainwave_core::torsion::TorqueSolver;

use crate::check::{finite as fin, non_negative as nonneg, positive as pos};
use crate::error::SimError;
use crate::rng::Rng;

const TAU: f64 = std::f64::consts::TAU;

/// The preset's TOML text.
pub const PRESET_TOML: &str = include_str!("../../presets/hda-arm.toml");

/// Largest `|ω h|` of the stiffest mode per RK4 sub-step (as in the joint twin).
pub const MAX_OMEGA_H: f64 = 0.6;

mod commands;
mod model;
mod scenario;
mod simulator;

pub use commands::*;
pub use model::*;
pub use scenario::*;
pub use simulator::*;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn preset_parses_and_round_trips() {
        let s = ArmScenario::preset().unwrap();
        assert_eq!(ArmScenario::from_toml(&s.to_toml()).unwrap(), s);
        for e in ArmExperiment::ALL {
            ArmScenario::experiment(e).unwrap();
        }
    }

    #[test]
    fn bad_values_name_their_key() {
        let bad = PRESET_TOML.replace("ratio = 100.0", "ratio = -1.0");
        match ArmScenario::from_toml(&bad) {
            Err(SimError::Invalid { key, .. }) => assert_eq!(key, "gear.ratio"),
            other => panic!("{other:?}"),
        }
        let unknown = PRESET_TOML.replace("[link]", "[link]\nmass_kg = 3.0");
        assert!(matches!(ArmScenario::from_toml(&unknown), Err(SimError::Parse { .. })));
    }

    #[test]
    fn hand_step_is_smooth_and_released() {
        let h = HandTorque::Step { at_s: 1.0, torque_nm: 10.0, rise_s: 0.1, release_s: Some(2.0) };
        assert_eq!(h.at(0.5), 0.0);
        assert!((h.at(1.05) - 5.0).abs() < 1e-9);
        assert_eq!(h.at(1.5), 10.0);
        assert!(h.at(3.0).abs() < 1e-12);
    }
}
