//! Inner torque of a PMSM from its flux linkages (docs/physics.md §6, Stoß et al. (2022) eqs. 12–13).
//!
//! ```text
//! T_e = 3/2 p [(ψ_d i_q − ψ_q i_d) + (i_d ∂ψ_d/∂γ + i_q ∂ψ_q/∂γ)]      (eq. 12)
//! T_e = 3/2 p (ψ_d i_q − ψ_q i_d)                                    (eq. 13, first bracket)
//! ```
//!
//! `p` pole pairs, `γ` electrical rotor angle (rad), `i_d, i_q` rotor-frame currents (A,
//! amplitude-invariant Park transform), `ψ_d, ψ_q` flux linkages (V·s). A linear machine
//! has `ψ_d = L_d i_d + Ψ_PM`, `ψ_q = L_q i_q` ([`LinearPmsm`]); a measured machine has
//! angle- and current-dependent maps ([`FluxMap`]), tabulated on a uniform grid over one
//! period of `γ` (periodic Catmull-Rom cubic, so `∂ψ/∂γ` is continuous) and increasing
//! grids of `i_d`, `i_q` (bilinear; the edge values hold outside the grid).

use crate::error::{finite, positive, Error};
use crate::Real;

/// Eq. 12: `3/2 p [(ψ_d i_q − ψ_q i_d) + (i_d ∂ψ_d/∂γ + i_q ∂ψ_q/∂γ)]`, N·m.
#[inline]
pub fn torque_eq12<T: Real>(pole_pairs: T, flux: &FluxSample<T>, i_d_a: T, i_q_a: T) -> T {
    T::from_f64(1.5)
        * pole_pairs
        * ((flux.psi_d_vs * i_q_a - flux.psi_q_vs * i_d_a)
            + (i_d_a * flux.dpsi_d_dgamma_vs + i_q_a * flux.dpsi_q_dgamma_vs))
}

/// Eq. 13: `3/2 p (ψ_d i_q − ψ_q i_d)`, N·m.
#[inline]
pub fn torque_eq13<T: Real>(pole_pairs: T, psi_d_vs: T, psi_q_vs: T, i_d_a: T, i_q_a: T) -> T {
    T::from_f64(1.5) * pole_pairs * (psi_d_vs * i_q_a - psi_q_vs * i_d_a)
}

/// A PMSM with constant inductances (Table II style data).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LinearPmsm<T: Real> {
    /// Pole pairs `p`.
    pub pole_pairs: T,
    /// Permanent-magnet flux linkage `Ψ_PM`, V·s.
    pub pm_flux_linkage_vs: T,
    /// `L_d`, H.
    pub d_inductance_h: T,
    /// `L_q`, H.
    pub q_inductance_h: T,
}

impl<T: Real> LinearPmsm<T> {
    /// Validates positive values.
    ///
    /// ```
    /// use strainwave_core::pmsm::LinearPmsm;
    /// let m = LinearPmsm::new(3.0_f64, 11.7e-3, 0.2e-3, 0.2e-3).unwrap();
    /// assert!((m.torque_nm(0.0, 2.0) - 0.1053).abs() < 1e-12);
    /// ```
    pub fn new(pole_pairs: T, pm_flux_linkage_vs: T, d_inductance_h: T, q_inductance_h: T) -> Result<Self, Error> {
        positive(pole_pairs, "pole_pairs")?;
        positive(pm_flux_linkage_vs, "pm_flux_linkage_vs")?;
        positive(d_inductance_h, "d_inductance_h")?;
        positive(q_inductance_h, "q_inductance_h")?;
        Ok(Self { pole_pairs, pm_flux_linkage_vs, d_inductance_h, q_inductance_h })
    }

    /// Nanotec DB59M024035R (Stoß et al. (2022) Table II): `p = 3`, `Ψ_PM = 11.7 mV·s`,
    /// `L_d = L_q = 0.2 mH`.
    ///
    /// ```
    /// let m = strainwave_core::pmsm::LinearPmsm::<f64>::nanotec_db59();
    /// assert_eq!(m.flux_linkage_vs(0.0, 1.0), (11.7e-3, 0.2e-3));
    /// ```
    pub fn nanotec_db59() -> Self {
        Self {
            pole_pairs: T::from_f64(3.0),
            pm_flux_linkage_vs: T::from_f64(11.7e-3),
            d_inductance_h: T::from_f64(0.2e-3),
            q_inductance_h: T::from_f64(0.2e-3),
        }
    }

    /// `(ψ_d, ψ_q) = (L_d i_d + Ψ_PM, L_q i_q)`, V·s.
    pub fn flux_linkage_vs(&self, i_d_a: T, i_q_a: T) -> (T, T) {
        (self.d_inductance_h * i_d_a + self.pm_flux_linkage_vs, self.q_inductance_h * i_q_a)
    }

