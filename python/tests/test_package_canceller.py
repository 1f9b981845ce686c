"""`strainwave.RippleCanceller`, the streaming canceller, against the command line: a
recording run through it (in one block, in uneven blocks, or sample by sample) gives
`strainwave filter`'s columns bit for bit, under the do-no-harm guard (the default) and
with `guard = false`; its health summary is the one `filter` prints."""

import re

import pytest
from conftest import ROOT, assert_bitwise_equal, read_csv_exact

np = pytest.importorskip("numpy")
pd = pytest.importorskip("pandas")
sw = pytest.importorskip("strainwave", reason="pip install ./python (./scripts/test-all does)")

CONFIG = ROOT / "examples" / "joint-taghirad.toml"
TAGHIRAD_6TH = ROOT / "examples" / "joint-taghirad-6th-order.toml"


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


def config_copy(config, folder, guard):
    """A copy of `config` in `folder` (its learned file by full path), with `guard = false`
    unless `guard`."""
    text = absolute_learned(config.read_text(), config)
    if not guard:
        text = text.replace("[filter]", "[filter]\nguard = false", 1)
    path = folder / (("guarded-" if guard else "bare-") + config.name)
    path.write_text(text)
    return path


def cli_filter(cli, config, recording, out, *extra, guard=False):
    """`strainwave filter` over `recording` with a copy of `config` (`guard = false`
    unless `guard`): (the output's columns, the copy's path, the command's stderr)."""
    copy = config_copy(config, out.parent, guard)
    res = cli("filter", "--config", copy, "--in", recording, "--out", out, *extra)
    assert res.returncode == 0, res.stderr
    names, cols = read_csv_exact(out)
    return dict(zip(names, cols)), copy, res.stderr


def assert_block_is_cli(got, cli_cols, what):
    for name, values in got.items():
        assert name in cli_cols, f"{what}: `{name}` not in the command line's output"
        assert_bitwise_equal(values, cli_cols[name], f"{what} column {name}")


@pytest.fixture(scope="module")
def cold_config(tmp_path_factory):
    """joint-taghirad.toml without its learned file: the `full` model starts cold, as the
    guard starts it."""
    text = CONFIG.read_text()
    assert 'learned = "joint-taghirad-learned.toml"' in text
    path = tmp_path_factory.mktemp("cfg") / "joint-cold.toml"
    path.write_text(text.replace('learned = "joint-taghirad-learned.toml"', ""))
    return path


@pytest.fixture(scope="module")
def velocity_config(tmp_path_factory):
    """The Taghirad 6th-order model with its phase from the tachometer (`filter.phase = "velocity"`)."""
    text = TAGHIRAD_6TH.read_text()
    assert 'phase = "angle"' in text
    path = tmp_path_factory.mktemp("cfg") / "joint-velocity.toml"
    path.write_text(text.replace('phase = "angle"', 'phase = "velocity"'))
    return path


def health_lines(stderr):
    """The health summary `filter` prints: its `health:` line and the order lines after it."""
    lines = stderr.splitlines()
    start = next(i for i, l in enumerate(lines) if l.startswith("health: "))
    end = start + 1
    while end < len(lines) and lines[end].startswith("  "):
        end += 1
    return lines[start:end]


@pytest.mark.parametrize("guard", [True, False], ids=["guard", "bare"])
@pytest.mark.parametrize("config", ["full", "cold", "taghirad-6th", "denoised", "velocity"])
def test_run_is_the_cli_bit_for_bit(
    cli, recording, tmp_path, cold_config, denoised_config, velocity_config, config, guard
):
    config = {
        "full": CONFIG,
        "cold": cold_config,
        "taghirad-6th": TAGHIRAD_6TH,
        "denoised": denoised_config,
        "velocity": velocity_config,
    }[config]
    expected, copy, stderr = cli_filter(cli, config, recording, tmp_path / "out.csv", guard=guard)
    rec = sw.read_recording(recording)
    c = sw.RippleCanceller.from_config(copy)
    assert c.guard is guard and not c.learning
    got = c.run(rec)
    assert list(got) == sw.OUTPUT_COLUMNS + (["torque_denoised"] if config == denoised_config else [])
    assert all(len(v) == len(rec) for v in got.values())
    assert_block_is_cli(got, expected, "one block")
    assert c.samples == len(rec)
    h = c.health()
    if guard:
        # The summary `filter` prints, line for line, and its warnings among the command's.
        assert h["lines"] == health_lines(stderr), stderr
        assert h["samples"] == len(rec) and h["expected_nis"] == 1.0
        assert h["lines"][0].startswith(f"health: mean NIS {h['mean_nis']:.2f} (expected 1)")
        assert [o for o, _ in h["applied_share"]] == [l.split(" applied ")[0].strip() for l in h["lines"][1:]]
        assert all(0.0 <= share <= 1.0 for _, share in h["applied_share"])
        for w in h["warnings"]:
            assert f"warning: {w}" in stderr.splitlines(), (w, stderr)
        # Some sample carries guard bits (bits 8 and up) or the corrections were all applied.
        flags = got["filter_flags"].astype(np.int64)
        assert (flags >> 8).any() or all(share == 1.0 for _, share in h["applied_share"])
    else:
        assert h is None and "health:" not in stderr
    # Uneven blocks, one of them empty: the state carries over.
    c.reset()
    edges = [0, 1, 2, 700, 700, 1999, len(rec)]
    parts = [c.run(rec.iloc[a:b]) for a, b in zip(edges, edges[1:])]
    joined = {k: np.concatenate([p[k] for p in parts]) for k in got}
    assert_block_is_cli(joined, expected, "blocks after reset")


