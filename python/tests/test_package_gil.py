"""The package releases the GIL while Rust runs: a Python thread keeps running while
another thread filters a long recording (`filter_recording`, `RippleCanceller.run`)."""

import threading
import time

import pytest
from conftest import ROOT

np = pytest.importorskip("numpy")
pd = pytest.importorskip("pandas")
sw = pytest.importorskip("strainwave", reason="pip install ./python (./scripts/test-all does)")


CONFIG = ROOT / "examples" / "joint-taghirad-seed-6th.toml"


@pytest.fixture(scope="module")
def long_recording():
    one = sw.simulate("taghirad", duration=20, seed=5)
    # 30 copies end to end (time shifted), long enough that the Rust call takes a while.
    parts = []
    for k in range(30):
        p = one.copy()
        p["time"] = p["time"] + 20.0 * k
        parts.append(p)
    return pd.concat(parts, ignore_index=True)


@pytest.mark.parametrize("call", ["filter_recording", "RippleCanceller.run"])
def test_rust_calls_let_other_threads_run(long_recording, call):
    rec = long_recording
    span = {}

    def work():
        t0 = time.perf_counter()
        if call == "filter_recording":
            sw.filter_recording(rec, config=CONFIG)
        else:
            sw.RippleCanceller.from_config(CONFIG).run(rec)
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
    # With the GIL held for the whole Rust run, this thread would stall for about its length.
    assert gaps.max() < 0.5 * span["s"], f"longest stall {gaps.max():.3f} s of a {span['s']:.3f} s call"
    assert len(ticks) > 100
