#!/usr/bin/env python3
"""Python package timings, printed as Markdown tables for docs/performance.md.

1. `strainwave.filter_recording` on N rows (DataFrame in memory) against the command line
   `strainwave filter` on the same rows (CSV file in and out, the process's wall time), and
   a filterpy Kalman filter with the same state size (6: three oscillators) on the same
   rows, each the best of `--repeat` runs. The Python package is also timed end to end
   (read the CSV, filter, write the CSV) like the command line.
2. A fleet: `--fleet` recordings of `--minutes` each (Parquet, one file per recording),
   filtered serially in one process and with `strainwave.dask.filter_many` on a
   LocalCluster of `--workers` processes (one thread each). Each side reports its wall
   time, the CPU time its processes used, and their peak resident memory; the outputs are
   compared by SHA-256 (the serial outputs are deleted once hashed, to halve the disk
   needed). `--fleet-frames` also times the DataFrame path (read, filter, write through
   pandas) on both sides.

    python python/bench/python_vs_cli.py --cli target/release/strainwave --rows 1000000
"""

import argparse
import hashlib
import math
import multiprocessing
import resource
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

import strainwave as sw

ROOT = Path(__file__).resolve().parents[2]
CONFIG = ROOT / "examples" / "joint-taghirad-6th-order.toml"
FLEET_CONFIG = ROOT / "examples" / "joint-taghirad.toml"


def best(f, repeat):
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        f()
        times.append(time.perf_counter() - t0)
    return min(times)


def filterpy_run(df, rows):
    """Three rotating oscillators (relative orders 2 and 4, output order 1) on the
    calibrated torque: a 6-state Kalman filter in filterpy, one predict and update per row."""
    from filterpy.kalman import KalmanFilter

    gain = 6.611
    y = df["bridge_voltage"].to_numpy()[:rows] * gain
    motor = df["motor_angle"].to_numpy()[:rows]
    out = df["output_angle"].to_numpy()[:rows]
    rel = motor - out  # wave generator angle relative to the flexspline
    kf = KalmanFilter(dim_x=6, dim_z=1)
    kf.x = np.zeros((6, 1))
    kf.P = np.eye(6)
    kf.H = np.array([[1.0, 0.0, 1.0, 0.0, 1.0, 0.0]])
    kf.R = np.array([[0.0162**2]])
    kf.Q = np.eye(6) * 1e-8
    f = np.eye(6)
    for k in range(1, rows):
        for i, inc in enumerate((2.0 * (rel[k] - rel[k - 1]), 4.0 * (rel[k] - rel[k - 1]), out[k] - out[k - 1])):
            c, s = math.cos(inc), math.sin(inc)
            f[2 * i : 2 * i + 2, 2 * i : 2 * i + 2] = [[c, s], [-s, c]]
        kf.F = f
        kf.predict()
        kf.update(y[k])


