"""The `strainwave` Python package against the `strainwave` command line: the same
recordings read, the same twin, the same filter outputs bit for bit, the same errors."""

import numpy as np
import pytest
from conftest import ROOT, assert_bitwise_equal, assert_frame_is_csv, cli_error, read_csv_exact

np = pytest.importorskip("numpy")
pd = pytest.importorskip("pandas")
sw = pytest.importorskip("strainwave", reason="pip install ./python (./scripts/test-all does)")

CONFIG = ROOT / "examples" / "joint-taghirad.toml"


@pytest.fixture(scope="module")
def recording(cli, tmp_path_factory):
    """4 s of the taghirad twin written by `strainwave simulate`."""
    path = tmp_path_factory.mktemp("rec") / "taghirad.csv"
    res = cli("simulate", "--preset", "taghirad", "--duration", 4, "--seed", 3, "--out", path, "--quiet")
    assert res.returncode == 0, res.stderr
    return path


def test_read_recording_gives_the_file_exactly(recording):
    df = sw.read_recording(recording)
    assert len(df) == 4000
    assert_frame_is_csv(df, recording)
    assert all(df[c].dtype == np.float64 for c in df.columns)


def test_read_recording_parquet_matches_csv(cli, recording, tmp_path):
    pq = tmp_path / "taghirad.parquet"
    res = cli("convert", "--in", recording, "--out", pq)
    if res.returncode != 0:
        pytest.skip(f"strainwave convert to Parquet: {res.stderr.strip()}")
    a, b = sw.read_recording(recording), sw.read_recording(pq)
    assert list(a.columns) == list(b.columns)
    for c in a.columns:
        assert_bitwise_equal(a[c], b[c], f"parquet column {c}")


def test_simulate_is_the_cli_twin(cli, tmp_path):
    path = tmp_path / "sim.csv"
    res = cli("simulate", "--preset", "flexspline-fixed", "--duration", 1.5, "--seed", 7, "--out", path, "--quiet")
    assert res.returncode == 0, res.stderr
    assert_frame_is_csv(sw.simulate("flexspline-fixed", duration=1.5, seed=7), path)


@pytest.mark.parametrize("smooth", [False, True], ids=["stream", "smooth"])
@pytest.mark.parametrize("config", ["joint-taghirad.toml", "joint-taghirad-6th-order.toml"])
def test_filter_recording_is_the_cli_bit_for_bit(cli, recording, tmp_path, smooth, config):
    config = ROOT / "examples" / config
    out = tmp_path / "out.csv"
    args = ["filter", "--config", config, "--in", recording, "--out", out, "--quiet"]
    res = cli(*args, *(["--smooth"] if smooth else []))
    assert res.returncode == 0, res.stderr
    got = sw.filter_recording(sw.read_recording(recording), config=config, smooth=smooth)
    # --smooth adds the smoothed torque and its 1σ after the filter's columns.
    added = ["torque_smoothed", "torque_smoothed_sd"] if smooth else []
    assert list(got.columns[-6 - len(added) :]) == sw.OUTPUT_COLUMNS + added
    assert_frame_is_csv(got, out)


def test_filter_recording_takes_a_dict_of_arrays_with_a_prefix(cli, recording, tmp_path):
    out = tmp_path / "out.csv"
    res = cli("filter", "--config", CONFIG, "--in", recording, "--out", out, "--prefix", "f_", "--quiet")
    assert res.returncode == 0, res.stderr
    df = sw.read_recording(recording)
    # Integer-typed and non-contiguous inputs are taken as float64.
    arrays = {c: np.repeat(df[c].to_numpy(), 2)[::2] for c in df.columns}
    got = sw.filter_recording(arrays, config=CONFIG, prefix="f_")
    assert_frame_is_csv(got, out)


def test_write_recording_is_the_cli_file_byte_for_byte(cli, recording, tmp_path):
    out = tmp_path / "cli.csv"
    assert cli("filter", "--config", CONFIG, "--in", recording, "--out", out, "--quiet").returncode == 0
    mine = tmp_path / "py.csv"
    got = sw.filter_recording(sw.read_recording(recording), config=CONFIG)
    assert sw.write_recording(got, mine) == 4000
    assert mine.read_bytes() == out.read_bytes()


def test_missing_column_is_the_cli_error(cli, recording, tmp_path):
    df = sw.read_recording(recording).rename(columns={"motor_angle": "motor_angel"})
    bad = tmp_path / "renamed.csv"
    sw.write_recording(df, bad)
    expected = cli_error(cli("filter", "--config", CONFIG, "--in", bad, "--out", tmp_path / "x.csv"))
    assert "no column `motor_angle`" in expected
    # The frame read from that file names it as the command line does.
    with pytest.raises(sw.StrainwaveError) as e:
        sw.filter_recording(sw.read_recording(bad), config=CONFIG)
    assert str(e.value) == expected
    # A frame built in Python is named by `input_name`.
    with pytest.raises(sw.StrainwaveError) as e:
        sw.filter_recording(df, config=CONFIG, input_name=str(bad))
    assert str(e.value) == expected
    # A frame with no file behind it is `<DataFrame>` (pandas carries `attrs` through
    # renames and copies, so the renamed frame above still named the file).
    plain = df.copy()
    plain.attrs = {}
    with pytest.raises(sw.StrainwaveError, match=r"^<DataFrame>: no column `motor_angle`"):
        sw.filter_recording(plain, config=CONFIG)


