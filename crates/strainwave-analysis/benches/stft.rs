//! STFT throughput against scipy on a 14-minute 20 kHz record (16.8 M samples), side by
//! side in one criterion group per transform:
//!
//! - `spectrogram`: [`spectrogram`] with the settings of `strainwave spectrogram` (periodic
//!   Hann, 4096-sample segments, 50 % overlap, constant detrend, density) against
//!   `scipy.signal.spectrogram(…, mode='psd')` with the same arguments;
//! - `stft`: [`stft`] (amplitude-scaled complex frames) against `scipy.signal.stft(…,
//!   detrend='constant', boundary=None, padded=False)`.
//!
//! The signal is written once to a temporary raw float64 file; scipy's entry runs
//! `python/bench/stft_scipy.py`, which loads it, runs the transform as many times as
//! criterion asks and reports its own elapsed time without the interpreter start and the
//! load, so both entries time the transform alone (single-threaded on both sides).
//! Before timing, one run of each side is compared (checksums to 1e-9 relative) so the
//! two entries compute the same thing. Without python3, numpy or scipy the scipy entries
//! are skipped with a message. `PYTHON` overrides the interpreter.
//!
//! Run: `cargo bench -p strainwave-analysis --bench stft`

use std::f64::consts::TAU;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Duration;

use criterion::{black_box, Criterion, SamplingMode, Throughput};
use strainwave_analysis::psd::SpectralConfig;
use strainwave_analysis::stft::{spectrogram, stft};

/// Sample rate, Hz.
const FS: f64 = 20_000.0;
/// 14 minutes at `FS`.
const SAMPLES: usize = 14 * 60 * 20_000;
/// `strainwave spectrogram`'s default segment; its overlap is half of it.
const NPERSEG: usize = 4096;
const NOVERLAP: usize = NPERSEG / 2;

/// A deterministic test-bench-like record: a logarithmic chirp 2 Hz → 8 kHz with its 2nd
/// and 3rd harmonics (aliased where above Nyquist), a 50 Hz line, an offset and
/// uniform noise from a fixed-seed xorshift generator.
fn signal() -> Vec<f64> {
    let duration = SAMPLES as f64 / FS;
    let (f0, f1) = (2.0_f64, 8000.0_f64);
    let rate = (f1 / f0).ln() / duration;
    let mut seed = 0x9E37_79B9_7F4A_7C15_u64;
    (0..SAMPLES)
        .map(|k| {
            let t = k as f64 / FS;
            // Phase of f(t) = f0 e^{rate t}.
            let phase = TAU * f0 * ((rate * t).exp() - 1.0) / rate;
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            let noise = (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5;
            0.3 + phase.sin()
                + 0.2 * (2.0 * phase).sin()
                + 0.05 * (3.0 * phase + 0.4).sin()
                + 0.1 * (TAU * 50.0 * t).sin()
                + 0.01 * noise
        })
        .collect()
}

fn config() -> SpectralConfig {
    SpectralConfig::new(NPERSEG).with_noverlap(NOVERLAP)
}

/// The scipy side: the interpreter, the helper script and the signal file.
struct Scipy {
    python: String,
    script: PathBuf,
    data: PathBuf,
}

/// What the helper reports.
struct ScipyRun {
    seconds: f64,
    checksum: f64,
    frames: usize,
}

impl Scipy {
    /// `None` (with the reason printed) when python3, numpy or scipy is not usable.
    fn new(data: &Path) -> Option<Self> {
        let python = std::env::var("PYTHON").unwrap_or_else(|_| "python3".into());
        let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../python/bench/stft_scipy.py");
        let probe = Command::new(&python).args(["-c", "import numpy, scipy.signal"]).output();
        match probe {
            Ok(o) if o.status.success() => Some(Self { python, script, data: data.to_path_buf() }),
            Ok(o) => {
                let err = String::from_utf8_lossy(&o.stderr);
                let last = err.trim_end().lines().last().unwrap_or("").to_string();
                eprintln!("stft bench: skipping the scipy entries: `{python}` cannot import numpy and scipy ({last})");
                None
            }
            Err(e) => {
                eprintln!("stft bench: skipping the scipy entries: cannot run `{python}` ({e})");
                None
            }
        }
    }

    fn run(&self, kind: &str, iterations: u64) -> Result<ScipyRun, String> {
        let o = Command::new(&self.python)
            .arg(&self.script)
            .arg(&self.data)
            .args([FS.to_string(), NPERSEG.to_string(), NOVERLAP.to_string(), kind.into(), iterations.to_string()])
            .output()
            .map_err(|e| format!("cannot run {}: {e}", self.python))?;
        if !o.status.success() {
            return Err(format!("stft_scipy.py failed: {}", String::from_utf8_lossy(&o.stderr).trim_end()));
        }
        let out = String::from_utf8_lossy(&o.stdout);
        let field = |name: &str| -> Result<f64, String> {
            let key = format!("\"{name}\": ");
            let start = out.find(&key).ok_or_else(|| format!("no `{name}` in `{out}`"))? + key.len();
            let rest = &out[start..];
            let end = rest.find([',', '}']).unwrap_or(rest.len());
            rest[..end].trim().parse().map_err(|e| format!("`{name}` in `{out}`: {e}"))
        };
        Ok(ScipyRun { seconds: field("seconds")?, checksum: field("checksum")?, frames: field("frames")? as usize })
    }
}

/// Σ of the spectrogram and Σ |frame| / one-sided factor of the STFT (scipy's scaling).
fn checksums(x: &[f64]) -> (f64, usize, f64) {
    let s = spectrogram(x, FS, &config()).expect("spectrogram");
    let sum_s = s.power.iter().flatten().sum::<f64>();
    let z = stft(x, FS, &config()).expect("stft");
    let last = z.freqs_hz.len() - 1;
    let sum_z = z
        .frames
        .iter()
        .flat_map(|f| f.iter().enumerate())
        .map(|(i, c)| if i == 0 || i == last { c.norm() } else { c.norm() / 2.0 })
        .sum::<f64>();
    (sum_s, s.times_s.len(), sum_z)
}

fn compare(what: &str, ours: f64, ours_frames: usize, theirs: &ScipyRun) {
    let rel = (ours - theirs.checksum).abs() / theirs.checksum.abs();
    let verdict = if rel <= 1e-9 && ours_frames == theirs.frames { "same" } else { "DIFFERENT" };
    eprintln!(
        "stft bench: {what}: {verdict} result as scipy ({ours_frames} vs {} frames, checksum relative difference {rel:.1e})",
        theirs.frames
    );
}

/// A temporary file, removed on drop (also when a benchmark panics).
struct TempFile(PathBuf);

impl Drop for TempFile {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.0);
    }
}

