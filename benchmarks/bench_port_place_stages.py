"""Where the default port-place run's time goes (issue 53): each stage of `surgopt port-place` on its embedded
default, warm, in one process, so that the next issue can aim at the largest.

Run:  python benchmarks/bench_port_place_stages.py [--repeat 3]
Prints, best of the repeats (each on a fresh prepared model, the kernels compiled by a first untimed pass):
- the model (sites, target, docking frames; ``tables.prepare``);
- the cart's dock tables (each arm's setup joints at each site and floor pose: ``tables.dock_tables``);
- the per-port and per-pair tables without the links, and the link tables (``link_tables.link_tables``);
- the designs combined into rows (``study.compute_task`` over every chunk), with designs/s;
- the closing report (``report.summary`` over the stored rows: counts, the best layouts, the links' screen; once,
  for the screen's roll searches are memoised in a process);
- the whole run end to end through the CLI (``surgopt port-place --store <new>``), and the stages' share of it.
"""
from __future__ import annotations

import argparse
import math
import subprocess
import sys
import tempfile
import time


def stages(cfg) -> dict:
    """Seconds per stage on a fresh model of ``cfg`` (the process's kernels already compiled)."""
    import surgopt.studies.port_place.link_tables as L
    from surgopt.studies.port_place import study as S
    from surgopt.studies.port_place import model as M

    spent = {"links": 0.0}
    link_tables = L.link_tables

    def timed(*a, **k):
        t = time.perf_counter()
        out = link_tables(*a, **k)
        spent["links"] += time.perf_counter() - t
        return out

    L.link_tables = timed
    try:
        t0 = time.perf_counter()
        model = M.prepare(cfg)
        t1 = time.perf_counter()
        model.dock
        t2 = time.perf_counter()
        model.grid
        t3 = time.perf_counter()
        M._held.clear()
        M._held[cfg.model_dump_json()] = model  # the tasks read this model (``model_of``)
        n = S.n_total(cfg)
        chunk = S.auto_chunk(cfg)
        for task in range(math.ceil(n / chunk)):
            S.compute_task(cfg, chunk, task)
        t4 = time.perf_counter()
    finally:
        L.link_tables = link_tables
    return {"model": t1 - t0, "dock tables": t2 - t1, "port and pair tables": t3 - t2 - spent["links"],
            "link tables": spent["links"], "designs": t4 - t3, "designs_n": n}


def report_seconds(store: str) -> float:
    """The closing report of the stored default run, from its rows (a fresh process's screen is not memoised)."""
    from surgopt.store import Store
    from surgopt.studies.port_place import report as R
    from surgopt.studies.port_place import study as S

    (run,) = Store(store).runs("port-place")
    parts = run.parts(S.STUDY.schema_for(run.manifest["config"]))
    t = time.perf_counter()
    R.summary(parts)
    return time.perf_counter() - t


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    from surgopt.config import load_embedded
    from surgopt.studies.port_place import study as S

    cfg = load_embedded(S.DEFAULT_CONFIG, S.STUDY.config_model)
    stages(cfg)  # compile (or load) every kernel once
    best = {}
    for _ in range(args.repeat):
        for k, v in stages(cfg).items():
            best[k] = min(best.get(k, math.inf), v)
    n = int(best.pop("designs_n"))
    with tempfile.TemporaryDirectory() as d:
        t = time.perf_counter()
        subprocess.run([sys.executable, "-m", "surgopt", "port-place", "--store", f"{d}/s"], check=True,
                       capture_output=True)
        end_to_end = time.perf_counter() - t
        report = report_seconds(f"{d}/s")  # once: the roll screen is memoised in a process
    best["closing report"] = report
    print(f"port-place, embedded default, warm, best of {args.repeat} (2 threads for the tables):")
    for k, v in best.items():
        extra = f"  ({n / v / 1e6:.2f} M designs/s, {n:,} designs)" if k == "designs" else ""
        print(f"  {k:22s} {v:6.2f} s  {100 * v / end_to_end:5.1f} % of the run{extra}")
    print(f"  {'stages together':22s} {sum(best.values()):6.2f} s")
    print(f"  {'end to end (CLI)':22s} {end_to_end:6.2f} s  (the rest: starting Python and importing, storing "
          f"{n:,} rows, the page's files)")


if __name__ == "__main__":
    main()
