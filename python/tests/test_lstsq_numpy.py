"""Our Householder-QR least squares against numpy.linalg.lstsq on random problems.

Python writes well-conditioned random problems (fixed seed), the Rust example
`calib_golden lstsq` solves them, and the solutions must agree to 1e-10 relative.
Runs cargo from the repository root (honours CARGO_TARGET_DIR); skips without numpy
or cargo.
"""

import pytest

np = pytest.importorskip("numpy")

REL_TOL = 1e-10


def random_problems(rng, count):
    problems = []
    for k in range(count):
        n = 1 + k % 6
        m = n + 2 + (7 * k) % 40
        a = rng.standard_normal((m, n))
        # Mild column scaling, still well conditioned after equilibration.
        a *= 10.0 ** rng.uniform(-2, 2, size=n)
        b = rng.standard_normal(m)
        problems.append((a, b))
    return problems


def test_lstsq_matches_numpy(tmp_path, cargo_example):
    rng = np.random.default_rng(20240611)
    problems = random_problems(rng, 40)
    src = tmp_path / "problems.csv"
    dst = tmp_path / "solutions.csv"
    with src.open("w") as f:
        for a, b in problems:
            m, n = a.shape
            f.write(f"problem,{m},{n}\n")
            for i in range(m):
                f.write(",".join(repr(float(v)) for v in (*a[i], b[i])) + "\n")
    cargo_example("strainwave-analysis", "calib_golden", "lstsq", src, dst)
    rows = [line.split(",") for line in dst.read_text().splitlines() if line.strip()]
    assert len(rows) == len(problems)
    worst = 0.0
    for (a, b), row in zip(problems, rows):
        assert row[0] == "solution"
        ours = np.array([float(v) for v in row[1:-1]])
        ours_res = float(row[-1])
        ref, *_ = np.linalg.lstsq(a, b, rcond=None)
        assert np.linalg.cond(a) < 1e6
        rel = np.linalg.norm(ours - ref) / np.linalg.norm(ref)
        worst = max(worst, rel)
        assert rel < REL_TOL, (a.shape, rel)
        ref_res = np.linalg.norm(b - a @ ref)
        assert abs(ours_res - ref_res) <= REL_TOL * ref_res
    print(f"worst relative difference vs numpy.linalg.lstsq: {worst:.3e}")
