//! The online model-corrected fusion against the bench's true paths when its model is
//! wrong: shaft stiffness and the three inertias off by up to ±10 %, one at a time and all
//! corners of the box, for f32 and f64. It must stay stable (every pole inside the unit
//! circle, bounded output on a long bounded input) and degrade gracefully (a bounded gain
//! and phase error, far from the plain complementary filter's +20 dB at the resonance).
//! A property test designs it for any positive model: poles inside the unit circle.

use strainwave_core::fusion::{
    AccelerometerModel, ComplementaryFusion, OnlineCorrectedFusion, OnlineCorrectionConfig, TorsionShaftModel,
};
use strainwave_core::iir::Complex;
use strainwave_core::Real;

const FS: f64 = 20_000.0;
/// Nominal model: flat within this over 1 Hz … 4 kHz (dB, degrees).
const EXACT_TOL: (f64, f64) = (0.1, 0.5);
/// One parameter off by up to ±10 %: worst gain and phase error over 1 Hz … 4 kHz (dB, °).
const WRONG_TOL: (f64, f64) = (3.5, 25.0);
/// All four off by ±10 % at once (the corners of the box; `k` −10 % with `J_R` +10 % moves
/// the resonance by 9 %): the same, looser.
const CORNER_TOL: (f64, f64) = (12.0, 75.0);
/// Largest pole radius allowed (the slowest pole is the 0.05 Hz steady-torque corner).
const MAX_RADIUS: f64 = 1.0 - 1e-6;

/// Relative errors of the model: `(k, J_R, J_B, J_S)`.
type Errors = [f64; 4];

/// `(T_TS/T_e, T_acc/T_e)` at a frequency.
type PathPair<T> = (Complex<T>, Complex<T>);

/// One parameter at a time.
fn single_cases() -> Vec<Errors> {
    let mut v = Vec::new();
    for i in 0..4 {
        for e in [-0.1, -0.05, -0.02, 0.02, 0.05, 0.1] {
            let mut c = [0.0; 4];
            c[i] = e;
            v.push(c);
        }
    }
    v
}

/// All at once, ±10 %.
fn corner_cases() -> Vec<Errors> {
    (0..16).map(|corner: u32| core::array::from_fn(|i| if corner >> i & 1 == 1 { 0.1 } else { -0.1 })).collect()
}

/// The fusion designed from the model with `err`, and the true paths `h_ts`, `h_acc` the
/// fusion sees: the accelerometer torque is scaled by the model's `J_S` (`T_acc = J_S α`).
fn setup<T: Real>(err: Errors) -> (OnlineCorrectedFusion<T>, impl Fn(f64) -> PathPair<T>) {
    let (ts, acc) = (TorsionShaftModel::<f64>::kit(), AccelerometerModel::<f64>::kit());
    let m = TorsionShaftModel::new(
        T::from_f64(ts.rotor_inertia_kg_m2 * (1.0 + err[1])),
        T::from_f64(ts.brake_inertia_kg_m2 * (1.0 + err[2])),
        T::from_f64(ts.stiffness_nm_per_rad * (1.0 + err[0])),
        T::from_f64(ts.damping_nm_s_per_rad),
    )
    .unwrap();
    let js_model = acc.stator_inertia_kg_m2 * (1.0 + err[3]);
    let h = AccelerometerModel::new(
        T::from_f64(js_model),
        T::from_f64(acc.coupling_stiffness_nm_per_rad),
        T::from_f64(acc.stator_damping_nm_s_per_rad),
    )
    .unwrap();
    let f = OnlineCorrectedFusion::new(&m, &h, &OnlineCorrectionConfig::kit(), T::from_f64(FS)).unwrap();
    let paths = move |fr: f64| {
        let a = acc.response(fr).scale(js_model);
        let t = ts.response(fr);
        (Complex::new(T::from_f64(t.re), T::from_f64(t.im)), Complex::new(T::from_f64(a.re), T::from_f64(a.im)))
    };
    (f, paths)
}

