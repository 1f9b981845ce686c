"""The online corrected fusion of strainwave-core, evaluated by scipy.signal: the fused
response of its sections (freqz) on the bench's continuous path models (freqs of G_TS and
J_S G_ACC built here from Table I) is flat over 1 Hz-4 kHz, and every pole of every
section lies inside the unit circle (numpy roots).

Golden data from the Rust example `spectra_golden` (models.json, "fusion" -> "online").
"""

import json

import pytest

np = pytest.importorskip("numpy")
signal = pytest.importorskip("scipy.signal")

FS = 20_000.0
# The uninverted shaft-damping zero and the steady-torque section: well inside these.
GAIN_TOL_DB = 0.1
PHASE_TOL_DEG = 0.5


@pytest.fixture(scope="module")
def models(spectra_golden):
    return json.loads((spectra_golden / "models.json").read_text())


def cascade(sections, f):
    h = np.ones(len(f), dtype=complex)
    for s in sections:
        _, hs = signal.freqz(s["b"], s["a"], worN=f, fs=FS)
        h *= hs
    return h


def test_online_fusion_is_flat_on_the_model_paths(models):
    t = models["table_i"]
    jb, jr, js, g, k, ks, gls = (t[x] for x in ("J_B", "J_R", "J_S", "Gamma_LP", "k_TS", "k_S", "Gamma_LS"))
    f = np.geomspace(1.0, 4000.0, 2000)
    w = 2 * np.pi * f
    _, g_ts = signal.freqs([2 * jb * g, jb * k], [jb * jr, 2 * g * (jb + jr), k * (jb + jr)], worN=w)
    _, g_acc = signal.freqs([js, 0.0, 0.0], [js, gls, ks], worN=w)
    on = models["fusion"]["online"]
    r = cascade(on["torsion"], f) * g_ts + cascade(on["accel"], f) * g_acc
    gain_db = np.abs(20 * np.log10(np.abs(r)))
    phase_deg = np.abs(np.degrees(np.angle(r)))
    assert gain_db.max() < GAIN_TOL_DB, (gain_db.max(), f[np.argmax(gain_db)])
    assert phase_deg.max() < PHASE_TOL_DEG, (phase_deg.max(), f[np.argmax(phase_deg)])
    # The plain second-order complementary filter on the same paths, for contrast.
    fu = models["fusion"]["second"]
    _, lp = signal.freqz(fu["b"], fu["a"], worN=f, fs=FS)
    plain = lp * g_ts + (1 - lp) * g_acc
    assert np.abs(20 * np.log10(np.abs(plain))).max() > 10.0


def test_online_fusion_poles_inside_unit_circle(models):
    on = models["fusion"]["online"]
    for s in on["torsion"] + on["accel"]:
        poles = np.roots(s["a"])
        assert np.all(np.abs(poles) < 1.0), (s, np.abs(poles))
