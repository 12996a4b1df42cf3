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
from typing import Any

import numpy as np

from surgopt.plans import BatchCollector, Designs, OptimiserPlan, Task, split
from surgopt.plans.search import SearchPlan, SearchSpec

#: Optuna's own time per trial on one core, beyond the evaluation (benchmarks/bench_search.py, raven-sweep, batch
#: 64, in memory): TPE's grows with the history (~6 ms a trial over 1,000 trials, ~8 ms over 5,000).
SECONDS_PER_TRIAL = {"tpe": 0.008, "nsga2": 0.001, "random": 0.001}

#: Optuna's journal in the run's folder ("_": Parquet readers skip it, like the manifest), and its name before.
JOURNAL, LEGACY_JOURNAL = "_optuna.journal", "optuna.journal"


def journal_of(folder):
    """The run's journal: ``_optuna.journal``, or an older search's ``optuna.journal`` when only that exists."""
    if not (folder / JOURNAL).exists() and (folder / LEGACY_JOURNAL).exists():
        return folder / LEGACY_JOURNAL
    return folder / JOURNAL


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
        self.plan, self.spec, self.run, self.workers = plan, plan.spec, run, workers
        self.names = list(plan.space)
        self.n_batches = math.ceil(self.spec.trials / self.spec.trials_per_part)
        self.repair = (f"delete the run (`surgopt runs rm {run.key[:12]}`) or rerun with --force to search again "
                       f"from the start")
        try:
            self.journal = Journal.open(journal_of(run.path), plan)
        except JournalProblem as exc:
            raise StoreError(f"{exc}; {self.repair}") from None
        stored = run.done_tasks()
        beyond = sorted(k for k in stored if k >= self.journal.batches)
        if beyond:
            raise StoreError(f"{run.path}: part {beyond[0]} is stored but Optuna's journal holds only "
                             f"{self.journal.batches} complete batch(es) (deleted or replaced?): the search cannot "
                             f"resume to the same trials; {self.repair}")
        self.mem = memory_study(plan)
        self.mem.add_trials(self.journal.trials)
        self.dists = distributions(plan.space)
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
            self.mem.sampler = sampler_for(self.spec, k)
            asked = [self.mem.ask(self.dists) for _ in range(n)]
            points, recorded = [[float(t.params[name]) for name in self.names] for t in asked], None
        x, ids = np.asarray(points, dtype=np.float64), first + np.arange(n)
        slices = split(x, ids, self.workers)
        self._batch = (k, asked, recorded, BatchCollector(len(slices)))
        return [Task(k, j, Designs(xs, i, self.spec.method)) for j, (xs, i) in enumerate(slices)]

    def on_result(self, task: Task, cols: dict) -> list[tuple[int, dict]]:
        k, asked, recorded, collector = self._batch
        cols = collector.add(task.sub, cols)
        if cols is None:
            return []
        objectives = self.plan.objectives
        if recorded is not None:
            same_trials(self.run, k, cols, recorded, objectives, self.names)
        else:
            tell(self.mem, asked, [[float(cols[c][r]) for c, _ in objectives] for r in range(len(asked))])
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


# ---------------------------------------------------------------------------
# Optuna's plumbing: samplers, distributions, the in-memory study and its journal (complete batches only)
# ---------------------------------------------------------------------------


def sampler_for(spec: SearchSpec, batch_index: int):
    """A fresh Optuna sampler for one batch, seeded by (seed, batch): same history -> same trials."""
    import optuna

    seed = (spec.seed * 1_000_003 + batch_index) % (2 ** 31)
    if spec.method == "tpe":
        startup = min(2 * spec.trials_per_part, 100)
        return optuna.samplers.TPESampler(seed=seed, multivariate=True, n_startup_trials=startup)
    if spec.method == "nsga2":
        return optuna.samplers.NSGAIISampler(seed=seed, population_size=max(8, spec.trials_per_part))
    return optuna.samplers.RandomSampler(seed=seed)


def distributions(space: dict[str, Any]) -> dict:
    import optuna

    out = {}
    for name, dom in space.items():
        if isinstance(dom, tuple):
            out[name] = optuna.distributions.FloatDistribution(float(dom[0]), float(dom[1]))
        else:
            out[name] = optuna.distributions.CategoricalDistribution(list(dom))
    return out


