"""The real-arm table from `identify --summary-json` files (standard library only)."""

import json
import sys

print()
print("| joint | log | reference | model R² | model RMS N·m | fit % | plain linear R² | plain RMS N·m |")
print("|---|---|---|---|---|---|---|---|")
for path in sys.argv[1:]:
    with open(path) as f:
        s = json.load(f)
    h = s["holdout"]
    m, p = h["model"], h["plain_linear"]
    joint = path.rsplit("/", 1)[-1].rsplit("-summary", 1)[0]
    log = s["loaded"].rsplit("/", 1)[-1]
    print(
        f"| {joint} | {log} | current ({h['blocks']}-block holdout) | {m['r_squared']:.3f} | {m['rms']:.2f} | "
        f"{m['nrmse_fit_percent']:.1f} | {p['r_squared']:.3f} | {p['rms']:.2f} |"
    )
