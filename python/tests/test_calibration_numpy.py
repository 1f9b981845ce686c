"""The series-elastic dead-weight calibration fixture: our line fit against numpy.polyfit.

The Rust example `calib_golden sea` writes the fixture rows (deflection, torque) and
our slope/intercept; numpy.polyfit on the same rows must agree to 1e-9 relative.
Runs cargo from the repository root (honours CARGO_TARGET_DIR); skips without numpy
or cargo.
"""

import pytest

np = pytest.importorskip("numpy")

REL_TOL = 1e-9


def test_series_elastic_fit_matches_polyfit(tmp_path, cargo_example):
    out = tmp_path / "sea.csv"
    cargo_example("strainwave-analysis", "calib_golden", "sea", out)
    deflection, torque, fit = [], [], None
    for line in out.read_text().splitlines():
        kind, *vals = line.split(",")
        if kind == "row":
            deflection.append(float(vals[0]))
            torque.append(float(vals[1]))
        elif kind == "fit":
            fit = (float(vals[0]), float(vals[1]))
    assert fit is not None and len(deflection) == 11
    slope, intercept = np.polyfit(np.array(deflection), np.array(torque), 1)
    assert abs(fit[0] - slope) <= REL_TOL * abs(slope), (fit[0], slope)
    assert abs(fit[1] - intercept) <= REL_TOL * abs(intercept), (fit[1], intercept)
    print(
        f"slope {fit[0]!r} vs {slope!r} (rel {abs(fit[0] - slope) / abs(slope):.2e}); "
        f"intercept {fit[1]!r} vs {intercept!r} (rel {abs(fit[1] - intercept) / abs(intercept):.2e})"
    )
