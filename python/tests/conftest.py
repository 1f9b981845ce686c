"""Shared by the comparison tests: running the project's Rust examples through cargo."""

import os
import shutil
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


def run_cargo_example(package, example, *args):
    """Runs `cargo run -p PACKAGE --example EXAMPLE -- ARGS` from the repository root
    (CARGO_TARGET_DIR honoured); skips without cargo, fails with cargo's stderr."""
    if shutil.which("cargo") is None:
        pytest.skip("cargo not found")
    cmd = ["cargo", "run", "--quiet", "-p", package, "--example", example, "--", *map(str, args)]
    res = subprocess.run(cmd, cwd=ROOT, env=os.environ.copy(), capture_output=True, text=True, timeout=1800)
    if res.returncode != 0:
        pytest.fail(f"cargo run --example {example} failed:\n{res.stderr}")
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
