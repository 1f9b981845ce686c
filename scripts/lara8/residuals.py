"""Where the error of an estimate against the current torque lies (standard library only).

Reads `estimate`'s output: prints the mean and RMS of (current torque − model) per
contiguous block, and the current torque less the estimated link torque binned by speed
(what friction and inertia must explain). Usage: residuals.py ESTIMATE.csv COLUMN BLOCKS
"""

import csv
import math
import sys


def main() -> None:
    path, col, blocks = sys.argv[1], sys.argv[2], int(sys.argv[3])
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    ref = [float(r[col]) for r in rows]
    link = [float(r["torque"]) for r in rows]
    model = [float(r["current_torque"]) for r in rows] if "current_torque" in rows[0] else link
    n = len(ref)
    print(f"  in-sample residual (current torque - model) by block of {n // blocks} rows:")
    for b in range(blocks):
        lo, hi = b * n // blocks, (b + 1) * n // blocks
        e = [ref[k] - model[k] for k in range(lo, hi)]
        mean = sum(e) / len(e)
        rms = math.sqrt(sum(x * x for x in e) / len(e))
        print(f"    block {b + 1}: mean {mean:+7.2f} N·m, rms {rms:6.2f} N·m")
    print("  current torque - link torque, binned by the controller's joint speed:")
    j = col.rsplit("_", 1)[1]
    speed = [float(r[f"joint_velocity_{j}"]) for r in rows]
    edges = sorted(set([-1e9, -0.5, -0.1, -0.02, 0.02, 0.1, 0.5, 1e9]))
    for lo, hi in zip(edges, edges[1:]):
        d = [ref[k] - link[k] for k in range(n) if lo <= speed[k] < hi]
        if len(d) < 5:
            continue
        mean = sum(d) / len(d)
        sd = math.sqrt(sum((x - mean) ** 2 for x in d) / len(d))
        label = f"[{max(lo, -9.99):+.2f}, {min(hi, 9.99):+.2f}) rad/s"
        print(f"    {label:<24} {len(d):5d} rows: {mean:+8.2f} ± {sd:6.2f} N·m")


if __name__ == "__main__":
    main()
