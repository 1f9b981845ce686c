//! Order discovery: an order analysis of the canceller's innovation in the angle domain,
//! to find the lines the model does not have.
//!
//! Candidates are the multiples `n = 0.5, 1, 1.5, …, 20` of each reference angle
//! (relative, output, motor). For each, a least-squares fit of the innovation `e(k)`
//! on `cos nθ(k)`, `sin nθ(k)` runs over the samples where the candidate's line is
//! between the hold frequency and the Nyquist guard (`n |Δθ| ≤ 0.45 · 2π` per sample,
//! the canceller's own limits), so a varying speed, reversals and standstills are fine:
//!
//! ```text
//! G = Σ [c² cs; cs s²],  s = Σ e [c; s],   [a b]ᵀ = G⁻¹ s,   E = sᵀ G⁻¹ s
//! ```
//!
//! With white innovation of variance σ² and no line, `E / σ²` is χ² with 2 degrees of
//! freedom whatever the speed profile. Each candidate's statistic is `T = E / σ̂²`, σ̂²
//! its own residual variance `(Σ e² − E) / (n − 2)` over its own samples (candidates
//! see different samples: a high multiple passes the Nyquist guard sooner). Against a
//! coloured innovation, `T` is compared with the median of `T` over the candidates of
//! the same reference within ±6 orders (itself and the model's orders left out): under
//! no line the median of χ²₂ is `2 ln 2`, `P(T / median > t) = 2^(−t)`, and a line is
//! **significant** when `T / median > log₂(candidates tested / 0.001)`: one false alarm
//! in a thousand scans (Bonferroni over the candidates). A candidate needs 100 cycles
//! of its line.
//!
//! A line shows on several references when they turn together (with the flexspline
//! fixed the relative angle is the motor angle; with the circular spline fixed they
//! differ by `1/N`): significant candidates are taken strongest first, and one is
//! dropped as an alias when an accepted line, or an order of the model, drifts from it
//! by `d < 3` cycles over the run (the run cannot tell them apart), or could explain it
//! through leakage: `T ≤ 10 · T_accepted / (π d)²`, the `sinc²` bound of how much of a
//! line a fit `d` cycles away picks up.
//!
//! Phase: a whole multiple with angle input uses `n θ` of the absolute angle (as the
//! canceller's priors do); a half multiple, or velocity input, the phase integrated
//! from the run's first sample, which does not carry over to another run.

use std::f64::consts::PI;

use strainwave_core::ripple::{PhaseSource, Reference, RippleInput, StepFlags};

/// Candidate multiples per reference: 0.5 to `MAX_MULTIPLE` in steps of 0.5.
pub const MAX_MULTIPLE: f64 = 20.0;
const HALF_STEPS: usize = (2.0 * MAX_MULTIPLE) as usize;
/// False-alarm probability of a whole scan.
pub const FALSE_ALARM: f64 = 1e-3;
/// Neighbours each side (in half orders) for the noise median: ±6 orders.
const NEIGHBOURS: usize = 12;
/// Fewest neighbours for a noise estimate.
const MIN_NEIGHBOURS: usize = 6;
/// Cycles of its line a candidate needs.
pub const MIN_CYCLES: f64 = 100.0;
/// Two lines that drift apart by fewer cycles than this over the run are one line.
const UNRESOLVED_CYCLES: f64 = 3.0;
/// How much more than the `sinc²` leakage bound an alias may show.
const LEAK_MARGIN: f64 = 10.0;
/// A jump in a reference beyond this per sample (rad) is not motion.
const MAX_STEP_RAD: f64 = PI / 2.0;
const REFERENCES: [Reference; 3] = [Reference::Relative, Reference::Output, Reference::Motor];

/// One candidate's sums.
#[derive(Debug, Clone, Copy, Default)]
struct Sums {
    s: [f64; 2],
    g: [f64; 3],
    e2: f64,
    count: f64,
    cycles: f64,
}

/// A line the scan found.
#[derive(Debug, Clone, PartialEq)]
pub struct Discovery {
    /// Its reference angle.
    pub reference: Reference,
    /// Its multiple.
    pub multiple: f64,
    /// Least-squares coefficients of `cos nθ`, `sin nθ` in the innovation, N·m.
    pub coefficients_nm: [f64; 2],
    /// Their covariance, N·m², from the local noise estimate.
    pub covariance_nm2: [[f64; 2]; 2],
    /// `T / median` of the neighbours.
    pub power_ratio: f64,
    /// The significance threshold of the scan.
    pub threshold: f64,
    /// Cycles of the line over the samples used.
    pub cycles: f64,
    /// Whether the phase is that of the absolute angle (so the coefficients carry over).
    pub phase_carries: bool,
}

