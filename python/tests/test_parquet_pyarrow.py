"""Parquet files written by an independent library (`pyarrow`), as DAQ software and
dataframe tools write them, read by the built `strainwave` binary: every compression
pyarrow offers, timestamp time columns in each unit, `float16`, `float32` and integer
columns, nulls."""

import csv
import subprocess

import pytest
from conftest import cargo_executable

np = pytest.importorskip("numpy", reason="pip install numpy")
pa = pytest.importorskip("pyarrow", reason="pip install pyarrow")
pq = pytest.importorskip("pyarrow.parquet", reason="pip install pyarrow")

N = 500
RATE_HZ = 1000.0
EPOCH_S = 1_795_932_000  # 2026-11-29T06:00:00Z


@pytest.fixture(scope="module")
def binary():
    return cargo_executable("bin", "strainwave")


def convert(binary, path, tmp_path):
    out = tmp_path / (path.stem + ".csv")
    res = subprocess.run(
        [str(binary), "convert", "--in", str(path), "--out", str(out), "--quiet"],
        capture_output=True, text=True, timeout=120,
    )
    assert res.returncode == 0, res.stderr
    with open(out, newline="") as f:
        rows = list(csv.reader(f))
    return rows[0], np.array([[float(x) for x in r] for r in rows[1:]])


def signal():
    return np.sin(2 * np.pi * 7.0 * np.arange(N) / RATE_HZ)


@pytest.mark.parametrize("compression", ["zstd", "gzip", "lz4", "brotli", "snappy", "none"])
def test_every_pyarrow_compression_reads(binary, tmp_path, compression):
    # Before: all but snappy and none failed ("Disabled feature at compile time").
    path = tmp_path / f"{compression}.parquet"
    table = pa.table({"time": np.arange(N) / RATE_HZ, "torque": signal()})
    pq.write_table(table, path, compression=compression)
    header, rows = convert(binary, path, tmp_path)
    assert header == ["time", "torque"]
    assert rows[:, 0].tolist() == (np.arange(N) / RATE_HZ).tolist()
    assert rows[:, 1].tolist() == signal().tolist()


@pytest.mark.parametrize("unit", ["s", "ms", "us", "ns"])
def test_timestamp_columns_are_seconds_since_the_epoch(binary, tmp_path, unit):
    # Before: refused ("has type Timestamp(ns), expected a number").
    per_s = {"s": 1, "ms": 1_000, "us": 1_000_000, "ns": 1_000_000_000}[unit]
    step = per_s // 1000 if per_s >= 1000 else 1
    ticks = EPOCH_S * per_s + np.arange(N, dtype=np.int64) * step
    table = pa.table(
        {
            "time": pa.array(ticks, type=pa.timestamp(unit, tz="UTC")),
            "torque": pa.array(signal().astype(np.float16)),
            "mode": pa.array(np.arange(N, dtype=np.int32) % 3),
            "temp": pa.array([None if k % 100 == 0 else 20.5 for k in range(N)], type=pa.float32()),
        }
    )
    path = tmp_path / f"ts_{unit}.parquet"
    pq.write_table(table, path)
    header, rows = convert(binary, path, tmp_path)
    assert header[1:] == ["torque", "mode", "temp"]
    want = EPOCH_S + np.arange(N) * step / per_s
    # Seconds since the epoch in f64: within a microsecond (its resolution near 1.8e9 s).
    assert np.max(np.abs(rows[:, 0] - want)) < 1e-6, unit
    assert rows[:, 1].tolist() == signal().astype(np.float16).astype(np.float64).tolist()
    assert rows[:, 2].tolist() == (np.arange(N) % 3).tolist()
    assert np.isnan(rows[::100, 3]).all() and (rows[1::100, 3] == 20.5).all()


@pytest.mark.parametrize("unit, per_s", [("ms", 1e3), ("us", 1e6), ("min", 1 / 60)])
def test_a_time_field_in_another_unit_is_read_in_seconds(binary, tmp_path, unit, per_s):
    # Before: the values were kept as written and taken for seconds (`--resample-hz 2000`
    # on 0.5 s in ms gave 1e6 rows 0.5 ms apart, headed `time [ms]`).
    fields = [pa.field("time", pa.float64(), metadata={"unit": unit}), pa.field("torque", pa.float64())]
    t_s = np.arange(N) / RATE_HZ
    table = pa.Table.from_arrays([pa.array(t_s * per_s), pa.array(signal())], schema=pa.schema(fields))
    path = tmp_path / f"time_{unit}.parquet"
    pq.write_table(table, path)
    header, rows = convert(binary, path, tmp_path)
    assert header == ["time", "torque"]  # seconds, the unit of a time column by default
    assert np.max(np.abs(rows[:, 0] - t_s)) < 1e-12
    out = tmp_path / "resampled.csv"
    res = subprocess.run(
        [str(binary), "convert", "--in", str(path), "--out", str(out), "--resample-hz", "2000", "--quiet"],
        capture_output=True, text=True, timeout=120,
    )
    assert res.returncode == 0, res.stderr
    resampled = np.loadtxt(out, delimiter=",", skiprows=1)
    assert len(resampled) == 2 * N - 1
    assert np.max(np.abs(np.diff(resampled[:, 0]) - 0.5e-3)) < 1e-12


