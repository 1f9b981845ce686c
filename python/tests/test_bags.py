"""ROS 2 bags written by an independent library (`rosbags`), in both rosbag2 storages
(MCAP and SQLite 3), read by the built `strainwave` binary.

The bag holds what a ros2_control robot records, interleaved at three rates:
`sensor_msgs/msg/JointState` at 500 Hz, `control_msgs/msg/DynamicJointState` at 1 kHz
(interfaces position, motor_position, torque_sensor), `geometry_msgs/msg/WrenchStamped`
at 250 Hz, and a custom nested message (fixed array of a nested type holding a
`geometry_msgs/Vector3`, a sequence, an integer) at 100 Hz. Header stamps are the sample
times; log times lag them by a varying delay.

Checks: every value comes back exactly at its own message time (`--align none`); after
alignment on the 1 kHz clock each column equals its own samples interpolated (linear,
hold); `--topic` and `--time log`; `filter --in bag.mcap --out filtered.mcap` end to end,
read back with the `mcap` reader; bad bags give one-line errors.
"""

import csv
import math
import os
import subprocess

import pytest
from conftest import cargo_executable

np = pytest.importorskip("numpy", reason="pip install numpy")
rosbag2 = pytest.importorskip("rosbags.rosbag2", reason="pip install rosbags")
typesys = pytest.importorskip("rosbags.typesys", reason="pip install rosbags")


INTERFACE_VALUE = "string[] interface_names\nfloat64[] values\n"
DYNAMIC_JOINT_STATE = "std_msgs/Header header\nstring[] joint_names\ncontrol_msgs/InterfaceValue[] interface_values\n"
STAGE = "float64 torque\ngeometry_msgs/Vector3 accel\n"
GEARBOX = "std_msgs/Header header\nstrainwave_test/Stage[2] stages\nfloat32[] temps\nint32 mode\n"

JOINTS = ["j1", "j2"]
T0_NS = 1_700_000_000_000_000_000  # epoch-like stamps
DURATION_S = 0.2
RATES = {"/dynamic_joint_states": 1000, "/joint_states": 500, "/wrench": 250, "/gearbox": 100}


def truth(name, t):
    """The value of a signal at time t (s since T0)."""
    k = {"pos": 1.0, "mpos": 2.0, "torq": 3.0, "vel": 4.0, "eff": 5.0, "fx": 6.0, "tz": 7.0, "st": 8.0}[name[0]]
    j = name[1]
    return math.sin(2 * math.pi * (3 + k) * t + j) * (10 + k) + 0.1 * j


@pytest.fixture(scope="module")
def binary():
    return cargo_executable("bin", "strainwave")


def run(binary, *args, ok=True):
    res = subprocess.run([str(binary), *map(str, args)], capture_output=True, text=True, timeout=600)
    if ok and res.returncode != 0:
        pytest.fail(f"strainwave {' '.join(map(str, args))} failed ({res.returncode}):\n{res.stderr}")
    return res


def read_csv(path):
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    return rows[0], np.array([[float(x) for x in r] for r in rows[1:]])


def typestore():
    store = typesys.get_typestore(typesys.Stores.ROS2_HUMBLE)
    types = {}
    types.update(typesys.get_types_from_msg(INTERFACE_VALUE, "control_msgs/msg/InterfaceValue"))
    types.update(typesys.get_types_from_msg(DYNAMIC_JOINT_STATE, "control_msgs/msg/DynamicJointState"))
    types.update(typesys.get_types_from_msg(STAGE, "strainwave_test/msg/Stage"))
    types.update(typesys.get_types_from_msg(GEARBOX, "strainwave_test/msg/Gearbox"))
    store.register(types)
    return store