    /// Eq. 13 for this machine, N·m.
    pub fn torque_nm(&self, i_d_a: T, i_q_a: T) -> T {
        let (pd, pq) = self.flux_linkage_vs(i_d_a, i_q_a);
        torque_eq13(self.pole_pairs, pd, pq, i_d_a, i_q_a)
    }
}

/// Flux linkages and their angle derivatives at one operating point.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct FluxSample<T: Real> {
    /// `ψ_d`, V·s.
    pub psi_d_vs: T,
    /// `ψ_q`, V·s.
    pub psi_q_vs: T,
    /// `∂ψ_d/∂γ`, V·s/rad.
    pub dpsi_d_dgamma_vs: T,
    /// `∂ψ_q/∂γ`, V·s/rad.
    pub dpsi_q_dgamma_vs: T,
}

/// Tabulated flux linkages `ψ_d,q(γ, i_d, i_q)`: `NG` angles over one period, `ND` d-axis
/// and `NQ` q-axis currents. Memory: `2 NG ND NQ` scalars, no heap.
#[derive(Debug, Clone, PartialEq)]
pub struct FluxMap<T: Real, const NG: usize, const ND: usize, const NQ: usize> {
    period_rad: T,
    id_grid_a: [T; ND],
    iq_grid_a: [T; NQ],
    psi_d_vs: [[[T; NQ]; ND]; NG],
    psi_q_vs: [[[T; NQ]; ND]; NG],
}

fn check_grid<T: Real, const N: usize>(g: &[T; N], name: &'static str) -> Result<(), Error> {
    if N == 0 {
        return Err(Error::OutOfRange(name));
    }
    for (k, v) in g.iter().enumerate() {
        finite(*v, name)?;
        if k > 0 && *v <= g[k - 1] {
            return Err(Error::NotIncreasing(name));
        }
    }
    Ok(())
}

/// Interval index and weight of `x` on an increasing grid (clamped at the edges).
#[inline]
fn locate<T: Real, const N: usize>(g: &[T; N], x: T) -> (usize, usize, T) {
    // NaN compares as `None`: it takes the first node.
    if N < 2 || x.partial_cmp(&g[0]) != Some(core::cmp::Ordering::Greater) {
        return (0, 0, T::ZERO);
    }
    if x >= g[N - 1] {
        return (N - 1, N - 1, T::ZERO);
    }
    let mut i = 0;
    while i + 2 < N && x >= g[i + 1] {
        i += 1;
    }
    (i, i + 1, (x - g[i]) / (g[i + 1] - g[i]))
}

impl<T: Real, const NG: usize, const ND: usize, const NQ: usize> FluxMap<T, NG, ND, NQ> {
    /// From tables `psi[g][d][q]` at `γ_g = g · period / NG`. Needs `NG ≥ 4`, increasing
    /// finite current grids and finite tables.
    ///
    /// ```
    /// use strainwave_core::pmsm::FluxMap;
    /// // ψ_d = 1 + 0.1 cos γ sampled at 4 angles, no current dependence.
    /// let d = [[[1.1]], [[1.0]], [[0.9]], [[1.0]]];
    /// let q = [[[0.0]]; 4];
    /// let map = FluxMap::<f64, 4, 1, 1>::from_tables(std::f64::consts::TAU, [0.0], [0.0], d, q).unwrap();
    /// assert_eq!(map.evaluate(0.0, 0.0, 0.0).psi_d_vs, 1.1);
    /// assert_eq!(map.mean_flux_vs(0.0, 0.0), (1.0, 0.0));
    /// ```
    pub fn from_tables(
        period_rad: T,
        id_grid_a: [T; ND],
        iq_grid_a: [T; NQ],
        psi_d_vs: [[[T; NQ]; ND]; NG],
        psi_q_vs: [[[T; NQ]; ND]; NG],
    ) -> Result<Self, Error> {
        positive(period_rad, "period_rad")?;
        if NG < 4 {
            return Err(Error::OutOfRange("angle_points"));
        }
        check_grid(&id_grid_a, "id_grid_a")?;
        check_grid(&iq_grid_a, "iq_grid_a")?;
        for (a, b) in psi_d_vs.iter().zip(psi_q_vs.iter()) {
            for (ra, rb) in a.iter().zip(b.iter()) {
                for (x, y) in ra.iter().zip(rb.iter()) {
                    finite(*x, "psi_d_vs")?;
                    finite(*y, "psi_q_vs")?;
                }
            }
        }
        Ok(Self { period_rad, id_grid_a, iq_grid_a, psi_d_vs, psi_q_vs })
    }

