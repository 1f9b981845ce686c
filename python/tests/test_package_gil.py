"""The package releases the GIL while Rust runs: a Python thread keeps running while
another thread filters a long recording (`filter_recording`, `RippleCanceller.run`)."""

import pytest
from conftest import ROOT, assert_lets_other_threads_run

np = pytest.importorskip("numpy")
pd = pytest.importorskip("pandas")
sw = pytest.importorskip("strainwave", reason="pip install ./python (./scripts/test-all does)")


CONFIG = ROOT / "examples" / "joint-taghirad-6th-order.toml"


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
    if call == "filter_recording":
        assert_lets_other_threads_run(lambda: sw.filter_recording(rec, config=CONFIG))
    else:
        assert_lets_other_threads_run(lambda: sw.RippleCanceller.from_config(CONFIG).run(rec))