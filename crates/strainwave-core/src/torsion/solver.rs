use super::*;

/// A solved torque with the work it took.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Solution<T: Real> {
    /// Torque, N·m.
    pub torque_nm: T,
    /// Iterations used (0 when the start point already satisfied the tolerance).
    pub iterations: u32,
    /// Final residual `θ(τ) − w`, rad.
    pub residual_rad: T,
}

/// Bounded, bracketed Newton solver of `θ(τ) = w` for any [`Compliance`].
///
/// Real-time safe: at most `max_iterations` evaluations of the model, never leaves the
/// bracket `[−L, L]` (`L` = `torque_limit_nm`), falls back to bisection whenever a Newton
/// step would leave the current bracket or fails to halve it, and returns an error value
/// (`OutOfRange` when `w` is beyond `θ(±L)`, `NoConvergence` at the cap) instead of diverging.
/// From a warm start (the previous sample's torque) it typically takes 1–3 iterations.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TorqueSolver<T: Real> {
    torque_limit_nm: T,
    tolerance_nm: T,
    max_iterations: u32,
}

impl<T: Real> TorqueSolver<T> {
    /// Bracket `±torque_limit_nm`, stop when a step is below `tolerance_nm` (plus a few
    /// ulps of the torque), at most `max_iterations` (1..=200).
    ///
    /// ```
    /// use strainwave_core::compliance::ThreeSlopeStiffness;
    /// use strainwave_core::torsion::TorqueSolver;
    /// let k = ThreeSlopeStiffness::new(6.7e4, 1.1e5, 1.2e5, 29.0, 108.0).unwrap();
    /// let solver = TorqueSolver::new(400.0_f64, 1e-9, 60).unwrap();
    /// let s = solver.solve(&k, 7.15e-4, 0.0).unwrap();
    /// assert!((s.torque_nm - 60.0).abs() < 0.1);
    /// assert!(solver.solve(&k, 1.0, 0.0).is_err()); // 1 rad needs far more than 400 N·m
    /// ```
    pub fn new(torque_limit_nm: T, tolerance_nm: T, max_iterations: u32) -> Result<Self, Error> {
        positive(torque_limit_nm, "torque_limit_nm")?;
        positive(tolerance_nm, "tolerance_nm")?;
        if max_iterations == 0 || max_iterations > 200 {
            return Err(Error::OutOfRange("max_iterations"));
        }
        Ok(Self { torque_limit_nm, tolerance_nm, max_iterations })
    }

    /// Defaults for a gear of a given rated torque: limit 4 × rated, tolerance
    /// 1e-9 × rated, 60 iterations (bisection alone needs about 45).
    pub fn for_rated_torque(rated_torque_nm: T) -> Result<Self, Error> {
        positive(rated_torque_nm, "rated_torque_nm")?;
        Self::new(T::from_f64(4.0) * rated_torque_nm, T::from_f64(1e-9) * rated_torque_nm, 60)
    }

    /// The bracket half-width `L`, N·m.
    pub fn torque_limit_nm(&self) -> T {
        self.torque_limit_nm
    }

    /// The iteration cap.
    pub fn max_iterations(&self) -> u32 {
        self.max_iterations
    }

    /// Solves `model.twist_rad(τ) = windup_rad` for `τ`, starting from `guess_nm`.
    pub fn solve<C: Compliance<T> + ?Sized>(
        &self,
        model: &C,
        windup_rad: T,
        guess_nm: T,
    ) -> Result<Solution<T>, Error> {
        finite(windup_rad, "windup_rad")?;
        if let Some(max) = model.max_twist_rad() {
            if windup_rad.abs() >= max {
                return Err(Error::OutOfRange("windup_rad"));
            }
        }
        let limit = self.torque_limit_nm;
        let g_hi = model.twist_rad(limit) - windup_rad;
        let g_lo = model.twist_rad(-limit) - windup_rad;
        if !(g_hi.is_finite() && g_lo.is_finite()) {
            return Err(Error::NonFinite("twist_rad"));
        }
        if g_hi < T::ZERO || g_lo > T::ZERO {
            return Err(Error::OutOfRange("windup_rad"));
        }
        let (mut lo, mut hi) = (-limit, limit);
        let four_eps = T::from_f64(4.0) * T::EPSILON;
        let mut tau = if guess_nm.is_finite() { guess_nm.clamp(lo, hi) } else { T::ZERO };
        // Step before last and last step (rtsafe-style safeguard).
        let mut dx_old = hi - lo;
        let mut dx = dx_old;
        for it in 0..self.max_iterations {
            let r = model.twist_rad(tau) - windup_rad;
            if !r.is_finite() {
                return Err(Error::NonFinite("twist_rad"));
            }
            if r == T::ZERO {
                return Ok(Solution { torque_nm: tau, iterations: it, residual_rad: r });
            }
            if r > T::ZERO {
                hi = tau;
            } else {
                lo = tau;
            }
            let slope = model.compliance_rad_per_nm(tau);
            let newton_step = r / slope;
            let newton = tau - newton_step;
            let newton_ok = slope > T::ZERO
                && newton.is_finite()
                && newton > lo
                && newton < hi
                && T::TWO * newton_step.abs() <= dx_old.abs();
            dx_old = dx;
            let next = if newton_ok {
                dx = newton_step;
                newton
            } else {
                dx = T::HALF * (hi - lo);
                lo + dx
            };
            tau = next;
            let tol = self.tolerance_nm + four_eps * tau.abs();
            if dx.abs() <= tol || hi - lo <= tol {
                let r = model.twist_rad(tau) - windup_rad;
                return Ok(Solution { torque_nm: tau, iterations: it + 1, residual_rad: r });
            }
        }
        Err(Error::NoConvergence("torque_nm"))
    }
}
