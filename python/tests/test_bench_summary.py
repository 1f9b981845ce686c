"""`scripts/bench-summary` on a made-up criterion folder: the figures it prints."""

import json
import os
import subprocess
import sys

from conftest import ROOT


def write_bench(root, directory, full_id, times, iters, slope, elements=None):
    d = root / "criterion" / directory / "new"
    d.mkdir(parents=True)
    meta = {"full_id": full_id, "throughput": {"Elements": elements} if elements else None}
    (d / "benchmark.json").write_text(json.dumps(meta))
    (d / "sample.json").write_text(json.dumps({"iters": iters, "times": times}))
    (d / "estimates.json").write_text(json.dumps({"mean": {"point_estimate": 1.0}, "slope": {"point_estimate": slope}}))


def run(target, *args):
    env = dict(os.environ, CARGO_TARGET_DIR=str(target))
    script = ROOT / "scripts" / "bench-summary"
    return subprocess.run([sys.executable, str(script), *args], env=env, capture_output=True, text=True)


def test_fastest_percentile_median_and_per_element(tmp_path):
    # Ten samples of 10 iterations: 10, 20, …, 100 ns per iteration.
    iters = [10.0] * 10
    times = [100.0 * k for k in range(10, 0, -1)]
    write_bench(tmp_path, "bank", "ripple/bank/x", times, iters, 55.0, elements=8)
    write_bench(tmp_path, "one", "ripple/one", [500.0, 300.0], [10.0, 10.0], 40.0)
    res = run(tmp_path, "bank")
    assert res.returncode == 0, res.stderr
    line = next(ln for ln in res.stdout.splitlines() if ln.startswith("ripple/bank/x"))
    figures = [float(v) for v in line.split("per element:")[0].split()[1:]]
    assert figures == [10.0, 20.0, 60.0, 55.0]
    per_element = [float(v) for v in line.split("per element:")[1].split()]
    assert per_element == [1.2, 2.5, 7.5, 6.9]
    assert "ripple/one" not in res.stdout


def test_speedup_against_each_sibling(tmp_path):
    # strainwave 10/20 ns, the dense filter 25/30 ns; one iteration per sample.
    write_bench(tmp_path, "sw", "ripple/6-state/f64/strainwave", [10.0, 20.0], [1.0, 1.0], 15.0)
    write_bench(tmp_path, "dense", "ripple/6-state/f64/nalgebra-dense", [25.0, 30.0], [1.0, 1.0], 30.0)
    write_bench(tmp_path, "alone", "ripple/4-state/f64/adskalman", [5.0], [1.0], 5.0)
    res = run(tmp_path, "ripple")
    assert res.returncode == 0, res.stderr
    lines = [ln for ln in res.stdout.splitlines() if ln.endswith("x") and "ripple/" in ln]
    assert len(lines) == 1, res.stdout
    name, *figures = lines[0].split()
    assert name == "ripple/6-state/f64/nalgebra-dense"
    # fastest 25/10, p10 25/10, median 30/20, slope 30/15.
    assert figures == ["2.50x", "2.50x", "1.50x", "2.00x"]


def test_no_results_is_an_error(tmp_path):
    res = run(tmp_path)
    assert res.returncode == 1
    assert "no criterion results" in res.stderr
