//! The Stoß et al. (2022) models and the PMSM torque against independent derivations and the
//! reference numbers of docs/physics.md §7, for f32 and f64.

use strainwave_core::fusion::{
    kit, AccelerometerModel, AccelerometerModelFull, AccelerometerPair, ComplementaryFusion, CrossoverOrder,
    FusionState, TorsionShaftModel,
};
use strainwave_core::iir::Complex;
use strainwave_core::pmsm::{FluxMap, LinearPmsm};
use strainwave_core::Real;

/// Reference numbers to the digits docs/physics.md §7 gives them, with the scalar's own rounding.
fn reference_numbers<T: Real>(tol: f64) {
    let ts = TorsionShaftModel::<T>::kit();
    assert!((ts.resonance_hz().to_f64() - 829.3).abs() < 0.05 + tol * 829.3);
    assert!((ts.response(T::ZERO).re.to_f64() - 0.905).abs() < 5e-4);
    let acc = AccelerometerModel::<T>::kit();
    assert!((acc.resonance_hz().to_f64() - 23.73).abs() < 0.005 + tol * 23.73);
    let m = LinearPmsm::<T>::nanotec_db59();
    assert!((m.torque_nm(T::ZERO, T::from_f64(2.0)).to_f64() - 0.1053).abs() < 1e-12 + tol);
    let pair = AccelerometerPair::<T>::kit();
    let (lo, hi) = pair.torque_range_nm(T::from_f64(kit::ACCEL_MIN_M_S2), T::from_f64(kit::ACCEL_MAX_M_S2));
    assert!((lo.to_f64() - 21e-6).abs() < 0.5e-6 && (hi.to_f64() - 97e-3).abs() < 0.5e-3);
}

#[test]
fn spec_reference_numbers_f32_f64() {
    reference_numbers::<f64>(1e-12);
    reference_numbers::<f32>(1e-6);
}

/// Eq. 1 from the two-mass equations solved at `s = jω`:
/// `J_R s² θ_R = T − T_sh`, `J_B s² θ_B = T_sh`, `T_sh = (k + 2Γ s)(θ_R − θ_B)`.
#[test]
fn torsion_model_is_the_two_mass_system() {
    let m = TorsionShaftModel::<f64>::kit();
    for f in [0.1, 10.0, 300.0, 829.3, 1000.0, 5000.0] {
        let s = Complex::new(0.0, std::f64::consts::TAU * f);
        let z = Complex::real(m.stiffness_nm_per_rad) + s.scale(2.0 * m.damping_nm_s_per_rad);
        // θ_B = z δ / (J_B s²); J_R s² (δ + θ_B) = T − z δ  ⇒  δ = T / (J_R s² + z (1 + J_R/J_B)).
        let s2 = s * s;
        let delta = Complex::real(1.0)
            / (s2.scale(m.rotor_inertia_kg_m2) + z.scale(1.0 + m.rotor_inertia_kg_m2 / m.brake_inertia_kg_m2));
        let want = z * delta;
        let got = m.response(f);
        assert!((got - want).norm() < 1e-12 * want.norm(), "{f} Hz");
    }
}

/// Eq. 6 from `J_S s² θ_S = −T − Γ_LS s θ_S − k_S θ_S`, `α_m = −s² θ_S`.
#[test]
fn accelerometer_model_is_the_housing_on_its_coupling() {
    let m = AccelerometerModel::<f64>::kit();
    for f in [1.0, 23.73, 250.0, 4000.0] {
        let s = Complex::new(0.0, std::f64::consts::TAU * f);
        let s2 = s * s;
        let theta = Complex::real(-1.0)
            / (s2.scale(m.stator_inertia_kg_m2)
                + s.scale(m.stator_damping_nm_s_per_rad)
                + Complex::real(m.coupling_stiffness_nm_per_rad));
        let want = -(s2 * theta);
        assert!((m.response(f) - want).norm() < 1e-12 * want.norm(), "{f} Hz");
    }
    // Flat above the resonance: ±1 % from 250 Hz up, the paper's measurable range.
    for f in [250.0, 1000.0, 4000.0] {
        assert!((m.torque_response(f).norm() - 1.0).abs() < 0.01, "{f} Hz");
    }
}

/// Eq. 5 as the paper writes it: its denominator holds the undamped DUT–brake resonance of
/// `k_RB,Acc` (1209.7 Hz, the "approx. 1.2 kHz" of the paper's Fig. 6); away from it the
/// full form stays within a few % of eq. 6 above 100 Hz.
#[test]
fn full_accelerometer_model_shows_the_rotor_brake_resonance() {
    let full = AccelerometerModelFull::<f64>::kit();
    let fr = full.rotor_brake_resonance_hz();
    assert!((fr - 1209.7).abs() < 0.05);
    assert!(full.torque_response(fr * (1.0 + 1e-6)).norm() > 50.0);
    for f in [100.0, 300.0, 600.0, 3000.0] {
        let r = full.torque_response(f).norm() / full.housing.torque_response(f).norm();
        assert!((r - 1.0).abs() < 0.05, "{f} Hz: {r}");
    }
}

/// A flux map of the Table II machine with a 6th-harmonic ripple gives eq. 12 with the
/// analytic torque ripple `3/2 p i_q (A_d + 6 A_q) cos 6γ` at `i_d = 0`.
#[test]
fn flux_map_torque_ripple() {
    let m = LinearPmsm::<f64>::nanotec_db59();
    let (ad, aq) = (20e-6, 12e-6);
    let map = FluxMap::<f64, 64, 2, 2>::from_fn(std::f64::consts::TAU / 6.0, [-8.0, 8.0], [-8.0, 8.0], |g, id, iq| {
        let (pd, pq) = m.flux_linkage_vs(id, iq);
        (pd + ad * (6.0 * g).cos(), pq + aq * (6.0 * g).sin())
    })
    .unwrap();
    for k in 0..50 {
        let g = 0.0377 * k as f64;
        let want = 0.1053 + 4.5 * 2.0 * (ad + 6.0 * aq) * (6.0 * g).cos();
        let got = map.torque_nm(3.0, g, 0.0, 2.0);
        assert!((got - want).abs() < 2e-6, "{g}: {got} vs {want}");
    }
    assert!((map.fundamental_torque_nm(3.0, 0.0, 2.0) - 0.1053).abs() < 1e-12);
}

/// A torque step seen by the shaft only (accelerometers see no constant torque) settles to
/// the step; a ripple seen by both passes unchanged at once.
#[test]
fn fusion_step_and_ripple() {
    for order in [CrossoverOrder::First, CrossoverOrder::Second] {
        let f = ComplementaryFusion::<f64>::new(250.0, 20_000.0, order).unwrap();
        let mut st = FusionState::default();
        let mut y = 0.0;
        for _ in 0..2000 {
            y = f.step(&mut st, 0.1, 0.0);
        }
        assert!((y - 0.1).abs() < 1e-6, "{order:?}: {y}");
        for k in 0..500 {
            let r = 0.003 * (k as f64 * 0.31).sin();
            let out = f.step(&mut st, 0.1 + r, r);
            assert!((out - (0.1 + r)).abs() < 1e-9);
        }
    }
}
