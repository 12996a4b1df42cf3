"""The readers' speed goals of issue 42 item 5, measured end to end as a user runs them (each a fresh `surgopt`
process, wall time, median of --repeat runs), on the default port-place run (2,165,292 rows) and a second run
of 1.5 M rows for `diff`:

    cache hit of `surgopt port-place`            goal <= 0.5 s
    `surgopt --help`                             goal <= 0.3 s
    `surgopt summarize` of the 2.2 M-row run     goal <= 2 s
    `surgopt export --out x.csv`                 goal <= 10 s per million rows
    `surgopt diff` of two 2.2 M / 1.5 M-row runs goal <= 10 s

Same-run ratios: each derived reader with its `_derived.json` removed first (derived from the rows, as before
this round) against kept. Run on an idle machine (`python benchmarks/bench_readers.py [--store DIR]`); the first
call computes the two runs if the store lacks them (~10 s each with warm kernels).
"""
from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

SECOND = "patient.semi_axes_mm=[170,200,140]"  # a smaller abdomen: 1,524,240 layouts


def timed(args: list[str], repeat: int, before=None) -> float:
    """Median wall time (s) of ``surgopt ARGS`` over ``repeat`` runs (``before()`` ahead of each, untimed)."""
    times = []
    for _ in range(repeat):
        if before is not None:
            before()
        t0 = time.perf_counter()
        subprocess.run([sys.executable, "-m", "surgopt", *args], check=True, stdout=subprocess.DEVNULL,
                       stderr=subprocess.DEVNULL)
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--store", type=Path, default=None, help="a store to use (default: a new temporary one)")
    ap.add_argument("--repeat", type=int, default=5)
    opts = ap.parse_args()
    store = opts.store or Path(tempfile.mkdtemp(prefix="bench-readers-")) / "store"
    s = ["--store", str(store)]
    subprocess.run([sys.executable, "-m", "surgopt", "port-place", *s, "-q"], check=True, stdout=subprocess.DEVNULL)
    subprocess.run([sys.executable, "-m", "surgopt", "port-place", SECOND, *s, "-q"], check=True,
                   stdout=subprocess.DEVNULL)
    from surgopt.derived import DERIVED
    from surgopt.store import Store

    runs = sorted(Store(store).runs("port-place"), key=lambda r: -r.rows)
    big, small = runs[0], runs[1]
    derived = big.path / DERIVED

    def forget() -> None:
        derived.unlink(missing_ok=True)

    rows = []
    subprocess.run([sys.executable, "-m", "surgopt", "port-place", *s], check=True, stdout=subprocess.DEVNULL)
    hit_recorded = timed(["port-place", *s], opts.repeat)  # surgopt.hits: the command line recorded just above
    hit_kept = timed(["port-place", *s, "--jobs", "2"], opts.repeat)  # an option: the usual way, the study loaded
    hit_fresh = timed(["port-place", *s, "--jobs", "2"], max(1, opts.repeat // 2), before=forget)
    rows.append(("cache hit, `surgopt port-place`", hit_recorded, 0.5,
                 f"{hit_kept / hit_recorded:.1f}x against the usual way ({hit_kept:.2f} s: the study loaded, the "
                 f"report kept); {hit_fresh / hit_recorded:.1f}x against derived again ({hit_fresh:.2f} s)"))
    rows.append(("`surgopt --help`", timed(["--help"], opts.repeat), 0.3, ""))
    summ = ["summarize", big.key[:12], *s]
    first = timed(summ, max(1, opts.repeat // 2), before=lambda: (forget(), subprocess.run(
        [sys.executable, "-m", "surgopt", "port-place", *s], check=True, stdout=subprocess.DEVNULL)))
    kept = timed(summ, opts.repeat)
    cold = timed(summ, max(1, opts.repeat // 2), before=forget)
    rows.append(("`summarize`, first after the run", first, 2.0, f"nothing kept: {cold:.2f} s"))
    rows.append(("`summarize`, again", kept, 2.0, f"{cold / kept:.1f}x against nothing kept"))
    out = Path(tempfile.mkdtemp()) / "x.csv"
    export = timed(["export", big.key[:12], "--out", str(out), *s], max(1, opts.repeat // 2))
    per_m = export / (big.rows / 1e6)
    rows.append((f"`export --out x.csv` ({big.rows:,} rows, {out.stat().st_size / 1e9:.2f} GB)", export,
                 10.0 * big.rows / 1e6, f"{per_m:.1f} s per million rows"))
    out.unlink()
    rows.append((f"`diff` ({big.rows:,} against {small.rows:,} rows)",
                 timed(["diff", big.key[:12], small.key[:12], *s], max(1, opts.repeat // 2)), 10.0, ""))
    print(f"| reader | measured (s) | goal (s) | note |\n|---|---|---|---|")
    for name, t, goal, note in rows:
        print(f"| {name} | {t:.2f} | {goal:g} ({'met' if t <= goal else 'missed'}) | {note} |")


if __name__ == "__main__":
    main()
