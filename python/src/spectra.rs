//! Spectra of one signal: Welch's PSD, the STFT, and order slices against speed, with
//! the analysis crate's scipy conventions.

use numpy::{Complex64, PyArray1, PyArray2, PyReadonlyArray1};
use pyo3::prelude::*;
use strainwave_analysis::campbell::{order_slice, OrderSliceConfig};
use strainwave_analysis::psd::{welch, Detrend, Scaling, SpectralConfig, Window};
use strainwave_analysis::stft::stft;

use crate::error::StrainwaveError;

fn err(e: impl std::fmt::Display) -> PyErr {
    StrainwaveError::new_err(e.to_string())
}

/// The segmentation, window, detrending and scaling, from scipy's keyword names.
fn config(
    nperseg: usize,
    noverlap: Option<usize>,
    nfft: Option<usize>,
    window: Option<PyReadonlyArray1<'_, f64>>,
    detrend: &str,
    scaling: &str,
) -> PyResult<SpectralConfig> {
    let mut c = SpectralConfig::new(nperseg);
    c.noverlap = noverlap;
    c.nfft = nfft;
    if let Some(w) = window {
        c.window = Window::Custom(w.as_array().to_vec());
    }
    c.detrend = detrend.parse::<Detrend>().map_err(|e| err(format!("detrend: {e}")))?;
    c.scaling = scaling.parse::<Scaling>().map_err(|e| err(format!("scaling: {e}")))?;
    Ok(c)
}

/// A 1-D input as a vector (copied: the GIL is released while it is read).
fn samples(x: &PyReadonlyArray1<'_, f64>) -> Vec<f64> {
    x.as_array().to_vec()
}

/// What `welch_psd` returns: frequencies and PSD.
type Spectrum<'py> = (Bound<'py, PyArray1<f64>>, Bound<'py, PyArray1<f64>>);

/// Welch's averaged periodogram (scipy `welch`): frequencies (Hz) and PSD.
/// `window`: coefficients (`None`: periodic Hann).
#[pyfunction]
#[pyo3(signature = (x, sample_rate_hz, nperseg, *, noverlap=None, nfft=None, window=None, detrend=String::from("constant"), scaling=String::from("density")))]
#[allow(clippy::too_many_arguments)]
pub fn welch_psd<'py>(
    py: Python<'py>,
    x: PyReadonlyArray1<'py, f64>,
    sample_rate_hz: f64,
    nperseg: usize,
    noverlap: Option<usize>,
    nfft: Option<usize>,
    window: Option<PyReadonlyArray1<'py, f64>>,
    detrend: String,
    scaling: String,
) -> PyResult<Spectrum<'py>> {
    let cfg = config(nperseg, noverlap, nfft, window, &detrend, &scaling)?;
    let x = samples(&x);
    let p = py.detach(|| welch(&x, sample_rate_hz, &cfg)).map_err(err)?;
    Ok((PyArray1::from_vec(py, p.freqs_hz), PyArray1::from_vec(py, p.psd)))
}

/// What `stft_frames` returns: frequencies, segment centres and `frames[frame, bin]`.
type Frames<'py> = (Bound<'py, PyArray1<f64>>, Bound<'py, PyArray1<f64>>, Bound<'py, PyArray2<Complex64>>);

/// Amplitude-scaled complex STFT frames (`A cos(2π f t + φ)` on a bin reads `A e^{jφ'}`).
#[pyfunction]
#[pyo3(signature = (x, sample_rate_hz, nperseg, *, noverlap=None, nfft=None, window=None, detrend=String::from("constant")))]
#[allow(clippy::too_many_arguments)]
pub fn stft_frames<'py>(
    py: Python<'py>,
    x: PyReadonlyArray1<'py, f64>,
    sample_rate_hz: f64,
    nperseg: usize,
    noverlap: Option<usize>,
    nfft: Option<usize>,
    window: Option<PyReadonlyArray1<'py, f64>>,
    detrend: String,
) -> PyResult<Frames<'py>> {
    let cfg = config(nperseg, noverlap, nfft, window, &detrend, "density")?;
    let x = samples(&x);
    // Frames × bins complex values, bounded as a recording read whole is.
    let step = cfg.nperseg.saturating_sub(cfg.noverlap.unwrap_or(cfg.nperseg / 8)).max(1);
    let frames = x.len().saturating_sub(cfg.nperseg) / step + 1;
    let bins = cfg.nfft.unwrap_or(cfg.nperseg).max(cfg.nperseg) / 2 + 1;
    let values = (frames as u64).saturating_mul(2 * bins as u64);
    if values > strainwave_io::MAX_TABLE_VALUES {
        return Err(err(format!(
            "{frames} frames × {bins} bins is more than {} values (1 GiB) in memory: raise the hop \
             (nperseg − noverlap) or cut the signal",
            strainwave_io::MAX_TABLE_VALUES
        )));
    }
    let s = py.detach(|| stft(&x, sample_rate_hz, &cfg)).map_err(err)?;
    let bins = s.freqs_hz.len();
    let flat: Vec<Complex64> = s.frames.into_iter().flatten().collect();
    let frames = numpy::ndarray::Array2::from_shape_vec((s.times_s.len(), bins), flat).map_err(err)?;
    Ok((PyArray1::from_vec(py, s.freqs_hz), PyArray1::from_vec(py, s.times_s), PyArray2::from_owned_array(py, frames)))
}

/// What `order_slice_blocks` returns: block time (s), speed (rpm), amplitude, phase (rad).
type Slice<'py> = [Bound<'py, PyArray1<f64>>; 4];

/// One order's amplitude and phase per angle-domain block against speed.
#[pyfunction]
#[pyo3(signature = (signal, speed_rpm, sample_rate_hz, order, *, revs_per_block=8.0, initial_angle_rev=0.0))]
pub fn order_slice_blocks<'py>(
    py: Python<'py>,
    signal: PyReadonlyArray1<'py, f64>,
    speed_rpm: PyReadonlyArray1<'py, f64>,
    sample_rate_hz: f64,
    order: f64,
    revs_per_block: f64,
    initial_angle_rev: f64,
) -> PyResult<Slice<'py>> {
    let (x, v) = (samples(&signal), samples(&speed_rpm));
    let cfg = OrderSliceConfig { revs_per_block, initial_angle_rev };
    let s = py.detach(|| order_slice(&x, &v, sample_rate_hz, order, &cfg)).map_err(err)?;
    Ok([s.time_s, s.speed_rpm, s.amplitude, s.phase_rad].map(|c| PyArray1::from_vec(py, c)))
}
