"""`sw.identify` and `sw.estimate` against `strainwave identify` and `strainwave estimate`:
the same model file and summary, the same estimated columns bit for bit, the same errors."""

import json

import pytest
from conftest import ROOT, assert_bitwise_equal, assert_frame_is_csv, assert_lets_other_threads_run, cli_error, read_csv_exact

np = pytest.importorskip("numpy")
pd = pytest.importorskip("pandas")
sw = pytest.importorskip("strainwave", reason="pip install ./python (./scripts/test-all does)")

CONFIG = ROOT / "examples" / "arm-hda.toml"


@pytest.fixture(scope="module")
def runs(cli, tmp_path_factory):
    """The HDA arm twin's no-load run (2 s), loaded run and step run, written by the CLI,
    and a copy of the arm config with a fixed kinematic order (cross-validation is slow
    in an unoptimized build and is not what is compared here)."""
    d = tmp_path_factory.mktemp("arm")
    out = {}
    for name, preset, duration in [("nl", "hda-arm-no-load", 2), ("ld", "hda-arm-loaded-hold", None), ("step", "hda-arm", None)]:
        out[name] = d / f"{name}.csv"
        args = ["simulate", "--preset", preset, "--quiet", "--out", out[name]]
        res = cli(*args, *(["--duration", duration] if duration else []))
        assert res.returncode == 0, res.stderr
    text = CONFIG.read_text()
    assert 'order = "cv"' in text and "# mesh_harmonics = 4" in text
    out["config"] = d / "arm-fixed.toml"
    out["config"].write_text(text.replace('order = "cv"', "order = 1").replace("# mesh_harmonics = 4", "mesh_harmonics = 2"))
    out["dir"] = d
    return out


def test_identify_from_files_writes_the_cli_model_and_summary(cli, runs, tmp_path):
    model, summary = tmp_path / "cli-model.toml", tmp_path / "cli-summary.json"
    res = cli("identify", "--config", runs["config"], "--no-load", runs["nl"], "--loaded", runs["ld"],
              "--out", model, "--summary-json", summary, "--quiet")
    assert res.returncode == 0, res.stderr
    py_model = tmp_path / "py-model.toml"
    found = sw.identify(runs["ld"], config=runs["config"], no_load=runs["nl"], out=py_model)
    assert py_model.read_bytes() == model.read_bytes()
    assert found.model_text == model.read_text()
    assert found.summary == json.loads(summary.read_text())
    assert found.summary["no_load"] == str(runs["nl"])
    assert found.model["kinematic"]["basis"] == "fourier"


def test_identify_and_estimate_from_dataframes_are_the_cli(cli, runs, tmp_path):
    model, summary = tmp_path / "cli-model.toml", tmp_path / "cli-summary.json"
    res = cli("identify", "--config", CONFIG, "--loaded", runs["ld"], "--out", model,
              "--summary-json", summary, "--quiet")
    assert res.returncode == 0, res.stderr
    # The frame read from the file is named by it, so the model's header and the summary
    # name the same run as the command line's.
    found = sw.identify(sw.read_recording(runs["ld"]), config=CONFIG)
    assert found.model_text == model.read_text()
    assert found.summary == json.loads(summary.read_text())
    assert any("not identifiable" in n for n in found.summary["kinematic"]["notes"])

    est = tmp_path / "cli-est.csv"
    res = cli("estimate", "--config", model, "--in", runs["step"], "--out", est, "--quiet")
    assert res.returncode == 0, res.stderr
    got = sw.estimate(sw.read_recording(runs["step"]), config=model)
    assert list(got.columns[-4:]) == ["torque", "torsion", "kinematic_error", "estimate_flags"]
    assert_frame_is_csv(got, est)
    # A file name gives the same frame.
    assert_frame_is_csv(sw.estimate(runs["step"], config=model), est)


def test_identify_errors_are_the_cli_errors(cli, runs, tmp_path):
    # A missing column.
    df = sw.read_recording(runs["ld"]).drop(columns=["link_counts"])
    bad = tmp_path / "no-link.csv"
    sw.write_recording(df, bad)
    expected = cli_error(cli("identify", "--config", CONFIG, "--loaded", bad, "--out", tmp_path / "m.toml"))
    assert "no column `link_counts` (channels.link)" in expected
    with pytest.raises(sw.StrainwaveError) as e:
        sw.identify(sw.read_recording(bad), config=CONFIG)
    assert str(e.value) == expected
    with pytest.raises(sw.StrainwaveError) as e:
        sw.identify(df, config=CONFIG, input_name=str(bad))
    assert str(e.value) == expected
    # A misspelt config key.
    cfg = tmp_path / "arm.toml"
    cfg.write_text(CONFIG.read_text().replace("rated_torque_nm = 40.0", "rated_torque_nm = 40.0\nrated_torqe_nm = 40.0"))
    expected = cli_error(cli("identify", "--config", cfg, "--loaded", runs["ld"], "--out", tmp_path / "m.toml"))
    assert "rated_torqe_nm" in expected
    with pytest.raises(sw.StrainwaveError) as e:
        sw.identify(runs["ld"], config=cfg)
    assert str(e.value) == expected


def test_estimate_errors_are_the_cli_errors(cli, runs, tmp_path):
    model = tmp_path / "model.toml"
    sw.identify(runs["ld"], config=CONFIG, out=model)
    # A missing encoder column.
    df = sw.read_recording(runs["step"]).drop(columns=["motor_counts"])
    bad = tmp_path / "no-motor.csv"
    sw.write_recording(df, bad)
    expected = cli_error(cli("estimate", "--config", model, "--in", bad, "--out", tmp_path / "e.csv"))
    assert "missing encoder column `motor_counts`" in expected
    with pytest.raises(sw.StrainwaveError) as e:
        sw.estimate(sw.read_recording(bad), config=model)
    assert str(e.value) == expected
    # An unknown key in the model file.
    edited = tmp_path / "edited.toml"
    edited.write_text(model.read_text().replace("[gear]", "[gear]\nratioo = 100.0"))
    expected = cli_error(cli("estimate", "--config", edited, "--in", runs["step"], "--out", tmp_path / "e.csv"))
    assert "ratioo" in expected
    with pytest.raises(sw.StrainwaveError) as e:
        sw.estimate(runs["step"], config=edited)
    assert str(e.value) == expected


def test_identify_lets_other_threads_run(runs):
    frame = sw.read_recording(runs["ld"])
    assert_lets_other_threads_run(lambda: sw.identify(frame, config=CONFIG))