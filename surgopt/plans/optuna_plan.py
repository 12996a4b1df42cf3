"""The Optuna plan: TPE, NSGA-II or random sampling ([search] method), batch after batch on a study in memory.

Batch k asks ``batch`` trials (sampler seeded by (seed, k)), spreads them over the workers, tells them, appends
them to Optuna's journal in the run's folder (optuna-dashboard reads it), and is stored as part k. Resuming
rebuilds the study from the journal's complete batches: a batch in the journal whose part is missing is evaluated
again from its recorded parameters (and must give the recorded values); the rest is asked anew from the same
history with the same seed, so the trials are an uninterrupted search's wherever the kill fell. A journal that is
gone or unreadable while parts are stored cannot give the same trials: refused, with the repair.
"""
from __future__ import annotations

import math

import numpy as np

from surgopt.plans import BatchCollector, Designs, OptimiserPlan, Task, split

#: Optuna's own time per trial on one core, beyond the evaluation (benchmarks/bench_search.py, raven-sweep, batch
#: 64, in memory): TPE's grows with the history (~6 ms a trial over 1,000 trials, ~8 ms over 5,000).
SECONDS_PER_TRIAL = {"tpe": 0.008, "nsga2": 0.001, "random": 0.001}


class OptunaPlan(OptimiserPlan):
    name = "optuna"

    @property
    def seconds_per_trial(self) -> float:
        return SECONDS_PER_TRIAL[self.spec.method]

    def record(self) -> dict:
        return {"name": self.name, "method": self.spec.method}

    def session(self, study, cfg, chunk: int, run, workers: int) -> OptunaSession:
        return OptunaSession(study.search_plan(cfg), run, workers)


class OptunaSession:
    unit = "trials"

    def __init__(self, plan, run, workers: int):
        from surgopt.errors import StoreError
        from surgopt.studies import search as S

        self.plan, self.spec, self.run, self.workers = plan, plan.spec, run, workers
        self.names = list(plan.space)
        self.n_batches = math.ceil(self.spec.trials / self.spec.trials_per_part)
        self.repair = (f"delete the run (`surgopt runs rm {run.key[:12]}`) or rerun with --force to search again "
                       f"from the start")
        try:
            self.journal = S.Journal.open(run.path / "optuna.journal", plan)
        except S.JournalProblem as exc:
            raise StoreError(f"{exc}; {self.repair}") from None
        stored = run.done_tasks()
        beyond = sorted(k for k in stored if k >= self.journal.batches)
        if beyond:
            raise StoreError(f"{run.path}: part {beyond[0]} is stored but Optuna's journal holds only "
                             f"{self.journal.batches} complete batch(es) (deleted or replaced?): the search cannot "
                             f"resume to the same trials; {self.repair}")
        self.mem = S.memory_study(plan)
        self.mem.add_trials(self.journal.trials)
        self.dists = S.distributions(plan.space)
        self.total = self.spec.trials
        self.done = sum(self._size(k) for k in stored)
        self.k = 0
        self._batch = None

    def _size(self, k: int) -> int:
        return min(self.spec.trials_per_part, self.spec.trials - k * self.spec.trials_per_part)

    @property
    def remaining(self) -> bool:
        return any(k not in self.run.done_tasks() for k in range(self.n_batches))

    def next_tasks(self) -> list[Task]:
        from surgopt.studies import search as S

        stored = self.run.done_tasks()
        while self.k < self.n_batches and self.k < self.journal.batches and self.k in stored:
            self.k += 1
        if self.k >= self.n_batches:
            return []
        k, first, n = self.k, self.k * self.spec.trials_per_part, self._size(self.k)
        if k < self.journal.batches:  # told and recorded before the interruption: evaluated again
            recorded = self.journal.trials[first:first + n]
            points, asked = [[float(t.params[name]) for name in self.names] for t in recorded], None
        else:
            self.mem.sampler = S.sampler_for(self.spec, k)
            asked = [self.mem.ask(self.dists) for _ in range(n)]
            points, recorded = [[float(t.params[name]) for name in self.names] for t in asked], None
        x, ids = np.asarray(points, dtype=np.float64), first + np.arange(n)
        slices = split(x, ids, self.workers)
        self._batch = (k, asked, recorded, BatchCollector(len(slices)))
        return [Task(k, j, Designs(xs, i, self.spec.method)) for j, (xs, i) in enumerate(slices)]

    def on_result(self, task: Task, cols: dict) -> list[tuple[int, dict]]:
        from surgopt.studies import search as S

        k, asked, recorded, collector = self._batch
        cols = collector.add(task.sub, cols)
        if cols is None:
            return []
        objectives = self.plan.objectives
        if recorded is not None:
            same_trials(self.run, k, cols, recorded, objectives, self.names)
        else:
            S.tell(self.mem, asked, [[float(cols[c][r]) for c, _ in objectives] for r in range(len(asked))])
            first = k * self.spec.trials_per_part
            self.journal.append(self.mem.get_trials(deepcopy=False)[first:first + len(asked)])
        self.k += 1
        self.done += self._size(k)
        return [(k, cols)]

    def final_meta(self) -> dict:
        return {}


def same_trials(run, index, cols, recorded, objectives, names) -> None:
    """A batch evaluated again from its journal record gives the journal's values, or the store is inconsistent."""
    from surgopt.errors import StoreError

    for r, t in enumerate(recorded):
        values = [float(cols[c][r]) for c, _ in objectives]
        if t.values is None:  # told as failed: some objective was not finite
            same = not all(math.isfinite(a) for a in values)
        else:
            same = all(a == b for a, b in zip(values, t.values))
        if not same or [float(cols[name][r]) for name in names] != [float(t.params[name]) for name in names]:
            raise StoreError(f"{run.path}: batch {index} evaluated again differs from Optuna's journal "
                             f"(trial {t.number}); delete the run and search again")