def part_one(a, tmp):
    rows = a.rows
    df = sw.simulate("taghirad", duration=rows / 1000.0, seed=1).iloc[:rows]
    rec = tmp / "rec.csv"
    sw.write_recording(df, rec)
    out = tmp / "out.csv"

    def cli():
        subprocess.run([a.cli, "filter", "--config", CONFIG, "--in", rec, "--out", out, "--quiet"], check=True)

    t_cli = best(cli, a.repeat) if not a.no_cli else float("nan")
    t_py = best(lambda: sw.filter_recording(df, config=CONFIG), a.repeat)
    t_py_files = best(lambda: sw.write_recording(sw.filter_recording(sw.read_recording(rec), config=CONFIG), tmp / "py.csv"), a.repeat)
    same = None if a.no_cli else (tmp / "py.csv").read_bytes() == out.read_bytes()

    def canceller_run():
        sw.RippleCanceller.from_config(CONFIG).run(df)

    t_run = best(canceller_run, a.repeat)
    n_step = min(a.step_rows, rows)
    step_cols = df[["time", "bridge_voltage", "motor_angle", "output_angle"]].iloc[:n_step].to_numpy().tolist()

    def canceller_steps():
        c = sw.RippleCanceller.from_config(CONFIG)
        for t, v, m, o in step_cols:
            c.step(v, m, o, time=t)

    t_step = best(canceller_steps, 1) if n_step > 0 else float("nan")
    print(f"\n### filter_recording, {rows} rows, `{CONFIG.name}` (best of {a.repeat})\n")
    print("| what | time, s | rows/s | vs CLI |")
    print("|---|---:|---:|---:|")
    print(f"| CLI `strainwave filter` (CSV in, CSV out) | {t_cli:.3f} | {rows / t_cli:.3g} | 1.00 |")
    print(f"| `sw.filter_recording` (DataFrame in memory) | {t_py:.3f} | {rows / t_py:.3g} | {t_py / t_cli:.2f} |")
    print(f"| `sw.read_recording` + `filter_recording` + `write_recording` (CSV) | {t_py_files:.3f} | {rows / t_py_files:.3g} | {t_py_files / t_cli:.2f} |")
    print(f"| `sw.RippleCanceller.run` (DataFrame in memory, one block) | {t_run:.3f} | {rows / t_run:.3g} | {t_run / t_cli:.2f} |")
    if n_step > 0:
        print(f"| `sw.RippleCanceller.step` in a Python loop, first {n_step} rows (1 run) | {t_step:.3f} | {n_step / t_step:.3g} | {t_step / n_step * rows / t_cli:.1f} (per row) |")
    if a.filterpy_rows > 0:
        try:
            import filterpy  # noqa: F401
        except ImportError:
            print("| filterpy | not installed | | |")
        else:
            n = min(a.filterpy_rows, rows)
            t_fp = best(lambda: filterpy_run(df, n), 1)
            print(f"| filterpy `KalmanFilter`, 6 states, on the first {n} rows (1 run) | {t_fp:.3f} | {n / t_fp:.3g} | {t_fp / n * rows / t_cli:.1f} (per row) |")
    print(f"\nPython's CSV output byte for byte the CLI's: {same}")


def load():
    with open("/proc/loadavg") as f:
        return " ".join(f.read().split()[:3])


def sha256(path):
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def cpu_s():
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def peak_mb():
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def frames_file(path, config, out):
    """The DataFrame path: read into pandas, filter, write (what `filter_file` did before
    it streamed file to file)."""
    df = sw.filter_recording(sw.read_recording(path), config)
    return sw.write_recording(df, out)


def serial_child(paths, config, out_dir, frames):
    """The serial loop in a fresh process, so that its peak memory is its own:
    (wall s, CPU s, peak MB)."""
    import strainwave.dask

    t0, c0 = time.perf_counter(), cpu_s()
    for p in paths:
        if frames:
            frames_file(p, config, os.path.join(out_dir, os.path.basename(p)))
        else:
            strainwave.dask.filter_file(p, config, os.path.join(out_dir, os.path.basename(p)))
    return time.perf_counter() - t0, cpu_s() - c0, peak_mb()


def warm_up():
    import strainwave.dask  # noqa: F401


def worker_usage():
    return cpu_s(), peak_mb()


