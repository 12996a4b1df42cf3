"""Searches against the evaluator alone and against the grid (issue #24's targets), same run, same machine.

Run:  python benchmarks/bench_search.py [TRIALS] [--tpe] [--batch=N]   (default 5000; raven-sweep Table II, 2 workers;
      CMA-ES parts of N trials, default the plan's own, 256)

1. The whole 250,000-design Table II grid through `run_study` (threads, 2 workers).
2. CMA-ES (the `cmaes` plan, IPOP restarts) with TRIALS trials through `run_study`: optimiser, runner, store.
3. The evaluator alone on the same designs (the study's `evaluate`, 2 threads, no optimiser, no store).
4. With --tpe: Optuna's TPE through `run_study` at 1,000 trials and at TRIALS, and its per-trial overhead.
Prints wall times, trials per second and the ratios the targets are stated in: (2) <= 2 x (3), (2) <= 2 x (1).
The kernels' memo of geometries is cleared before each, so no run reuses another's evaluations.
"""
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor

import numpy as np


def main(trials: int, tpe: bool, batch: int | None) -> None:
    import cmaes  # noqa: F401  (imports scipy.stats, ~0.75 s once a process: paid before timing, like compiling)

    from surgopt.kinematics.raven_workspace import clear_memo
    from surgopt.plans import split
    from surgopt.runner import run_study
    from surgopt.store import Store
    from surgopt.studies.raven_sweep import study as R
    from surgopt.plans.search import SearchSpec

    grid_cfg = R.Config()
    R.warm_up(grid_cfg)

    def timed_run(cfg):
        clear_memo()
        with tempfile.TemporaryDirectory() as tmp:
            t0 = time.perf_counter()
            res = run_study(R.STUDY, cfg, config_name="bench", store=Store(tmp), jobs=2, quiet=True, max_hours=None)
            table = res.table
            return time.perf_counter() - t0, table

    t_grid, grid = timed_run(grid_cfg)
    print(f"grid, {grid.num_rows:,} designs                      {t_grid:6.2f} s  "
          f"{grid.num_rows / t_grid:9,.0f} designs/s  best C {np.nanmax(grid['cost'].to_numpy()):,.0f}")
    cma_cfg = grid_cfg.model_copy(update={"search": SearchSpec(method="cmaes", trials=trials, batch=batch, seed=0)})
    t_cma, cma = timed_run(cma_cfg)
    print(f"CMA-ES (cmaes plan), {trials:,} trials               {t_cma:6.2f} s  {trials / t_cma:9,.0f} trials/s  "
          f"best C {np.nanmax(cma['cost'].to_numpy()):,.0f}")
    x = np.column_stack([cma[p].to_numpy() for p in R.PARAMS])
    ids = np.arange(len(x))
    clear_memo()
    t0 = time.perf_counter()
    with ThreadPoolExecutor(2) as pool:
        list(pool.map(lambda s: R.evaluate_designs(grid_cfg, s[0], s[1], "bench"), split(x, ids, 2)))
    t_eval = time.perf_counter() - t0
    print(f"evaluator alone, the same {trials:,} designs, 2 threads   {t_eval:6.2f} s  {trials / t_eval:9,.0f} designs/s")
    print(f"CMA-ES / evaluator alone: {t_cma / t_eval:.2f}x (target <= 2);  CMA-ES / grid: {t_cma / t_grid:.2f}x "
          f"(target <= 2);  optimiser + runner + store: {(t_cma - t_eval) / trials * 1e3:.3f} ms a trial")
    if tpe:
        for n in (1000, trials):
            cfg = grid_cfg.model_copy(update={"search": SearchSpec(method="tpe", trials=n, batch=64, seed=0)})
            t, _ = timed_run(cfg)
            print(f"TPE (Optuna), {n:,} trials                       {t:6.2f} s  {n / t:9,.0f} trials/s  "
                  f"~{(t - t_eval * n / trials) / n * 1e3:.2f} ms a trial beyond the evaluation")


if __name__ == "__main__":
    args = [a for a in sys.argv[1:] if not a.startswith("--")]
    given = [a.split("=", 1)[1] for a in sys.argv[1:] if a.startswith("--batch=")]
    main(int(args[0]) if args else 5000, "--tpe" in sys.argv, int(given[0]) if given else None)