fn bench(c: &mut Criterion) {
    let x = signal();
    let data = TempFile(std::env::temp_dir().join(format!("strainwave-bench-stft-{}.f64", std::process::id())));
    let bytes: Vec<u8> = x.iter().flat_map(|v| v.to_le_bytes()).collect();
    std::fs::write(&data.0, bytes).expect("write the signal file");
    let mut scipy = Scipy::new(&data.0);

    // One run of each side: the same frames and values, or no scipy entries.
    if let Some(py) = &scipy {
        let (sum_s, frames, sum_z) = checksums(&x);
        match (py.run("spectrogram", 1), py.run("stft", 1)) {
            (Ok(s), Ok(z)) => {
                compare("spectrogram", sum_s, frames, &s);
                compare("stft", sum_z, frames, &z);
            }
            (Err(e), _) | (_, Err(e)) => {
                eprintln!("stft bench: skipping the scipy entries: {e}");
                scipy = None;
            }
        }
    }

    for kind in ["spectrogram", "stft"] {
        let mut group = c.benchmark_group(format!("{kind}/14min-20kHz"));
        group
            .throughput(Throughput::Elements(SAMPLES as u64))
            .sample_size(10)
            .sampling_mode(SamplingMode::Flat)
            .warm_up_time(Duration::from_secs(1))
            .measurement_time(Duration::from_secs(20));
        let cfg = config();
        group.bench_function("strainwave", |b| match kind {
            "spectrogram" => b.iter(|| black_box(spectrogram(black_box(&x), FS, &cfg).expect("spectrogram"))),
            _ => b.iter(|| black_box(stft(black_box(&x), FS, &cfg).expect("stft"))),
        });
        if let Some(py) = &scipy {
            group.bench_function("scipy", |b| {
                b.iter_custom(|iters| match py.run(kind, iters) {
                    Ok(r) => Duration::from_secs_f64(r.seconds),
                    Err(e) => panic!("{e}"),
                })
            });
        }
        group.finish();
    }
}

fn main() {
    let mut c = Criterion::default().configure_from_args();
    bench(&mut c);
    c.final_summary();
}
