//! Small dense symmetric positive definite algebra for the smoothed torque's
//! information-form combination.

// Index loops read as the formulas.
#![allow(clippy::needless_range_loop)]

use super::torque_ripple::MAX_N;

/// Inverse of the symmetric positive definite leading `n × n` block (Cholesky), `None`
/// when it is not positive definite or not finite.
pub(super) fn inverse_spd(a: &[[f64; MAX_N]; MAX_N], n: usize) -> Option<[[f64; MAX_N]; MAX_N]> {
    let mut l = [[0.0; MAX_N]; MAX_N];
    for i in 0..n {
        for j in 0..=i {
            let s = a[i][j] - (0..j).map(|k| l[i][k] * l[j][k]).sum::<f64>();
            if i == j {
                if !(s.is_finite() && s > 0.0) {
                    return None;
                }
                l[i][i] = s.sqrt();
            } else {
                l[i][j] = s / l[j][j];
            }
        }
    }
    // L⁻¹ (lower), then A⁻¹ = L⁻ᵀ L⁻¹.
    let mut li = [[0.0; MAX_N]; MAX_N];
    for i in 0..n {
        li[i][i] = 1.0 / l[i][i];
        for j in 0..i {
            li[i][j] = -(j..i).map(|k| l[i][k] * li[k][j]).sum::<f64>() / l[i][i];
        }
    }
    let mut inv = [[0.0; MAX_N]; MAX_N];
    for i in 0..n {
        for j in 0..=i {
            let v: f64 = (i..n).map(|k| li[k][i] * li[k][j]).sum();
            inv[i][j] = v;
            inv[j][i] = v;
        }
    }
    Some(inv)
}