def test_a_timestamp_is_seconds_whatever_its_unit_metadata_says(binary, tmp_path):
    ticks = EPOCH_S * 1000 + np.arange(N, dtype=np.int64)
    fields = [pa.field("time", pa.timestamp("ms"), metadata={"unit": "ms"}), pa.field("torque", pa.float64())]
    table = pa.Table.from_arrays([pa.array(ticks, type=pa.timestamp("ms")), pa.array(signal())], schema=pa.schema(fields))
    path = tmp_path / "stamp.parquet"
    pq.write_table(table, path)
    header, rows = convert(binary, path, tmp_path)
    assert header == ["time", "torque"]  # seconds, the unit of a time column by default
    assert np.max(np.abs(rows[:, 0] - (EPOCH_S + np.arange(N) / 1000))) < 1e-6


def test_text_category_and_flag_columns_are_left_out_with_a_warning(binary, tmp_path):
    # A test stand's export as pandas writes it: a step name (text), a category, a flag.
    # Before: the whole file refused ("column `step` has type Utf8, expected a number").
    table = pa.table(
        {
            "time": np.arange(N) / RATE_HZ,
            "step": pa.array(["ramp" if k < N // 2 else "hold" for k in range(N)]),
            "torque": signal(),
            "state": pa.array(["a", "b"] * (N // 2)).dictionary_encode(),
            "ok": pa.array([True] * N),
        }
    )
    path = tmp_path / "stand.parquet"
    pq.write_table(table, path)
    out = tmp_path / "stand.csv"
    res = subprocess.run(
        [str(binary), "convert", "--in", str(path), "--out", str(out)], capture_output=True, text=True, timeout=120
    )
    assert res.returncode == 0, res.stderr
    warned = [l for l in res.stderr.splitlines() if l.startswith("warning:")]
    assert warned == [
        f"warning: {path}: column `step` (Utf8) is not numeric: left out",
        f"warning: {path}: column `state` (Dictionary(Int32, Utf8)) is not numeric: left out",
        f"warning: {path}: column `ok` (Boolean) is not numeric: left out",
    ], res.stderr
    header, rows = convert(binary, path, tmp_path)
    assert header == ["time", "torque"]
    assert rows[:, 1].tolist() == signal().tolist()
    # A file with no numeric column at all is refused, naming a column.
    pq.write_table(pa.table({"step": pa.array(["a"] * 3)}), path)
    res = subprocess.run(
        [str(binary), "convert", "--in", str(path), "--out", str(out)], capture_output=True, text=True, timeout=120
    )
    assert res.returncode == 1 and res.stderr.strip() == f"error: {path}: column `step` has type Utf8, expected a number"


def test_the_package_reads_a_text_column_with_a_warning(tmp_path):
    # The package reads as the command line: a DAQ export's text column left out, warned of.
    sw = pytest.importorskip("strainwave", reason="pip install ./python (./scripts/test-all does)")
    path = tmp_path / "daq.txt"
    path.write_text("time\ttorque [N*m]\tstate\n0\t1,5\tRamp up\n0,001\t2\thold\n", encoding="utf-8")
    with pytest.warns(sw.RecordingWarning, match="daq.txt: column `state` holds text in data row 1: left out"):
        df = sw.read_recording(path)
    assert list(df.columns) == ["time", "torque"] and df["torque"].tolist() == [1.5, 2.0]


def test_decimal_columns_read_as_numbers(binary, tmp_path):
    # A historian database's fixed-point columns, as pandas' read_sql hands them on.
    # Before: refused ("has type Decimal128(10, 3), expected a number").
    from decimal import Decimal

    values = [Decimal("1.250"), Decimal("-0.125"), Decimal("1234567.001"), None]
    table = pa.table(
        {
            "time": np.arange(4) / RATE_HZ,
            "torque": pa.array(values, type=pa.decimal128(10, 3)),
            "count": pa.array([Decimal(5), Decimal(-7), Decimal(0), Decimal(1)], type=pa.decimal128(38, 0)),
        }
    )
    path = tmp_path / "decimal.parquet"
    pq.write_table(table, path)
    header, rows = convert(binary, path, tmp_path)
    assert header == ["time", "torque", "count"]
    assert rows[:3, 1].tolist() == [1.25, -0.125, 1234567.001] and np.isnan(rows[3, 1])
    assert rows[:, 2].tolist() == [5.0, -7.0, 0.0, 1.0]
