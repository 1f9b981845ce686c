//! The torque solver on every compliance model: the catalogue example, convergence within
//! the cap over ±3× rated torque (property test, f32 and f64), and bad inputs.

use proptest::prelude::*;
use strainwave_core::compliance::{
    CatalogueCompliance, Compliance, CubicStiffness, FlexsplineStiffening, HdaArmCompliance, ThreeSlopeStiffness,
    WaveGeneratorSoftening,
};
use strainwave_core::torsion::TorqueSolver;
use strainwave_core::{Error, Real};

/// Rated torque of the example gear, N·m.
const RATED_NM: f64 = 40.0;
/// Relative torque tolerance of a converged solve, f64 / f32.
const REL_TOL_F64: f64 = 1e-7;
const REL_TOL_F32: f64 = 2e-3;

fn hda_arm_model<T: Real>() -> HdaArmCompliance<T> {
    HdaArmCompliance::new(
        FlexsplineStiffening::new(T::from_f64(2.0e4), T::from_f64(0.015)).unwrap(),
        WaveGeneratorSoftening::new(T::from_f64(2.5), T::from_f64(1.5)).unwrap(),
        T::from_f64(100.0),
    )
    .unwrap()
}

fn three_slope<T: Real>() -> ThreeSlopeStiffness<T> {
    ThreeSlopeStiffness::new(
        T::from_f64(1.3e4),
        T::from_f64(1.6e4),
        T::from_f64(2.5e4),
        T::from_f64(7.0),
        T::from_f64(25.0),
    )
    .unwrap()
}

fn catalogue<T: Real>() -> CatalogueCompliance<T> {
    CatalogueCompliance::new(three_slope(), T::from_f64(2.9e-4), T::from_f64(1.0)).unwrap()
}

fn cubic<T: Real>() -> CubicStiffness<T> {
    CubicStiffness::new(T::from_f64(1.1e4), T::from_f64(2.0e8)).unwrap()
}

fn softening_cubic<T: Real>() -> CubicStiffness<T> {
    // Peak torque (2/3) k1 θ* with θ* = √(k1/(3|k3|)) = 0.0191 rad → 140 N·m > 3× rated.
    CubicStiffness::new(T::from_f64(1.1e4), T::from_f64(-1.0e7)).unwrap()
}

/// Solves θ(τ) back to τ; returns (relative error, iterations).
fn round_trip<T: Real, C: Compliance<T>>(model: &C, tau: f64, guess: f64) -> (f64, u32) {
    let solver = TorqueSolver::for_rated_torque(T::from_f64(RATED_NM)).unwrap();
    let w = model.twist_rad(T::from_f64(tau));
    let s = solver.solve(model, w, T::from_f64(guess)).unwrap_or_else(|e| panic!("τ = {tau}: {e}"));
    assert!(s.iterations <= solver.max_iterations());
    ((s.torque_nm.to_f64() - tau).abs() / (1.0 + tau.abs()), s.iterations)
}

#[test]
fn catalogue_example_inverts_to_60_nm() {
    // T = 60 N·m with T1 = 29, K1 = 6.7e4, T2 = 108, K2 = 1.1e5, K3 = 1.2e5 → 7.15e-4 rad.
    let k = ThreeSlopeStiffness::new(6.7e4, 1.1e5, 1.2e5, 29.0, 108.0).unwrap();
    let solver = TorqueSolver::new(400.0_f64, 1e-9, 60).unwrap();
    let s = solver.solve(&k, 7.15e-4, 0.0).unwrap();
    // 7.15e-4 is the catalogue's rounding of 7.1467e-4: 60 N·m to within 0.04 N·m.
    assert!((s.torque_nm - 60.0).abs() < 0.04, "{s:?}");
    let exact = solver.solve(&k, k.twist_rad(60.0), 0.0).unwrap();
    assert!((exact.torque_nm - 60.0).abs() < 1e-6, "{exact:?}");
    assert!(exact.iterations <= 6, "{exact:?}");
    println!("catalogue 7.15e-4 rad → {:.4} N·m in {} iterations", s.torque_nm, s.iterations);
}

