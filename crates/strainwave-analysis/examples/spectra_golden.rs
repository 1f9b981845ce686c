//! Golden data for the Python comparison tests (`python/tests/test_spectra_scipy.py`,
//! `python/tests/test_bench_scipy.py`): writes `spectra.json` (a deterministic two-channel
//! signal and this crate's Welch, CSD, H1, coherence, spectrogram and spectral combination
//! of it for several settings) and `models.json` (the Stoß et al. (2022) models' coefficients and
//! complex responses, the complementary filters' and the online corrected fusion's
//! coefficients) into the directory given.
//!
//! `cargo run -p strainwave-analysis --example spectra_golden -- target/golden`

use std::fmt::Write as _;
use std::path::PathBuf;

use strainwave_analysis::bench::{spectral_combination, to_complex};
use strainwave_analysis::frf::h1;
use strainwave_analysis::psd::{csd, welch, Detrend, Scaling, SpectralConfig, Window};
use strainwave_analysis::stft::spectrogram;
use strainwave_core::fusion::{
    AccelerometerModel, AccelerometerModelFull, ComplementaryFusion, CrossoverOrder, OnlineCorrectedFusion,
    OnlineCorrectionConfig, TorsionShaftModel,
};

const FS: f64 = 1000.0;
const N: usize = 5000;

/// Shortest round-trip text of every number, as a JSON array.
fn arr(v: &[f64]) -> String {
    let items: Vec<String> = v.iter().map(|x| format!("{x:e}")).collect();
    format!("[{}]", items.join(","))
}

/// Deterministic uniform noise in [−0.5, 0.5).
struct Lcg(u64);
impl Lcg {
    fn next(&mut self) -> f64 {
        self.0 = self.0.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (self.0 >> 11) as f64 / (1u64 << 53) as f64 - 0.5
    }
}

fn signals() -> (Vec<f64>, Vec<f64>) {
    let mut r = Lcg(2024);
    let tau = std::f64::consts::TAU;
    let x: Vec<f64> = (0..N)
        .map(|k| {
            let t = k as f64 / FS;
            r.next() + 0.8 * (tau * 50.0 * t).sin() + 0.3 * (tau * 123.4 * t + 0.2).cos() + 0.5 + 0.01 * k as f64 / FS
        })
        .collect();
    // y: a two-pole resonator driven by x, plus independent noise.
    let mut y = vec![0.0; N];
    for k in 0..N {
        let (y1, y2) = (if k > 0 { y[k - 1] } else { 0.0 }, if k > 1 { y[k - 2] } else { 0.0 });
        y[k] = 0.2 * x[k] + 1.6 * y1 - 0.81 * y2;
    }
    for v in y.iter_mut() {
        *v += 0.3 * r.next();
    }
    (x, y)
}

fn spectra_json() -> String {
    let (x, y) = signals();
    let mut cases = Vec::new();
    let configs: Vec<(&str, SpectralConfig)> = vec![
        ("hann-256-default", SpectralConfig::new(256)),
        ("hann-256-spectrum", SpectralConfig::new(256).with_noverlap(200).with_scaling(Scaling::Spectrum)),
        ("hann-255-odd", SpectralConfig::new(255).with_noverlap(100)),
        ("hann-200-nfft512", SpectralConfig::new(200).with_noverlap(50).with_nfft(512)),
        ("hann-301-nfft301-linear", SpectralConfig::new(301).with_noverlap(150).with_detrend(Detrend::Linear)),
        (
            "boxcar-128-none",
            SpectralConfig::new(128).with_noverlap(0).with_window(Window::Rectangular).with_detrend(Detrend::None),
        ),
    ];
    for (name, cfg) in &configs {
        let scaling = match cfg.scaling {
            Scaling::Density => "density",
            Scaling::Spectrum => "spectrum",
        };
        let detrend = match cfg.detrend {
            Detrend::None => "none",
            Detrend::Constant => "constant",
            Detrend::Linear => "linear",
        };
        let window = match cfg.window {
            Window::Rectangular => "boxcar",
            _ => "hann",
        };
        let p = welch(&x, FS, cfg).expect("welch");
        let c = csd(&x, &y, FS, cfg).expect("csd");
        let f = h1(&x, &y, FS, cfg).expect("h1");
        let mut spec_cfg = cfg.clone();
        if cfg.noverlap.is_none() {
            spec_cfg = spec_cfg.with_noverlap(cfg.nperseg / 8);
        }
        let s = spectrogram(&x, FS, &spec_cfg).expect("spectrogram");
        let sxx: Vec<String> = s.power.iter().map(|r| arr(r)).collect();
        let mut o = String::new();
        let _ = write!(
            o,
            "{{\"name\":\"{name}\",\"window\":\"{window}\",\"nperseg\":{},\"noverlap\":{},\"nfft\":{},\"spec_noverlap\":{},\
             \"scaling\":\"{scaling}\",\"detrend\":\"{detrend}\",\"freqs\":{},\"welch\":{},\"csd_re\":{},\"csd_im\":{},\
             \"h1_re\":{},\"h1_im\":{},\"coherence\":{},\"spec_freqs\":{},\"spec_times\":{},\"spec\":[{}]}}",
            cfg.nperseg,
            cfg.noverlap.map_or("null".to_string(), |v| v.to_string()),
            cfg.nfft.unwrap_or(cfg.nperseg),
            spec_cfg.noverlap.unwrap_or(0),
            arr(&p.freqs_hz),
            arr(&p.psd),
            arr(&c.csd.iter().map(|v| v.re).collect::<Vec<_>>()),
            arr(&c.csd.iter().map(|v| v.im).collect::<Vec<_>>()),
            arr(&f.h1.iter().map(|v| v.re).collect::<Vec<_>>()),
            arr(&f.h1.iter().map(|v| v.im).collect::<Vec<_>>()),
            arr(&f.coherence),
            arr(&s.freqs_hz),
            arr(&s.times_s),
            sxx.join(",")
        );
        cases.push(o);
    }
    let comb = spectral_combination(&x, &y, FS, 250.0).expect("spectral combination");
    format!(
        "{{\"fs\":{FS:e},\"x\":{},\"y\":{},\"crossover_hz\":250.0,\"combination\":{},\"cases\":[{}]}}",
        arr(&x),
        arr(&y),
        arr(&comb),
        cases.join(",")
    )
}

