"""Plans: how a study's design space is explored, one class each, in one registry.

A study says *what* it evaluates (``surgopt.studies.Study``: its grid as chunks, ``evaluate`` for any batch of
designs, ``search_plan`` for its named dimensions and objectives). A plan says *how* the space is explored:

- ``grid``    the study's own chunks (rcm-grid's full map, raven-sweep's sweep, every study's default);
- ``cull``    a study's exact argmax by culling in one task (rcm-grid's ``--cull``);
- ``refine``  a compass search from the top-k designs of a parent run (``--refine``), recorded with its key;
- ``optuna``  Optuna's TPE, NSGA-II or random sampler ([search] method = "tpe" | "nsga2" | "random");
- ``cmaes``   CMA-ES on the ``cmaes`` package (ask/tell, IPOP or BIPOP restarts, CMA-ES with margin when a
              dimension is categorical).

The runner (``surgopt.runner``) has one path for every plan: it asks a plan's *session* for tasks, runs them on
the backend, hands each task's rows back to the session and stores the parts the session gives it. Tasks carry
their designs as payload; the config stays exactly what the user wrote. A new plan is a module here with a class
that has ``name``, ``key``, ``record``, ``n_parts``, ``chunk``, ``session``, and one line in ``PLANS``.
"""
from __future__ import annotations

import hashlib
import itertools
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from surgopt.parts import concat_rows

#: Plan name -> "module:class" (imported on first use, so that importing surgopt loads no optimiser).
PLANS = {"grid": "surgopt.plans.grid:GridPlan", "cull": "surgopt.plans.cull:CullPlan",
         "refine": "surgopt.plans.refine:RefinePlan",
         "optuna": "surgopt.plans.optuna_plan:OptunaPlan", "cmaes": "surgopt.plans.cmaes_plan:CmaesPlan"}



@dataclass(frozen=True)
class Designs:
    """Payload of a task: evaluate these designs (rows x the plan's dimensions, in ``search_plan`` order) with
    these row ids; ``source`` names the plan in the rows of studies that record it."""

    x: np.ndarray
    ids: np.ndarray
    source: str


@dataclass(frozen=True)
class Compass:
    """Payload of a task: a compass search (``compass_search``) from ``start`` inside ``bounds`` with ``steps``,
    maximising ``sign * objective``; rows are every design it evaluated, ids from ``first_id``."""

    start: tuple
    bounds: tuple
    steps: tuple
    max_evals: int
    objective: str
    sign: float
    first_id: int


class Cull:
    """Payload of the cull plan's one task (``plans.cull``): the study's exact argmax by culling."""


@dataclass(frozen=True)
class Task:
    """One unit of work on a backend: ``index`` (the study's chunk, or the plan's batch), ``sub`` (a slice of a
    batch spread over the workers), ``payload`` (None: the study's own chunk ``index``; ``Designs``; ``Compass``)."""

    index: int
    sub: int = 0
    payload: Any = None


def run_task(study, cfg, chunk: int, task: Task) -> dict:
    """A task's rows as a dict of numpy columns (runs in a thread, a worker process or on a cluster)."""
    p = task.payload
    if p is None:
        return study.compute_task(cfg, chunk, task.index)
    if isinstance(p, Designs):
        return study.evaluate(cfg, p.x, p.ids, p.source)
    if isinstance(p, Compass):
        return compass_rows(study, cfg, p)
    if isinstance(p, Cull):
        return study.cull(cfg)
    raise TypeError(f"unknown task payload {type(p).__name__}")


def compass_rows(study, cfg, p: Compass) -> dict:
    """Every design a compass search from ``p.start`` evaluated, as the study's rows (ids from ``p.first_id``)."""
    from surgopt.plans.search import compass_search

    rows = []

    def value(x):
        r = study.evaluate(cfg, np.asarray([x]), np.array([p.first_id + len(rows)]), "refine")
        rows.append(r)
        return p.sign * float(r[p.objective][0])  # NaN (no workspace) never counts as an improvement

    compass_search(value, p.start, p.bounds, p.steps, p.max_evals)
    return concat_rows(rows)


def split(x: np.ndarray, ids: np.ndarray, parts: int) -> list[tuple[np.ndarray, np.ndarray]]:
    """A batch's designs in at most ``parts`` contiguous slices (one per worker); concatenated, they are the batch."""
    n = x.shape[0]
    parts = max(1, min(parts, n))
    cuts = np.linspace(0, n, parts + 1).round().astype(int)
    return [(x[a:b], ids[a:b]) for a, b in itertools.pairwise(cuts) if b > a]


