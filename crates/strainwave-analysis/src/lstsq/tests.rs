use super::*;

const TIGHT: f64 = 1e-13;

#[test]
fn hand_computed_three_by_two() {
    // A = [[1,1],[1,2],[1,3]], b = [1,2,2]. By hand: x = (2/3, 1/2),
    // residuals (−1/6, 1/3, −1/6), ‖r‖² = 1/6, σ² = 1/6,
    // (AᵀA)⁻¹ = [[14/6, −1], [−1, 1/2]].
    let a = [1.0, 1.0, 1.0, 2.0, 1.0, 3.0];
    let s = lstsq(&a, 2, &[1.0, 2.0, 2.0]).unwrap();
    assert!((s.x[0] - 2.0 / 3.0).abs() < TIGHT);
    assert!((s.x[1] - 0.5).abs() < TIGHT);
    for (r, want) in s.residuals.iter().zip([-1.0 / 6.0, 1.0 / 3.0, -1.0 / 6.0]) {
        assert!((r - want).abs() < TIGHT);
    }
    assert!((s.residual_norm - (1.0f64 / 6.0).sqrt()).abs() < TIGHT);
    let c = s.covariance().unwrap();
    let s2 = 1.0 / 6.0;
    for (got, want) in c.iter().zip([14.0 / 6.0 * s2, -s2, -s2, 0.5 * s2]) {
        assert!((got - want).abs() < TIGHT, "{got} vs {want}");
    }
}

#[test]
fn pivoting_and_scaling_recover_badly_scaled_columns() {
    // Columns differ by 1e8 in scale; the solution is exact.
    let (x0, x1) = (3.0e-6, -2.0e3);
    let rows: Vec<(f64, f64)> = (0..6).map(|i| (1e6 * (i as f64 + 1.0), 1e-2 * (i as f64).powi(2))).collect();
    let a: Vec<f64> = rows.iter().flat_map(|&(p, q)| [p, q]).collect();
    let b: Vec<f64> = rows.iter().map(|&(p, q)| x0 * p + x1 * q).collect();
    let s = lstsq(&a, 2, &b).unwrap();
    assert!(((s.x[0] - x0) / x0).abs() < 1e-12 && ((s.x[1] - x1) / x1).abs() < 1e-12);
    assert!(s.rcond_estimate() > 0.0);
}

#[test]
fn singular_problems_are_named() {
    // Third column = first + second.
    let a = [1.0, 2.0, 3.0, 4.0, 5.0, 9.0, 7.0, 1.0, 8.0, 2.0, 2.0, 4.0];
    match lstsq(&a, 3, &[1.0, 2.0, 3.0, 4.0]) {
        Err(LstsqError::RankDeficient { rank: 2, unknowns: 3, .. }) => {}
        other => panic!("{other:?}"),
    }
    // A zero column.
    let z = [1.0, 0.0, 2.0, 0.0, 3.0, 0.0];
    assert!(matches!(lstsq(&z, 2, &[1.0, 2.0, 3.0]), Err(LstsqError::RankDeficient { column: 1, rank: 1, .. })));
    // Everything at one load.
    assert!(matches!(fit_line(&[2.0; 5], &[1.0, 2.0, 3.0, 4.0, 5.0]), Err(LstsqError::RankDeficient { .. })));
    assert!(matches!(fit_through_origin(&[0.0; 3], &[1.0; 3]), Err(LstsqError::RankDeficient { .. })));
    let msg = lstsq(&a, 3, &[1.0, 2.0, 3.0, 4.0]).unwrap_err().to_string();
    assert!(msg.contains("singular"), "{msg}");
}

