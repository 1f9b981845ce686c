"""`strainwave.RippleCanceller` learning as `strainwave filter --learn FILE` does: a cold
canceller learns beside the output, and `save_learned` writes the file the command
writes, byte for byte, both for a new file and for a merge into an existing one; a file
of another joint is refused with the command's message."""

import os
import shutil

import pytest
from conftest import ROOT, assert_bitwise_equal, read_csv_exact

np = pytest.importorskip("numpy")
tomllib = pytest.importorskip("tomllib", reason="Python 3.11 or later (tomllib)")
sw = pytest.importorskip("strainwave", reason="pip install ./python (./scripts/test-all does)")

CONFIG = ROOT / "examples" / "joint-taghirad.toml"
TAGHIRAD_6TH = ROOT / "examples" / "joint-taghirad-6th-order.toml"


@pytest.fixture(scope="module")
def runs(cli, tmp_path_factory):
    """Two 8 s recordings of the taghirad twin (seeds 21 and 22), written by `strainwave simulate`."""
    d = tmp_path_factory.mktemp("learn-recs")
    paths = []
    for seed in (21, 22):
        path = d / f"run{seed}.csv"
        res = cli("simulate", "--preset", "taghirad", "--duration", 8, "--seed", seed, "--out", path, "--quiet")
        assert res.returncode == 0, res.stderr
        paths.append(path)
    return paths


def cli_learn(cli, config, recording, learned, out):
    res = cli("filter", "--config", config, "--in", recording, "--out", out, "--learn", learned)
    assert res.returncode == 0, res.stderr
    return res.stderr


def notes(stderr):
    return [l[len("note: ") :] for l in stderr.splitlines() if l.startswith("note: ")]


def test_a_new_file_is_filter_learn_byte_for_byte(cli, runs, tmp_path):
    cli_file, py_file = tmp_path / "cli-learned.toml", tmp_path / "py-learned.toml"
    stderr = cli_learn(cli, CONFIG, runs[0], cli_file, tmp_path / "out.csv")
    c = sw.RippleCanceller.from_config(CONFIG, learn=py_file)
    assert c.learning and c.guard
    out = c.run(sw.read_recording(runs[0]))
    lines = c.save_learned()
    assert py_file.read_bytes() == cli_file.read_bytes()
    # The report lines are the notes the command printed.
    cli_notes = [n.replace(str(cli_file), str(py_file)) for n in notes(stderr)]
    assert lines and all(l in cli_notes for l in lines), (lines, stderr)
    # The output is the guarded canceller's, as `filter --learn` writes it.
    names, cols = read_csv_exact(tmp_path / "out.csv")
    for n, col in zip(names, cols):
        if n in out:
            assert_bitwise_equal(out[n], col, n)
    # learned() lists the file's entries.
    entries = c.learned()
    assert [e[0] for e in entries[:5]] == ["relative", "relative", "relative", "relative", "output"]
    with open(py_file, "rb") as f:
        saved = tomllib.load(f)["orders"]
    assert [(o["reference"], o["multiple"], o["load_scaled"], o["cos_nm"], o["sin_nm"], o["variance_nm2"]) for o in saved] == entries
    # Written atomically: nothing but the file is left in the folder.
    assert sorted(os.listdir(tmp_path)) == ["cli-learned.toml", "out.csv", "py-learned.toml"]


def test_a_merge_into_an_existing_file_is_filter_learn_byte_for_byte(cli, runs, tmp_path):
    first = tmp_path / "first.toml"
    cli_learn(cli, CONFIG, runs[0], first, tmp_path / "out0.csv")
    cli_file, py_file = tmp_path / "cli.toml", tmp_path / "py.toml"
    shutil.copy(first, cli_file)
    shutil.copy(first, py_file)
    cli_learn(cli, CONFIG, runs[1], cli_file, tmp_path / "out1.csv")
    assert cli_file.read_bytes() != first.read_bytes()
    assert "runs = 2" in cli_file.read_text()
    c = sw.RippleCanceller.from_config(CONFIG, learn=py_file)
    rec = sw.read_recording(runs[1])
    for block in np.array_split(np.arange(len(rec)), 3):
        c.run(rec.iloc[block], input_name=str(runs[1]))
    c.save_learned()
    assert py_file.read_bytes() == cli_file.read_bytes()


def test_learn_true_saves_anywhere_and_reset_starts_over(cli, runs, tmp_path):
    cli_file = tmp_path / "cli.toml"
    cli_learn(cli, CONFIG, runs[0], cli_file, tmp_path / "out.csv")
    c = sw.RippleCanceller.from_config(CONFIG, learn=True)
    c.run(sw.read_recording(runs[1]))
    c.reset()
    assert c.samples == 0
    c.run(sw.read_recording(runs[0]))
    c.save_learned(tmp_path / "py.toml")
    assert (tmp_path / "py.toml").read_bytes() == cli_file.read_bytes()
    # merge=False replaces an existing file with the run's own learning.
    existing = tmp_path / "existing.toml"
    shutil.copy(ROOT / "examples" / "joint-taghirad-learned.toml", existing)
    c.save_learned(existing, merge=False)
    assert existing.read_bytes() == cli_file.read_bytes()
    # That file holds an order discovered in this run; this canceller did not learn it
    # (it started without the file), so merging into it is refused, naming the way.
    if "discovered = true" in existing.read_text():
        with pytest.raises(sw.StrainwaveError, match="start with learn="):
            c.save_learned(existing)
        assert existing.read_bytes() == cli_file.read_bytes()


def test_a_file_of_another_joint_is_refused_as_filter_refuses_it(cli, runs, tmp_path):
    other = tmp_path / "other.toml"
    cli_learn(cli, TAGHIRAD_6TH, runs[0], other, tmp_path / "out.csv")
    before = other.read_bytes()
    res = cli("filter", "--config", CONFIG, "--in", runs[0], "--out", tmp_path / "x.csv", "--learn", other)
    assert res.returncode == 1
    expected = [l for l in res.stderr.splitlines() if l.startswith("error: ")][0][len("error: ") :]
    assert "another joint" in expected
    with pytest.raises(sw.StrainwaveError) as e:
        sw.RippleCanceller.from_config(CONFIG, learn=other)
    assert str(e.value) == expected
    # Saved into later: refused too, and the file is left as it was.
    c = sw.RippleCanceller.from_config(CONFIG, learn=True)
    c.run(sw.read_recording(runs[0]).iloc[:2000])
    with pytest.raises(sw.StrainwaveError, match="another joint"):
        c.save_learned(other)
    assert other.read_bytes() == before


def test_saving_over_the_config_is_refused(runs, tmp_path):
    """As `filter --learn` refuses it: the config the canceller reads is not a learned file."""
    config = tmp_path / "joint.toml"
    config.write_text(
        CONFIG.read_text().replace(
            'learned = "joint-taghirad-learned.toml"', f"learned = {str(ROOT / 'examples' / 'joint-taghirad-learned.toml')!r}"
        )
    )
    before = config.read_bytes()
    c = sw.RippleCanceller.from_config(config, learn=True)
    c.run(sw.read_recording(runs[0]).iloc[:2000])
    with pytest.raises(sw.StrainwaveError, match="is also an input"):
        c.save_learned(config, merge=False)
    assert config.read_bytes() == before
