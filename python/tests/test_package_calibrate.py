"""`strainwave.calibrate` against `strainwave calibrate` on the same recordings: the same
calibration file, byte for byte, and the same one-line errors."""

import pytest

np = pytest.importorskip("numpy")
pd = pytest.importorskip("pandas")
sw = pytest.importorskip("strainwave", reason="pip install ./python (./scripts/test-all does)")


@pytest.fixture(scope="module")
def locked(cli, tmp_path_factory):
    """The taghirad twin's locked wave generator procedure (8 experiments in one file)."""
    path = tmp_path_factory.mktemp("cal") / "locked.csv"
    res = cli("simulate", "--preset", "taghirad", "--procedure", "locked-wg", "--out", path, "--quiet")
    assert res.returncode == 0, res.stderr
    return path


def cli_error(res):
    assert res.returncode == 1, f"expected the command line to fail:\n{res.stderr}"
    lines = [l for l in res.stderr.splitlines() if l.startswith("error: ")]
    assert len(lines) == 1, res.stderr
    return lines[0][len("error: ") :]


@pytest.mark.parametrize(
    "model, extra, kwargs",
    [
        ("gain", [], {}),
        ("gain", ["--with-offset", "--full-scale", 50], dict(with_offset=True, full_scale=50)),
        ("static", [], {}),
        ("dynamic", [], {}),
    ],
    ids=["gain", "gain-offset", "static", "dynamic"],
)
def test_calibration_file_is_the_cli_file(cli, locked, tmp_path, model, extra, kwargs):
    out = tmp_path / "cli.toml"
    res = cli(
        "calibrate", "--in", locked, "--experiment-column", "experiment", "--reference", "reference_torque",
        "--sensor", "bridge_voltage", "--model", model, "--out", out, "--quiet", *extra,
    )
    assert res.returncode == 0, res.stderr
    rec = sw.read_recording(str(locked))
    mine = tmp_path / "py.toml"
    cal = sw.calibrate(
        rec, "reference_torque", "bridge_voltage", model=model, experiment_column="experiment", out=mine, **kwargs
    )
    assert cal["toml"] == out.read_text()
    assert mine.read_text() == out.read_text()
    assert cal["file"]["model"] == ("static" if model == "gain" and kwargs else model)


def test_two_inputs_are_two_experiments(cli, locked, tmp_path):
    rec = sw.read_recording(locked)
    paths = []
    for k in (2, 5):
        p = tmp_path / f"exp{k}.csv"
        sw.write_recording(rec[rec["experiment"] == k], p)
        paths.append(p)
    out = tmp_path / "cli.toml"
    res = cli("calibrate", "--in", paths[0], "--in", paths[1], "--reference", "reference_torque",
              "--sensor", "bridge_voltage", "--out", out, "--quiet")
    assert res.returncode == 0, res.stderr
    cal = sw.calibrate([sw.read_recording(str(p)) for p in paths], "reference_torque", "bridge_voltage")
    assert cal["toml"] == out.read_text()


def test_errors_are_the_cli_errors(cli, locked, tmp_path):
    base = ["calibrate", "--in", locked, "--reference", "reference_torque"]
    rec = sw.read_recording(str(locked))
    expected = cli_error(cli(*base, "--sensor", "bridge_volts"))
    assert "no column `bridge_volts`" in expected
    with pytest.raises(sw.StrainwaveError) as e:
        sw.calibrate(rec, "reference_torque", "bridge_volts")
    assert str(e.value) == expected
    expected = cli_error(cli(*base, "--sensor", "bridge_voltage", "--model", "speed-table"))
    with pytest.raises(sw.StrainwaveError) as e:
        sw.calibrate(rec, "reference_torque", "bridge_voltage", model="speed-table")
    assert str(e.value) == expected
    expected = cli_error(cli(*base, "--sensor", "bridge_voltage", "--model", "static", "--with-offset"))
    with pytest.raises(sw.StrainwaveError) as e:
        sw.calibrate(rec, "reference_torque", "bridge_voltage", model="static", with_offset=True)
    assert str(e.value) == expected
    bad = rec.copy()
    bad.loc[41, "bridge_voltage"] = np.nan
    path = tmp_path / "nan.csv"
    sw.write_recording(bad, path)
    expected = cli_error(cli("calibrate", "--in", path, "--reference", "reference_torque", "--sensor", "bridge_voltage"))
    assert "row 42" in expected
    with pytest.raises(sw.StrainwaveError) as e:
        sw.calibrate(sw.read_recording(str(path)), "reference_torque", "bridge_voltage")
    assert str(e.value) == expected
    # One glitched row, far beyond the column's range: refused, not fitted.
    bad = rec.copy()
    bad.loc[41, "reference_torque"] = 4e9
    path = tmp_path / "glitch.csv"
    sw.write_recording(bad, path)
    expected = cli_error(cli("calibrate", "--in", path, "--reference", "reference_torque", "--sensor", "bridge_voltage"))
    assert "row 42: `reference_torque` = 4000000000.0 is over 100 times" in expected
    with pytest.raises(sw.StrainwaveError) as e:
        sw.calibrate(sw.read_recording(str(path)), "reference_torque", "bridge_voltage")
    assert str(e.value) == expected