#[test]
fn warm_start_converges_in_few_iterations() {
    let m = hda_arm_model::<f64>();
    let mut worst = 0;
    for i in 0..1000 {
        let tau = 100.0 * (i as f64 * 0.01).sin();
        let prev = 100.0 * ((i as f64 - 1.0) * 0.01).sin();
        let (err, it) = round_trip::<f64, _>(&m, tau, prev);
        assert!(err < REL_TOL_F64);
        worst = worst.max(it);
    }
    assert!(worst <= 5, "worst {worst}");
}

#[test]
fn out_of_range_and_nan_are_errors() {
    let solver = TorqueSolver::for_rated_torque(RATED_NM).unwrap();
    let m = hda_arm_model::<f64>();
    // Twist beyond the hardening springs' asymptote, and beyond θ(±4 × rated).
    assert_eq!(solver.solve(&m, 0.02, 0.0), Err(Error::OutOfRange("windup_rad")));
    assert_eq!(solver.solve(&m, -0.0075, 0.0), Err(Error::OutOfRange("windup_rad")));
    assert_eq!(solver.solve(&m, f64::NAN, 0.0), Err(Error::NonFinite("windup_rad")));
    assert_eq!(solver.solve(&m, f64::INFINITY, 0.0), Err(Error::NonFinite("windup_rad")));
    // A NaN warm start is ignored.
    assert!(solver.solve(&m, 1e-3, f64::NAN).is_ok());
    let k = three_slope::<f64>();
    assert_eq!(solver.solve(&k, 1.0, 0.0), Err(Error::OutOfRange("windup_rad")));
    let soft = softening_cubic::<f64>();
    assert_eq!(solver.solve(&soft, 0.03, 0.0), Err(Error::OutOfRange("windup_rad")));
    assert!(TorqueSolver::new(0.0_f64, 1e-9, 10).is_err());
    assert!(TorqueSolver::new(1.0_f64, 1e-9, 0).is_err());
}

#[test]
fn iteration_cap_gives_no_convergence() {
    let solver = TorqueSolver::new(1.0e3_f64, 1e-15, 2).unwrap();
    let m = hda_arm_model::<f64>();
    assert_eq!(solver.solve(&m, 5e-3, -1.0e3), Err(Error::NoConvergence("torque_nm")));
}

fn check_all<T: Real>(tau: f64, guess: f64, tol: f64) -> Result<(), TestCaseError> {
    let (e, _) = round_trip::<T, _>(&hda_arm_model::<T>(), tau, guess);
    prop_assert!(e < tol, "seed {e}");
    let (e, _) = round_trip::<T, _>(&three_slope::<T>(), tau, guess);
    prop_assert!(e < tol, "three-slope {e}");
    let (e, _) = round_trip::<T, _>(&catalogue::<T>(), tau, guess);
    prop_assert!(e < tol, "catalogue {e}");
    let (e, _) = round_trip::<T, _>(&cubic::<T>(), tau, guess);
    prop_assert!(e < tol, "cubic {e}");
    let (e, _) = round_trip::<T, _>(&softening_cubic::<T>(), tau, guess);
    prop_assert!(e < tol, "softening cubic {e}");
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]

    #[test]
    fn converges_within_cap_over_three_times_rated_f64(tau in -3.0 * RATED_NM..3.0 * RATED_NM, guess in -4.0 * RATED_NM..4.0 * RATED_NM) {
        check_all::<f64>(tau, guess, REL_TOL_F64)?;
    }

    #[test]
    fn converges_within_cap_over_three_times_rated_f32(tau in -3.0 * RATED_NM..3.0 * RATED_NM, guess in -4.0 * RATED_NM..4.0 * RATED_NM) {
        check_all::<f32>(tau, guess, REL_TOL_F32)?;
    }

    #[test]
    fn never_panics_on_any_windup(w in proptest::num::f64::ANY, guess in proptest::num::f64::ANY) {
        let solver = TorqueSolver::for_rated_torque(RATED_NM).unwrap();
        let _ = solver.solve(&hda_arm_model::<f64>(), w, guess);
        let _ = solver.solve(&cubic::<f64>(), w, guess);
        let _ = solver.solve(&catalogue::<f64>(), w, guess);
    }
}