impl Discovery {
    /// Amplitude `√(a² + b²)`, N·m.
    pub fn amplitude_nm(&self) -> f64 {
        self.coefficients_nm[0].hypot(self.coefficients_nm[1])
    }
}

/// The streaming scan: constant memory (3 × 40 candidates), one pass.
#[derive(Debug, Clone)]
pub struct OrderScan {
    sample_period_s: f64,
    nyquist_fraction: f64,
    hold_below_hz: f64,
    velocity: bool,
    sums: Vec<[Sums; HALF_STEPS]>,
    last: Option<[f64; 3]>,
    /// Phase integrated from the first sample, rad.
    psi: [f64; 3],
    /// Angle at the first sample (angle input), rad.
    theta0: Option<[f64; 3]>,
}

fn wrap_pi(x: f64) -> f64 {
    x - 2.0 * PI * (x / (2.0 * PI)).round()
}

impl OrderScan {
    /// A scan at `sample_rate_hz` with the canceller's Nyquist fraction and hold
    /// frequency.
    pub fn new(sample_rate_hz: f64, nyquist_fraction: f64, hold_below_hz: f64, phase: PhaseSource) -> Self {
        Self {
            sample_period_s: 1.0 / sample_rate_hz,
            nyquist_fraction,
            hold_below_hz,
            velocity: phase == PhaseSource::Velocity,
            sums: vec![[Sums::default(); HALF_STEPS]; 3],
            last: None,
            psi: [0.0; 3],
            theta0: None,
        }
    }

    /// One sample: the canceller's input and the innovation and flags of its step.
    pub fn observe(&mut self, input: &RippleInput<f64>, innovation_nm: f64, flags: StepFlags) {
        let v = input.references.as_array();
        let dt = input.dt_s.unwrap_or(self.sample_period_s);
        if !(v.iter().all(|x| x.is_finite()) && dt.is_finite() && dt > 0.0) {
            return;
        }
        let Some(last) = self.last.replace(v) else {
            self.theta0 = Some(v);
            return;
        };
        let delta: [f64; 3] =
            core::array::from_fn(|r| if self.velocity { 0.5 * (last[r] + v[r]) * dt } else { wrap_pi(v[r] - last[r]) });
        if delta.iter().any(|d| d.abs() > MAX_STEP_RAD) {
            return;
        }
        for (p, d) in self.psi.iter_mut().zip(delta) {
            *p += d;
        }
        let skip = StepFlags::MEASUREMENT_SKIPPED.bits()
            | StepFlags::ANGLE_SKIPPED.bits()
            | StepFlags::GAP_RESET.bits()
            | StepFlags::JUMP_RESET.bits()
            | StepFlags::COVARIANCE_RESET.bits()
            | StepFlags::LOAD_STEP.bits();
        if !innovation_nm.is_finite() || flags.bits() & skip != 0 {
            return;
        }
        let theta0 = self.theta0.unwrap_or([0.0; 3]);
        for r in 0..3 {
            let step = delta[r].abs();
            if step == 0.0 {
                continue;
            }
            // Half-order phasor of the integrated phase, raised to each multiple.
            let (s_h, c_h) = (0.5 * self.psi[r]).sin_cos();
            let (mut c, mut s) = (1.0, 0.0);
            for (k, acc) in self.sums[r].iter_mut().enumerate() {
                (c, s) = (c * c_h - s * s_h, s * c_h + c * s_h);
                let n = 0.5 * (k + 1) as f64;
                let line = n * step;
                if line > self.nyquist_fraction * 2.0 * PI {
                    break;
                }
                if line < 2.0 * PI * self.hold_below_hz * dt {
                    continue;
                }
                // Whole multiples of an angle: the absolute phase n θ = n ψ + n θ₀.
                let (cn, sn) = if k % 2 == 1 && !self.velocity {
                    let (so, co) = (n * theta0[r]).sin_cos();
                    (c * co - s * so, s * co + c * so)
                } else {
                    (c, s)
                };
                acc.s[0] += innovation_nm * cn;
                acc.s[1] += innovation_nm * sn;
                acc.g[0] += cn * cn;
                acc.g[1] += cn * sn;
                acc.g[2] += sn * sn;
                acc.e2 += innovation_nm * innovation_nm;
                acc.count += 1.0;
                acc.cycles += line / (2.0 * PI);
            }
        }
    }

