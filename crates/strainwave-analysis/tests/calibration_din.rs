//! DIN 51309 / EURAMET cg-14 figures on a hand-made set of series whose figures are
//! worked out by hand in the comments.

use strainwave_analysis::calibration::{din51309_figures, CalibrationError, DinOptions, LoadSeries};

const TOL: f64 = 1e-12;

/// The usual scheme: two increasing series at 0°, one increasing + decreasing series at
/// 120° and at 240°, each ending with a zero reading. Indication in mV/V-like units.
fn series() -> Vec<LoadSeries> {
    vec![
        // X1: deflections 1.000, 2.000; zero returns to 0.002.
        LoadSeries::new(0.0, &[(0.0, 0.000), (10.0, 1.000), (20.0, 2.000), (0.0, 0.002)]),
        // X2: zero 0.010 → deflections 1.002, 2.004; zero returns to 0.010.
        LoadSeries::new(0.0, &[(0.0, 0.010), (10.0, 1.012), (20.0, 2.014), (0.0, 0.010)]),
        // X3 / X4': 1.010, 2.020, unloading 1.030; zero 0.004.
        LoadSeries::new(120.0, &[(0.0, 0.000), (10.0, 1.010), (20.0, 2.020), (10.0, 1.030), (0.0, 0.004)]),
        // X5 / X6': 0.990, 1.990, unloading 1.000; zero 0.
        LoadSeries::new(240.0, &[(0.0, 0.000), (10.0, 0.990), (20.0, 1.990), (10.0, 1.000), (0.0, 0.000)]),
    ]
}

#[test]
fn hand_worked_figures() {
    let opts = DinOptions { interpolation_degree: 1, through_zero: true, resolution: Some(0.001) };
    let r = din51309_figures(&series(), &opts).unwrap();
    assert_eq!(r.mounting_positions_deg, vec![0.0, 120.0, 240.0]);
    let (s10, s20) = (&r.steps[0], &r.steps[1]);

    // 10 N·m: X̄_wr = (1.000 + 1.002)/2 = 1.001, b' = 0.002/1.001.
    assert!((s10.mean_deflection_same_position - 1.001).abs() < TOL);
    assert!((s10.repeatability.unwrap() - 0.002 / 1.001).abs() < TOL);
    // X̄_r = (1.000 + 1.010 + 0.990)/3 = 1.000, b = (1.010 − 0.990)/1.000 = 0.02.
    assert!((s10.mean_deflection - 1.0).abs() < TOL);
    assert!((s10.reproducibility.unwrap() - 0.02).abs() < TOL);
    // h = (|1.030 − 1.010| + |1.000 − 0.990|) / (2 · 1.000) = 0.015.
    assert!((s10.reversibility.unwrap() - 0.015).abs() < TOL);
    // r = 0.001 / 1.000.
    assert!((s10.resolution.unwrap() - 0.001).abs() < TOL);

    // 20 N·m: X̄_wr = 2.002, b' = 0.004/2.002; X̄_r = (2.000 + 2.020 + 1.990)/3 = 6.01/3.
    assert!((s20.repeatability.unwrap() - 0.004 / 2.002).abs() < TOL);
    let xr20 = 6.01 / 3.0;
    assert!((s20.mean_deflection - xr20).abs() < TOL);
    assert!((s20.reproducibility.unwrap() - 0.030 / xr20).abs() < TOL);
    // The top step has no unloading reading.
    assert!(s20.reversibility.is_none());

    // Line through zero: a = (10 · 1.0 + 20 · X̄_r(20)) / (10² + 20²).
    let a = (10.0 * 1.0 + 20.0 * xr20) / 500.0;
    assert!((r.interpolation_coeffs[0]).abs() < TOL && (r.interpolation_coeffs[1] - a).abs() < TOL);
    assert!((s10.interpolation - (1.0 - 10.0 * a) / (10.0 * a)).abs() < TOL);
    assert!((s20.interpolation - (xr20 - 20.0 * a) / (20.0 * a)).abs() < TOL);

    // f0 per series: 0.002/2.000, 0/2.004, 0.004/2.020, 0/1.990.
    let f0: Vec<f64> = r.zero_error.iter().map(|f| f.unwrap()).collect();
    for (got, want) in f0.iter().zip([0.001, 0.0, 0.004 / 2.020, 0.0]) {
        assert!((got - want).abs() < TOL, "{got} vs {want}");
    }
    assert!((r.max_zero_error.unwrap() - 0.004 / 2.020).abs() < TOL);
}

