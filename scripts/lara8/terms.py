"""What each candidate term of the current-torque model adds out of sample (numpy).

Rebuilds `identify`'s linear pipeline for a LARA8 joint (kinematic error: mesh
harmonics of the motor angle, a direction term and a degree-15 slow trend fitted on the
training rows; then one least-squares solve of the current torque on the wind-up, its
zero and the friction columns) and scores it by the same 5-block holdout. It prints the
baseline beside `identify`'s own figure as a check, then the baseline plus one term at a
time. A term's free setting (a speed or a length) is chosen inside each training set by
an inner blocked cross-validation over its 4 blocks: the held-out block never picks it.

Usage: terms.py CONFIG.toml LOG.csv [CONFIG.toml LOG.csv ...]
"""

import csv
import sys
import tomllib

import numpy as np

BLOCKS = 5
SLOW_TREND_DEGREE = 15
EPS = 0.01  # the default smoothing speed of the sign, rad/s
SPAN = 4  # rate difference span, samples


def load(config, log):
    with open(config, "rb") as f:
        cfg = tomllib.load(f)
    enc, ch = cfg["encoders"], cfg["channels"]
    with open(log, newline="") as f:
        rows = list(csv.DictReader(f))
    col = lambda c: np.array([float(r[c]) for r in rows])
    rad = lambda c, off, cpr, d: d * (col(c) - off) * 2 * np.pi / cpr
    m = rad(ch["motor"], enc["motor_offset_counts"], enc["motor_counts_per_rev"], enc["motor_direction"])
    link = rad(ch["link"], enc["link_offset_counts"], enc["link_counts_per_rev"], enc["link_direction"])
    t = col(ch["time"])
    n_s = -cfg["gear"]["ratio"]  # circular spline fixed
    fs = (len(t) - 1) / (t[-1] - t[0])
    x = m / n_s  # the motor angle referred to the link
    v = np.zeros_like(x)
    a = np.zeros_like(x)
    v[SPAN:] = (x[SPAN:] - x[:-SPAN]) * fs / SPAN
    a[2 * SPAN :] = (v[2 * SPAN :] - v[SPAN:-SPAN]) * fs / SPAN
    return dict(m=m, link=link, torsion=link - m / n_s, y=col(ch["reference_torque"]), v=v, a=a, fs=fs,
                harmonics=cfg["kinematic"].get("mesh_harmonics", 4), name=ch["reference_torque"])


def kinematic_design(d):
    n = len(d["m"])
    cols = [np.ones(n)]
    for k in range(1, d["harmonics"] + 1):
        cols += [np.cos(k * d["m"]), np.sin(k * d["m"])]
    basis = len(cols)
    link = d["link"]
    lo, hi = np.maximum(np.arange(n) - 5, 0), np.minimum(np.arange(n) + 5, n - 1)
    speed = (link[hi] - link[lo]) / (hi - lo) * d["fs"]
    direction = np.where(np.abs(speed) < 0.02, 0.0, np.sign(speed))
    if np.any(direction != direction[0]):
        cols.append(direction)
    tt = np.linspace(-1, 1, n)
    p_prev, p = np.ones(n), tt
    for deg in range(1, SLOW_TREND_DEGREE + 1):
        cols.append(p)
        p_prev, p = p, ((2 * deg + 1) * tt * p - deg * p_prev) / (deg + 1)
    return np.column_stack(cols), basis


def windup(d, rows):
    """w = θ_k − θ_h with the kinematic error fitted on `rows`."""
    X, basis = d["kin"]
    c, *_ = np.linalg.lstsq(X[rows], d["torsion"][rows], rcond=None)
    return X[:, :basis] @ c[:basis] - d["torsion"]


def dahl(v, fs, length):
    """Presliding state z ∈ [−1, 1]: dz = (dx − |dx| z) / length (Dahl, 1968)."""
    z, out = 0.0, np.empty_like(v)
    for k, vk in enumerate(v):
        dx = vk / fs
        z = min(1.0, max(-1.0, z + (dx - abs(dx) * z) / length))
        out[k] = z
    return out


