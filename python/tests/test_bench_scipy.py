"""The Stoß et al. (2022) bench models of strainwave-core (G_TS, G_ACC simplified and full) and the
complementary fusion filters against scipy.signal on the same coefficients, and the
coefficients themselves against Table I by the paper's formulas (eqs. 1, 5, 6).

Golden data from the Rust example `spectra_golden`, run through cargo from the repository
root. Relative agreement 1e-9.
"""

import json
import math

import pytest

np = pytest.importorskip("numpy")
signal = pytest.importorskip("scipy.signal")

RTOL = 1e-9


@pytest.fixture(scope="module")
def models(spectra_golden):
    return json.loads((spectra_golden / "models.json").read_text())


def table_i_coefficients(t):
    jb, jr, js, g, kts, kacc, ks, gls = (t[k] for k in ("J_B", "J_R", "J_S", "Gamma_LP", "k_TS", "k_Acc", "k_S", "Gamma_LS"))
    ts = ([2 * jb * g, jb * kts], [jb * jr, 2 * g * (jb + jr), kts * (jb + jr)])
    acc = ([1.0, 0.0, 0.0], [js, gls, ks])
    full_b = [jb * jr, jb * g, kacc * (jb + jr), kacc * g, 0.0]
    full_a = np.polymul([jb * jr, 0.0, kacc * (jb + jr)], [js, g + gls, ks])
    return {"g_ts": ts, "g_acc": acc, "g_acc_full": (full_b, list(full_a))}


@pytest.mark.parametrize("name", ["g_ts", "g_acc", "g_acc_full"])
def test_model_coefficients_follow_the_paper(models, name):
    b, a = table_i_coefficients(models["table_i"])[name]
    np.testing.assert_allclose(models[name]["b"], b, rtol=RTOL, atol=0)
    np.testing.assert_allclose(models[name]["a"], a, rtol=RTOL, atol=0)


@pytest.mark.parametrize("name", ["g_ts", "g_acc", "g_acc_full"])
def test_model_response_matches_scipy_freqs(models, name):
    m = models[name]
    w = 2 * np.pi * np.array(models["freqs"])
    _, h = signal.freqs(m["b"], m["a"], worN=w)
    rust = np.array(m["h"]["re"]) + 1j * np.array(m["h"]["im"])
    err = np.abs(rust - h) / np.abs(h)
    assert np.max(err) < RTOL, (name, np.max(err), models["freqs"][int(np.argmax(err))])


def test_reference_numbers(models):
    t = models["table_i"]
    f_ts = math.sqrt(t["k_TS"] * (1 / t["J_B"] + 1 / t["J_R"])) / (2 * math.pi)
    f_acc = math.sqrt(t["k_S"] / t["J_S"]) / (2 * math.pi)
    assert abs(f_ts - 829.3) < 0.05 and abs(f_acc - 23.73) < 0.005
    b, a = models["g_ts"]["b"], models["g_ts"]["a"]
    assert abs(b[-1] / a[-1] - 0.905) < 5e-4


@pytest.mark.parametrize("order", ["first", "second"])
def test_fusion_lowpass_is_the_prewarped_bilinear_transform(models, order):
    fu = models["fusion"]
    fc, fs = fu["crossover_hz"], fu["fs"]
    if order == "first":
        w = 2 * np.pi * fc
        b_s, a_s = [w], [1.0, w]
    else:
        w = 2 * np.pi * fc / math.sqrt(2 + math.sqrt(5))
        b_s, a_s = [2 * w, w * w], [1.0, 2 * w, w * w]
    # Prewarp at the crossover: scipy's s = 2 fs' (z−1)/(z+1) with fs' = c/2.
    wc = 2 * np.pi * fc
    c = wc / math.tan(wc / (2 * fs))
    bz, az = signal.bilinear(b_s, a_s, fs=c / 2)
    bz = np.pad(bz, (0, 3 - len(bz)))
    az = np.pad(az, (0, 3 - len(az)))
    got = fu[order]
    np.testing.assert_allclose(got["a"], az, rtol=RTOL, atol=1e-15)
    np.testing.assert_allclose(got["b"], bz, rtol=1e-9, atol=1e-15)
    # Complementary at the crossover: |LP| = |HP| = |1 − LP|.
    _, h = signal.freqz(got["b"], got["a"], worN=[fc], fs=fs)
    assert abs(abs(h[0]) - abs(1 - h[0])) < 1e-9
