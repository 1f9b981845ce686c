"""Text exports written by an independent library (pandas' `to_csv`), as dataframe
tools and data loggers write them, read by the built `strainwave` binary: a datetime
index as the time column, a text column beside the numbers."""

import csv
import subprocess

import pytest
from conftest import cargo_executable

np = pytest.importorskip("numpy", reason="pip install numpy")
pd = pytest.importorskip("pandas", reason="pip install pandas")

N = 1000
EPOCH_S = 1_795_932_000  # 2026-11-29T06:00:00Z


@pytest.fixture(scope="module")
def binary():
    return cargo_executable("bin", "strainwave")


def convert(binary, path, out):
    res = subprocess.run(
        [str(binary), "convert", "--in", str(path), "--out", str(out)], capture_output=True, text=True, timeout=120
    )
    if res.returncode != 0:
        return res, []
    with open(out, newline="") as f:
        return res, list(csv.reader(f))


@pytest.mark.parametrize("zone", [None, "UTC", "Europe/Berlin"])
def test_a_datetime_index_is_seconds_since_1970_and_text_is_left_out(binary, tmp_path, zone):
    # Before: "row 1, column `time`: `2026-11-29 06:00:00` is not a number".
    time = pd.date_range("2026-11-29 06:00:00", periods=N, freq="250us", tz=zone, name="time")
    torque = np.sin(2 * np.pi * 7.0 * np.arange(N) / 4000.0)
    frame = pd.DataFrame({"torque": torque, "step": ["ramp"] * (N // 2) + ["hold"] * (N - N // 2)}, index=time)
    path = tmp_path / "export.csv"
    frame.to_csv(path)
    res, rows = convert(binary, path, tmp_path / "out.csv")
    assert res.returncode == 0, res.stderr
    assert [l for l in res.stderr.splitlines() if l.startswith("warning:")] == [
        f"warning: {path}: column `step` holds text in data row 1: left out"
    ]
    assert rows[0] == ["time", "torque"], rows[0]
    got = np.array([[float(x) for x in r] for r in rows[1:]])
    want = time.tz_convert("UTC").tz_localize(None) if zone else time
    want_s = (want - pd.Timestamp("1970-01-01")) / pd.Timedelta(seconds=1)
    # Seconds since 1970 in f64: within a microsecond (its resolution near 1.8e9 s).
    assert np.max(np.abs(got[:, 0] - want_s.to_numpy())) < 1e-6
    assert got[:, 1].tolist() == torque.tolist()
    if zone is None:
        assert got[0, 0] == EPOCH_S


def test_a_time_that_stops_being_a_date_is_named(binary, tmp_path):
    path = tmp_path / "bad.csv"
    path.write_text("time,x\n2026-11-29 06:00:00,1\n2026-11-29 06:00:01,2\nlater,3\n")
    res, _ = convert(binary, path, tmp_path / "out.csv")
    assert res.returncode == 1
    assert res.stderr.startswith(f"error: {path}: row 3, column `time`: `later` is not a date and time"), res.stderr
    assert not (tmp_path / "out.csv").exists()


def test_nan_written_by_pandas_is_read_as_nan(binary, tmp_path):
    # pandas writes a NaN as an empty field. Before: "row 3, column `torque`: `` is not a number".
    torque = np.sin(np.arange(N) / 10.0)
    torque[2] = np.nan
    frame = pd.DataFrame({"time": np.arange(N) * 1e-3, "torque": torque, "speed": np.nan})
    path = tmp_path / "with_nan.csv"
    frame.to_csv(path, index=False)
    assert path.read_text().splitlines()[3].endswith(",,"), "pandas writes NaN as an empty field"
    res, rows = convert(binary, path, tmp_path / "out.csv")
    assert res.returncode == 0, res.stderr
    got = np.array([[float(x) for x in r] for r in rows[1:]])
    assert np.array_equal(got[:, 1], torque, equal_nan=True) and np.isnan(got[:, 2]).all()
    sw = pytest.importorskip("strainwave", reason="the package is not installed")
    back = sw.read_recording(path)
    assert np.array_equal(back["torque"].to_numpy(), torque, equal_nan=True)
