"""`sw.fuse` against `strainwave fuse`: every method's fused torque bit for bit, the same
printed report, the same errors."""

import pytest
from conftest import ROOT, assert_bitwise_equal, assert_lets_other_threads_run, cli_error, read_csv_exact

np = pytest.importorskip("numpy")
pd = pytest.importorskip("pandas")
sw = pytest.importorskip("strainwave", reason="pip install ./python (./scripts/test-all does)")

CONFIG = ROOT / "examples" / "bench-kit.toml"


@pytest.fixture(scope="module")
def bench(cli, tmp_path_factory):
    """0.5 s of the KIT bench twin (20 kHz) written by `strainwave simulate`."""
    path = tmp_path_factory.mktemp("bench") / "kit.csv"
    res = cli("simulate", "--preset", "kit-bench", "--duration", 0.5, "--seed", 1, "--out", path, "--quiet")
    assert res.returncode == 0, res.stderr
    return path


@pytest.mark.parametrize("method", ["online-corrected", "complementary", "spectral", "corrected"])
def test_fuse_is_the_cli_bit_for_bit(cli, bench, tmp_path, method):
    out = tmp_path / "fused.csv"
    res = cli("fuse", "--config", CONFIG, "--in", bench, "--out", out, "--method", method,
              "--reference", "true_dut_torque")
    assert res.returncode == 0, res.stderr
    got = sw.fuse(sw.read_recording(bench), config=CONFIG, method=method, reference="true_dut_torque")
    names, cols = read_csv_exact(out)
    assert list(got.columns) == names and names[-1] == "fused_torque"
    for n, c in zip(names, cols):
        assert_bitwise_equal(got[n].to_numpy(), c, f"{method} column {n}")
    # What the command line prints (design response, check against the reference).
    assert got.attrs["strainwave_report"] == res.stdout
    assert f"{method} against `true_dut_torque`" in res.stdout


def test_fuse_takes_a_file_name(cli, bench, tmp_path):
    out = tmp_path / "fused.csv"
    res = cli("fuse", "--config", CONFIG, "--in", bench, "--out", out, "--method", "complementary")
    assert res.returncode == 0, res.stderr
    got = sw.fuse(bench, config=CONFIG, method="complementary")
    names, cols = read_csv_exact(out)
    assert_bitwise_equal(got["fused_torque"].to_numpy(), cols[names.index("fused_torque")], "fused_torque")


def test_fuse_errors_are_the_cli_errors(cli, bench, tmp_path):
    # A missing column, in a streaming and in an offline method.
    df = sw.read_recording(bench).drop(columns=["accel_2"])
    bad = tmp_path / "no-accel.csv"
    sw.write_recording(df, bad)
    for method in ["online-corrected", "spectral"]:
        expected = cli_error(cli("fuse", "--config", CONFIG, "--in", bad, "--out", tmp_path / "f.csv", "--method", method))
        assert expected.startswith(f"{bad}: no column `accel_2` (channels.accel_2); columns: time,"), expected
        with pytest.raises(sw.StrainwaveError) as e:
            sw.fuse(sw.read_recording(bad), config=CONFIG, method=method)
        assert str(e.value) == expected
    # A misspelt config key.
    cfg = tmp_path / "bench.toml"
    cfg.write_text(CONFIG.read_text().replace("radius_m = 0.6727", "radius_mm = 0.6727"))
    expected = cli_error(cli("fuse", "--config", cfg, "--in", bench, "--out", tmp_path / "f.csv"))
    assert "radius_mm" in expected
    with pytest.raises(sw.StrainwaveError) as e:
        sw.fuse(bench, config=cfg)
    assert str(e.value) == expected
    # A method the command line does not know.
    with pytest.raises(sw.StrainwaveError, match=r"^method: `hoka` is not one of online-corrected, complementary"):
        sw.fuse(bench, config=CONFIG, method="hoka")


def test_fuse_lets_other_threads_run(cli, tmp_path):
    # 3 s of the bench (60,000 rows), so that one call lasts long enough to tell.
    path = tmp_path / "kit-3s.csv"
    res = cli("simulate", "--preset", "kit-bench", "--duration", 3, "--seed", 1, "--out", path, "--quiet")
    assert res.returncode == 0, res.stderr
    frame = sw.read_recording(path)
    assert_lets_other_threads_run(lambda: sw.fuse(frame, config=CONFIG, method="corrected"))