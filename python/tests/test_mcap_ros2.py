"""MCAP input against an independent writer: a ROS 2 log written with the Python `mcap` and
`mcap-ros2-support` packages (JointState in CDR on /joint_states, a JSON channel, and a
channel with an unknown protobuf schema), converted by `strainwave convert` to CSV.

Checks the columns (`time`, `<joint>.position|velocity|effort`, `<topic>.<path>`), every
value and time exactly (times are log_time_ns / 1e9), NaN where a message lacks a column,
and the warning that names the skipped topic and schema.
"""

import csv
import json
import math
import struct

import pytest

mcap_writer = pytest.importorskip("mcap.writer", reason="pip install mcap")
ros2_writer = pytest.importorskip("mcap_ros2.writer", reason="pip install mcap-ros2-support")


JOINT_STATE_DEF = """std_msgs/Header header
string[] name
float64[] position
float64[] velocity
float64[] effort
================================================================================
MSG: std_msgs/Header
builtin_interfaces/Time stamp
string frame_id
================================================================================
MSG: builtin_interfaces/Time
int32 sec
uint32 nanosec
"""

JOINTS = ["shoulder_pan", "elbow", "wrist_3"]  # odd and even name lengths exercise CDR alignment
T0_NS = 1_000_000_000
DT_NS = 2_500_000  # 400 Hz; all times below 2**53 ns, so log_time_ns / 1e9 is exact to compare


def joint_values(k):
    pos = [0.1 * k + j for j in range(len(JOINTS))]
    vel = [-0.25 * k * (j + 1) for j in range(len(JOINTS))]
    eff = [1e-3 * (k + 1) ** 2 - j for j in range(len(JOINTS))]
    return pos, vel, eff


def status_doc(k):
    return {"mode": "run", "temp_c": 30.0 + k / 8, "motor": {"current_a": [k * 0.5, -k * 0.5]}, "ok": True}


@pytest.fixture(scope="module")
def converted(tmp_path_factory, cli):
    tmp = tmp_path_factory.mktemp("mcap")
    log = tmp / "ros2.mcap"
    expected = []  # (log_time_ns, {column: value})
    with open(log, "wb") as f:
        w = ros2_writer.Writer(f)
        schema = w.register_msgdef("sensor_msgs/msg/JointState", JOINT_STATE_DEF)
        # JSON and an unknown schema go through the same file's underlying `mcap` writer.
        raw = w._writer
        json_ch = raw.register_channel(topic="/status", message_encoding="json", schema_id=0)
        pb_schema = raw.register_schema(name="foxglove.CompressedImage", encoding="protobuf", data=b"\x0a\x03\xff\x00\x01")
        pb_ch = raw.register_channel(topic="/camera/image", message_encoding="protobuf", schema_id=pb_schema)
        for k in range(6):
            t = T0_NS + k * DT_NS
            pos, vel, eff = joint_values(k)
            msg = {
                "header": {"stamp": {"sec": 1, "nanosec": 500 + k}, "frame_id": "base_link"},
                "name": JOINTS,
                "position": pos,
                "velocity": vel,
                "effort": eff,
            }
            w.write_message("/joint_states", schema, msg, log_time=t, publish_time=t, sequence=k)
            cols = {}
            for j, name in enumerate(JOINTS):
                cols[f"{name}.position"] = pos[j]
                cols[f"{name}.velocity"] = vel[j]
                cols[f"{name}.effort"] = eff[j]
            expected.append((t, cols))
            if k % 2 == 1:
                tj = t + DT_NS // 2
                doc = status_doc(k)
                raw.add_message(channel_id=json_ch, log_time=tj, publish_time=tj, data=json.dumps(doc).encode(), sequence=k)
                cur = doc["motor"]["current_a"]
                expected.append(
                    (
                        tj,
                        {
                            "/status.temp_c": doc["temp_c"],
                            "/status.motor.current_a.0": cur[0],
                            "/status.motor.current_a.1": cur[1],
                        },
                    )
                )
            raw.add_message(channel_id=pb_ch, log_time=t + 1, publish_time=t + 1, data=bytes([k, 0xFF, 0x00, 7]))
        w.finish()

    out = tmp / "ros2.csv"
    # One row per message at its log time (the default aligns topics on one clock).
    res = cli("convert", "--in", log, "--out", out, "--align", "none", "--time", "log")
    if res.returncode != 0:
        pytest.fail(f"strainwave convert failed ({res.returncode}):\n{res.stderr}")
    with open(out, newline="") as f:
        rows = list(csv.reader(f))
    return {"header": rows[0], "rows": [[float(x) for x in r] for r in rows[1:]], "stderr": res.stderr, "expected": expected}


def test_columns_are_time_joints_then_json_paths(converted):
    joint_cols = [f"{n}.{field}" for n in JOINTS for field in ("position", "velocity", "effort")]
    json_cols = ["/status.temp_c", "/status.motor.current_a.0", "/status.motor.current_a.1"]
    assert converted["header"] == ["time"] + joint_cols + json_cols


