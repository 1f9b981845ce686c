"""`strainwave.dask.filter_many` on a local Dask cluster of two worker processes: every
recording's output is the command line's, bit for bit."""

import pytest
from conftest import ROOT, assert_bitwise_equal, read_csv_exact

np = pytest.importorskip("numpy")
pd = pytest.importorskip("pandas")
sw = pytest.importorskip("strainwave", reason="pip install ./python (./scripts/test-all does)")
distributed = pytest.importorskip("distributed", reason="pip install 'dask[distributed]'")
dd = pytest.importorskip("dask.dataframe", reason="pip install 'dask[dataframe]'")
import strainwave.dask  # noqa: E402

CONFIG = ROOT / "examples" / "joint-taghirad.toml"
SEEDS = [11, 12, 13, 14]


@pytest.fixture(scope="module")
def client():
    cluster = distributed.LocalCluster(
        n_workers=2, processes=True, threads_per_worker=1, dashboard_address=None, silence_logs=40
    )
    with distributed.Client(cluster) as c:
        yield c
    cluster.close()


@pytest.fixture(scope="module")
def fleet(cli, tmp_path_factory):
    """Four recordings (twin seeds) and the command line's filtered output of each."""
    d = tmp_path_factory.mktemp("fleet")
    recs, outs = [], []
    for s in SEEDS:
        rec, out = d / f"joint{s}.csv", d / f"joint{s}-cli.csv"
        res = cli("simulate", "--preset", "taghirad", "--duration", 3, "--seed", s, "--out", rec, "--quiet")
        assert res.returncode == 0, res.stderr
        res = cli("filter", "--config", CONFIG, "--in", rec, "--out", out, "--quiet")
        assert res.returncode == 0, res.stderr
        recs.append(rec)
        outs.append(out)
    return recs, outs


def test_filter_many_files_on_two_worker_processes(client, fleet, tmp_path):
    recs, outs = fleet
    done = strainwave.dask.filter_many(recs, CONFIG, out_dir=tmp_path / "out")
    assert [d.input for d in done] == [str(r) for r in recs]
    assert all(d.rows == 3000 for d in done)
    for d, cli_out in zip(done, outs):
        assert open(d.output, "rb").read() == cli_out.read_bytes(), d.output
    # Both worker processes took part.
    assert len(client.scheduler_info()["workers"]) == 2


def test_filter_many_returns_frames(client, fleet):
    recs, outs = fleet
    frames = strainwave.dask.filter_many(recs, CONFIG)
    for df, cli_out in zip(frames, outs):
        names, cols = read_csv_exact(cli_out)
        assert list(df.columns) == names
        for n, c in zip(names, cols):
            assert_bitwise_equal(df[n].to_numpy(), c, f"{cli_out.name} {n}")


def test_filter_many_over_a_partitioned_dataframe(client, fleet):
    recs, outs = fleet
    # One partition per recording, each read on its worker.
    meta = sw.read_recording(recs[0]).iloc[:0]
    ddf = dd.from_map(sw.read_recording, [str(r) for r in recs], meta=meta)
    assert ddf.npartitions == len(recs)
    got = strainwave.dask.filter_many(ddf, CONFIG).compute()
    want = pd.concat([sw.read_recording(o) for o in outs])
    assert list(got.columns) == list(want.columns)
    for c in want.columns:
        assert_bitwise_equal(got[c].to_numpy(), want[c].to_numpy(), c)


def test_filter_many_over_a_parquet_dataset(client, fleet, tmp_path):
    pytest.importorskip("pyarrow", reason="pip install pyarrow")
    recs, outs = fleet
    for r in recs:
        sw.write_recording(sw.read_recording(r), tmp_path / (r.stem + ".parquet"))
    ddf = dd.read_parquet(str(tmp_path), split_row_groups=False)
    assert ddf.npartitions == len(recs)
    got = strainwave.dask.filter_many(ddf, CONFIG).compute()
    want = pd.concat([sw.read_recording(o) for o in outs])
    assert list(got.columns) == list(want.columns)
    for c in want.columns:
        assert_bitwise_equal(got[c].to_numpy(), want[c].to_numpy(), c)


def test_filter_many_reports_the_cli_error(client, fleet, tmp_path):
    recs, _ = fleet
    with pytest.raises(Exception, match=r"nope\.csv"):
        strainwave.dask.filter_many([recs[0], tmp_path / "nope.csv"], CONFIG, out_dir=tmp_path / "o")