#[test]
fn shape_and_finiteness_errors() {
    assert_eq!(lstsq(&[1.0, 2.0], 2, &[1.0]), Err(LstsqError::TooFewRows { rows: 1, unknowns: 2 }));
    assert_eq!(lstsq(&[1.0, 2.0, 3.0], 2, &[1.0, 2.0]), Err(LstsqError::Shape { what: "a", len: 3, expected: 4 }));
    assert_eq!(
        lstsq(&[1.0, 0.0, 1.0, f64::NAN, 1.0, 2.0], 2, &[0.0; 3]),
        Err(LstsqError::NonFinite { what: "a", row: 1, col: 1 })
    );
    assert_eq!(
        lstsq(&[1.0, 2.0, 3.0], 1, &[0.0, f64::INFINITY, 0.0]),
        Err(LstsqError::NonFinite { what: "b", row: 1, col: 0 })
    );
    assert_eq!(polyfit(&[0.0, 1.0], &[0.0, 1.0], 2), Err(LstsqError::TooFewRows { rows: 2, unknowns: 3 }));
    assert_eq!(
        polyfit(&[0.0, 1.0, 2.0], &[0.0, f64::NAN, 1.0], 1),
        Err(LstsqError::NonFinite { what: "y", row: 1, col: 0 })
    );
    assert!(matches!(lstsq_rtol(&[1.0], 1, &[1.0], f64::NAN), Err(LstsqError::BadTolerance(_))));
    assert!(matches!(lstsq(&[], 0, &[]), Err(LstsqError::Shape { .. })));
    let e: AnalysisError = LstsqError::TooFewRows { rows: 1, unknowns: 2 }.into();
    assert_eq!(e, AnalysisError::TooShort { what: "least-squares rows", needed: 2, got: 1 });
}

#[test]
fn square_system_has_no_covariance() {
    let s = lstsq(&[2.0, 0.0, 0.0, 4.0], 2, &[2.0, 2.0]).unwrap();
    assert!((s.x[0] - 1.0).abs() < TIGHT && (s.x[1] - 0.5).abs() < TIGHT);
    assert!(s.sigma2().is_none() && s.covariance().is_none());
}

#[test]
fn polyfit_with_large_offset_and_covariance() {
    // x around 1000: the raw Vandermonde would be badly conditioned.
    let x: Vec<f64> = (0..9).map(|i| 1000.0 + i as f64).collect();
    let noise = [0.01, -0.02, 0.0, 0.015, -0.01, 0.0, 0.02, -0.015, 0.01];
    let y: Vec<f64> = x.iter().zip(noise).map(|(t, e)| 3.0 + 0.25 * (t - 1000.0) + e).collect();
    let p = polyfit(&x, &y, 1).unwrap();
    // Compare with the line fitted in the shifted variable (exact same problem).
    let xs: Vec<f64> = x.iter().map(|t| t - 1000.0).collect();
    let q = polyfit(&xs, &y, 1).unwrap();
    assert!((p.coeffs[1] - q.coeffs[1]).abs() < 1e-12);
    assert!((p.coeffs[0] - (q.coeffs[0] - 1000.0 * q.coeffs[1])).abs() < 1e-9);
    assert!((p.eval(1004.0) - q.eval(4.0)).abs() < 1e-12);
    // Slope variance is shift-invariant; intercept variance is not.
    let (cp, cq) = (p.covariance.unwrap(), q.covariance.unwrap());
    assert!(((cp[3] - cq[3]) / cq[3]).abs() < 1e-9);
    // Var(c0 at x=1000 from p) = Var(c0) + 2000 Cov + 1e6 Var(c1) should equal cq[0].
    let var_at = cp[0] + 2.0 * 1000.0 * cp[1] + 1e6 * cp[3];
    assert!(((var_at - cq[0]) / cq[0]).abs() < 1e-6);
}

#[test]
fn expansion_matrix_matches_binomials() {
    // u = (x − 1)/2: u² = (x² − 2x + 1)/4.
    let t = expansion_matrix(1.0, 2.0, 3);
    assert_eq!([t[2], t[5], t[8]], [0.25, -0.5, 0.25]);
    assert_eq!([t[0], t[1], t[4]], [1.0, -0.5, 0.5]);
}