def columns(d, w, term, setting):
    """Regressors: wind-up, its zero, Coulomb, viscous, inertia, and the candidate
    term(s) (several joined by " + "; `setting` applies to the one that has one)."""
    one = np.ones_like(w)
    sign = np.tanh(d["v"] / EPS)
    cols = [w, one, sign, d["v"], d["a"]]
    for t in (term or "").split(" + "):
        if t == "smooth sign tanh(v/v_s)":
            cols[2] = np.tanh(d["v"] / setting)
        elif t == "Stribeck F_s e^-(v/v_s)^2":
            cols.append(sign * np.exp(-((d["v"] / setting) ** 2)))
        elif t == "cubic spring k3 w^3":
            cols.append(w**3)
        elif t == "position a cos θ, b sin θ":
            cols += [np.cos(d["link"]), np.sin(d["link"])]
        elif t == "position-dependent Coulomb":
            cols += [sign * np.cos(d["link"]), sign * np.sin(d["link"])]
        elif t == "presliding (Dahl) state":
            cols.append(d["dahl"][setting])
        elif t == "drift: linear in time":
            cols.append(np.linspace(-1, 1, len(w)))
    return cols


SETTINGS = {
    "smooth sign tanh(v/v_s)": [0.002, 0.005, 0.02, 0.05, 0.1, 0.2],
    "Stribeck F_s e^-(v/v_s)^2": [0.02, 0.05, 0.1, 0.2, 0.4],
    "presliding (Dahl) state": [1e-5, 3e-5, 1e-4, 3e-4, 1e-3],
}


def solve(X, train, y):
    """Least squares with each column scaled to unit RMS on the training rows (the
    wind-up's cube is ~1e-10 of the others)."""
    scale = np.sqrt(np.mean(X[train] ** 2, axis=0))
    scale[scale == 0] = 1.0
    c, *_ = np.linalg.lstsq(X[train] / scale, y[train], rcond=None)
    return c / scale


def fit_predict(d, term, setting, train, test):
    """Identify on `train`, predict `test`. μ|τ_link| is solved by re-linearising on the
    model's own link torque (4 rounds, as `identify` does)."""
    w = windup(d, train)
    cols = columns(d, w, term, setting)
    if term == "load-dependent μ|τ_link|":
        link = d["y"]
        for _ in range(5):
            X = np.column_stack(cols + [np.tanh(d["v"] / EPS) * np.abs(link)])
            c = solve(X, train, d["y"])
            link = c[0] * w + c[1]
        return X[test] @ c
    X = np.column_stack(cols)
    return X[test] @ solve(X, train, d["y"])


