"""Optuna searches: trials per second through the runner and store against a plain ask/tell loop.

Run:  python benchmarks/bench_search.py [TRIALS]   (default 640; raven-sweep Table II space, batch 64)

Same run, same evaluation function (the study's compute_task on one batch of points): (1) a plain
loop of Optuna's ask/tell on an in-memory study, (2) the same with the journal file the runner uses,
(3) `run_study` with a [search] section (journal, one stored part per batch, verification). Prints
each one's trials per second, the evaluation's share, and the ratios.
"""
import sys
import tempfile
import time
from pathlib import Path

import numpy as np


def main(trials: int) -> None:
    import optuna
    from optuna.storages import JournalStorage
    from optuna.storages.journal import JournalFileBackend

    from surgopt.runner import run_study
    from surgopt.store import Store
    from surgopt.studies import raven_sweep as R
    from surgopt.studies import search as S

    optuna.logging.set_verbosity(optuna.logging.WARNING)
    spec = S.SearchSpec(method="cmaes", trials=trials, batch=64, seed=0)
    cfg = R.Config().model_copy(update={"search": spec})
    plan = R.search_plan(cfg)
    R.warm_up(cfg)

    def evaluate(points):
        c = cfg.model_copy(update={"search": spec.model_copy(update={"points": points})})
        return R.compute_task(c, 64, 0)["cost"]

    from surgopt.kinematics.raven_workspace import clear_memo

    results = {}
    for label, storage in (("plain ask/tell, in memory", None), ("plain ask/tell, journal file", "journal")):
        clear_memo()  # the same seed asks the same trials: no run may reuse another's evaluations
        with tempfile.TemporaryDirectory() as tmp:
            st = optuna.create_study(storage=None if storage is None else JournalStorage(
                JournalFileBackend(str(Path(tmp) / "j"))), directions=["maximize"])
            t_eval = 0.0
            t0 = time.perf_counter()
            for k in range(int(np.ceil(trials / 64))):
                st.sampler = S.sampler_for(spec, k)
                batch = S.ask(st, plan, min(64, trials - 64 * k))
                t1 = time.perf_counter()
                values = evaluate([[t.params[n] for n in plan.space] for t in batch])
                t_eval += time.perf_counter() - t1
                S.tell(st, batch, [[float(v)] for v in values])
            results[label] = (time.perf_counter() - t0, t_eval)
    clear_memo()
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        run_study(R.STUDY, cfg, config_name="bench", store=Store(tmp), jobs=1, quiet=True, max_hours=None)
        results["surgopt run_study (journal, parts, verification)"] = (time.perf_counter() - t0, float("nan"))
    base = results["plain ask/tell, in memory"][0]
    for label, (wall, t_eval) in results.items():
        share = f", evaluation {t_eval / wall:.0%} of it" if np.isfinite(t_eval) else ""
        print(f"{label:52s} {trials / wall:7.1f} trials/s ({wall:6.2f} s{share}); {wall / base:4.1f}x the in-memory loop")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 640)