fn models_json() -> String {
    let ts = TorsionShaftModel::<f64>::kit();
    let acc = AccelerometerModel::<f64>::kit();
    let full = AccelerometerModelFull::<f64>::kit();
    let freqs: Vec<f64> = (0..=300).map(|i| 0.1 * 10f64.powf(i as f64 / 60.0)).collect();
    let resp = |g: &dyn Fn(f64) -> realfft::num_complex::Complex<f64>| {
        let v: Vec<_> = freqs.iter().map(|&f| g(f)).collect();
        format!(
            "{{\"re\":{},\"im\":{}}}",
            arr(&v.iter().map(|c| c.re).collect::<Vec<_>>()),
            arr(&v.iter().map(|c| c.im).collect::<Vec<_>>())
        )
    };
    let (ts_b, ts_a) = ts.coefficients();
    let (acc_b, acc_a) = acc.coefficients();
    let (full_b, full_a) = full.coefficients();
    let mut fusion = Vec::new();
    for (name, order) in [("first", CrossoverOrder::First), ("second", CrossoverOrder::Second)] {
        let f = ComplementaryFusion::<f64>::new(250.0, 20_000.0, order).expect("fusion");
        let lp = f.lowpass();
        fusion.push(format!("\"{name}\":{{\"b\":{},\"a\":[1.0,{:e},{:e}]}}", arr(&lp.b), lp.a[0], lp.a[1]));
    }
    // The online corrected fusion from Table I: its sections, torsion path then accelerometers.
    let cfg = OnlineCorrectionConfig::<f64>::kit();
    let online = OnlineCorrectedFusion::new(&ts, &acc, &cfg, 20_000.0).expect("online fusion");
    let sections = |qs: &[strainwave_core::iir::Biquad<f64>]| {
        let v: Vec<String> =
            qs.iter().map(|q| format!("{{\"b\":{},\"a\":[1.0,{:e},{:e}]}}", arr(&q.b), q.a[0], q.a[1])).collect();
        format!("[{}]", v.join(","))
    };
    fusion.push(format!(
        "\"online\":{{\"crossover_hz\":{:e},\"static_corner_hz\":{:e},\"torsion\":{},\"accel\":{}}}",
        cfg.crossover_hz,
        cfg.static_corner_hz,
        sections(online.torsion_sections()),
        sections(online.accel_sections())
    ));
    format!(
        "{{\"table_i\":{{\"J_B\":{:e},\"J_R\":{:e},\"J_S\":{:e},\"Gamma_LP\":{:e},\"k_TS\":{:e},\"k_Acc\":{:e},\"k_S\":{:e},\
         \"Gamma_LS\":{:e}}},\"freqs\":{},\"g_ts\":{{\"b\":{},\"a\":{},\"h\":{}}},\"g_acc\":{{\"b\":{},\"a\":{},\"h\":{}}},\
         \"g_acc_full\":{{\"b\":{},\"a\":{},\"h\":{}}},\"fusion\":{{\"crossover_hz\":250.0,\"fs\":20000.0,{}}}}}",
        ts.brake_inertia_kg_m2,
        ts.rotor_inertia_kg_m2,
        acc.stator_inertia_kg_m2,
        ts.damping_nm_s_per_rad,
        ts.stiffness_nm_per_rad,
        full.drive.stiffness_nm_per_rad,
        acc.coupling_stiffness_nm_per_rad,
        acc.stator_damping_nm_s_per_rad,
        arr(&freqs),
        arr(&ts_b),
        arr(&ts_a),
        resp(&|f| to_complex(ts.response(f))),
        arr(&acc_b),
        arr(&acc_a),
        resp(&|f| to_complex(acc.response(f))),
        arr(&full_b),
        arr(&full_a),
        resp(&|f| to_complex(full.response(f))),
        fusion.join(",")
    )
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let dir = PathBuf::from(std::env::args().nth(1).ok_or("usage: spectra_golden <output directory>")?);
    std::fs::create_dir_all(&dir)?;
    std::fs::write(dir.join("spectra.json"), spectra_json())?;
    std::fs::write(dir.join("models.json"), models_json())?;
    println!("wrote {}", dir.display());
    Ok(())
}
