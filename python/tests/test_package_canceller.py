"""`strainwave.RippleCanceller`, the streaming canceller, against the command line: a
recording run through it (in one block, in uneven blocks, or sample by sample) gives
`strainwave filter`'s columns bit for bit, the command run with the bare canceller
(`guard = false`), which is what `RippleCanceller` runs."""

import re

import pytest
from conftest import ROOT, assert_bitwise_equal, read_csv_exact

np = pytest.importorskip("numpy")
pd = pytest.importorskip("pandas")
sw = pytest.importorskip("strainwave", reason="pip install ./python (./scripts/test-all does)")

CONFIG = ROOT / "examples" / "joint-taghirad.toml"
SEED_6TH = ROOT / "examples" / "joint-taghirad-seed-6th.toml"


@pytest.fixture(scope="module")
def recording(cli, tmp_path_factory):
    """3 s of the taghirad twin written by `strainwave simulate`."""
    path = tmp_path_factory.mktemp("rec") / "taghirad.csv"
    res = cli("simulate", "--preset", "taghirad", "--duration", 3, "--seed", 5, "--out", path, "--quiet")
    assert res.returncode == 0, res.stderr
    return path


@pytest.fixture(scope="module")
def denoised_config(tmp_path_factory):
    """joint-taghirad.toml with the torque denoiser on (and its learned file by full path)."""
    learned = ROOT / "examples" / "joint-taghirad-learned.toml"
    text = CONFIG.read_text().replace('learned = "joint-taghirad-learned.toml"', f"learned = {str(learned)!r}")
    text = text.replace("# torque_bandwidth_hz = 20.0", "torque_bandwidth_hz = 20.0")
    assert "torque_bandwidth_hz = 20.0" in text and str(learned) in text
    path = tmp_path_factory.mktemp("cfg") / "joint-denoised.toml"
    path.write_text(text)
    return path


def absolute_learned(text, config):
    """The config's text with its learned file named by full path (for a copy elsewhere)."""
    return re.sub(r'^learned = "([^"/]+)"', lambda m: f"learned = {str(config.parent / m.group(1))!r}", text, flags=re.M)


def cli_filter(cli, config, recording, out, *extra):
    """`strainwave filter` with the bare canceller (`guard = false`), which is what
    `RippleCanceller` runs, as the C ABI does; the do-no-harm guard is the command's."""
    text = absolute_learned(config.read_text(), config).replace("[filter]", "[filter]\nguard = false", 1)
    bare = out.parent / ("bare-" + config.name)
    bare.write_text(text)
    res = cli("filter", "--config", bare, "--in", recording, "--out", out, "--quiet", *extra)
    assert res.returncode == 0, res.stderr
    names, cols = read_csv_exact(out)
    return dict(zip(names, cols))


def assert_block_is_cli(got, cli_cols, what):
    for name, values in got.items():
        assert name in cli_cols, f"{what}: `{name}` not in the command line's output"
        assert_bitwise_equal(values, cli_cols[name], f"{what} column {name}")


@pytest.fixture(scope="module")
def velocity_config(tmp_path_factory):
    """The Taghirad 6th-order model with its phase from the tachometer (`filter.phase = "velocity"`)."""
    text = SEED_6TH.read_text()
    assert 'phase = "angle"' in text
    path = tmp_path_factory.mktemp("cfg") / "joint-velocity.toml"
    path.write_text(text.replace('phase = "angle"', 'phase = "velocity"'))
    return path


@pytest.mark.parametrize("config", ["full", "seed-6th", "denoised", "velocity"])
def test_run_is_the_cli_bit_for_bit(cli, recording, tmp_path, denoised_config, velocity_config, config):
    config = {"full": CONFIG, "seed-6th": SEED_6TH, "denoised": denoised_config, "velocity": velocity_config}[config]
    expected = cli_filter(cli, config, recording, tmp_path / "out.csv")
    rec = sw.read_recording(recording)
    c = sw.RippleCanceller.from_config(config)
    got = c.run(rec)
    assert list(got) == sw.OUTPUT_COLUMNS + (["torque_denoised"] if config == denoised_config else [])
    assert all(len(v) == len(rec) for v in got.values())
    assert_block_is_cli(got, expected, "one block")
    assert c.samples == len(rec)
    # Uneven blocks, one of them empty: the state carries over.
    c.reset()
    edges = [0, 1, 2, 700, 700, 1999, len(rec)]
    parts = [c.run(rec.iloc[a:b]) for a, b in zip(edges, edges[1:])]
    joined = {k: np.concatenate([p[k] for p in parts]) for k in got}
    assert_block_is_cli(joined, expected, "blocks after reset")