def test_times_and_values_exact_with_nan_elsewhere(converted):
    header, rows, expected = converted["header"], converted["rows"], converted["expected"]
    expected = sorted(expected, key=lambda e: e[0])
    assert len(rows) == len(expected) == 9
    for row, (t_ns, cols) in zip(rows, expected):
        assert row[0] == t_ns / 1e9, (row[0], t_ns)
        for name, value in zip(header[1:], row[1:]):
            if name in cols:
                assert value == cols[name], (t_ns, name, value, cols[name])
            else:
                assert math.isnan(value), (t_ns, name, value)


def test_unknown_schema_is_skipped_with_a_warning_naming_it(converted):
    warnings = [line for line in converted["stderr"].splitlines() if line.startswith("warning:")]
    camera = [line for line in warnings if "/camera/image" in line]
    assert len(camera) == 1, converted["stderr"]
    assert "foxglove.CompressedImage" in camera[0] and "protobuf" in camera[0], camera[0]
    assert "skipped 6 message" in camera[0], camera[0]
    # the JSON strings and booleans ("mode", "ok") are not columns and raise no warning
    assert not any("/status" in line for line in warnings), warnings


def float64_log(path, n, chunked):
    """`n` std_msgs/Float64 messages on /torque (value k at log time T0 + k ms), written by
    the `mcap` package in 512-byte zstd chunks or unchunked; the file's bytes."""
    with open(path, "wb") as f:
        w = mcap_writer.Writer(f, chunk_size=512, use_chunking=chunked)
        w.start(profile="ros2")
        schema = w.register_schema(name="std_msgs/msg/Float64", encoding="ros2msg", data=b"float64 data\n")
        channel = w.register_channel(topic="/torque", message_encoding="cdr", schema_id=schema)
        for k in range(n):
            t = T0_NS + k * 1_000_000
            cdr = b"\x00\x01\x00\x00" + struct.pack("<d", float(k))
            w.add_message(channel_id=channel, log_time=t, publish_time=t, data=cdr, sequence=k)
        w.finish()
    return path.read_bytes()


@pytest.mark.parametrize("chunked", [True, False])
def test_a_log_cut_short_gives_the_messages_before_the_cut_with_a_warning(tmp_path, cli, chunked):
    # A recorder killed before it closed its file leaves no summary or footer, and a copy
    # can stop anywhere. Before: exit 1 and no output, though every message was read.
    data = float64_log(tmp_path / "full.mcap", 300, chunked)
    for fraction in (0.97, 0.6):
        cut = tmp_path / "cut.mcap"
        cut.write_bytes(data[: int(len(data) * fraction)])
        out = tmp_path / "cut.csv"
        res = cli("convert", "--in", cut, "--out", out, "--align", "none", "--time", "log")
        assert res.returncode == 0, res.stderr
        warn = [l for l in res.stderr.splitlines() if l.startswith("warning:")]
        assert len(warn) == 1 and "ends before its footer" in warn[0], res.stderr
        with open(out, newline="") as f:
            rows = [[float(x) for x in r] for r in list(csv.reader(f))[1:]]
        assert 0 < len(rows) <= 300 and (fraction > 0.9 or len(rows) < 300), len(rows)
        assert [r[1] for r in rows] == [float(k) for k in range(len(rows))]
        assert [r[0] for r in rows] == [(T0_NS + k * 1_000_000) / 1e9 for k in range(len(rows))]


def test_a_log_without_messages_is_an_error_not_a_crash(tmp_path, cli):
    # Before: a panic (exit 101) on an MCAP with no messages, or cut before the first.
    data = float64_log(tmp_path / "none.mcap", 0, True)
    res = cli("convert", "--in", tmp_path / "none.mcap", "--out", tmp_path / "none.csv")
    assert res.returncode == 1 and "none.mcap: no messages in the log" in res.stderr, res.stderr
    (tmp_path / "head.mcap").write_bytes(float64_log(tmp_path / "one.mcap", 5, True)[:20])
    res = cli("convert", "--in", tmp_path / "head.mcap", "--out", tmp_path / "head.csv")
    assert res.returncode == 1 and "ends before its first message" in res.stderr, res.stderr
    assert data and not (tmp_path / "none.csv").exists() and not (tmp_path / "head.csv").exists()


def test_the_package_reads_a_cut_log_with_a_warning(tmp_path):
    # Before: `read_recording` returned the rows before the cut as if the log were whole.
    sw = pytest.importorskip("strainwave", reason="pip install ./python (./scripts/test-all does)")
    data = float64_log(tmp_path / "full.mcap", 300, True)
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[: int(len(data) * 0.6)])
    with pytest.warns(sw.RecordingWarning, match="cut.mcap: .*ends before its footer"):
        df = sw.read_recording(cut)
    assert 0 < len(df) < 300
    assert len(df.attrs["strainwave_warnings"]) == 1
    # A whole log: no warning.
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error", sw.RecordingWarning)
        whole = sw.read_recording(tmp_path / "full.mcap")
    assert len(whole) == 300 and whole.attrs["strainwave_warnings"] == []