def memory_study(plan: SearchPlan):
    """A fresh Optuna study in memory, in the plan's directions (the search runs on it; the journal is its record)."""
    import optuna

    optuna.logging.set_verbosity(optuna.logging.WARNING)
    return optuna.create_study(study_name="surgopt", storage=optuna.storages.InMemoryStorage(),
                               directions=[d for _, d in plan.objectives])


def _journal_study(path, plan: SearchPlan):
    import optuna
    from optuna.storages import JournalStorage
    from optuna.storages.journal import JournalFileBackend

    optuna.logging.set_verbosity(optuna.logging.WARNING)
    return optuna.create_study(study_name="surgopt", storage=JournalStorage(JournalFileBackend(str(path))),
                               load_if_exists=True, directions=[d for _, d in plan.objectives])


class Journal:
    """The search's record on disk: Optuna's journal file in the run's folder (optuna-dashboard reads it),
    holding every trial of every *complete* batch, appended batch by batch once the batch is told.

    ``Journal.open`` reads what an interrupted search left: the trials of its leading complete batches
    (a batch cut short by a kill, or a half-written last line, is dropped and the file rewritten without
    it). An unreadable journal raises ``JournalProblem``.
    """

    def __init__(self, path, plan: SearchPlan, study, trials: list):
        self.path, self.plan, self._study, self.trials = path, plan, study, trials

    @classmethod
    def open(cls, path, plan: SearchPlan) -> "Journal":
        from pathlib import Path

        path = Path(path)
        batch = plan.spec.trials_per_part
        trials = []
        ends_cleanly = not path.exists() or path.stat().st_size == 0 or _last_byte(path) == b"\n"
        if path.exists() and path.stat().st_size:
            try:
                trials = _read_journal(path)
            except Exception as exc:  # noqa: BLE001 - whatever Optuna raises on a damaged file
                raise JournalProblem(f"{path}: Optuna's journal cannot be read ({type(exc).__name__}: "
                                     f"{str(exc)[:120]})") from None
        complete = []
        for k in range(0, len(trials), batch):
            n = min(batch, plan.spec.trials - k)
            chunk = trials[k:k + n]
            if len(chunk) < n or not all(t.state.is_finished() for t in chunk) \
                    or [t.number for t in chunk] != list(range(k, k + n)):
                break
            complete += chunk
        if len(complete) != len(trials) or not ends_cleanly:
            _rewrite_journal(path, plan, complete)
        return cls(path, plan, None, complete)

    @property
    def batches(self) -> int:
        """How many complete batches the journal holds."""
        return -(-len(self.trials) // self.plan.spec.trials_per_part) if self.trials else 0

    def append(self, frozen_trials: list) -> None:
        if self._study is None:
            self._study = _journal_study(self.path, self.plan)
        self._study.add_trials(frozen_trials)
        self.trials += frozen_trials


def _read_journal(path) -> list:
    """The trials a journal holds, read without writing to it (creating the study would append to the file)."""
    import optuna
    from optuna.storages import JournalStorage
    from optuna.storages.journal import JournalFileBackend

    storage = JournalStorage(JournalFileBackend(str(path)))
    if not storage.get_all_studies():
        return []
    return optuna.load_study(study_name="surgopt", storage=storage).get_trials(deepcopy=False)


class JournalProblem(ValueError):
    """A journal that cannot be read."""


def _last_byte(path) -> bytes:
    with open(path, "rb") as f:
        f.seek(-1, 2)
        return f.read(1)


def _rewrite_journal(path, plan: SearchPlan, trials: list) -> None:
    """Replace the journal with one holding exactly ``trials`` (written beside it, then renamed)."""
    import os

    tmp = path.with_name(f".{path.name}.tmp-{os.getpid()}")
    tmp.unlink(missing_ok=True)
    try:
        _journal_study(tmp, plan).add_trials(trials)
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


def tell(study, trials, values: list[list[float]]) -> None:
    import optuna

    for trial, v in zip(trials, values):
        if all(np.isfinite(v)):
            study.tell(trial, v if len(v) > 1 else v[0])
        else:
            study.tell(trial, state=optuna.trial.TrialState.FAIL)
