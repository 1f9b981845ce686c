"""`strainwave.welch`, `stft` and `orders` from Python: the order table against the
`strainwave orders` command on the same recording, its errors against the command's,
and the spectra against scipy on the same samples."""

import math

import pytest
from conftest import ROOT

np = pytest.importorskip("numpy")
pd = pytest.importorskip("pandas")
sw = pytest.importorskip("strainwave", reason="pip install ./python (./scripts/test-all does)")


@pytest.fixture(scope="module")
def bench(cli, tmp_path_factory):
    """10 s of the kit-bench twin (a run-up), written by `strainwave simulate`."""
    path = tmp_path_factory.mktemp("bench") / "bench.csv"
    res = cli("simulate", "--preset", "kit-bench", "--duration", 10, "--seed", 1, "--out", path, "--quiet")
    assert res.returncode == 0, res.stderr
    return path


def cli_error(res):
    assert res.returncode == 1, f"expected the command line to fail:\n{res.stderr}"
    lines = [l for l in res.stderr.splitlines() if l.startswith("error: ")]
    assert len(lines) == 1, res.stderr
    return lines[0][len("error: ") :]


def parse_orders_table(stdout):
    """`strainwave orders` stdout: rows of (low, high, [amplitude, phase °] per order);
    a dash is NaN."""
    rows = []
    for line in stdout.splitlines()[3:]:
        cells = line.split()
        low, high = cells[0].split("–")
        vals = [math.nan if c == "—" else float(c) for c in cells[1:]]
        rows.append([float(low), float(high), *vals])
    return np.array(rows)


@pytest.mark.parametrize("order_list", [[6.0, 12.0], [1.5]])
def test_orders_table_is_the_cli_table(cli, bench, tmp_path, order_list):
    args = ["orders", "--in", bench, "--signal", "accel_torque", "--speed", "speed_rpm", "--out", tmp_path / "o.svg"]
    for o in order_list:
        args += ["--order", o]
    res = cli(*args, "--speed-bin", 250)
    assert res.returncode == 0, res.stderr
    expected = parse_orders_table(res.stdout)
    got = sw.orders(sw.read_recording(bench), "accel_torque", "speed_rpm", order_list, speed_bin=250)
    table = got["table"]
    assert len(table) == len(expected) > 5
    assert list(table.columns[:2]) == ["speed_low_rpm", "speed_high_rpm"]
    np.testing.assert_array_equal(table[["speed_low_rpm", "speed_high_rpm"]].to_numpy(), expected[:, :2])
    for k, o in enumerate(order_list):
        name = f"{o:g}x"
        amp, ph = table[f"{name}_amplitude"].to_numpy(), table[f"{name}_phase_deg"].to_numpy()
        # The command prints 5 significant digits and tenths of a degree.
        cli_amp, cli_ph = expected[:, 2 + 2 * k], expected[:, 3 + 2 * k]
        assert np.array_equal(np.isnan(amp), np.isnan(cli_amp))
        ok = ~np.isnan(amp)
        np.testing.assert_array_equal(np.array([float(f"{a:.4e}") for a in amp[ok]]), cli_amp[ok])
        np.testing.assert_array_equal(np.round(ph[ok], 1), cli_ph[ok])
    blocks = got["blocks"]
    assert set(blocks["order"]) == set(order_list)
    assert (blocks["amplitude"] >= 0).all() and np.isfinite(blocks.to_numpy()).all()


def test_orders_errors_are_the_cli_errors(cli, bench, tmp_path):
    rec = sw.read_recording(bench)
    out = tmp_path / "o.svg"
    base = ["orders", "--in", bench, "--out", out]
    # A missing signal column.
    expected = cli_error(cli(*base, "--signal", "nope", "--speed", "speed_rpm", "--order", 6))
    with pytest.raises(sw.StrainwaveError) as e:
        sw.orders(rec, "nope", "speed_rpm", [6])
    assert str(e.value) == expected
    # A bad order and a bad speed bin.
    expected = cli_error(cli(*base, "--signal", "accel_torque", "--speed", "speed_rpm", "--order=-2"))
    with pytest.raises(sw.StrainwaveError) as e:
        sw.orders(rec, "accel_torque", "speed_rpm", [-2])
    assert str(e.value) == expected
    expected = cli_error(cli(*base, "--signal", "accel_torque", "--speed", "speed_rpm", "--order", 6, "--speed-bin", 0))
    with pytest.raises(sw.StrainwaveError) as e:
        sw.orders(rec, "accel_torque", "speed_rpm", [6], speed_bin=0)
    assert str(e.value) == expected
    # A reverse run, and a time column that steps back (row 1-based).
    rev = rec.copy()
    rev["speed_rpm"] = -rev["speed_rpm"]
    rev_path = tmp_path / "reverse.csv"
    sw.write_recording(rev, rev_path)
    expected = cli_error(cli("orders", "--in", rev_path, "--out", out, "--signal", "accel_torque", "--speed", "speed_rpm", "--order", 6))
    with pytest.raises(sw.StrainwaveError) as e:
        sw.orders(sw.read_recording(rev_path), "accel_torque", "speed_rpm", [6])
    assert str(e.value) == expected
    back = rec.copy()
    back.loc[500, "time"] = back.loc[498, "time"]
    back_path = tmp_path / "back.csv"
    sw.write_recording(back, back_path)
    expected = cli_error(cli("orders", "--in", back_path, "--out", out, "--signal", "accel_torque", "--speed", "speed_rpm", "--order", 6))
    assert "row 501" in expected
    with pytest.raises(sw.StrainwaveError) as e:
        sw.orders(sw.read_recording(back_path), "accel_torque", "speed_rpm", [6])
    assert str(e.value) == expected