/// Worst `|gain| dB` and `|phase| °` of the fused response over 1 Hz … 4 kHz.
fn worst<T: Real>(f: &OnlineCorrectedFusion<T>, paths: &impl Fn(f64) -> PathPair<T>) -> (f64, f64) {
    let (mut g, mut p) = (0.0_f64, 0.0_f64);
    let mut fr = 1.0;
    while fr <= 4000.0 {
        let (h_ts, h_acc) = paths(fr);
        let r = f.fused_response(T::from_f64(fr), h_ts, h_acc);
        let (re, im) = (r.re.to_f64(), r.im.to_f64());
        g = g.max((10.0 * (re * re + im * im).log10()).abs());
        p = p.max(im.atan2(re).to_degrees().abs());
        fr *= 1.005;
    }
    (g, p)
}

/// A bounded, broadband input: a log chirp 1 Hz … 9 kHz plus a pseudo-random ±1 sequence.
fn input(n: usize) -> impl Iterator<Item = (f64, f64)> {
    let mut s = 0x9e37_79b9_7f4a_7c15_u64;
    (0..n).map(move |k| {
        s = s.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1_442_695_040_888_963_407);
        let r = (s >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0;
        let t = k as f64 / FS;
        let dur = n as f64 / FS;
        let l = 9000f64.ln();
        let chirp = (std::f64::consts::TAU * dur / l * ((l * t / dur).exp() - 1.0)).sin();
        (chirp, 0.5 * chirp + 0.5 * r)
    })
}

fn robustness<T: Real>(cases: &[Errors], tol: (f64, f64)) -> (f64, f64) {
    let (mut g_all, mut p_all) = (0.0_f64, 0.0_f64);
    for &err in cases {
        let (f, paths) = setup::<T>(err);
        assert!(f.max_pole_radius() < MAX_RADIUS, "{err:?}: pole radius {}", f.max_pole_radius());
        let (g, p) = worst(&f, &paths);
        assert!(g < tol.0 && p < tol.1, "{err:?}: {g:.2} dB {p:.1}°");
        g_all = g_all.max(g);
        p_all = p_all.max(p);
        // Bounded input, bounded output: the gains of the two paths bound the output.
        let mut st = Default::default();
        let mut peak = 0.0_f64;
        for (t, a) in input(100_000) {
            let y = f.step(&mut st, T::from_f64(t), T::from_f64(a)).to_f64();
            assert!(y.is_finite(), "{err:?}");
            peak = peak.max(y.abs());
        }
        assert!(peak < 20.0, "{err:?}: peak {peak}");
    }
    (g_all, p_all)
}

#[test]
fn wrong_model_stays_stable_and_degrades_gracefully() {
    let (g64, p64) = robustness::<f64>(&single_cases(), WRONG_TOL);
    let (g32, p32) = robustness::<f32>(&single_cases(), WRONG_TOL);
    println!("worst, one parameter off by ≤ ±10 %: f64 {g64:.2} dB {p64:.1}°, f32 {g32:.2} dB {p32:.1}°");
    let (gc, pc) = robustness::<f64>(&corner_cases(), CORNER_TOL);
    let (gc32, pc32) = robustness::<f32>(&corner_cases(), CORNER_TOL);
    println!("worst, all four off by ±10 %: f64 {gc:.2} dB {pc:.1}°, f32 {gc32:.2} dB {pc32:.1}°");
    // The plain complementary filter with the exact model, for scale.
    let plain = ComplementaryFusion::<f64>::kit(FS).unwrap();
    let ts = TorsionShaftModel::<f64>::kit();
    let (lp, hp) = plain.responses(ts.resonance_hz());
    let r = lp * ts.response(ts.resonance_hz()) + hp * AccelerometerModel::kit().torque_response(ts.resonance_hz());
    assert!(20.0 * r.norm().log10() > 3.0 * g64.max(g32), "{r:?}");
}