    /// The significant lines not in `modelled` (the model's orders, reference and
    /// multiple), strongest first; `tested` gets the number of candidates tested.
    pub fn finish(&self, modelled: &[(Reference, f64)], tested: &mut usize) -> Vec<Discovery> {
        struct Fit {
            r: usize,
            k: usize,
            ab: [f64; 2],
            ginv: [[f64; 2]; 2],
            /// `E / σ̂²` with σ̂² the candidate's own residual variance.
            e: f64,
            sigma2: f64,
            cycles: f64,
            /// Mean cycles per sample: the line's mean frequency.
            rate: f64,
            modelled: bool,
        }
        let mut fits: Vec<Fit> = Vec::new();
        for (r, row) in self.sums.iter().enumerate() {
            for (k, acc) in row.iter().enumerate() {
                let [a, b, d] = acc.g;
                let det = a * d - b * b;
                if acc.cycles < MIN_CYCLES || det.is_nan() || det <= 1e-9 * (a + d) * (a + d) {
                    continue;
                }
                let ginv = [[d / det, -b / det], [-b / det, a / det]];
                let ab = [ginv[0][0] * acc.s[0] + ginv[0][1] * acc.s[1], ginv[1][0] * acc.s[0] + ginv[1][1] * acc.s[1]];
                let explained = ab[0] * acc.s[0] + ab[1] * acc.s[1];
                let sigma2 = (acc.e2 - explained) / (acc.count - 2.0);
                if sigma2.is_nan() || sigma2 <= 0.0 {
                    continue;
                }
                let e = explained / sigma2;
                let n = 0.5 * (k + 1) as f64;
                let modelled = modelled.iter().any(|&(mr, mn)| mr == REFERENCES[r] && mn == n);
                let rate = acc.cycles / acc.count;
                fits.push(Fit { r, k, ab, ginv, e, sigma2, cycles: acc.cycles, rate, modelled });
            }
        }
        let candidates = fits.iter().filter(|f| !f.modelled).count();
        *tested = candidates;
        let threshold = (candidates.max(1) as f64 / FALSE_ALARM).log2();
        // Noise scale of each fit: the median E of its neighbours.
        let median_of = |f: &Fit| -> Option<f64> {
            let mut nb: Vec<f64> = fits
                .iter()
                .filter(|g| g.r == f.r && !g.modelled && g.k != f.k && g.k.abs_diff(f.k) <= NEIGHBOURS)
                .map(|g| g.e)
                .collect();
            if nb.len() < MIN_NEIGHBOURS {
                return None;
            }
            nb.sort_by(f64::total_cmp);
            let m = nb.len() / 2;
            Some(if nb.len() % 2 == 1 { nb[m] } else { 0.5 * (nb[m - 1] + nb[m]) })
        };
        let mut significant: Vec<(usize, f64, f64)> = Vec::new();
        for (i, f) in fits.iter().enumerate() {
            if f.modelled {
                continue;
            }
            if let Some(med) = median_of(f).filter(|m| *m > 0.0) {
                let ratio = f.e / med;
                if ratio > threshold {
                    significant.push((i, ratio, med));
                }
            }
        }
        significant.sort_by(|a, b| fits[b.0].e.total_cmp(&fits[a.0].e));
        // The model's orders explain their aliases as accepted lines do.
        let mut accepted: Vec<usize> = (0..fits.len()).filter(|&i| fits[i].modelled).collect();
        let mut out = Vec::new();
        for (i, ratio, med) in significant {
            let f = &fits[i];
            let alias = accepted.iter().any(|&j| {
                let d = (fits[j].rate / f.rate - 1.0).abs() * f.cycles.min(fits[j].cycles);
                d < UNRESOLVED_CYCLES || f.e <= LEAK_MARGIN * fits[j].e / (PI * d).powi(2)
            });
            if alias {
                continue;
            }
            accepted.push(i);
            // The noise variance behind the fit: its own residual, scaled by how far the
            // neighbourhood's median sits from that of χ²₂ (coloured innovation).
            let sigma2 = f.sigma2 * med / (2.0 * std::f64::consts::LN_2);
            let whole = f.k % 2 == 1;
            out.push(Discovery {
                reference: REFERENCES[f.r],
                multiple: 0.5 * (f.k + 1) as f64,
                coefficients_nm: f.ab,
                covariance_nm2: [
                    [sigma2 * f.ginv[0][0], sigma2 * f.ginv[0][1]],
                    [sigma2 * f.ginv[1][0], sigma2 * f.ginv[1][1]],
                ],
                power_ratio: ratio,
                threshold,
                cycles: f.cycles,
                phase_carries: whole && !self.velocity,
            });
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use strainwave_core::ripple::ReferenceValues;

    /// Gaussian noise from a fixed seed (xorshift64* and Box–Muller).
    struct Noise(u64);

    impl Noise {
        fn uniform(&mut self) -> f64 {
            self.0 ^= self.0 >> 12;
            self.0 ^= self.0 << 25;
            self.0 ^= self.0 >> 27;
            ((self.0.wrapping_mul(0x2545_f491_4f6c_dd1d) >> 11) as f64 + 0.5) / (1u64 << 53) as f64
        }
        fn normal(&mut self) -> f64 {
            (-2.0 * self.uniform().ln()).sqrt() * (2.0 * PI * self.uniform()).cos()
        }
    }

    /// A scan of `n` samples at 1 kHz: the motor turns at a varying speed, the relative
    /// angle is `k_rel` times it, the output 1/50 of it; the innovation is white noise of
    /// 0.1 N·m plus `line(relative, output, motor)`.
    fn scan(n: usize, k_rel: f64, seed: u64, line: impl Fn(f64, f64, f64) -> f64) -> Vec<Discovery> {
        let mut s = OrderScan::new(1000.0, 0.45, 0.05, PhaseSource::Angle);
        let mut noise = Noise(seed);
        let mut motor = 0.3;
        for k in 0..n {
            let t = k as f64 * 1e-3;
            motor += 1e-3 * (40.0 + 15.0 * (0.7 * t).sin());
            let (rel, out) = (k_rel * motor, motor / 50.0);
            let e = 0.1 * noise.normal() + line(rel, out, motor);
            let input = RippleInput::new(e, ReferenceValues::new(rel, out, motor));
            s.observe(&input, e, StepFlags::empty());
        }
        let mut tested = 0;
        let found = s.finish(&[(Reference::Relative, 2.0)], &mut tested);
        assert!(tested > 60, "{tested} candidates");
        found
    }

    #[test]
    fn white_noise_has_no_line() {
        for seed in 1..=5 {
            let found = scan(20_000, 1.02, seed, |_, _, _| 0.0);
            assert!(found.is_empty(), "seed {seed}: {found:?}");
        }
    }

    #[test]
    fn a_half_order_line_is_found_with_its_size() {
        let found = scan(20_000, 1.02, 7, |_, _, m| 0.05 * (1.5 * m + 0.4).sin());
        assert_eq!(found.len(), 1, "{found:?}");
        let d = &found[0];
        assert_eq!((d.reference, d.multiple, d.phase_carries), (Reference::Motor, 1.5, false));
        assert!((d.amplitude_nm() - 0.05).abs() < 0.01, "{}", d.amplitude_nm());
    }

    #[test]
    fn a_line_on_angles_that_turn_together_is_reported_once() {
        // Relative and motor angles equal (flexspline fixed): one line, on the relative angle.
        let found = scan(20_000, 1.0, 11, |r, _, _| 0.1 * (3.0 * r).cos());
        assert_eq!(found.len(), 1, "{found:?}");
        let d = &found[0];
        assert_eq!((d.reference, d.multiple, d.phase_carries), (Reference::Relative, 3.0, true));
        // 0.1 cos 3θ: cos coefficient 0.1 with the absolute phase.
        assert!((d.coefficients_nm[0] - 0.1).abs() < 0.01 && d.coefficients_nm[1].abs() < 0.01, "{d:?}");
        // A line on a model order's angle is the model's, not a discovery.
        let found = scan(20_000, 1.0, 12, |r, _, _| 0.1 * (2.0 * r).cos());
        assert!(found.is_empty(), "{found:?}");
    }
}
