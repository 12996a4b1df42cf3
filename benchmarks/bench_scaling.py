"""Scaling of each study with the size of its design grid: threads (1 and 2), loky (2 workers), dask.

Run:  python benchmarks/bench_scaling.py      (about 3 minutes on 2 cores)
For each study, 3-4 grid sizes spanning at least 16x in work, each run as
`surgopt STUDY CONFIG --force` in a fresh process with a warm numba cache,
with 1 and 2 threads (the default backend), 2 loky workers and a 2-worker dask LocalCluster.
Prints wall time and the peak resident memory of the largest process
(GNU time's %M), and a Markdown table for docs/performance.md.
"""
from __future__ import annotations

import os
import subprocess
import sys
import tempfile
from pathlib import Path

RCM = """[workspace]
points_per_side = 17
[candidates.grid]
x_min_m = 0.2
x_max_m = 0.8
x_count = {n}
z_min_m = -0.6
z_max_m = 0.0
z_count = {n}
"""
RAVEN = """[sweep]
alpha_deg = {{start = 5.0, stop = 90.0, step = 20.0}}
beta_deg = {{start = 5.0, stop = 90.0, step = 20.0}}
phi_x_deg = {{start = -20.0, stop = 20.0, step = 10.0}}
phi_y_deg = {{start = -20.0, stop = 20.0, step = 10.0}}
phi_z_deg = {{start = -20.0, stop = 20.0, step = 10.0}}
bx_mm = {bx}
by_mm = {by}
iso_min = {{start = 0.1, stop = 0.9, step = 0.2}}
"""
SUTURE = """arm_length_mm = [550.0]
[weights]
W1 = [1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0]
[task]
radius_mm = {radii}
"""

CASES = {
    "rcm-grid": [(f"{n * n} candidates", RCM.format(n=n), n * n) for n in (16, 31, 61, 121)],
    "raven-sweep": [("125 geometries", RAVEN.format(bx="[100.0]", by="[50.0]"), 125),
                    ("500 geometries", RAVEN.format(bx="[50.0, 100.0, 150.0, 200.0]", by="[50.0]"), 500),
                    ("2000 geometries", RAVEN.format(bx="[50.0, 100.0, 150.0, 200.0]",
                                                     by="[50.0, 100.0, 150.0, 200.0]"), 2000)],
    "suture-sim": [(f"{k} runs", SUTURE.format(radii=[6.0 + 0.5 * i for i in range(k)]), k) for k in (1, 4, 16)],
}
MODES = [("threads, 1", ["--jobs", "1"]), ("threads, 2", ["--jobs", "2"]),
         ("loky, 2 workers", ["--backend", "loky", "--jobs", "2"]),
         ("dask LocalCluster, 2 workers", ["--backend", "dask", "--jobs", "2"])]


def timed(cmd, env):
    r = subprocess.run(["/usr/bin/time", "-f", "%e %M", *cmd], capture_output=True, text=True, env=env)
    if r.returncode != 0:
        raise RuntimeError(r.stderr)
    wall, rss_kb = r.stderr.strip().splitlines()[-1].split()
    return float(wall), int(rss_kb) / 1024


def main():
    env = dict(os.environ)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for study, cases in CASES.items():
            for label, text, work in cases:
                cfg = Path(tmp) / f"{study}-{work}.toml"
                cfg.write_text(text)
                base = [sys.executable, "-m", "surgopt", study, str(cfg), "--quiet", "--force", "--store",
                        str(Path(tmp) / "store")]
                subprocess.run(base + ["--jobs", "1"], check=True, capture_output=True, env=env)  # warm cache
                cells = []
                for mode, args in MODES:
                    wall, rss = timed(base + args, env)
                    cells.append((wall, rss))
                    print(f"{study:12s} {label:18s} {mode:30s} {wall:7.2f} s  {rss:6.0f} MB", flush=True)
                rows.append((study, label, cells))
    print("\n| study | size | " + " | ".join(f"{m}: s / MB" for m, _ in MODES) + " | 2 threads vs 1 |")
    print("|---|---|" + "---|" * (len(MODES) + 1))
    for study, label, cells in rows:
        print(f"| {study} | {label} | " + " | ".join(f"{w:.2f} / {r:.0f}" for w, r in cells)
              + f" | {cells[0][0] / cells[1][0]:.2f}x |")


if __name__ == "__main__":
    main()
