//! Helpers shared by the ripple integration tests: a seeded RNG, a synthetic joint
//! with known truth, and a textbook dense prediction-type Kalman filter.
// Dense reference algebra reads best with explicit indices.
#![allow(dead_code, clippy::needless_range_loop)]

use std::f64::consts::TAU;

/// SplitMix64 with Box–Muller normals; fixed seeds make every test reproducible.
pub struct Rng(u64);

impl Rng {
    pub fn new(seed: u64) -> Self {
        Self(seed)
    }
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    /// Uniform in (0, 1).
    pub fn uniform(&mut self) -> f64 {
        ((self.next_u64() >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    }
    pub fn normal(&mut self) -> f64 {
        let (u, v) = (self.uniform(), self.uniform());
        (-2.0 * u.ln()).sqrt() * (TAU * v).cos()
    }
}

/// One synthetic sample with its truth.
#[derive(Clone, Copy, Debug, Default)]
pub struct Sample {
    pub t_s: f64,
    /// Relative WG–FS angle φ, rad (unwrapped).
    pub relative: f64,
    /// Output angle, rad (unwrapped).
    pub output: f64,
    /// Motor angle, rad.
    pub motor: f64,
    pub true_torque: f64,
    pub true_ripple: f64,
    pub true_misalignment: f64,
    pub measured: f64,
}

/// A circular-spline-fixed joint: ratio N, ripple 2×/4× in φ whose amplitude grows with
/// load, misalignment 1× output, white noise.
#[derive(Clone, Copy, Debug)]
pub struct Joint {
    pub ratio: f64,
    pub fs: f64,
    pub ripple2: (f64, f64, f64),
    pub ripple4: (f64, f64, f64),
    pub misalignment: (f64, f64),
    pub noise: f64,
}

impl Default for Joint {
    fn default() -> Self {
        Self {
            ratio: 100.0,
            fs: 1000.0,
            // (amplitude N·m, extra amplitude per N·m of load, phase rad)
            ripple2: (0.5, 0.01, 0.3),
            ripple4: (0.2, 0.004, -1.1),
            misalignment: (1.0, 0.7),
            noise: 0.05,
        }
    }
}

impl Joint {
    /// Samples for a motor-angle trajectory `motor(t)` and load `load(t)`.
    pub fn run(&self, n: usize, seed: u64, motor: impl Fn(f64) -> f64, load: impl Fn(f64) -> f64) -> Vec<Sample> {
        let mut rng = Rng::new(seed);
        (0..n)
            .map(|k| {
                let t = k as f64 / self.fs;
                let m = motor(t);
                let out = -m / self.ratio;
                let rel = m - out;
                let tl = load(t);
                let a2 = self.ripple2.0 + self.ripple2.1 * tl.abs();
                let a4 = self.ripple4.0 + self.ripple4.1 * tl.abs();
                let ripple = a2 * (2.0 * rel + self.ripple2.2).cos() + a4 * (4.0 * rel + self.ripple4.2).cos();
                let mis = self.misalignment.0 * (out + self.misalignment.1).cos();
                Sample {
                    t_s: t,
                    relative: rel,
                    output: out,
                    motor: m,
                    true_torque: tl,
                    true_ripple: ripple,
                    true_misalignment: mis,
                    measured: tl + ripple + mis + self.noise * rng.normal(),
                }
            })
            .collect()
    }
}

/// Root mean square.
pub fn rms(v: impl IntoIterator<Item = f64>) -> f64 {
    let (mut s, mut n) = (0.0, 0usize);
    for x in v {
        s += x * x;
        n += 1;
    }
    (s / n.max(1) as f64).sqrt()
}

/// Amplitude of the component of `e` at `multiple × angle` (least-squares projection).
pub fn order_amplitude(e: &[f64], angle: &[f64], multiple: f64) -> f64 {
    let (mut cc, mut ss, mut cs, mut ec, mut es) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for (&x, &a) in e.iter().zip(angle) {
        let (s, c) = (multiple * a).sin_cos();
        cc += c * c;
        ss += s * s;
        cs += c * s;
        ec += x * c;
        es += x * s;
    }
    let det = cc * ss - cs * cs;
    let a = (ec * ss - es * cs) / det;
    let b = (es * cc - ec * cs) / det;
    (a * a + b * b).sqrt()
}

/// Textbook dense prediction-type Kalman filter (Taghirad and Bélanger, 1999), f64:
/// `K = Φ P Cᵀ / (R + C P Cᵀ)`, `x ← Φ x + K (y − C x)`, `P ← Q + (Φ − K C) P Φᵀ`.
pub struct DenseKf {
    pub x: Vec<f64>,
    pub p: Vec<Vec<f64>>,
    pub c: Vec<f64>,
    pub r: f64,
}

impl DenseKf {
    pub fn new(x0: Vec<f64>, p0: Vec<Vec<f64>>, c: Vec<f64>, r: f64) -> Self {
        Self { x: x0, p: p0, c, r }
    }
    pub fn n(&self) -> usize {
        self.x.len()
    }
    /// `C x̂(k|k−1)`.
    pub fn predict_y(&self) -> f64 {
        self.c.iter().zip(&self.x).map(|(c, x)| c * x).sum()
    }
    /// `P Cᵀ` and `S = R + C P Cᵀ`.
    pub fn pc(&self) -> (Vec<f64>, f64) {
        let n = self.n();
        let pc: Vec<f64> = (0..n).map(|i| (0..n).map(|j| self.p[i][j] * self.c[j]).sum()).collect();
        let s = self.r + (0..n).map(|i| self.c[i] * pc[i]).sum::<f64>();
        (pc, s)
    }
    /// Posterior `x̂(k|k)`, `P(k|k)` for measurement `y` (not stored).
    pub fn posterior(&self, y: f64) -> (Vec<f64>, Vec<Vec<f64>>) {
        let n = self.n();
        let (pc, s) = self.pc();
        let e = y - self.predict_y();
        let x = (0..n).map(|i| self.x[i] + pc[i] * e / s).collect();
        let p = (0..n).map(|i| (0..n).map(|j| self.p[i][j] - pc[i] * pc[j] / s).collect()).collect();
        (x, p)
    }
    /// One literal step of eqs 12–14 with transition `phi` and noise `q`.
    pub fn step(&mut self, y: f64, phi: &[Vec<f64>], q: &[Vec<f64>]) {
        let n = self.n();
        let (pc, s) = self.pc();
        let k: Vec<f64> = (0..n).map(|i| (0..n).map(|j| phi[i][j] * pc[j]).sum::<f64>() / s).collect();
        let e = y - self.predict_y();
        let x_new: Vec<f64> = (0..n).map(|i| (0..n).map(|j| phi[i][j] * self.x[j]).sum::<f64>() + k[i] * e).collect();
        // (Φ − K C)
        let a: Vec<Vec<f64>> = (0..n).map(|i| (0..n).map(|j| phi[i][j] - k[i] * self.c[j]).collect()).collect();
        let ap: Vec<Vec<f64>> =
            (0..n).map(|i| (0..n).map(|j| (0..n).map(|m| a[i][m] * self.p[m][j]).sum()).collect()).collect();
        let p_new: Vec<Vec<f64>> = (0..n)
            .map(|i| (0..n).map(|j| q[i][j] + (0..n).map(|m| ap[i][m] * phi[j][m]).sum::<f64>()).collect())
            .collect();
        self.x = x_new;
        self.p = p_new;
    }
}

/// Block-diagonal `Φ` with blocks `[[cos a, sin a], [−sin a, cos a]]` (and 1 for a bias).
pub fn block_phi(increments: &[f64], bias: bool) -> Vec<Vec<f64>> {
    let n = 2 * increments.len() + usize::from(bias);
    let mut phi = vec![vec![0.0; n]; n];
    for (i, &a) in increments.iter().enumerate() {
        let (s, c) = a.sin_cos();
        phi[2 * i][2 * i] = c;
        phi[2 * i][2 * i + 1] = s;
        phi[2 * i + 1][2 * i] = -s;
        phi[2 * i + 1][2 * i + 1] = c;
    }
    if bias {
        phi[n - 1][n - 1] = 1.0;
    }
    phi
}

/// Whether a symmetric matrix is positive semi-definite up to `tol · trace`
/// (Cholesky with a small diagonal shift).
pub fn is_psd(p: &[Vec<f64>], tol: f64) -> bool {
    let n = p.len();
    let trace: f64 = (0..n).map(|i| p[i][i]).sum();
    if !trace.is_finite() {
        return false;
    }
    let shift = tol * trace.max(f64::MIN_POSITIVE);
    let mut l = vec![vec![0.0; n]; n];
    for i in 0..n {
        for j in 0..=i {
            let mut s = p[i][j] + if i == j { shift } else { 0.0 };
            for k in 0..j {
                s -= l[i][k] * l[j][k];
            }
            if i == j {
                if s.is_nan() || s <= 0.0 {
                    return false;
                }
                l[i][j] = s.sqrt();
            } else {
                l[i][j] = s / l[j][j];
            }
        }
    }
    true
}