def test_step_loop_equals_run(recording):
    rec = sw.read_recording(recording).iloc[:1500]
    whole = sw.RippleCanceller.from_config(CONFIG).run(rec)
    c = sw.RippleCanceller.from_config(CONFIG)
    torque, flags = [], []
    for t, v, m, o in rec[["time", "bridge_voltage", "motor_angle", "output_angle"]].itertuples(index=False):
        q, f = c.step(v, m, o, time=t)
        torque.append(q)
        flags.append(f)
    assert_bitwise_equal(np.array(torque), whole["torque"], "step torque")
    assert np.array_equal(np.array(flags, dtype=np.float64), whole["filter_flags"])
    assert c.samples == 1500


def test_nan_samples_are_flagged_not_errors(recording):
    rec = sw.read_recording(recording).iloc[:200].copy()
    rec.loc[100, "bridge_voltage"] = np.nan
    out = sw.RippleCanceller.from_config(SEED_6TH).run(rec)
    skipped = 1  # StepFlags::MEASUREMENT_SKIPPED
    assert int(out["filter_flags"][100]) & skipped
    assert not any(int(f) & skipped for f in np.delete(out["filter_flags"], 100))
    assert np.isfinite(out["torque"][101:]).all()


def test_errors_are_the_cli_messages(cli, recording, tmp_path):
    df = sw.read_recording(recording).rename(columns={"output_angle": "out_angle"})
    bad = tmp_path / "renamed.csv"
    sw.write_recording(df, bad)
    res = cli("filter", "--config", CONFIG, "--in", bad, "--out", tmp_path / "x.csv")
    assert res.returncode == 1
    expected = [l for l in res.stderr.splitlines() if l.startswith("error: ")][0][len("error: ") :]
    assert "no column `output_angle`" in expected
    with pytest.raises(sw.StrainwaveError) as e:
        sw.RippleCanceller.from_config(CONFIG).run(sw.read_recording(bad))
    assert str(e.value) == expected
    cfg = tmp_path / "joint.toml"
    cfg.write_text(absolute_learned(CONFIG.read_text(), CONFIG).replace("noise_nm = 0.0162", "noise_nm = -1.0"))
    res = cli("filter", "--config", cfg, "--in", recording, "--out", tmp_path / "y.csv")
    assert res.returncode == 1
    expected = [l for l in res.stderr.splitlines() if l.startswith("error: ")][0][len("error: ") :]
    with pytest.raises(sw.StrainwaveError) as e:
        sw.RippleCanceller.from_config(cfg)
    # The command names the key through the learned file's check; the reason is the same.
    reason = "joint.toml: `noise_nm` must be positive"
    assert str(e.value).endswith(reason) and expected.endswith(reason), (str(e.value), expected)
    with pytest.raises(sw.StrainwaveError, match="nope.toml"):
        sw.RippleCanceller.from_config(CONFIG, learned=tmp_path / "nope.toml")
    with pytest.raises(sw.StrainwaveError, match="learn=True"):
        sw.RippleCanceller.from_config(CONFIG, learned=ROOT / "examples" / "joint-taghirad-learned.toml", learn=True)


def test_bad_rows_are_filter_lenient(cli, recording, tmp_path):
    """NaN readings, a missing angle and a time step back: the canceller flags and goes
    on, with `filter --lenient`'s numbers."""
    rec = sw.read_recording(recording).iloc[:1200].copy()
    rec.loc[100, "bridge_voltage"] = np.nan
    rec.loc[200, "motor_angle"] = np.nan
    rec.loc[300, "time"] = rec.loc[250, "time"]
    rec.loc[400:402, "output_angle"] = np.inf
    bad = tmp_path / "bad.csv"
    sw.write_recording(rec, bad)
    expected = cli_filter(cli, SEED_6TH, bad, tmp_path / "out.csv", "--lenient")
    got = sw.RippleCanceller.from_config(SEED_6TH).run(sw.read_recording(bad))
    assert_block_is_cli(got, expected, "lenient run")
    assert int(got["filter_flags"][100]) & 1 and int(got["filter_flags"][200]) & 2
