"""Welch PSD, CSD, H1, coherence, spectrogram and the spectral combination of
strainwave-analysis against scipy.signal / numpy on the same input.

The Rust side is the example `spectra_golden` (crates/strainwave-analysis/examples), run
through cargo from the repository root (CARGO_TARGET_DIR is honoured by cargo). Every
value must agree to 1e-9 relative (plus an absolute floor of 1e-12 × the largest value,
for entries that are zero up to rounding).
"""

import json

import pytest

np = pytest.importorskip("numpy")
signal = pytest.importorskip("scipy.signal")

RTOL = 1e-9
ATOL_REL = 1e-12


@pytest.fixture(scope="module")
def spectra(spectra_golden):
    return json.loads((spectra_golden / "spectra.json").read_text())


def close(rust, ref):
    rust = np.asarray(rust, dtype=float)
    ref = np.asarray(ref, dtype=float)
    assert rust.shape == ref.shape, (rust.shape, ref.shape)
    np.testing.assert_allclose(rust, ref, rtol=RTOL, atol=ATOL_REL * np.max(np.abs(ref)))


def kwargs(case):
    return dict(
        fs=None,
        window=case["window"],
        nperseg=case["nperseg"],
        noverlap=case["noverlap"],
        nfft=case["nfft"],
        detrend=False if case["detrend"] == "none" else case["detrend"],
        scaling=case["scaling"],
    )


def cases(spectra):
    return [pytest.param(c, id=c["name"]) for c in spectra["cases"]]


def test_welch_matches_scipy(spectra):
    x = np.array(spectra["x"])
    for case in spectra["cases"]:
        kw = kwargs(case)
        kw["fs"] = spectra["fs"]
        f, p = signal.welch(x, **kw)
        close(case["freqs"], f)
        close(case["welch"], p)


def test_csd_h1_and_coherence_match_scipy(spectra):
    x, y = np.array(spectra["x"]), np.array(spectra["y"])
    for case in spectra["cases"]:
        kw = kwargs(case)
        kw["fs"] = spectra["fs"]
        _, pxy = signal.csd(x, y, **kw)
        close(case["csd_re"], pxy.real)
        close(case["csd_im"], pxy.imag)
        _, pxx = signal.welch(x, **kw)
        h = pxy / pxx
        close(case["h1_re"], h.real)
        close(case["h1_im"], h.imag)
        kw.pop("scaling")  # coherence does not depend on it
        _, coh = signal.coherence(x, y, **kw)
        close(case["coherence"], coh)


def test_spectrogram_matches_scipy(spectra):
    x = np.array(spectra["x"])
    for case in spectra["cases"]:
        kw = kwargs(case)
        kw["fs"] = spectra["fs"]
        kw["noverlap"] = case["spec_noverlap"]
        f, t, sxx = signal.spectrogram(x, mode="psd", **kw)
        close(case["spec_freqs"], f)
        close(case["spec_times"], t)
        close(np.array(case["spec"]).T, sxx)


def test_spectrogram_default_overlap_is_scipys(spectra):
    case = spectra["cases"][0]
    assert case["noverlap"] is None
    assert case["spec_noverlap"] == case["nperseg"] // 8


def test_spectral_combination_matches_numpy(spectra):
    x, y = np.array(spectra["x"]), np.array(spectra["y"])
    n = len(x)
    f = np.fft.rfftfreq(n, 1.0 / spectra["fs"])
    mix = np.where(f < spectra["crossover_hz"], np.fft.rfft(x), np.fft.rfft(y))
    close(spectra["combination"], np.fft.irfft(mix, n))