def messages(store):
    """(topic, type, stamp_ns, log_ns, msg, {column: value}) in log-time order."""
    t = store.types
    Header, Time = t["std_msgs/msg/Header"], t["builtin_interfaces/msg/Time"]
    out = []
    for topic, rate in RATES.items():
        period_ns = 1_000_000_000 // rate
        for k in range(int(DURATION_S * rate)):
            ts = k * period_ns * 1e-9
            stamp = T0_NS + k * period_ns
            log = stamp + 150_000 + (k * 37_000) % 300_000  # 0.15–0.45 ms late
            header = Header(stamp=Time(sec=stamp // 10**9, nanosec=stamp % 10**9), frame_id="base")
            if topic == "/joint_states":
                pos = [truth(("pos", j), ts) for j in range(2)]
                vel = [truth(("vel", j), ts) for j in range(2)]
                eff = [truth(("eff", j), ts) for j in range(2)]
                msg = t["sensor_msgs/msg/JointState"](
                    header=header, name=JOINTS, position=np.array(pos), velocity=np.array(vel), effort=np.array(eff)
                )
                cols = {}
                for j, n in enumerate(JOINTS):
                    cols[f"/joint_states/{n}.position"] = pos[j]
                    cols[f"{n}.velocity"] = vel[j]
                    cols[f"{n}.effort"] = eff[j]
                mtype = "sensor_msgs/msg/JointState"
            elif topic == "/dynamic_joint_states":
                ifaces = ["position", "motor_position", "torque_sensor"]
                vals = [[truth((s, j), ts) for s in ("pos", "mpos", "torq")] for j in range(2)]
                msg = t["control_msgs/msg/DynamicJointState"](
                    header=header,
                    joint_names=JOINTS,
                    interface_values=[
                        t["control_msgs/msg/InterfaceValue"](interface_names=ifaces, values=np.array(v)) for v in vals
                    ],
                )
                cols = {}
                for j, n in enumerate(JOINTS):
                    cols[f"/dynamic_joint_states/{n}.position"] = vals[j][0]
                    cols[f"{n}.motor_position"] = vals[j][1]
                    cols[f"{n}.torque_sensor"] = vals[j][2]
                mtype = "control_msgs/msg/DynamicJointState"
            elif topic == "/wrench":
                V3 = t["geometry_msgs/msg/Vector3"]
                f = V3(x=truth(("fx", 0), ts), y=truth(("fx", 1), ts), z=-1.5)
                tq = V3(x=0.25, y=-0.5, z=truth(("tz", 0), ts))
                msg = t["geometry_msgs/msg/WrenchStamped"](header=header, wrench=t["geometry_msgs/msg/Wrench"](force=f, torque=tq))
                cols = {
                    "/wrench/wrench.force.x": f.x,
                    "/wrench/wrench.force.y": f.y,
                    "/wrench/wrench.force.z": -1.5,
                    "/wrench/wrench.torque.x": 0.25,
                    "/wrench/wrench.torque.y": -0.5,
                    "/wrench/wrench.torque.z": tq.z,
                }
                mtype = "geometry_msgs/msg/WrenchStamped"
            else:
                V3 = t["geometry_msgs/msg/Vector3"]
                stages = [
                    t["strainwave_test/msg/Stage"](torque=truth(("st", i), ts), accel=V3(x=i, y=0.5 * k, z=-k)) for i in range(2)
                ]
                temps = np.array([30.0 + 0.5 * k, 31.25], dtype=np.float32)
                msg = t["strainwave_test/msg/Gearbox"](header=header, stages=stages, temps=temps, mode=k % 3 - 1)
                cols = {"/gearbox/mode": float(k % 3 - 1), "/gearbox/temps.0": float(temps[0]), "/gearbox/temps.1": 31.25}
                for i in range(2):
                    cols[f"/gearbox/stages.{i}.torque"] = stages[i].torque
                    cols[f"/gearbox/stages.{i}.accel.x"] = float(i)
                    cols[f"/gearbox/stages.{i}.accel.y"] = 0.5 * k
                    cols[f"/gearbox/stages.{i}.accel.z"] = float(-k)
                mtype = "strainwave_test/msg/Gearbox"
            out.append((topic, mtype, stamp, log, msg, cols))
    out.sort(key=lambda m: (m[3], m[0]))
    return out


def write_bag(path, storage, extra=None):
    store = typestore()
    msgs = messages(store)
    with rosbag2.Writer(path, version=9, storage_plugin=storage) as w:
        conns = {}
        for topic, mtype, _, _, _, _ in msgs:
            if topic not in conns:
                conns[topic] = w.add_connection(topic, mtype, typestore=store)
        for topic, mtype, _, log, msg, _ in msgs:
            w.write(conns[topic], log, store.serialize_cdr(msg, mtype))
        if extra:
            extra(w, store, conns)
    return msgs


STORAGES = {"mcap": "MCAP", "sqlite3": "SQLITE3"}


@pytest.fixture(scope="module", params=sorted(STORAGES))
def bag(request, tmp_path_factory):
    storage = getattr(rosbag2.StoragePlugin, STORAGES[request.param])
    path = tmp_path_factory.mktemp(request.param) / "robot"
    msgs = write_bag(path, storage)
    files = sorted(p for p in path.iterdir() if p.suffix in (".mcap", ".db3"))
    assert len(files) == 1, list(path.iterdir())
    return {"folder": path, "file": files[0], "messages": msgs, "storage": request.param}


def test_every_value_exactly_at_its_own_message_time(binary, bag, tmp_path):
    # The folder and the bare file read the same.
    for source in (bag["folder"], bag["file"]):
        out = tmp_path / "none.csv"
        run(binary, "convert", "--in", source, "--align", "none", "--out", out)
        header, rows = read_csv(out)
        msgs = sorted(bag["messages"], key=lambda m: m[2])
        assert len(rows) == len(msgs)
        expected_cols = set().union(*(m[5].keys() for m in msgs))
        assert set(header[1:]) == expected_cols, set(header[1:]) ^ expected_cols
        index = {c: i for i, c in enumerate(header)}
        for row, (topic, _, stamp, _, _, cols) in zip(rows, msgs):
            assert row[0] == stamp / 1e9, (topic, row[0], stamp)
            for name, i in index.items():
                if name == "time":
                    continue
                if name in cols:
                    assert row[i] == cols[name], (topic, name, row[i], cols[name])
                else:
                    assert math.isnan(row[i]), (topic, name, row[i])


def own_samples(msgs, column):
    pts = sorted((m[2], m[5][column]) for m in msgs if column in m[5])
    return np.array([p[0] for p in pts], dtype=np.int64), np.array([p[1] for p in pts])


def test_aligned_columns_equal_their_own_samples_interpolated(binary, bag, tmp_path):
    out = tmp_path / "linear.csv"
    res = run(binary, "convert", "--in", bag["folder"], "--out", out)
    header, rows = read_csv(out)
    clock_ns = np.array(sorted(m[2] for m in bag["messages"] if m[0] == "/dynamic_joint_states"), dtype=np.int64)
    assert len(rows) == len(clock_ns) == 200, res.stderr
    assert np.array_equal(rows[:, 0], clock_ns / 1e9)
    t_rel = (clock_ns - T0_NS).astype(float)
    checked = 0
    for i, name in enumerate(header[1:], start=1):
        ts, vs = own_samples(bag["messages"], name)
        rel = (ts - T0_NS).astype(float)
        inside = (t_rel >= rel[0]) & (t_rel <= rel[-1])
        want = np.interp(t_rel, rel, vs)
        got = rows[:, i]
        assert np.all(np.isnan(got[~inside])), name
        err = np.abs(got[inside] - want[inside])
        assert np.all(err <= 1e-12 * (1 + np.abs(want[inside]))), (name, err.max())
        # At its own times, exactly its own value.
        own = np.isin(clock_ns, ts)
        assert np.array_equal(got[own], vs[np.searchsorted(ts, clock_ns[own])]), name
        checked += 1
    assert checked == len(header) - 1 > 20


def test_summary_counts_messages_per_topic_and_rows_written(binary, bag, tmp_path):
    import re

    out = tmp_path / "summary.csv"
    res = run(binary, "convert", "--in", bag["file"], "--out", out)
    lines = [l for l in res.stderr.splitlines() if l.startswith("converted")]
    assert len(lines) == 1, res.stderr
    m = re.fullmatch(r"converted (\d+) messages \((.*)\) of (.*) -> (\d+) rows, (\d+) columns in (.*)", lines[0])
    assert m, lines[0]
    per_topic = dict((t, int(n)) for t, n in (p.rsplit(" ", 1) for p in m.group(2).split(", ")))
    assert per_topic == {t: int(DURATION_S * r) for t, r in RATES.items()}
    assert int(m.group(1)) == sum(per_topic.values())
    header, rows = read_csv(out)
    assert (m.group(3), int(m.group(4)), int(m.group(5)), m.group(6)) == (str(bag["file"]), len(rows), len(header), str(out))
    # Rows are the 1 kHz clock's, fewer than the messages read.
    assert len(rows) == 200 < int(m.group(1))


def test_hold_on_a_uniform_clock_and_max_gap(binary, bag, tmp_path):
    out = tmp_path / "hold.csv"
    run(binary, "convert", "--in", bag["file"], "--align", "hold", "--resample-hz", "400", "--max-gap", "0.006", "--out", out)
    header, rows = read_csv(out)
    assert len(rows) == 80  # 0.2 s from the first stamp minus the last step, at 400 Hz
    grid = T0_NS + np.round(np.arange(len(rows)) * 1e9 / 400).astype(np.int64)
    assert np.array_equal(rows[:, 0], grid / 1e9)
    for name in ("j1.velocity", "/wrench/wrench.force.x", "/gearbox/stages.1.torque"):
        ts, vs = own_samples(bag["messages"], name)
        got = rows[:, header.index(name)]
        for g, v in zip(grid, got):
            k = np.searchsorted(ts, g, side="right") - 1
            if k >= 0 and g - ts[k] <= 6_000_000:
                assert v == vs[k], (name, g, v, vs[k])
            else:
                assert math.isnan(v), (name, g, v)
    # /gearbox is 100 Hz: of the 4 grid rows per sample (0, 2.5, 5, 7.5 ms after it) the
    # last is beyond the 6 ms gap.
    assert np.isnan(rows[:, header.index("/gearbox/stages.1.torque")]).sum() == 20


def test_topic_selection_and_log_time(binary, bag, tmp_path):
    out = tmp_path / "wrench.csv"
    run(binary, "convert", "--in", bag["file"], "--topic", "/wrench", "--time", "log", "--out", out)
    header, rows = read_csv(out)
    assert all(c == "time" or c.startswith("/wrench/") for c in header), header
    logs = sorted(m[3] for m in bag["messages"] if m[0] == "/wrench")
    assert np.array_equal(rows[:, 0], np.array(logs) / 1e9)
    # Without a clash, positions are not prefixed.
    out = tmp_path / "djs.csv"
    run(binary, "convert", "--in", bag["file"], "--topic", "/dynamic_joint_states", "--out", out)
    header, _ = read_csv(out)
    assert header == ["time"] + [f"{j}.{i}" for j in JOINTS for i in ("position", "motor_position", "torque_sensor")]
    res = run(binary, "convert", "--in", bag["file"], "--topic", "/nope", "--out", tmp_path / "x.csv", ok=False)
    assert res.returncode == 1 and "/nope" in res.stderr and "/wrench" in res.stderr, res.stderr


JOINT_CONFIG = """
[gear]
ratio = 100.0
fixed = "circular_spline"

[channels]
time = "time"
torque = "j1.torque_sensor"
motor_angle = "j1.motor_position"
output_angle = "j1.position"

[filter]
model = "product"
sample_rate_hz = 1000.0
noise_nm = 0.02
phase = "angle"
"""


def test_filter_bag_to_mcap_end_to_end(binary, bag, tmp_path):
    mcap_reader = pytest.importorskip("mcap.reader", reason="pip install mcap")
    decoder = pytest.importorskip("mcap_ros2.decoder", reason="pip install mcap-ros2-support")
    config = tmp_path / "joint.toml"
    config.write_text(JOINT_CONFIG)
    out = tmp_path / "filtered.mcap"
    run(binary, "filter", "--config", config, "--in", bag["file"], "--topic", "/dynamic_joint_states", "--out", out)
    csv_out = tmp_path / "filtered.csv"
    run(binary, "filter", "--config", config, "--in", bag["file"], "--topic", "/dynamic_joint_states", "--out", csv_out)
    header, rows = read_csv(csv_out)
    topics = {}
    with open(out, "rb") as f:
        reader = mcap_reader.make_reader(f, decoder_factories=[decoder.DecoderFactory()])
        for schema, channel, message, ros in reader.iter_decoded_messages():
            assert schema.name == "std_msgs/msg/Float64"
            topics.setdefault(channel.topic, []).append((message.log_time, ros.data))
    for i, name in enumerate(header[1:], start=1):
        topic = "/strainwave/" + name.replace(".", "/")
        got = topics[topic]
        finite = ~np.isnan(rows[:, i])
        assert len(got) == finite.sum(), name
        assert [g[1] for g in got] == list(rows[finite, i]), name
        assert [g[0] for g in got] == [round(t * 1e9) for t in rows[finite, 0]], name
    # Reading the written MCAP back gives the filter's columns again.
    back = tmp_path / "back.csv"
    run(binary, "convert", "--in", out, "--align", "none", "--time", "log", "--out", back)
    bh, _ = read_csv(back)
    assert len(bh) == len(header)


def test_damaged_bags_are_one_line_errors(binary, tmp_path):
    mcap_writer = pytest.importorskip("mcap.writer", reason="pip install mcap")
    path = tmp_path / "robot"
    write_bag(path, rosbag2.StoragePlugin.MCAP)
    (file,) = path.glob("*.mcap")
    data = file.read_bytes()
    # Cut short (a recorder killed): the messages before the cut, with one warning.
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[: len(data) * 2 // 3])
    res = run(binary, "convert", "--in", cut, "--align", "none", "--out", tmp_path / "cut.csv")
    warn = [l for l in res.stderr.splitlines() if l.startswith("warning:")]
    assert len(warn) == 1 and "cut.mcap" in warn[0] and "ends before its footer" in warn[0], res.stderr

    # A message whose CDR does not match its schema, and an unknown schema encoding.
    bad = tmp_path / "bad.mcap"
    with open(bad, "wb") as f:
        w = mcap_writer.Writer(f)
        w.start(profile="ros2")
        s = w.register_schema(name="geometry_msgs/msg/Vector3", encoding="ros2msg", data=b"float64 x\nfloat64 y\nfloat64 z\n")
        c = w.register_channel(topic="/v", message_encoding="cdr", schema_id=s)
        p = w.register_schema(name="my.Proto", encoding="protobuf", data=b"\x01")
        pc = w.register_channel(topic="/proto", message_encoding="protobuf", schema_id=p)
        body = bytes([0, 1, 0, 0]) + np.array([1.0, 2.0, 3.0]).tobytes()
        w.add_message(channel_id=c, log_time=1_000_000_000, publish_time=0, data=body)
        w.add_message(channel_id=pc, log_time=1_100_000_000, publish_time=0, data=b"\x08\x01")
        w.add_message(channel_id=c, log_time=2_000_000_000, publish_time=0, data=body[:20])
        w.finish()
    res = run(binary, "convert", "--in", bad, "--out", tmp_path / "bad.csv", ok=False)
    assert res.returncode == 1, res.stderr
    line = [l for l in res.stderr.splitlines() if l.startswith("error:")]
    assert len(line) == 1 and "/v" in line[0] and "log time 2 s" in line[0] and "schema" in line[0], res.stderr
    # The unknown encoding alone: a warning, the rest read.
    good = tmp_path / "good.mcap"
    with open(good, "wb") as f:
        w = mcap_writer.Writer(f)
        w.start(profile="ros2")
        s = w.register_schema(name="geometry_msgs/msg/Vector3", encoding="ros2msg", data=b"float64 x\nfloat64 y\nfloat64 z\n")
        c = w.register_channel(topic="/v", message_encoding="cdr", schema_id=s)
        p = w.register_schema(name="my.Proto", encoding="protobuf", data=b"\x01")
        pc = w.register_channel(topic="/proto", message_encoding="protobuf", schema_id=p)
        w.add_message(channel_id=c, log_time=1_000_000_000, publish_time=0, data=body)
        w.add_message(channel_id=pc, log_time=1_100_000_000, publish_time=0, data=b"\x08\x01")
        w.finish()
    res = run(binary, "convert", "--in", good, "--out", tmp_path / "good.csv")
    warn = [l for l in res.stderr.splitlines() if "/proto" in l]
    assert len(warn) == 1 and "protobuf" in warn[0] and "my.Proto" in warn[0], res.stderr
    header, rows = read_csv(tmp_path / "good.csv")
    assert header == ["time", "/v/x", "/v/y", "/v/z"] and rows.tolist() == [[1.0, 1.0, 2.0, 3.0]]


def bounded(limit_bytes):
    """A child limited to `limit_bytes` of address space: memory that grows without bound
    ends the run instead of the machine's."""
    import resource

    def limit():
        resource.setrlimit(resource.RLIMIT_AS, (limit_bytes, limit_bytes))

    return limit


def test_a_glitched_first_stamp_is_an_error_not_unbounded_memory(binary, tmp_path):
    # A driver not yet synced stamps its first message 0.001 s, the rest Unix time: a
    # grid at 1 kHz would need 1.7e12 rows. Before: memory grew until the run aborted.
    store = typesys.get_typestore(typesys.Stores.ROS2_HUMBLE)
    t = store.types
    JointState, Header, Time = t["sensor_msgs/msg/JointState"], t["std_msgs/msg/Header"], t["builtin_interfaces/msg/Time"]
    path = tmp_path / "glitch"
    with rosbag2.Writer(path, version=9, storage_plugin=rosbag2.StoragePlugin.MCAP) as w:
        c = w.add_connection("/joint_states", "sensor_msgs/msg/JointState", typestore=store)
        for k in range(200):
            log_ns = T0_NS + k * 1_000_000
            stamp = 1_000_000 if k == 0 else log_ns
            msg = JointState(
                header=Header(stamp=Time(sec=stamp // 10**9, nanosec=stamp % 10**9), frame_id=""),
                name=["j1"],
                position=np.array([k * 1e-3]),
                velocity=np.array([1.0]),
                effort=np.array([0.0]),
            )
            w.write(c, log_ns, store.serialize_cdr(msg, "sensor_msgs/msg/JointState"))
    out = tmp_path / "glitch.csv"
    res = subprocess.run(
        [str(binary), "convert", "--in", str(path), "--resample-hz", "1000", "--out", str(out)],
        capture_output=True, text=True, timeout=120, preexec_fn=bounded(1 << 30),
    )
    err = [l for l in res.stderr.splitlines() if l.startswith("error:")]
    assert res.returncode == 1 and len(err) == 1, res.stderr
    assert "glitch" in err[0] and "/joint_states" in err[0] and "more than 10000000 rows" in err[0], err[0]
    assert not out.exists() and [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []
    # The same bag on the topic's own clock reads.
    run(binary, "convert", "--in", path, "--out", out, "--quiet")
    assert out.exists()


def test_schemas_that_would_expand_or_spin_are_read_at_once(binary, tmp_path):
    mcap_writer = pytest.importorskip("mcap.writer", reason="pip install mcap")

    def write(name, schema, body):
        path = tmp_path / name
        with open(path, "wb") as f:
            w = mcap_writer.Writer(f)
            w.start(profile="ros2")
            s = w.register_schema(name="p/msg/Root", encoding="ros2msg", data=schema.encode())
            c = w.register_channel(topic="/x", message_encoding="cdr", schema_id=s)
            for k in range(3):
                w.add_message(channel_id=c, log_time=(k + 1) * 1_000_000, publish_time=0, data=body)
            w.finish()
        return path

    # 24 levels, each using the next twice (2^24 uses of the last type), in 1 KB.
    # Before: the schema was copied per use, gigabytes, and the run aborted.
    text = "T1 a\nT1 b\n"
    for d in range(1, 24):
        text += f"===\nMSG: p/T{d}\nT{d + 1} a\nT{d + 1} b\n"
    text += "===\nMSG: p/T24\nfloat64 x\n"
    deep = write("deep.mcap", text, b"\x00\x01\x00\x00" + bytes(16))
    res = subprocess.run(
        [str(binary), "convert", "--in", str(deep), "--out", str(tmp_path / "deep.csv")],
        capture_output=True, text=True, timeout=60, preexec_fn=bounded(1 << 30),
    )
    err = [l for l in res.stderr.splitlines() if l.startswith("error:")]
    assert res.returncode == 1 and len(err) == 1 and "deep.mcap" in err[0] and "/x" in err[0], res.stderr

    # Four billion elements that hold no value, then one that does. Before: never ended.
    body = b"\x00\x01\x00\x00" + np.array([2.5]).tobytes()
    empty = write("empty.mcap", "Z[4000000000] z\nfloat64 v\n===\nMSG: p/Z\nfloat64[0] a\n", body)
    res = run(binary, "convert", "--in", empty, "--align", "none", "--out", tmp_path / "empty.csv")
    header, rows = read_csv(tmp_path / "empty.csv")
    assert header == ["time", "/x/v"] and rows[:, 1].tolist() == [2.5, 2.5, 2.5], res.stderr


def humble_writer(path, messages):
    """A rosbag2 SQLite bag of `(topic, type, log_ns, message)`, written by `rosbags`."""
    store = typesys.get_typestore(typesys.Stores.ROS2_HUMBLE)
    with rosbag2.Writer(path, version=9, storage_plugin=rosbag2.StoragePlugin.SQLITE3) as w:
        conns = {}
        for topic, kind, log_ns, build in messages:
            if topic not in conns:
                conns[topic] = w.add_connection(topic, kind, typestore=store)
            w.write(conns[topic], log_ns, store.serialize_cdr(build(store.types), kind))


def joint_state(stamp_ns, name, position):
    def build(t):
        stamp = t["builtin_interfaces/msg/Time"](sec=stamp_ns // 10**9, nanosec=stamp_ns % 10**9)
        header = t["std_msgs/msg/Header"](stamp=stamp, frame_id="")
        one = np.array([position])
        return t["sensor_msgs/msg/JointState"](header=header, name=[name], position=one, velocity=one, effort=one)

    return build


def test_two_publishers_on_one_topic_keep_their_own_rates(binary, tmp_path):
    # An arm at 1 kHz and a gripper at 10 Hz on /joint_states. Before: the gripper's
    # columns took the topic's 4 ms gap and were NaN in 2000 of 2020 rows.
    msgs = []
    for k in range(2000):
        t = T0_NS + k * 1_000_000
        msgs.append(("/joint_states", "sensor_msgs/msg/JointState", t, joint_state(t, "arm", k * 1e-3)))
        if k % 100 == 50:
            msgs.append(("/joint_states", "sensor_msgs/msg/JointState", t, joint_state(t, "gripper", k / 1000)))
    humble_writer(tmp_path / "two", msgs)
    out = tmp_path / "two.csv"
    run(binary, "convert", "--in", tmp_path / "two", "--out", out, "--quiet")
    header, rows = read_csv(out)
    g = rows[:, header.index("gripper.position")]
    inside = (rows[:, 0] >= rows[50, 0]) & (rows[:, 0] <= rows[1950, 0])
    assert not np.isnan(g[inside]).any(), f"{np.isnan(g[inside]).sum()} NaN between the gripper's samples"
    # Linear between its own samples (k = 50, 150, ...).
    assert np.allclose(g[inside], np.arange(2000)[inside] / 1000, atol=1e-9)


def test_topics_on_different_clocks_are_named_in_a_warning(binary, tmp_path):
    # JointState stamped in boot time, Float64 (no header) at log time: its column cannot
    # meet the clock. Before: all NaN, with no word.
    def torque(v):
        return lambda t: t["std_msgs/msg/Float64"](data=v)

    msgs = []
    for k in range(500):
        t = T0_NS + k * 1_000_000
        msgs.append(("/joint_states", "sensor_msgs/msg/JointState", t, joint_state(5 * 10**9 + k * 1_000_000, "j1", k)))
        if k % 10 == 0:
            msgs.append(("/torque", "std_msgs/msg/Float64", t, torque(float(k))))
    humble_writer(tmp_path / "mixed", msgs)
    res = run(binary, "convert", "--in", tmp_path / "mixed", "--out", tmp_path / "mixed.csv")
    warn = [l for l in res.stderr.splitlines() if "/torque" in l and "--time log" in l]
    assert len(warn) == 1 and "miss those of the clock topic `/joint_states`" in warn[0], res.stderr
    run(binary, "convert", "--in", tmp_path / "mixed", "--time", "log", "--out", tmp_path / "log.csv", "--quiet")
    header, rows = read_csv(tmp_path / "log.csv")
    assert not np.isnan(rows[:491, header.index("/torque/data")]).any()


def test_a_missing_part_of_a_split_bag_is_an_error_naming_it(binary, tmp_path):
    # Before: the parts listed in metadata.yaml but absent were skipped without a word,
    # leaving a jump in time.
    msgs = [
        ("/joint_states", "sensor_msgs/msg/JointState", T0_NS + k * 1_000_000, joint_state(T0_NS + k * 1_000_000, "j1", k))
        for k in range(100)
    ]
    humble_writer(tmp_path / "split", msgs)
    meta = tmp_path / "split" / "metadata.yaml"
    text = meta.read_text()
    assert "- split.db3" in text, text
    meta.write_text(text.replace("- split.db3", "- split.db3\n  - split_1.db3", 1))
    res = run(binary, "convert", "--in", tmp_path / "split", "--out", tmp_path / "split.csv", ok=False)
    err = [l for l in res.stderr.splitlines() if l.startswith("error:")]
    assert res.returncode == 1 and len(err) == 1, res.stderr
    assert "metadata.yaml lists `split_1.db3`, which is not in the folder" in err[0], err
    assert not (tmp_path / "split.csv").exists()
    # Older rosbag2 versions list `folder/file`; a renamed bag's stale list names no file
    # that is there, and the folder's files are read.
    meta.write_text(text.replace("- split.db3", "- split/split.db3", 1))
    run(binary, "convert", "--in", tmp_path / "split", "--out", tmp_path / "prefixed.csv", "--quiet")
    (tmp_path / "split" / "split.db3").rename(tmp_path / "split" / "renamed_0.db3")
    run(binary, "convert", "--in", tmp_path / "split", "--out", tmp_path / "renamed.csv", "--quiet")
    for out in ("prefixed.csv", "renamed.csv"):
        assert len(read_csv(tmp_path / out)[1]) == 100, out


def test_messages_at_one_time_are_counted_in_a_warning(binary, tmp_path):
    # A driver that stamps two messages alike: on one clock the second gives no row.
    # Before: 100 messages gave 90 rows without a word.
    msgs = []
    for k in range(100):
        stamp = T0_NS + (k - k % 10 // 9) * 1_000_000  # k = 9, 19, … repeat the stamp before
        msgs.append(("/joint_states", "sensor_msgs/msg/JointState", T0_NS + k * 1_000_000, joint_state(stamp, "j1", k)))
    humble_writer(tmp_path / "dup", msgs)
    res = run(binary, "convert", "--in", tmp_path / "dup", "--out", tmp_path / "dup.csv")
    header, rows = read_csv(tmp_path / "dup.csv")
    assert len(rows) == 90
    warn = [l for l in res.stderr.splitlines() if l.startswith("warning:")]
    assert len(warn) == 1, res.stderr
    assert "topic `/joint_states`: 10 message(s) give a column a second value at one time" in warn[0], warn
    assert f"(the first at {(T0_NS + 8_000_000) / 1e9} s)" in warn[0], warn
    res = run(binary, "convert", "--in", tmp_path / "dup", "--align", "none", "--out", tmp_path / "all.csv")
    assert len(read_csv(tmp_path / "all.csv")[1]) == 100 and "warning" not in res.stderr, res.stderr
    # Two joints in two messages stamped alike lose nothing, and raise no warning.
    msgs = []
    for k in range(100):
        stamp = T0_NS + k * 1_000_000
        for j in ("j1", "j2"):
            msgs.append(("/joint_states", "sensor_msgs/msg/JointState", stamp, joint_state(stamp, j, float(k))))
    humble_writer(tmp_path / "two", msgs)
    res = run(binary, "convert", "--in", tmp_path / "two", "--out", tmp_path / "two.csv")
    header, rows = read_csv(tmp_path / "two.csv")
    assert "warning" not in res.stderr and len(rows) == 100, res.stderr
    assert (rows[:, header.index("j2.position")] == np.arange(100)).all()


@pytest.mark.parametrize("storage", sorted(STORAGES))
def test_a_bag_compressed_message_by_message_or_file_by_file_reads(binary, tmp_path, storage):
    # rosbag2's `--compression-mode message`: each message a zstd frame. Before: "CDR
    # representation 0x28b5 is not supported" (the frame's magic taken for CDR).
    # `--compression-mode file`: each file one zstd stream (`bag_0.db3.zstd`). Before:
    # refused with "decompress it with `zstd -d`".
    store = typesys.get_typestore(typesys.Stores.ROS2_HUMBLE)
    kind = "std_msgs/msg/Float64"
    scratch = tmp_path / "tmp"
    scratch.mkdir()
    for mode in ("MESSAGE", "FILE"):
        path = tmp_path / f"{storage}_{mode.lower()}"
        w = rosbag2.Writer(path, version=8, storage_plugin=getattr(rosbag2.StoragePlugin, STORAGES[storage]))
        w.set_compression(getattr(rosbag2.CompressionMode, mode), rosbag2.CompressionFormat.ZSTD)
        with w:
            c = w.add_connection("/torque", kind, typestore=store)
            for k in range(100):
                data = store.serialize_cdr(store.types[kind](data=float(k) / 3), kind)
                w.write(c, T0_NS + k * 1_000_000, data)
        parts = sorted(p.name for p in path.iterdir() if p.name != "metadata.yaml")
        assert all(p.endswith(".zstd") for p in parts) == (mode == "FILE"), parts
        # The folder, and (compressed whole) its one file given alone.
        inputs = [path] + ([path / parts[0]] if mode == "FILE" else [])
        for k, given in enumerate(inputs):
            out = tmp_path / f"{storage}_{mode.lower()}_{k}.csv"
            res = subprocess.run(
                [str(binary), "convert", "--in", str(given), "--out", str(out), "--quiet"],
                capture_output=True, text=True, timeout=600, env={**os.environ, "TMPDIR": str(scratch)},
            )
            assert res.returncode == 0 and res.stderr == "", res.stderr
            header, rows = read_csv(out)
            assert header == ["time", "/torque/data"]
            assert rows[:, 1].tolist() == [k / 3 for k in range(100)]
            assert rows[:, 0].tolist() == [(T0_NS + k * 1_000_000) / 1e9 for k in range(100)]
    # The decompressed copies are gone.
    assert list(scratch.iterdir()) == []


@pytest.mark.parametrize("storage", sorted(STORAGES))
def test_a_bag_compressed_file_by_file_that_is_damaged_gets_one_line(binary, tmp_path, storage):
    """A file compressed whole that is not zstd, or cut short: an MCAP file gives the
    messages before the cut with a warning (as uncompressed), SQLite one line."""
    store = typesys.get_typestore(typesys.Stores.ROS2_HUMBLE)
    kind = "std_msgs/msg/Float64"
    path = tmp_path / "bag"
    w = rosbag2.Writer(path, version=8, storage_plugin=getattr(rosbag2.StoragePlugin, STORAGES[storage]))
    w.set_compression(rosbag2.CompressionMode.FILE, rosbag2.CompressionFormat.ZSTD)
    with w:
        c = w.add_connection("/torque", kind, typestore=store)
        for k in range(20000):
            # Values that do not compress much, so that the file has many blocks.
            data = store.serialize_cdr(store.types[kind](data=math.sin(k * 1.1) * 1e3), kind)
            w.write(c, T0_NS + k * 1_000_000, data)
    (part,) = [p for p in path.iterdir() if p.name.endswith(".zstd")]
    whole = part.read_bytes()
    part.write_bytes(whole[: len(whole) // 2])
    out = tmp_path / "cut.csv"
    res = run(binary, "convert", "--in", part, "--out", out, ok=False)
    lines = res.stderr.splitlines()
    if storage == "mcap":
        assert res.returncode == 0 and "ends before its footer" in lines[0], res.stderr
        header, rows = read_csv(out)
        assert 0 < len(rows) < 20000
    else:
        assert res.returncode == 1 and len(lines) == 1 and lines[0].startswith(f"error: {part}:"), res.stderr
        assert not out.exists()
    part.write_bytes(b"not zstd at all")
    res = run(binary, "convert", "--in", part, "--out", out, ok=False)
    assert res.returncode == 1 and res.stderr.splitlines() == [f"error: {part}: zstd: Unknown frame descriptor"]


@pytest.mark.parametrize("storage", sorted(STORAGES))
def test_transforms_are_columns_by_frame_not_by_place_in_the_message(binary, tmp_path, storage):
    # /tf carries the frames of several publishers: robot_state_publisher's links in one
    # message, a localization's odom -> base_link in another. Before: `transforms.0.*`
    # took whichever frame came first in each message (link1's x, then base_link's).
    store = typesys.get_typestore(typesys.Stores.ROS2_HUMBLE)
    T = store.types
    kind = "tf2_msgs/msg/TFMessage"

    def transform(stamp, child, x):
        t = T["builtin_interfaces/msg/Time"](sec=stamp // 10**9, nanosec=stamp % 10**9)
        return T["geometry_msgs/msg/TransformStamped"](
            header=T["std_msgs/msg/Header"](stamp=t, frame_id="base"),
            child_frame_id=child,
            transform=T["geometry_msgs/msg/Transform"](
                translation=T["geometry_msgs/msg/Vector3"](x=x, y=0.0, z=0.0),
                rotation=T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
            ),
        )

    path = tmp_path / "tf"
    with rosbag2.Writer(path, version=8, storage_plugin=getattr(rosbag2.StoragePlugin, STORAGES[storage])) as w:
        c = w.add_connection("/tf", kind, typestore=store)
        for k in range(100):
            stamp = T0_NS + k * 1_000_000
            frames = [("link1", 1.0), ("link2", 2.0)] if k % 2 == 0 else [("base_link", 3.0)]
            message = T[kind](transforms=[transform(stamp, child, x) for child, x in frames])
            w.write(c, stamp, store.serialize_cdr(message, kind))
    out = tmp_path / "tf.csv"
    res = run(binary, "convert", "--in", path, "--out", out, "--quiet")
    header, rows = read_csv(out)
    assert "/tf/transforms.0.transform.translation.x" not in header, header
    for frame, x in (("link1", 1.0), ("link2", 2.0), ("base_link", 3.0)):
        column = rows[:, header.index(f"/tf/{frame}.translation.x")]
        assert np.all(column[~np.isnan(column)] == x) and np.sum(~np.isnan(column)) >= 49, (frame, column[:6])
        assert np.all(rows[~np.isnan(column), header.index(f"/tf/{frame}.rotation.w")] == 1.0)


def test_the_package_reads_each_storage_as_the_command_line(binary, bag, tmp_path):
    # Before: a `.db3` bag (rosbag2's default storage on Humble) gave "this build has no
    # `sqlite` support" in Python.
    sw = pytest.importorskip("strainwave", reason="pip install ./python (./scripts/test-all does)")
    out = tmp_path / "cli.csv"
    run(binary, "convert", "--in", bag["folder"], "--out", out)
    header, rows = read_csv(out)
    for source in (bag["folder"], bag["file"]):
        df = sw.read_recording(source)
        assert df.columns.tolist() == header
        assert np.array_equal(df.to_numpy(), rows, equal_nan=True), source