def test_welch_is_scipy_welch():
    signal = pytest.importorskip("scipy.signal")
    rng = np.random.default_rng(3)
    fs = 2000.0
    t = np.arange(20000) / fs
    x = 0.7 * np.cos(2 * np.pi * 125 * t + 0.3) + 0.1 * rng.standard_normal(t.size) + 0.05 * t
    for kw in [
        dict(nperseg=512),
        dict(nperseg=500, noverlap=100, nfft=1024, detrend="linear", scaling="spectrum"),
        dict(nperseg=256, window="boxcar", detrend=False),
    ]:
        ours = dict(kw)
        if ours.get("detrend") is False:
            ours["detrend"] = "none"
        p = sw.welch(x, sample_rate_hz=fs, **ours)
        f, q = signal.welch(x, fs=fs, window=kw.pop("window", "hann"), **kw)
        np.testing.assert_allclose(p["frequency_hz"], f, rtol=1e-12)
        np.testing.assert_allclose(p["psd"], q, rtol=1e-9, atol=1e-12 * q.max())


def test_welch_and_stft_take_a_dataframe_column(bench):
    rec = sw.read_recording(bench)
    fs = sw.sample_rate_hz(rec)
    assert fs == pytest.approx(20000.0, rel=1e-9)
    a = sw.welch(rec, "torsion_torque", nperseg=2048)
    b = sw.welch(rec["torsion_torque"].to_numpy(), sample_rate_hz=fs, nperseg=2048)
    pd.testing.assert_frame_equal(a, b)
    s = sw.stft(rec, "torsion_torque", nperseg=2048)
    assert s["frames"].shape == (len(s["time_s"]), len(s["frequency_hz"]))
    with pytest.raises(sw.StrainwaveError, match=r"^signal: no column `nope` in "):
        sw.welch(rec, "nope")
    with pytest.raises(sw.StrainwaveError, match="needs at least 256 samples, got 100"):
        sw.welch(np.zeros(100), sample_rate_hz=1000.0, nperseg=256)
    with pytest.raises(sw.StrainwaveError, match="sample_rate_hz"):
        sw.welch(np.zeros(1000))
    with pytest.raises(sw.StrainwaveError, match="not finite"):
        sw.welch(np.r_[np.zeros(500), np.nan, np.zeros(500)], sample_rate_hz=1000.0, nperseg=64)


def test_stft_is_scipy_spectrogram_amplitude():
    signal = pytest.importorskip("scipy.signal")
    fs = 1000.0
    t = np.arange(5000) / fs
    x = 3.0 * np.cos(2 * np.pi * 100 * t + 0.4) + 0.5 * np.sin(2 * np.pi * 37 * t)
    s = sw.stft(x, sample_rate_hz=fs, nperseg=200, noverlap=50)
    f, tt, z = signal.spectrogram(x, fs=fs, window="hann", nperseg=200, noverlap=50, mode="complex", scaling="spectrum")
    np.testing.assert_allclose(s["frequency_hz"], f, rtol=1e-12)
    np.testing.assert_allclose(s["time_s"], tt, rtol=1e-12)
    # One-sided amplitude: twice scipy's X/Σw off DC and Nyquist.
    z = z.T.copy()
    z[:, 1:-1] *= 2
    np.testing.assert_allclose(s["frames"], z, rtol=1e-9, atol=1e-12)
    assert abs(s["frames"][3, 20]) == pytest.approx(3.0, rel=1e-3)  # leakage of the 37 Hz tone


def test_results_too_large_for_memory_are_errors_before_any_allocation():
    # Before: the interpreter aborted ("memory allocation of 7168 bytes failed") under a
    # memory limit; numpy raises for the same size. Both are refused at once now.
    with pytest.raises(sw.StrainwaveError, match=r"frames × 501 bins is more than 134217728 values"):
        sw.stft(np.zeros(200_000), sample_rate_hz=1000.0, nperseg=1000, noverlap=999)
    with pytest.raises(sw.StrainwaveError, match=r"more than 134217728 values \(1 GiB\) in memory"):
        sw.simulate("taghirad", duration=2e4)


def test_orders_limits_are_the_cli_errors(cli, bench, tmp_path):
    # The signal and speed magnitudes and --revs-per-block, named as the command line names
    # them (the checks came to the command line first).
    rec = sw.read_recording(bench)
    path = tmp_path / "limits.csv"
    out = tmp_path / "o.svg"
    cases = [
        ("accel_torque", 1e200, {}),
        ("speed_rpm", -1.7e308, {}),
        (None, None, {"revs_per_block": 0.0}),
    ]
    for column, value, kwargs in cases:
        edited = rec.copy()
        if column is not None:
            edited.loc[100, column] = value
        sw.write_recording(edited, path)
        args = ["--revs-per-block", str(kwargs["revs_per_block"])] if kwargs else []
        expected = cli_error(
            cli("orders", "--in", path, "--out", out, "--signal", "accel_torque", "--speed", "speed_rpm", "--order", 6, *args)
        )
        with pytest.raises(sw.StrainwaveError) as e:
            sw.orders(sw.read_recording(path), "accel_torque", "speed_rpm", [6], **kwargs)
        assert str(e.value) == expected