def test_duplicate_column_is_the_cli_error(cli, recording, tmp_path):
    # The CSV the command line refuses, and the frame of that shape (pandas allows it,
    # e.g. after a concat): neither takes the first `bridge_voltage` and goes on.
    df = sw.read_recording(recording)
    twice = pd.concat([df, df[["bridge_voltage"]] * 2.0], axis=1)
    assert list(twice.columns).count("bridge_voltage") == 2
    bad = tmp_path / "twice.csv"
    with pytest.raises(sw.StrainwaveError) as e:
        sw.write_recording(twice, bad)
    assert not bad.exists()
    text = recording.read_text().splitlines()
    bad.write_text("\n".join([text[0] + ",bridge_voltage"] + [line + ",0" for line in text[1:]]) + "\n")
    expected = cli_error(cli("filter", "--config", CONFIG, "--in", bad, "--out", tmp_path / "x.csv"))
    assert expected.endswith("column `bridge_voltage` appears twice in the header"), expected
    with pytest.raises(sw.StrainwaveError) as e:
        sw.filter_recording(twice, config=CONFIG, input_name=str(bad))
    assert str(e.value) == expected


def test_bad_row_is_the_cli_error(cli, recording, tmp_path):
    df = sw.read_recording(recording)
    df.loc[1233, "bridge_voltage"] = np.inf
    bad = tmp_path / "inf.csv"
    sw.write_recording(df, bad)
    expected = cli_error(cli("filter", "--config", CONFIG, "--in", bad, "--out", tmp_path / "x.csv"))
    assert "1234" in expected
    with pytest.raises(sw.StrainwaveError) as e:
        sw.filter_recording(sw.read_recording(bad), config=CONFIG)
    assert str(e.value) == expected


def test_bad_config_and_bad_file_are_the_cli_errors(cli, recording, tmp_path):
    cfg = tmp_path / "joint.toml"
    cfg.write_text(CONFIG.read_text().replace('model = "full"', 'model = "fulll"'))
    expected = cli_error(cli("filter", "--config", cfg, "--in", recording, "--out", tmp_path / "x.csv"))
    with pytest.raises(sw.StrainwaveError) as e:
        sw.filter_recording(sw.read_recording(recording), config=cfg)
    assert str(e.value) == expected
    missing = tmp_path / "nope.csv"
    expected = cli_error(cli("filter", "--config", CONFIG, "--in", missing, "--out", tmp_path / "x.csv"))
    with pytest.raises(sw.StrainwaveError) as e:
        sw.read_recording(missing)
    assert str(e.value) == expected


def test_a_text_column_is_left_out_with_a_warning_and_text_among_numbers_is_named(recording):
    # Before: any text column refused the frame ("column `state`: not numbers").
    rec = sw.read_recording(recording)
    plain = sw.filter_recording(rec, config=CONFIG)
    with pytest.warns(sw.RecordingWarning, match=r"taghirad\.csv: column `state` holds text in data row 1: left out$"):
        out = sw.filter_recording(rec.assign(state="RUN"), config=CONFIG)
    assert out.columns.tolist() == plain.columns.tolist() and out["torque"].equals(plain["torque"])
    # Text further down a column of numbers: the row, 1-based, as the command line names it.
    bad = rec.astype({"bridge_voltage": object})
    bad.loc[3, "bridge_voltage"] = "ERR"
    with pytest.raises(sw.StrainwaveError, match=r"taghirad\.csv: row 4, column `bridge_voltage`: `ERR` is not a number$"):
        sw.filter_recording(bad, config=CONFIG)
    # With lenient=True the cell is a missing value, as `filter --lenient` reads it: its
    # sample is skipped with a flag (bit 0), counted in one warning.
    with pytest.warns(sw.RecordingWarning, match=r"1 cell\(s\) that are not numbers read as NaN, the first at row 4, "):
        out = sw.filter_recording(bad, config=CONFIG, lenient=True)
    assert int(out["filter_flags"].iloc[3]) & 1 == 1 and np.isfinite(out["torque"].iloc[4])
    # An empty string is a missing value, lenient or not (as an empty cell of a file).
    blank = rec.astype({"true_ripple": object})
    blank.loc[3, "true_ripple"] = " "
    out = sw.filter_recording(blank, config=CONFIG)
    assert np.isnan(out["true_ripple"].iloc[3]) and out["torque"].equals(plain["torque"])


def test_non_numeric_and_ragged_columns_are_errors():
    with pytest.warns(sw.RecordingWarning, match="column `time` holds text"):
        with pytest.raises(sw.StrainwaveError, match=r"^<DataFrame>: no column `time`"):
            sw.filter_recording(pd.DataFrame({"time": ["a", "b"]}), config=CONFIG)
    with pytest.raises(sw.StrainwaveError, match="has 3 rows, the first column 2"):
        sw._native.filter_columns(str(CONFIG), ["a", "b"], [np.zeros(2), np.zeros(3)], input_name="x")
    with pytest.raises(sw.StrainwaveError, match="no data rows"):
        sw.filter_recording(sw.simulate("taghirad", duration=1, seed=1).iloc[:0], config=CONFIG)


def test_simulate_errors():
    with pytest.raises(sw.StrainwaveError, match="preset"):
        sw.simulate("no-such-preset")
    with pytest.raises(sw.StrainwaveError, match="duration"):
        sw.simulate("taghirad", duration=-1)