@dataclass
class BatchCollector:
    """Rows of one batch's sub-tasks, put back in order once every slice is in."""

    n: int
    got: dict = field(default_factory=dict)

    def add(self, sub: int, cols: dict) -> dict | None:
        self.got[sub] = cols
        if len(self.got) < self.n:
            return None
        return concat_rows([self.got[k] for k in range(self.n)])


class TaskList:
    """A session whose tasks are known up front (a grid's chunks, a refine's starts): each task is one part."""

    def __init__(self, total: int, tasks: list[Task], unit: str):
        self.total, self.done, self.unit, self._todo = total, total - len(tasks), unit, tasks

    @property
    def remaining(self) -> bool:
        return bool(self._todo)

    def next_tasks(self) -> list[Task]:
        todo, self._todo = self._todo, []
        return todo

    def on_result(self, task: Task, cols: dict) -> list[tuple[int, dict]]:
        self.done += 1
        return [(task.index, cols)]

    def final_meta(self) -> dict:
        return {}


class OptimiserPlan:
    """What the optimiser plans share: a [search] section (``spec``) names them, so the run's key is the config's;
    a part holds ``batch`` trials (CMA-ES: at least, whole generations); the estimate adds the optimiser's own
    time per trial (``seconds_per_trial``) to the study's for its evaluations."""

    name = "optimiser"
    seconds_per_trial = 0.0

    def __init__(self, spec):
        self.spec = spec

    def key(self, study, cfg, base_key: str) -> str:
        return base_key

    def estimate(self, study, cfg):
        return with_overhead(study.estimate(cfg), self.seconds_per_trial)

    def chunk(self, study, cfg) -> int:
        return self.spec.trials_per_part

    def n_parts(self, study, cfg, chunk: int) -> int:
        return math.ceil(self.spec.trials / self.spec.trials_per_part)


def derived_key(base_key: str, plan_record: dict) -> str:
    """The store key of a run that explores a config another way than its own plan (a refine from a parent run):
    sha256 of the config's key and the plan's record."""
    import json

    h = hashlib.sha256(base_key.encode())
    h.update(json.dumps(plan_record, sort_keys=True).encode())
    return h.hexdigest()


def estimate(study, cfg, plan=None):
    """What ``cfg`` explored by ``plan`` (None: the config's own) costs before it runs: the study's estimate of
    its evaluations plus the plan's own time (an optimiser's ask and tell), or None if the study has none."""
    if study.estimate is None:
        return None
    plan = plan if plan is not None else plan_for(study, cfg)
    return plan.estimate(study, cfg)


def with_overhead(est, seconds_per_item: float):
    """``est`` with ``seconds_per_item`` of the plan's own work added per item (trial)."""
    from dataclasses import replace

    return replace(est, seconds_one_core=est.seconds_one_core + est.items * seconds_per_item)


def get_plan_class(name: str):
    import importlib

    module, cls = PLANS[name].split(":")
    return getattr(importlib.import_module(module), cls)


def plan_for(study, cfg):
    """The plan a config names: its [search] method's (an optimiser), else the study's own grid."""
    from surgopt.plans.search import optimiser_of

    spec = optimiser_of(cfg)
    if spec is None:
        return get_plan_class("cull" if getattr(cfg, "search", None) == "cull" and study.cull else "grid")()
    if study.search_plan is None or study.evaluate is None:
        from surgopt.errors import UsageError

        raise UsageError(f"{study.name}: [search] method {spec.method!r}: this study has no design space to search")
    from surgopt.plans.search import METHOD_PLANS

    return get_plan_class(METHOD_PLANS[spec.method])(spec)


def follow_up_plan(name: str, study, cfg, result):
    """The plan ``name`` exploring ``cfg`` from a finished run (``runner.RunResult``): e.g. the refine from its
    best designs, recording the run's key as its parent."""
    from surgopt.errors import UsageError

    cls = get_plan_class(name) if name in PLANS else None
    if cls is None or not hasattr(cls, "from_run"):
        follow = [n for n in PLANS if hasattr(get_plan_class(n), "from_run")]
        raise UsageError(f"plan {name!r} does not follow a run (one of: {', '.join(follow)})")
    if study.refine_space is None or study.evaluate is None:
        raise UsageError(f"{study.name}: plan {name!r} needs a design space, which this study does not declare")
    return cls.from_run(study, cfg, result.parts, result.run.key)