#[test]
fn interpolation_degree_two_with_constant_fits_three_steps_exactly() {
    // Three steps, a quadratic with a constant: the curve passes through every mean.
    let s = [LoadSeries::new(0.0, &[(0.0, 0.0), (5.0, 0.51), (10.0, 1.0), (15.0, 1.52)])];
    let opts = DinOptions { interpolation_degree: 2, through_zero: false, resolution: None };
    let r = din51309_figures(&s, &opts).unwrap();
    for st in &r.steps {
        assert!(st.interpolation.abs() < 1e-12);
        assert!(st.repeatability.is_none() && st.reproducibility.is_none() && st.resolution.is_none());
    }
    assert_eq!(r.zero_error, vec![None]);
    assert!(r.max_zero_error.is_none());
}

#[test]
fn malformed_series_are_refused_with_a_reason() {
    let opts = DinOptions::default();
    // Missing zero reading first.
    let bad = [LoadSeries::new(0.0, &[(10.0, 1.0), (20.0, 2.0)])];
    assert!(matches!(din51309_figures(&bad, &opts), Err(CalibrationError::Invalid { .. })));
    // Loading steps that differ between series.
    let mut s = series();
    s[1] = LoadSeries::new(0.0, &[(0.0, 0.0), (10.0, 1.0), (25.0, 2.5), (0.0, 0.0)]);
    let err = din51309_figures(&s, &opts).unwrap_err();
    // Series and steps are counted from 1, as users count.
    assert!(err.to_string().contains("series 2: its loading steps differ from series 1's"), "{err}");
    // Unloading to a step that was never loaded.
    let bad = [LoadSeries::new(0.0, &[(0.0, 0.0), (10.0, 1.0), (20.0, 2.0), (15.0, 1.5), (0.0, 0.0)])];
    assert!(din51309_figures(&bad, &opts).unwrap_err().to_string().contains("15"));
    // A NaN indication names series and row.
    let bad = [LoadSeries::new(0.0, &[(0.0, 0.0), (10.0, f64::NAN)])];
    assert_eq!(
        din51309_figures(&bad, &opts).unwrap_err(),
        CalibrationError::NonFiniteRow { what: "series 1".into(), row: 1, column: "indication" }
    );
    // Degree out of range.
    let o = DinOptions { interpolation_degree: 4, ..DinOptions::default() };
    assert!(din51309_figures(&series(), &o).is_err());
    // Too few steps for a cubic through zero (3 unknowns, 2 steps).
    let o = DinOptions { interpolation_degree: 3, ..DinOptions::default() };
    assert!(matches!(din51309_figures(&series(), &o), Err(CalibrationError::TooFewRows { needed: 3, got: 2, .. })));
    // Torque sign change within a series.
    let bad = [LoadSeries::new(0.0, &[(0.0, 0.0), (10.0, 1.0), (-20.0, -2.0)])];
    let err = din51309_figures(&bad, &opts).unwrap_err().to_string();
    assert!(err.starts_with("series 1: step 3: torque changes sign"), "{err}");
    assert!(din51309_figures(&[], &opts).is_err());
}

#[test]
fn anticlockwise_series_use_magnitudes() {
    let s = [
        LoadSeries::new(0.0, &[(0.0, 0.0), (-10.0, -1.0), (-20.0, -2.0), (0.0, 0.0)]),
        LoadSeries::new(0.0, &[(0.0, 0.0), (-10.0, -1.002), (-20.0, -2.0), (0.0, 0.0)]),
    ];
    let r = din51309_figures(&s, &DinOptions::default()).unwrap();
    assert!((r.steps[0].repeatability.unwrap() - 0.002 / 1.001).abs() < TOL);
}
