//! Welch, CSD, spectrogram and H1 against naive references with a fixed seed: a direct
//! DFT of every segment (scipy's conventions written out), and the exact response of a
//! known filter.

use realfft::num_complex::Complex;
use strainwave_analysis::frf::h1;
use strainwave_analysis::psd::{csd, welch, Detrend, Scaling, SpectralConfig, Window};
use strainwave_analysis::stft::spectrogram;
use strainwave_core::iir::{Biquad, BiquadState};

/// Agreement of the FFT path with the direct DFT (relative to the largest value).
const REF_TOL: f64 = 1e-10;

fn noise(n: usize, seed: u64) -> Vec<f64> {
    let mut s = seed;
    (0..n)
        .map(|_| {
            s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        })
        .collect()
}

/// scipy's `_spectral_helper` written out with a direct DFT: per-segment one-sided
/// `conj(X) Y`, scaled, doubled, not averaged.
fn naive_segments(x: &[f64], y: &[f64], fs: f64, cfg: &SpectralConfig, noverlap: usize) -> Vec<Vec<Complex<f64>>> {
    let n = cfg.nperseg;
    let nfft = cfg.nfft.unwrap_or(n);
    let w = cfg.window.coefficients(n);
    let scale = match cfg.scaling {
        Scaling::Density => 1.0 / (fs * w.iter().map(|v| v * v).sum::<f64>()),
        Scaling::Spectrum => 1.0 / w.iter().sum::<f64>().powi(2),
    };
    let step = n - noverlap;
    let segs = (x.len() - n) / step + 1;
    let prep = |s: &[f64]| -> Vec<f64> {
        let m = s.iter().sum::<f64>() / n as f64;
        s.iter().zip(&w).map(|(v, w)| (v - if cfg.detrend == Detrend::Constant { m } else { 0.0 }) * w).collect()
    };
    (0..segs)
        .map(|k| {
            let (a, b) = (prep(&x[k * step..k * step + n]), prep(&y[k * step..k * step + n]));
            (0..=nfft / 2)
                .map(|f| {
                    let dft = |s: &[f64]| {
                        s.iter().enumerate().fold(Complex::new(0.0, 0.0), |acc, (i, v)| {
                            acc + Complex::from_polar(*v, -std::f64::consts::TAU * (f * i) as f64 / nfft as f64)
                        })
                    };
                    let two = if f == 0 || (nfft & 1 == 0 && f == nfft / 2) { 1.0 } else { 2.0 };
                    dft(&a).conj() * dft(&b) * scale * two
                })
                .collect()
        })
        .collect()
}

fn configs() -> Vec<SpectralConfig> {
    vec![
        SpectralConfig::new(64),
        SpectralConfig::new(63).with_noverlap(20).with_scaling(Scaling::Spectrum),
        SpectralConfig::new(50).with_noverlap(10).with_nfft(80),
        SpectralConfig::new(64).with_noverlap(0).with_window(Window::Rectangular).with_detrend(Detrend::None),
    ]
}

#[test]
fn welch_csd_and_spectrogram_match_direct_dft() {
    let (x, y) = (noise(700, 1), noise(700, 2));
    let fs = 250.0;
    for cfg in configs() {
        let nov = cfg.noverlap.unwrap_or(cfg.nperseg / 2);
        let segs = naive_segments(&x, &y, fs, &cfg, nov);
        let k = segs.len() as f64;
        let mean = |i: usize| segs.iter().map(|s| s[i]).fold(Complex::new(0.0, 0.0), |a, b| a + b) / k;
        let c = csd(&x, &y, fs, &cfg).unwrap();
        let top = c.csd.iter().map(|v| v.norm()).fold(0.0, f64::max);
        for (i, v) in c.csd.iter().enumerate() {
            assert!((v - mean(i)).norm() < REF_TOL * top, "{cfg:?} bin {i}");
        }
        let pxx = naive_segments(&x, &x, fs, &cfg, nov);
        let p = welch(&x, fs, &cfg).unwrap();
        let top = p.psd.iter().cloned().fold(0.0, f64::max);
        for (i, v) in p.psd.iter().enumerate() {
            let want = pxx.iter().map(|s| s[i].re).sum::<f64>() / pxx.len() as f64;
            assert!((v - want).abs() < REF_TOL * top, "{cfg:?} bin {i}");
        }
        let spec_cfg = cfg.clone().with_noverlap(nov);
        let s = spectrogram(&x, fs, &spec_cfg).unwrap();
        assert_eq!(s.power.len(), pxx.len());
        for (row, want) in s.power.iter().zip(&pxx) {
            for (a, b) in row.iter().zip(want) {
                assert!((a - b.re).abs() < REF_TOL * top * pxx.len() as f64);
            }
        }
        assert!((s.times_s[1] - s.times_s[0] - (cfg.nperseg - nov) as f64 / fs).abs() < 1e-12);
    }
}

#[test]
fn h1_recovers_a_known_filter() {
    let fs = 1000.0;
    let f = Biquad::lowpass(100.0, 2.0, fs).unwrap();
    let x = noise(1 << 16, 3);
    let mut st = BiquadState::default();
    let y: Vec<f64> = x.iter().map(|v| f.step(&mut st, *v)).collect();
    let est = h1(&x, &y, fs, &SpectralConfig::new(4096)).unwrap();
    for k in 1..est.freqs_hz.len() - 1 {
        let want = f.response(est.freqs_hz[k], fs);
        let want = Complex::new(want.re, want.im);
        // The bias of H1 is about the filter's delay over the segment length (a few
        // samples in 4096), the random error √((1 − γ²)/2K).
        let rel = (est.h1[k] - want).norm() / want.norm().max(1e-3);
        assert!(rel < 5e-3, "{} Hz: {rel}", est.freqs_hz[k]);
        // Where the output is > −30 dB, leakage from stronger bins is negligible.
        if want.norm() > 0.03 {
            assert!(est.coherence[k] > 0.999, "{} Hz: {}", est.freqs_hz[k], est.coherence[k]);
        }
    }
}