@pytest.mark.parametrize("guard", [True, False], ids=["guard", "bare"])
def test_step_loop_equals_run(recording, tmp_path, guard):
    config = config_copy(CONFIG, tmp_path, guard)
    rec = sw.read_recording(recording).iloc[:1500]
    whole = sw.RippleCanceller.from_config(config).run(rec)
    c = sw.RippleCanceller.from_config(config)
    torque, flags = [], []
    for t, v, m, o in rec[["time", "bridge_voltage", "motor_angle", "output_angle"]].itertuples(index=False):
        q, f = c.step(v, m, o, time=t)
        torque.append(q)
        flags.append(f)
    assert_bitwise_equal(np.array(torque), whole["torque"], "step torque")
    assert np.array_equal(np.array(flags, dtype=np.float64), whole["filter_flags"])
    assert c.samples == 1500
    if guard:
        assert c.health()["samples"] == 1500


def test_nan_samples_are_flagged_not_errors(recording):
    rec = sw.read_recording(recording).iloc[:200].copy()
    rec.loc[100, "bridge_voltage"] = np.nan
    out = sw.RippleCanceller.from_config(TAGHIRAD_6TH).run(rec)
    skipped = 1  # StepFlags::MEASUREMENT_SKIPPED
    assert int(out["filter_flags"][100]) & skipped
    assert not any(int(f) & skipped for f in np.delete(out["filter_flags"], 100))
    assert np.isfinite(out["torque"][101:]).all()


def test_a_text_cell_is_a_flagged_sample_too(recording):
    # As a NaN: `run` skips what it cannot use (before: "`OVL` is not a number").
    rec = sw.read_recording(recording).iloc[:200].astype({"bridge_voltage": object})
    rec.loc[100, "bridge_voltage"] = "OVL"
    with pytest.warns(sw.RecordingWarning, match=r"1 cell\(s\) that are not numbers read as NaN, the first at row 101"):
        out = sw.RippleCanceller.from_config(TAGHIRAD_6TH).run(rec)
    assert int(out["filter_flags"][100]) & 1 and np.isfinite(out["torque"][101:]).all()


def test_an_overrange_code_is_skipped_and_the_canceller_goes_on(recording):
    rec = sw.read_recording(recording).iloc[:400].copy()
    rec.loc[250, "bridge_voltage"] = 9.9e37  # a DAQ's overrange code
    c = sw.RippleCanceller.from_config(CONFIG)
    out = c.run(rec)
    skipped = 1  # StepFlags::MEASUREMENT_SKIPPED
    assert int(out["filter_flags"][250]) & skipped
    assert np.isnan(out["nis"][250])
    assert np.abs(out["torque"][251:]).max() < 100.0
    # The next call goes on from there.
    assert np.isfinite(c.run(rec.iloc[:50])["torque"]).all()


def test_a_canceller_is_not_copied_by_reference():
    import copy

    c = sw.RippleCanceller.from_config(CONFIG)
    for how in (copy.copy, copy.deepcopy):
        with pytest.raises(TypeError, match="cannot be copied"):
            how(c)


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
    reason = "joint.toml: `filter.noise_nm` must be positive"
    assert str(e.value).endswith(reason) and expected.endswith(reason), (str(e.value), expected)
    with pytest.raises(sw.StrainwaveError, match="nope.toml"):
        sw.RippleCanceller.from_config(CONFIG, learned=tmp_path / "nope.toml")
    with pytest.raises(sw.StrainwaveError, match="does not learn"):
        sw.RippleCanceller.from_config(CONFIG).save_learned(tmp_path / "l.toml")
    with pytest.raises(sw.StrainwaveError, match="no path"):
        sw.RippleCanceller.from_config(CONFIG, learn=True).save_learned()
    with pytest.raises(TypeError, match="learn"):
        sw.RippleCanceller.from_config(CONFIG, learn=3)


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
    expected, copy, _ = cli_filter(cli, TAGHIRAD_6TH, bad, tmp_path / "out.csv", "--lenient", "--quiet", guard=True)
    got = sw.RippleCanceller.from_config(copy).run(sw.read_recording(bad))
    assert_block_is_cli(got, expected, "lenient run")
    assert int(got["filter_flags"][100]) & 1 and int(got["filter_flags"][200]) & 2