    /// Tabulates `f(γ, i_d, i_q) -> (ψ_d, ψ_q)` on the grid.
    ///
    /// ```
    /// use strainwave_core::pmsm::{torque_eq12, FluxMap, LinearPmsm};
    /// let m = LinearPmsm::<f64>::nanotec_db59();
    /// // A 6th-harmonic ripple of 1 % in ψ_d; one period of the map is 2π/6.
    /// let map = FluxMap::<f64, 48, 2, 2>::from_fn(std::f64::consts::TAU / 6.0, [-5.0, 5.0], [-5.0, 5.0], |g, id, iq| {
    ///     let (pd, pq) = m.flux_linkage_vs(id, iq);
    ///     (pd + 0.01 * m.pm_flux_linkage_vs * (6.0 * g).cos(), pq)
    /// })
    /// .unwrap();
    /// let s = map.evaluate(0.0, 0.0, 2.0);
    /// assert!((torque_eq12(3.0, &s, 0.0, 2.0) - 0.1053 * 1.01).abs() < 1e-5);
    /// assert!((map.fundamental_torque_nm(3.0, 0.0, 2.0) - 0.1053).abs() < 1e-9);
    /// ```
    pub fn from_fn(
        period_rad: T,
        id_grid_a: [T; ND],
        iq_grid_a: [T; NQ],
        f: impl Fn(T, T, T) -> (T, T),
    ) -> Result<Self, Error> {
        positive(period_rad, "period_rad")?;
        let mut pd = [[[T::ZERO; NQ]; ND]; NG];
        let mut pq = [[[T::ZERO; NQ]; ND]; NG];
        let h = period_rad / T::from_usize(NG.max(1));
        for g in 0..NG {
            let gamma = h * T::from_usize(g);
            for d in 0..ND {
                for q in 0..NQ {
                    let (a, b) = f(gamma, id_grid_a[d], iq_grid_a[q]);
                    pd[g][d][q] = a;
                    pq[g][d][q] = b;
                }
            }
        }
        Self::from_tables(period_rad, id_grid_a, iq_grid_a, pd, pq)
    }

    /// Period of the map in `γ`, rad.
    pub fn period_rad(&self) -> T {
        self.period_rad
    }

    /// Bilinear blend of one table at angle row `g`.
    #[inline]
    fn blend(table: &[[[T; NQ]; ND]; NG], g: usize, d: (usize, usize, T), q: (usize, usize, T)) -> T {
        let row = &table[g % NG];
        let lo = row[d.0][q.0] + (row[d.0][q.1] - row[d.0][q.0]) * q.2;
        let hi = row[d.1][q.0] + (row[d.1][q.1] - row[d.1][q.0]) * q.2;
        lo + (hi - lo) * d.2
    }

    /// `ψ_d, ψ_q` and `∂ψ/∂γ` at `(γ, i_d, i_q)`. Any `γ` (wrapped to the period); currents
    /// outside the grid take the edge values; a NaN input gives NaN, never a panic.
    pub fn evaluate(&self, gamma_rad: T, i_d_a: T, i_q_a: T) -> FluxSample<T> {
        let n = T::from_usize(NG);
        let h = self.period_rad / n;
        let mut u = gamma_rad / h;
        u = u - n * (u / n).floor();
        let fl = u.floor();
        let t = u - fl;
        // `as usize` saturates (NaN → 0); the modulo keeps every index in range.
        let i = (fl.to_f64() as usize) % NG;
        let d = locate(&self.id_grid_a, i_d_a);
        let q = locate(&self.iq_grid_a, i_q_a);
        let idx = [(i + NG - 1) % NG, i, (i + 1) % NG, (i + 2) % NG];
        let cr = |table: &[[[T; NQ]; ND]; NG]| {
            let p = idx.map(|g| Self::blend(table, g, d, q));
            let c1 = p[2] - p[0];
            let c2 = T::TWO * p[0] - T::from_f64(5.0) * p[1] + T::from_f64(4.0) * p[2] - p[3];
            let c3 = -p[0] + T::from_f64(3.0) * (p[1] - p[2]) + p[3];
            let value = p[1] + T::HALF * t * (c1 + t * (c2 + t * c3));
            let slope = T::HALF * (c1 + t * (T::TWO * c2 + T::from_f64(3.0) * t * c3)) / h;
            (value, slope)
        };
        let (psi_d_vs, dpsi_d_dgamma_vs) = cr(&self.psi_d_vs);
        let (psi_q_vs, dpsi_q_dgamma_vs) = cr(&self.psi_q_vs);
        FluxSample { psi_d_vs, psi_q_vs, dpsi_d_dgamma_vs, dpsi_q_dgamma_vs }
    }

