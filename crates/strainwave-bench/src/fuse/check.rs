//! What `fuse` prints about flatness: the online corrected fusion's response on its own
//! model, and the fused torque against a reference column (H1, best delay ≤ 1 ms).

use std::fmt::Write as _;

use anyhow::{bail, Result};
use strainwave_analysis::bench::{to_complex, ResponseError};
use strainwave_analysis::frf::{h1, Frf};
use strainwave_analysis::psd::SpectralConfig;
use strainwave_core::fusion::{AccelerometerModel, OnlineCorrectedFusion, TorsionShaftModel};
use strainwave_core::iir::Complex;

/// Rows of the reference check kept (2²¹: 105 s at 20 kHz, 32 MiB).
pub const MAX_CHECK_ROWS: usize = 1 << 21;
/// Largest delay removed before the phase error is taken, s.
pub const MAX_DELAY_S: f64 = 1e-3;
/// Bins below this coherence are not counted.
pub const MIN_COHERENCE: f64 = 0.5;
/// Longest H1 segment (2¹⁵: 0.61 Hz bins at 20 kHz).
const MAX_NPERSEG: usize = 1 << 15;
/// The bands reported, Hz.
const BANDS_HZ: [(f64, f64); 2] = [(1.0, 2000.0), (1.0, 4000.0)];
/// Largest gain error of the online fusion on its own model, dB, beyond which the model
/// is refused: a sound model gives a fraction of a dB, so this is a model the inversion
/// cannot use (absurd dampings or inertias), whose fused torque would be far off.
pub const MAX_OWN_MODEL_ERROR_DB: f64 = 6.0;

/// The bands that fit below 0.45 fs.
fn bands(fs: f64) -> Vec<(f64, f64)> {
    BANDS_HZ.iter().map(|&(lo, hi)| (lo, hi.min(0.45 * fs))).filter(|(lo, hi)| hi > lo).collect()
}

fn line(lo: f64, hi: f64, e: &ResponseError) -> String {
    format!(
        "  {lo:.0}–{hi:.0} Hz: worst {:.2} dB (at {:.1} Hz) / {:.2}° (at {:.1} Hz) after a delay of {:.3} ms\n",
        e.max_gain_db,
        e.worst_gain_hz,
        e.max_phase_deg,
        e.worst_phase_hz,
        e.delay_s * 1e3
    )
}

/// The online fusion's response on the model it was designed from, per band; an error
/// if its gain is off by more than [`MAX_OWN_MODEL_ERROR_DB`] (or not finite) in a band.
pub fn design_summary(
    f: &OnlineCorrectedFusion<f64>,
    (ts, acc): (TorsionShaftModel<f64>, AccelerometerModel<f64>),
) -> Result<String> {
    let fs = f.sample_rate_hz();
    let top = 0.45 * fs;
    let freqs_hz: Vec<f64> = (0..=2000).map(|i| top.powf(i as f64 / 2000.0)).collect();
    let h: Vec<_> =
        freqs_hz.iter().map(|&fr| to_complex(f.fused_response(fr, ts.response(fr), acc.torque_response(fr)))).collect();
    let n = freqs_hz.len();
    let frf = Frf {
        freqs_hz,
        h1: h,
        coherence: vec![1.0; n],
        pxx: vec![1.0; n],
        pyy: vec![1.0; n],
        pxy: vec![to_complex(Complex::real(0.0)); n],
        segments: 1,
    };
    let mut s = format!(
        "online-corrected: crossover {} Hz, torsion resonance {:.1} Hz and housing resonance {:.2} Hz inverted; \
         response on its own model:\n",
        f.crossover_hz(),
        ts.resonance_hz(),
        acc.resonance_hz()
    );
    for (lo, hi) in bands(fs) {
        let e = ResponseError::with_best_delay(&frf, lo, hi, MIN_COHERENCE, MAX_DELAY_S)?;
        // NaN counts as off.
        if e.max_gain_db.is_nan() || e.max_gain_db > MAX_OWN_MODEL_ERROR_DB {
            bail!(
                "the online fusion designed from `[model]` is off by {:.2} dB at {:.1} Hz on that very model \
                 (at most {MAX_OWN_MODEL_ERROR_DB} dB from {lo:.0} to {hi:.0} Hz): check its dampings, stiffness and \
                 inertias, or use --method complementary",
                e.max_gain_db,
                e.worst_gain_hz
            );
        }
        s += &line(lo, hi, &e);
    }
    Ok(s)
}

/// Reference and fused samples, the first [`MAX_CHECK_ROWS`].
pub struct Check {
    fs: f64,
    reference: Vec<f64>,
    fused: Vec<f64>,
    rows: u64,
}

impl Check {
    /// An empty check at `fs`.
    pub fn new(fs: f64) -> Self {
        Self { fs, reference: Vec::new(), fused: Vec::new(), rows: 0 }
    }

    /// One row (kept while fewer than [`MAX_CHECK_ROWS`]).
    pub fn push(&mut self, reference: f64, fused: f64) {
        self.rows += 1;
        if self.reference.len() < MAX_CHECK_ROWS {
            self.reference.push(reference);
            self.fused.push(fused);
        }
    }

    /// The worst gain and phase error against the reference per band, or why there are
    /// none (a short or non-finite reference, no coherent bins): one text block.
    pub fn summary(&self, method: &str, reference: &str) -> String {
        let n = self.reference.len();
        let mut nperseg = MAX_NPERSEG;
        while nperseg > 256 && nperseg * 4 > n {
            nperseg /= 2;
        }
        let mut s = format!(
            "{method} against `{reference}` (H1 over {n} of {} rows, {nperseg}-sample segments, coherence ≥ {MIN_COHERENCE}, \
             best delay ≤ {} ms):\n",
            self.rows,
            MAX_DELAY_S * 1e3
        );
        if n < 2 * nperseg {
            let _ = writeln!(s, "  not measured: {n} rows, fewer than two {nperseg}-sample segments");
            return s;
        }
        let frf = match h1(&self.reference, &self.fused, self.fs, &SpectralConfig::new(nperseg)) {
            Ok(f) => f,
            Err(e) => {
                let _ = writeln!(s, "  not measured: {e}");
                return s;
            }
        };
        for (lo, hi) in bands(self.fs) {
            match ResponseError::with_best_delay(&frf, lo, hi, MIN_COHERENCE, MAX_DELAY_S) {
                Ok(e) => s += &line(lo, hi, &e),
                Err(e) => {
                    let _ = writeln!(s, "  {lo:.0}–{hi:.0} Hz: not measured: {e}");
                }
            }
        }
        s
    }
}