def blocks(rows, k):
    n = len(rows)
    return [rows[b * n // k : (b + 1) * n // k] for b in range(k)]


def holdout(d, term):
    n = len(d["y"])
    pred = np.empty(n)
    chosen = []
    for test in blocks(np.arange(n), BLOCKS):
        train = np.setdiff1d(np.arange(n), test)
        setting = None
        grid = next((g for t, g in SETTINGS.items() if term and t in term), None)
        if grid:
            # Inner blocked CV over the training set's own contiguous pieces.
            inner = blocks(train, BLOCKS - 1)
            sse = []
            for s in grid:
                e = 0.0
                for itest in inner:
                    itrain = np.setdiff1d(train, itest)
                    e += np.sum((fit_predict(d, term, s, itrain, itest) - d["y"][itest]) ** 2)
                sse.append(e)
            setting = grid[int(np.argmin(sse))]
            chosen.append(setting)
        pred[test] = fit_predict(d, term, setting, train, test)
    return pred, chosen


def score(pred, y):
    e = pred - y
    return 1 - np.sum(e**2) / np.sum((y - y.mean()) ** 2), np.sqrt(np.mean(e**2))


TERMS = [
    "smooth sign tanh(v/v_s)",
    "Stribeck F_s e^-(v/v_s)^2",
    "load-dependent μ|τ_link|",
    "cubic spring k3 w^3",
    "position a cos θ, b sin θ",
    "position-dependent Coulomb",
    "presliding (Dahl) state",
    "drift: linear in time",
]


def main():
    args = sys.argv[1:]
    joints = []
    for config, log in zip(args[::2], args[1::2]):
        d = load(config, log)
        d["kin"] = kinematic_design(d)
        d["dahl"] = {s: dahl(d["v"], d["fs"], s) for s in SETTINGS["presliding (Dahl) state"]}
        joints.append(d)
    results = {}
    for d in joints:
        base, _ = holdout(d, None)
        results[(d["name"], None)] = (score(base, d["y"]), [])
        print(f"{d['name']}: baseline (Coulomb, viscous, inertia) R² {score(base, d['y'])[0]:.4f}, "
              f"RMS {score(base, d['y'])[1]:.2f} N·m (identify --holdout {BLOCKS} prints the same)")
        for term in TERMS:
            pred, chosen = holdout(d, term)
            results[(d["name"], term)] = (score(pred, d["y"]), chosen)
    names = [d["name"] for d in joints]
    print()
    print("| term added to the baseline | " + " | ".join(f"{n} R² (RMS N·m)" for n in names)
          + " | setting per block (inner CV) | improves both |")
    print("|---|" + "---|" * len(names) + "---|---|")
    row = ["baseline: Coulomb tanh(v/0.01), viscous, inertia"]
    for n in names:
        (r2, rms), _ = results[(n, None)]
        row.append(f"{r2:.4f} ({rms:.2f})")
    print("| " + " | ".join(row) + " | | |")
    for term in TERMS:
        row = [term]
        better = True
        settings = []
        for n in names:
            (r2, rms), chosen = results[(n, term)]
            r2b = results[(n, None)][0][0]
            better &= r2 > r2b
            row.append(f"{r2:.4f} ({rms:.2f}), {r2 - r2b:+.4f}")
            if chosen:
                settings.append(f"{n.rsplit('_', 1)[-1]}: " + "/".join(f"{c:g}" for c in chosen))
        print("| " + " | ".join(row) + f" | {'; '.join(settings)} | {'yes' if better else 'no'} |")
    # Where the error lies: the out-of-sample residual per block, baseline and with the
    # Stribeck term (the one `identify` adopts), and the fitted coefficients on the whole log.
    print()
    for d in joints:
        n = len(d["y"])
        for term in (None, "Stribeck F_s e^-(v/v_s)^2"):
            pred, chosen = holdout(d, term)
            print(f"{d['name']}: out-of-sample residual (current torque - model) by block, {term or 'baseline'}:")
            for b, test in enumerate(blocks(np.arange(n), BLOCKS)):
                e = d["y"][test] - pred[test]
                print(f"    block {b + 1}: mean {e.mean():+7.2f} N·m, rms {np.sqrt(np.mean(e**2)):6.2f} N·m")
        rows = np.arange(n)
        w = windup(d, rows)
        X = np.column_stack(columns(d, w, "cubic spring k3 w^3", None))
        c = solve(X, rows, d["y"])
        print(f"{d['name']}: whole-log fit with the cubic term: k {c[0]:.4g} N·m/rad, k3 {c[-1]:.4g} N·m/rad³")
        for term in (None, "position a cos θ, b sin θ"):
            X = np.column_stack(columns(d, w, term, None))
            c = solve(X, rows, d["y"])
            print(f"{d['name']}: whole-log fit, {term or 'baseline'}: stiffness k {c[0]:.4g} N·m/rad")
    # Position alone, no torsion: how much of the current torque the pose predicts.
    print()
    for d in joints:
        n = len(d["y"])
        pred = np.empty(n)
        for test in blocks(np.arange(n), BLOCKS):
            train = np.setdiff1d(np.arange(n), test)
            X = np.column_stack([np.ones(n), np.cos(d["link"]), np.sin(d["link"])])
            c, *_ = np.linalg.lstsq(X[train], d["y"][train], rcond=None)
            pred[test] = X[test] @ c
        r2, rms = score(pred, d["y"])
        print(f"{d['name']}: the link angle alone (c + a cos θ + b sin θ, no encoders' torsion): "
              f"R² {r2:.4f}, RMS {rms:.2f} N·m out of sample")


if __name__ == "__main__":
    main()
