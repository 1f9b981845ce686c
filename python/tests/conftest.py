"""Shared by the comparison tests: the project's Rust examples and `strainwave` binary through
cargo, and exact comparisons of recordings."""

import functools
import json
import os
import shutil
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


@functools.lru_cache(maxsize=None)
def cargo_executables():
    """{(kind, name): path} of the workspace's binaries and examples, from `cargo test
    --workspace --no-run` (CARGO_TARGET_DIR honoured): the units `cargo test --workspace`
    builds, so after it (as in ./scripts/test-all) nothing is rebuilt. (`cargo build` or
    `cargo run -p ...` would resolve other features and rebuild much of the workspace.)
    Skips without cargo, fails with cargo's stderr."""
    if shutil.which("cargo") is None:
        pytest.skip("cargo not found")
    res = subprocess.run(
        ["cargo", "test", "--quiet", "--workspace", "--no-run", "--message-format", "json"],
        cwd=ROOT, capture_output=True, text=True, timeout=3600,
    )
    if res.returncode != 0:
        pytest.fail(f"cargo test --workspace --no-run failed:\n{res.stderr}")
    found = {}
    for line in res.stdout.splitlines():
        msg = json.loads(line)
        kind = msg.get("target", {}).get("kind", [None])[0]
        if msg.get("reason") == "compiler-artifact" and msg.get("executable") and kind in ("bin", "example"):
            # A bin is listed twice (its test harness in deps/, then itself): keep the
            # one outside deps/.
            if kind == "example" or Path(msg["executable"]).parent.name != "deps":
                found[(kind, msg["target"]["name"])] = msg["executable"]
    return found


def cargo_executable(kind, name):
    """The path of binary or example `name` (see `cargo_executables`)."""
    exe = cargo_executables().get((kind, name))
    if exe is None:
        pytest.fail(f"cargo test --workspace --no-run built no {kind} `{name}`")
    return exe


def run_cargo_example(package, example, *args):
    """Runs the workspace's example EXAMPLE (of PACKAGE) with ARGS from the repository
    root; fails with its stderr."""
    cmd = [cargo_executable("example", example), *map(str, args)]
    res = subprocess.run(cmd, cwd=ROOT, env=os.environ.copy(), capture_output=True, text=True, timeout=1800)
    if res.returncode != 0:
        pytest.fail(f"example {example} of {package} failed:\n{res.stderr}")
    return res


@pytest.fixture(scope="session")
def cargo_example():
    """`run_cargo_example` as a fixture."""
    return run_cargo_example


@pytest.fixture(scope="session")
def spectra_golden(tmp_path_factory):
    """The folder `spectra_golden` writes (models.json, spectra.json), made once per session."""
    out = tmp_path_factory.mktemp("spectra_golden")
    run_cargo_example("strainwave-analysis", "spectra_golden", out)
    return out


@pytest.fixture(scope="session")
def cli():
    """The `strainwave` binary (see `cargo_executables`):
    a function running it with ARGS, returning the completed process (never raises).
    STRAINWAVE_BIN names an already built binary to use instead."""

    def runner(exe):
        def run(*args):
            return subprocess.run([exe, *map(str, args)], cwd=ROOT, capture_output=True, text=True, timeout=1800)

        return run

    if os.environ.get("STRAINWAVE_BIN"):
        return runner(os.environ["STRAINWAVE_BIN"])
    return runner(cargo_executable("bin", "strainwave"))


def read_csv_exact(path):
    """A CSV recording as (column names, float64 columns), parsed by Python's `float` (a
    correctly rounded parser, independent of the project's reader)."""
    import csv

    import numpy as np

    with open(path, newline="") as f:
        rows = csv.reader(f)
        names = next(rows)
        values = [[float(x) for x in r] for r in rows]
    data = np.array(values, dtype=np.float64).reshape(len(values), len(names))
    return names, [data[:, k].copy() for k in range(len(names))]


def assert_bitwise_equal(a, b, what):
    """Two float64 arrays equal bit for bit (NaN payloads aside: NaN where the other is NaN)."""
    import numpy as np

    a, b = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    assert a.shape == b.shape, f"{what}: shape {a.shape} != {b.shape}"
    nan = np.isnan(a)
    assert np.array_equal(nan, np.isnan(b)), f"{what}: NaN at different rows"
    same = a.view(np.uint64) == b.view(np.uint64)
    bad = np.flatnonzero(~same & ~nan)
    assert bad.size == 0, f"{what}: {bad.size} values differ, first at row {bad[0] + 1}: {a[bad[0]]!r} != {b[bad[0]]!r}"


def assert_lets_other_threads_run(call):
    """Runs `call()` on a second thread while this one keeps ticking, and fails when a tick
    waited for more than half the call: a call that holds the GIL for its whole Rust run
    would stall this thread for about its length."""
    import threading
    import time

    import numpy as np

    span = {}

    def work():
        t0 = time.perf_counter()
        call()
        span["s"] = time.perf_counter() - t0

    ticks = []
    t = threading.Thread(target=work)
    t.start()
    while t.is_alive():
        ticks.append(time.perf_counter())
        sum(range(200))
    t.join()
    gaps = np.diff(ticks)
    assert span["s"] > 0.05, f"the call took {span['s']:.3f} s, too short to tell"
    assert gaps.max() < 0.5 * span["s"], f"longest stall {gaps.max():.3f} s of a {span['s']:.3f} s call"
    assert len(ticks) > 100


def cli_error(res):
    """The one `error: ` line of a command that failed with exit 1, without its prefix."""
    assert res.returncode == 1, f"expected the command line to fail:\n{res.stderr}"
    lines = [l for l in res.stderr.splitlines() if l.startswith("error: ")]
    assert len(lines) == 1, res.stderr
    return lines[0][len("error: "):]


def assert_frame_is_csv(df, path):
    """`df` has the CSV file's columns, in order, with the same numbers bit for bit."""
    names, cols = read_csv_exact(path)
    assert list(df.columns) == names
    for n, c in zip(names, cols):
        assert_bitwise_equal(df[n].to_numpy(), c, f"{path.name} column {n}")