#[test]
fn exact_model_is_flat_for_both_scalars() {
    let (f64_g, f64_p) = {
        let (f, paths) = setup::<f64>([0.0; 4]);
        worst(&f, &paths)
    };
    let (f32_g, f32_p) = {
        let (f, paths) = setup::<f32>([0.0; 4]);
        worst(&f, &paths)
    };
    for (g, p) in [(f64_g, f64_p), (f32_g, f32_p)] {
        assert!(g < EXACT_TOL.0 && p < EXACT_TOL.1, "{g} dB {p}°");
    }
}

/// The f32 filter follows the f64 one sample by sample on the same input.
#[test]
fn f32_tracks_f64() {
    let (f64f, _) = setup::<f64>([0.0; 4]);
    let (f32f, _) = setup::<f32>([0.0; 4]);
    let (mut s64, mut s32) = (Default::default(), Default::default());
    let mut worst = 0.0_f64;
    let mut peak = 0.0_f64;
    for (t, a) in input(200_000) {
        let y64 = f64f.step(&mut s64, t, a);
        let y32 = f32f.step(&mut s32, t as f32, a as f32) as f64;
        worst = worst.max((y64 - y32).abs());
        peak = peak.max(y64.abs());
    }
    assert!(worst < 1e-3 * peak, "{worst} of {peak}");
}

/// Constant inputs from a settled state: the output is the steady torque, the shaft's.
#[test]
fn settled_state_starts_without_transient() {
    let (f, _) = setup::<f64>([0.0; 4]);
    let mut st = f.settled_state(0.08, 0.0);
    for _ in 0..1000 {
        assert!((f.step(&mut st, 0.08, 0.0) - 0.08).abs() < 1e-9);
    }
    let mut st2 = st;
    assert!(f.try_step(&mut st2, f64::NAN, 0.0).is_err());
    assert_eq!(st, st2);
}

/// Any positive model and any crossover below 0.45 fs: the design either fails with an
/// error or has every pole inside the unit circle and a finite output, f32 and f64.
fn any_model<T: Real>(p: &[f64; 8], ratio: f64, xs: &[f64]) {
    let [jr, jb, k, g, js, ks, gs, fs] = *p;
    let ts = TorsionShaftModel::new(T::from_f64(jr), T::from_f64(jb), T::from_f64(k), T::from_f64(g));
    let acc = AccelerometerModel::new(T::from_f64(js), T::from_f64(ks), T::from_f64(gs));
    let (Ok(ts), Ok(acc)) = (ts, acc) else { return };
    let cfg = OnlineCorrectionConfig { crossover_hz: T::from_f64(ratio * fs), static_corner_hz: T::from_f64(0.05) };
    let Ok(f) = OnlineCorrectedFusion::new(&ts, &acc, &cfg, T::from_f64(fs)) else { return };
    assert!(f.max_pole_radius() < 1.0, "{p:?} {ratio}: {}", f.max_pole_radius());
    let mut st = f.settled_state(T::from_f64(xs[0]), T::from_f64(-xs[0]));
    for &x in xs {
        let y = f.step(&mut st, T::from_f64(x), T::from_f64(-0.5 * x));
        assert!(y.is_finite(), "{p:?} {ratio}");
    }
}

proptest::proptest! {
    #![proptest_config(proptest::prelude::ProptestConfig::with_cases(64))]
    #[test]
    fn any_positive_model_is_stable(
        jr in 1e-7f64..1e-1, jb in 1e-7f64..1e-1, k in 1.0f64..1e5, g in 0.0f64..1e-1,
        js in 1e-6f64..1.0, ks in 0.1f64..1e4, gs in 0.0f64..1.0, fs in 1e3f64..1e5,
        ratio in 1e-3f64..0.44,
        xs in proptest::collection::vec(-1.0f64..1.0, 1..300),
    ) {
        let p = [jr, jb, k, g, js, ks, gs, fs];
        any_model::<f64>(&p, ratio, &xs);
        any_model::<f32>(&p, ratio, &xs);
    }
}
