"""The Spark pattern of docs/spark.md (`applyInPandas`, one group per recording) gives the
command line's numbers bit for bit. Runs only where pyspark and Java are installed."""

import shutil

import pytest
from conftest import ROOT, assert_bitwise_equal, read_csv_exact

pd = pytest.importorskip("pandas")
sw = pytest.importorskip("strainwave", reason="pip install ./python (./scripts/test-all does)")
pyspark_sql = pytest.importorskip("pyspark.sql", reason="pip install pyspark")
if shutil.which("java") is None:
    pytest.skip("no Java runtime (Spark needs one)", allow_module_level=True)

CONFIG = ROOT / "examples" / "joint-taghirad.toml"


def test_apply_in_pandas_is_the_cli(cli, tmp_path):
    frames, outs = [], []
    for s in (21, 22):
        rec, out = tmp_path / f"r{s}.csv", tmp_path / f"r{s}-out.csv"
        assert cli("simulate", "--preset", "taghirad", "--duration", 2, "--seed", s, "--out", rec, "--quiet").returncode == 0
        assert cli("filter", "--config", CONFIG, "--in", rec, "--out", out, "--quiet").returncode == 0
        df = sw.read_recording(rec)
        df.insert(0, "recording", s)
        frames.append(df)
        outs.append(out)

    spark = pyspark_sql.SparkSession.builder.master("local[2]").appName("strainwave-test").getOrCreate()
    try:
        sdf = spark.createDataFrame(pd.concat(frames, ignore_index=True))
        config = str(CONFIG)

        def filter_one(pdf):
            # One recording per group, in time order (Spark does not keep row order).
            pdf = pdf.sort_values("time", kind="stable").reset_index(drop=True)
            out = sw.filter_recording(pdf.drop(columns=["recording"]), config=config)
            out.insert(0, "recording", pdf["recording"].iloc[0])
            return out

        schema = sdf.schema
        for c in sw.OUTPUT_COLUMNS:
            schema = schema.add(c, "double")
        got = sdf.groupBy("recording").applyInPandas(filter_one, schema=schema).toPandas()
    finally:
        spark.stop()
    for s, out in zip((21, 22), outs):
        part = got[got["recording"] == s].sort_values("time", kind="stable")
        names, cols = read_csv_exact(out)
        for n, c in zip(names, cols):
            assert_bitwise_equal(part[n].to_numpy(), c, f"recording {s} {n}")
