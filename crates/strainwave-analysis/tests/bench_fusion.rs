//! The offline fusion methods on signals whose paths are exactly the paper's models: a
//! multisine "true torque" from 2 Hz to 4 kHz is filtered (periodically, in the frequency
//! domain) by `G_TS` and `J_S G_ACC`; each method must give back the true torque.

use std::f64::consts::TAU;

use realfft::num_complex::Complex;
use realfft::RealFftPlanner;
use strainwave_analysis::bench::{
    complementary, spectral_combination, to_complex, CorrectedFusion, CorrectionConfig, CrossoverBand,
};
use strainwave_analysis::fir::SampledResponse;
use strainwave_core::fusion::{AccelerometerModel, ComplementaryFusion, CrossoverOrder, TorsionShaftModel};

const FS: f64 = 20_000.0;
const N: usize = 1 << 17;
/// FIR taps of the corrected fusion; its half-length is cut from both ends of the check.
const TAPS: usize = 8191;

/// A periodic multisine on exact bins: ~60 lines log-spaced over 2 Hz … 4 kHz.
fn truth() -> Vec<f64> {
    let df = FS / N as f64;
    let mut bins: Vec<usize> = (0..60).map(|i| (2.0 * 2000f64.powf(i as f64 / 59.0) / df).round() as usize).collect();
    bins.dedup();
    (0..N)
        .map(|n| {
            bins.iter().enumerate().map(|(i, &k)| 1e-3 * (TAU * (k * n) as f64 / N as f64 + 0.7 * i as f64).cos()).sum()
        })
        .collect()
}

/// `x` filtered by `h(f)` periodically.
fn filter(x: &[f64], h: impl Fn(f64) -> Complex<f64>) -> Vec<f64> {
    let mut p = RealFftPlanner::<f64>::new();
    let (fwd, inv) = (p.plan_fft_forward(N), p.plan_fft_inverse(N));
    let mut a = x.to_vec();
    let mut s = fwd.make_output_vec();
    fwd.process(&mut a, &mut s).unwrap();
    for (k, v) in s.iter_mut().enumerate() {
        *v *= h(k as f64 * FS / N as f64) / N as f64;
    }
    s[0].im = 0.0;
    let last = s.len() - 1;
    s[last].im = 0.0;
    let mut out = inv.make_output_vec();
    inv.process(&mut s, &mut out).unwrap();
    out
}

fn rms_error(y: &[f64], t: &[f64]) -> f64 {
    let cut = TAPS;
    let (mut e, mut r) = (0.0, 0.0);
    for i in cut..N - cut {
        e += (y[i] - t[i]).powi(2);
        r += t[i].powi(2);
    }
    (e / r).sqrt()
}

#[test]
fn methods_on_model_paths() {
    let (ts, acc) = (TorsionShaftModel::<f64>::kit(), AccelerometerModel::<f64>::kit());
    let h_ts = |f: f64| to_complex(ts.response(f));
    let h_acc = |f: f64| to_complex(acc.torque_response(f));
    let t = truth();
    let t_ts = filter(&t, h_ts);
    let t_acc = filter(&t, h_acc);

    // Corrected fusion from the models: the true torque within 1 %.
    let fused = CorrectedFusion::design(h_ts, h_acc, FS, &CorrectionConfig::new(TAPS)).unwrap();
    let e_corr = rms_error(&fused.apply(&t_ts, &t_acc).unwrap(), &t);
    assert!(e_corr < 0.01, "corrected: {e_corr}");

    // The same from sampled responses (as an H1 estimate gives them): 1/3-octave-ish
    // samples are enough for these smooth paths.
    let grid: Vec<f64> = (0..400).map(|i| 0.5 * 1.03f64.powi(i)).filter(|f| *f < 9000.0).collect();
    let s_ts = SampledResponse::from_fn(grid.clone(), h_ts).unwrap();
    let s_acc = SampledResponse::from_fn(grid, h_acc).unwrap();
    let fused2 = CorrectedFusion::design(|f| s_ts.at(f), |f| s_acc.at(f), FS, &CorrectionConfig::new(TAPS)).unwrap();
    let e_sampled = rms_error(&fused2.apply(&t_ts, &t_acc).unwrap(), &t);
    assert!(e_sampled < 0.02, "corrected from samples: {e_sampled}");

    // The paper's spectral combination keeps G_TS(0) = 0.905 below the crossover: ≈ 10 %.
    let e_spec = rms_error(&spectral_combination(&t_ts, &t_acc, FS, 250.0).unwrap(), &t);
    assert!(e_spec > 0.03 && e_spec < 0.12, "spectral: {e_spec}");

    // Plain complementary filters let the torsion resonance through.
    for order in [CrossoverOrder::First, CrossoverOrder::Second] {
        let f = ComplementaryFusion::new(250.0, FS, order).unwrap();
        let e = rms_error(&complementary(&t_ts, &t_acc, &f).unwrap(), &t);
        assert!(e > 5.0 * e_corr.max(0.01), "{order:?}: {e}");
    }
}

#[test]
fn band_weights_are_complementary_and_designs_checked() {
    let b = CrossoverBand::new(200.0, 300.0).unwrap();
    for f in [0.0, 150.0, 200.0, 230.0, 250.0, 299.0, 300.0, 5000.0] {
        assert_eq!(b.lowpass_weight(f) + b.highpass_weight(f), 1.0);
    }
    assert!(CrossoverBand::new(300.0, 200.0).is_err());
    let one = |_: f64| Complex::new(1.0, 0.0);
    let mut cfg = CorrectionConfig::new(101);
    cfg.band = CrossoverBand::new(200.0, 20_000.0).unwrap();
    assert!(CorrectedFusion::design(one, one, FS, &cfg).is_err());
    assert!(CorrectedFusion::design(one, one, FS, &CorrectionConfig::new(100)).is_err());
}