    /// Angle-averaged flux linkages `(ψ̄_d, ψ̄_q)` (the mean of the periodic spline is the
    /// mean of its samples), V·s.
    pub fn mean_flux_vs(&self, i_d_a: T, i_q_a: T) -> (T, T) {
        let d = locate(&self.id_grid_a, i_d_a);
        let q = locate(&self.iq_grid_a, i_q_a);
        let (mut a, mut b) = (T::ZERO, T::ZERO);
        for g in 0..NG {
            a += Self::blend(&self.psi_d_vs, g, d, q);
            b += Self::blend(&self.psi_q_vs, g, d, q);
        }
        let n = T::from_usize(NG);
        (a / n, b / n)
    }

    /// Eq. 12 from the map, N·m.
    pub fn torque_nm(&self, pole_pairs: T, gamma_rad: T, i_d_a: T, i_q_a: T) -> T {
        torque_eq12(pole_pairs, &self.evaluate(gamma_rad, i_d_a, i_q_a), i_d_a, i_q_a)
    }

    /// Eq. 13 with the angle-averaged flux (the paper's sweep evaluation), N·m.
    pub fn fundamental_torque_nm(&self, pole_pairs: T, i_d_a: T, i_q_a: T) -> T {
        let (pd, pq) = self.mean_flux_vs(i_d_a, i_q_a);
        torque_eq13(pole_pairs, pd, pq, i_d_a, i_q_a)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Spline error bound for these tests (relative to the harmonic amplitude).
    const SPLINE_TOL: f64 = 5e-3;

    #[test]
    fn table_ii_machine_eq13() {
        let m = LinearPmsm::<f64>::nanotec_db59();
        assert!((m.torque_nm(0.0, 2.0) - 0.1053).abs() < 1e-12);
        let m32 = LinearPmsm::<f32>::nanotec_db59();
        assert!((m32.torque_nm(0.0, 2.0) - 0.1053).abs() < 1e-6);
        // L_d = L_q: i_d adds no reluctance torque.
        assert!((m.torque_nm(-4.0, 2.0) - 0.1053).abs() < 1e-12);
    }

    #[test]
    fn map_derivative_matches_analytic_harmonics() {
        let a = 1e-4;
        let map = FluxMap::<f64, 60, 3, 3>::from_fn(
            core::f64::consts::TAU / 6.0,
            [-5.0, 0.0, 5.0],
            [-5.0, 0.0, 5.0],
            |g, id, iq| {
                (0.0117 + 2e-4 * id + a * (6.0 * g).cos() + 0.2 * a * (12.0 * g).cos(), 2e-4 * iq + a * (6.0 * g).sin())
            },
        )
        .unwrap();
        for k in 0..97 {
            let g = -3.0 + 0.0731 * k as f64;
            let s = map.evaluate(g, -1.3, 2.2);
            let want_d = 0.0117 - 2.6e-4 + a * (6.0 * g).cos() + 0.2 * a * (12.0 * g).cos();
            let want_dd = -6.0 * a * (6.0 * g).sin() - 12.0 * 0.2 * a * (12.0 * g).sin();
            let want_dq = 6.0 * a * (6.0 * g).cos();
            assert!((s.psi_d_vs - want_d).abs() < SPLINE_TOL * a, "{g}");
            assert!((s.dpsi_d_dgamma_vs - want_dd).abs() < 10.0 * SPLINE_TOL * 6.0 * a, "{g}");
            assert!((s.dpsi_q_dgamma_vs - want_dq).abs() < 10.0 * SPLINE_TOL * 6.0 * a, "{g}");
        }
        let (pd, pq) = map.mean_flux_vs(0.0, 1.0);
        assert!((pd - 0.0117).abs() < 1e-12 && (pq - 2e-4).abs() < 1e-12);
    }

    #[test]
    fn map_never_panics() {
        let map = FluxMap::<f32, 4, 1, 1>::from_fn(1.0, [0.0], [0.0], |g, _, _| (g, -g)).unwrap();
        for x in [f32::NAN, f32::INFINITY, -f32::INFINITY, 1e30, -1e30] {
            let _ = map.evaluate(x, x, x);
            let _ = map.torque_nm(3.0, x, x, x);
        }
        assert_eq!(
            FluxMap::<f64, 4, 2, 1>::from_fn(1.0, [1.0, 0.0], [0.0], |_, _, _| (0.0, 0.0)),
            Err(Error::NotIncreasing("id_grid_a"))
        );
        assert_eq!(
            FluxMap::<f64, 3, 1, 1>::from_fn(1.0, [0.0], [0.0], |_, _, _| (0.0, 0.0)),
            Err(Error::OutOfRange("angle_points"))
        );
    }
}