def fleet_side(a, paths, out_dir, frames):
    """Serial, then the cluster: rows of the table and whether the outputs agree."""
    from dask import delayed
    from distributed import Client, LocalCluster

    import strainwave.dask

    out_dir.mkdir()
    serial_out, dask_out = out_dir / "serial", out_dir / "dask"
    serial_out.mkdir()
    what = "DataFrame path (read, filter, write in pandas)" if frames else "`strainwave.dask.filter_file` (file to file)"
    rows = []
    load0 = load()
    with multiprocessing.get_context("spawn").Pool(1) as pool:
        t_s, cpu_serial, peak_serial = pool.apply(serial_child, ([str(p) for p in paths], str(FLEET_CONFIG), str(serial_out), frames))
    hashes = {p.name: sha256(serial_out / p.name) for p in paths}
    shutil.rmtree(serial_out)
    load1 = load()
    rows.append((f"serial, one process, {what}", t_s, cpu_serial, f"{peak_serial:.0f}", load0, load1))
    with LocalCluster(n_workers=a.workers, processes=True, threads_per_worker=1, dashboard_address=None) as cluster, Client(cluster) as client:
        # The workers import the package before the clock starts, as the serial child
        # process did (its imports ran when it loaded this script).
        client.run(warm_up)
        before = client.run(worker_usage)
        load0 = load()
        t0 = time.perf_counter()
        if frames:
            dask_out.mkdir()
            tasks = [delayed(frames_file, pure=False)(str(p), str(FLEET_CONFIG), str(dask_out / p.name)) for p in paths]
            import dask

            dask.compute(*tasks)
        else:
            strainwave.dask.filter_many(paths, FLEET_CONFIG, out_dir=dask_out)
        t_d = time.perf_counter() - t0
        load1 = load()
        after = client.run(worker_usage)
    cpu_dask = sum(after[w][0] - before[w][0] for w in after)
    peaks = "/".join(f"{after[w][1]:.0f}" for w in sorted(after))
    how = f"LocalCluster, {a.workers} worker processes × 1 thread, {what}"
    rows.append((how, t_d, cpu_dask, peaks, load0, load1))
    same = all(sha256(dask_out / p.name) == hashes[p.name] for p in paths)
    shutil.rmtree(dask_out)
    return rows, same


def part_two(a, tmp):
    rows = int(a.minutes * 60 * 1000)
    d = tmp / "fleet"
    d.mkdir()
    paths = []
    t0 = time.perf_counter()
    for k in range(a.fleet):
        p = d / f"joint{k:03d}.parquet"
        sw.write_recording(sw.simulate("taghirad", duration=a.minutes * 60, seed=100 + k), p)
        paths.append(p)
    size_gb = sum(p.stat().st_size for p in paths) / 1e9
    print(f"\n(fleet written in {time.perf_counter() - t0:.0f} s: {size_gb:.2f} GB of Parquet)")
    table, same = fleet_side(a, paths, tmp / "file", frames=False)
    if a.fleet_frames:
        more, same_frames = fleet_side(a, paths, tmp / "frames", frames=True)
        table += more
        same = same and same_frames
    total = rows * a.fleet
    print(f"\n### Fleet: {a.fleet} recordings × {a.minutes:g} min ({total} rows, Parquet in and out)\n")
    print("| how | wall, s | rows/s | CPU, s | peak RSS, MB | load before → after |")
    print("|---|---:|---:|---:|---:|---|")
    for how, t, cpu, peak, l0, l1 in table:
        print(f"| {how} | {t:.2f} | {total / t:.3g} | {cpu:.1f} | {peak} | {l0} → {l1} |")
    print(f"\nOutputs identical (SHA-256 of every file): {same}")


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--cli", default=str(ROOT / "target" / "release" / "strainwave"))
    p.add_argument("--rows", type=int, default=1_000_000)
    p.add_argument("--repeat", type=int, default=3)
    p.add_argument("--filterpy-rows", type=int, default=1_000_000)
    p.add_argument("--step-rows", type=int, default=100_000, help="rows for the per-sample `step` loop (0: skip)")
    p.add_argument("--fleet", type=int, default=64)
    p.add_argument("--minutes", type=float, default=10.0)
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--skip-fleet", action="store_true")
    p.add_argument("--fleet-frames", action="store_true", help="also time the DataFrame path on both sides")
    p.add_argument("--tmp", help="folder for the fleet's files (default: the system's temporary folder)")
    p.add_argument("--no-cli", action="store_true", help="the filter table without the command line")
    p.add_argument("--skip-filter", action="store_true", help="only the fleet (no CLI needed)")
    a = p.parse_args()
    if not (a.skip_filter or a.no_cli) and shutil.which(a.cli) is None and not os.access(a.cli, os.X_OK):
        sys.exit(f"{a.cli}: no strainwave binary (cargo build --release -p strainwave-cli)")
    if a.tmp:
        os.makedirs(a.tmp, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix="sw-bench-", dir=a.tmp) as t:
        tmp = Path(t)
        if not a.skip_filter:
            part_one(a, tmp)
        if not a.skip_fleet:
            part_two(a, tmp)


if __name__ == "__main__":
    main()
