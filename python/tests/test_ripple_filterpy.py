"""The core ripple filter against filterpy's KalmanFilter on the same Φ sequence, Q and R.

The Rust example `ripple_golden` writes the measurements, the phase increments that
make Φ(k), the process noise Q(k) and the core filter's predictions ŷ(k|k−1) and
innovation variances S(k). filterpy replays the same model with its dense textbook
algebra; they must agree to 1e-9. Skips when numpy, filterpy or cargo is missing.
Set STRAINWAVE_GOLDEN_CSV to use an existing file instead of running cargo.
"""

import math
import os
import pathlib
import shutil
import subprocess

import pytest

np = pytest.importorskip("numpy")
kalman = pytest.importorskip("filterpy.kalman")

ROOT = pathlib.Path(__file__).resolve().parents[2]
TOL = 1e-9


def golden_csv(tmp_path):
    given = os.environ.get("STRAINWAVE_GOLDEN_CSV")
    if given:
        return pathlib.Path(given)
    cargo = shutil.which("cargo")
    if cargo is None:
        pytest.skip("cargo not found")
    out = tmp_path / "ripple_golden.csv"
    subprocess.run(
        [cargo, "run", "--quiet", "-p", "strainwave-core", "--example", "ripple_golden", "--", str(out)],
        cwd=ROOT,
        check=True,
    )
    return out


def read(path):
    with open(path) as f:
        meta_line = f.readline()
        assert meta_line.startswith("#")
        meta = dict(item.split("=") for item in meta_line[1:].split())
        data = np.genfromtxt(f, delimiter=",", names=True)
    return {k: (float(v) if "." in v or "e" in v else int(v)) for k, v in meta.items()}, data


def block_rotation(increments, bias):
    n = 2 * len(increments) + (1 if bias else 0)
    f = np.zeros((n, n))
    for i, a in enumerate(increments):
        c, s = math.cos(a), math.sin(a)
        f[2 * i : 2 * i + 2, 2 * i : 2 * i + 2] = [[c, s], [-s, c]]
    if bias:
        f[n - 1, n - 1] = 1.0
    return f


def test_core_filter_matches_filterpy(tmp_path):
    meta, d = read(golden_csv(tmp_path))
    m, bias = meta["orders"], meta["bias"] == 1
    n = 2 * m + (1 if bias else 0)
    kf = kalman.KalmanFilter(dim_x=n, dim_z=1)
    kf.x = np.zeros((n, 1))
    kf.P = np.diag([meta["p0"]] * (2 * m) + ([meta["p0_bias"]] if bias else []))
    kf.H = np.array([[1.0 if (i % 2 == 0 or (bias and i == n - 1)) else 0.0 for i in range(n)]])
    kf.R = np.array([[meta["r_nm2"]]])
    rho = meta["inflation"]
    worst_y, worst_s = 0.0, 0.0
    for row in d:
        k = int(row["k"])
        if k > 0:
            inc = [row[f"inc{i}"] for i in range(m)]
            q = np.zeros((n, n))
            for i in range(m):
                # Q(k) includes the core's covariance inflation ρ (isotropic per block).
                grow = rho * 0.5 * (kf.P[2 * i, 2 * i] + kf.P[2 * i + 1, 2 * i + 1])
                q[2 * i, 2 * i] = q[2 * i + 1, 2 * i + 1] = row[f"q{i}"] + grow
            if bias:
                q[n - 1, n - 1] = row["q_bias"] + rho * kf.P[n - 1, n - 1]
            kf.F = block_rotation(inc, bias)
            kf.Q = q
            kf.predict()
        y_hat = float((kf.H @ kf.x)[0, 0])
        s = float((kf.H @ kf.P @ kf.H.T)[0, 0] + kf.R[0, 0])
        worst_y = max(worst_y, abs(y_hat - row["y_hat"]) / max(1.0, abs(y_hat)))
        worst_s = max(worst_s, abs(s - row["s"]) / max(1.0, abs(s)))
        kf.update(np.array([[row["y"]]]))
    assert len(d) == 3000
    assert worst_y < TOL, f"prediction differs by {worst_y}"
    assert worst_s < TOL, f"innovation variance differs by {worst_s}"
