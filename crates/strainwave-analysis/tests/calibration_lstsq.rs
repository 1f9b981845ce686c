//! Least-squares behaviour: a hand-computed case, singular detection, and random
//! problems checked against the optimality condition Aᵀ r = 0 (fixed seed).

use strainwave_analysis::lstsq::{lstsq, polyfit, LstsqError};

/// A small deterministic generator (SplitMix64) so the test needs no crate.
struct SplitMix(u64);
impl SplitMix {
    fn next_f64(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        (z >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
    }
}

#[test]
fn hand_computed_line_fit() {
    // Points (0, 0), (1, 1), (2, 1), (3, 3): by hand Σx = 6, Σy = 5, Σx² = 14, Σxy = 12,
    // slope = (4·12 − 6·5)/(4·14 − 36) = 18/20 = 0.9, intercept = (5 − 0.9·6)/4 = −0.1.
    let a = [1.0, 0.0, 1.0, 1.0, 1.0, 2.0, 1.0, 3.0];
    let s = lstsq(&a, 2, &[0.0, 1.0, 1.0, 3.0]).unwrap();
    assert!((s.x[0] + 0.1).abs() < 1e-14 && (s.x[1] - 0.9).abs() < 1e-14);
    // Residuals 0.1, 0.2, −0.7, 0.4 → ‖r‖² = 0.7.
    assert!((s.residual_norm - 0.7f64.sqrt()).abs() < 1e-14);
}

#[test]
fn random_problems_satisfy_optimality() {
    let mut rng = SplitMix(2024);
    for trial in 0..50 {
        let n = 1 + trial % 6;
        let m = n + 3 + trial % 7;
        let a: Vec<f64> = (0..m * n).map(|_| rng.next_f64()).collect();
        let b: Vec<f64> = (0..m).map(|_| rng.next_f64()).collect();
        let s = lstsq(&a, n, &b).unwrap();
        // Aᵀ r = 0 at the minimiser (relative to ‖A‖ ‖r‖).
        for j in 0..n {
            let g: f64 = (0..m).map(|i| a[i * n + j] * s.residuals[i]).sum();
            assert!(g.abs() < 1e-12 * (m as f64) * (1.0 + s.residual_norm), "trial {trial}: {g}");
        }
        // Covariance is symmetric with a positive diagonal.
        let c = s.covariance().unwrap();
        for i in 0..n {
            assert!(c[i * n + i] > 0.0);
            for j in 0..n {
                assert!((c[i * n + j] - c[j * n + i]).abs() <= 1e-12 * c[i * n + i].abs().max(c[j * n + j].abs()));
            }
        }
    }
}

#[test]
fn near_and_exactly_singular() {
    // Columns x and 2x: refused, naming rank 1 of 2.
    let x = [1.0, 2.0, 3.0, 4.0];
    let a: Vec<f64> = x.iter().flat_map(|&v| [v, 2.0 * v]).collect();
    let err = lstsq(&a, 2, &[1.0, 2.0, 3.0, 4.0]).unwrap_err();
    assert!(matches!(err, LstsqError::RankDeficient { rank: 1, unknowns: 2, .. }), "{err}");
    // Polynomial with fewer distinct abscissae than coefficients.
    let err = polyfit(&[1.0, 1.0, 2.0, 2.0], &[0.0, 1.0, 0.0, 1.0], 2).unwrap_err();
    assert!(matches!(err, LstsqError::RankDeficient { .. }), "{err}");
}
