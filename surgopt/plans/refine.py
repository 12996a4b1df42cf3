"""The refine plan: a compass search (Kolda, Lewis & Torczon 2003, Sec. 3.5) from the top-k designs of a
parent run, inside the study's bounds. The config is the parent's, unchanged; the plan records the parent's key
(and the run's key is derived from both), so a refine of another grid run is another run."""
from __future__ import annotations

from surgopt.plans import Compass, Task, TaskList, derived_key

#: Row ids of start k begin at k * IDS_PER_START (a compass search evaluates at most refine.max_evals designs).
IDS_PER_START = 1_000_000


class RefinePlan:
    """From ``parent`` (the parent run's key) and its ``starts`` (designs, in the study's ``refine_space`` order),
    one task per start: a compass search with ``max_evals`` evaluations at most, maximising ``objective``."""

    name = "refine"

    def __init__(self, parent: str, starts: list[list[float]], max_evals: int, objective: str, sign: float = 1.0):
        self.parent, self.starts, self.max_evals = parent, [list(map(float, s)) for s in starts], int(max_evals)
        self.objective, self.sign = objective, float(sign)

    @classmethod
    def from_run(cls, study, cfg, parts, parent_key: str) -> RefinePlan:
        """The refine of a stored run: its top ``cfg.refine.top_k`` designs by the study's objective."""
        names, _, _ = study.refine_space(cfg)
        top = parts.top(study.objective, cfg.refine.top_k)
        starts = [[top[p][i].as_py() for p in names] for i in range(top.num_rows)]
        return cls(parent_key, starts, cfg.refine.max_evals, study.objective)

    def record(self) -> dict:
        return {"name": self.name, "parent": self.parent, "starts": self.starts, "max_evals": self.max_evals,
                "objective": self.objective, "sign": self.sign}

    def key(self, study, cfg, base_key: str) -> str:
        return derived_key(base_key, self.record())

    def estimate(self, study, cfg):
        """Starts x max_evals designs, each costed as the study costs one trial of a search."""
        from dataclasses import replace

        from surgopt.plans.search import SearchSpec

        n = max(1, len(self.starts)) * self.max_evals
        as_trials = study.estimate(cfg.model_copy(update={"search": SearchSpec(method="random", trials=n)}))
        return replace(as_trials, what="designs evaluated by the compass search (at most)")

    def chunk(self, study, cfg) -> int:
        return 1

    def n_parts(self, study, cfg, chunk: int) -> int:
        return max(1, len(self.starts))

    def session(self, study, cfg, chunk: int, run, workers: int) -> TaskList:
        _, bounds, steps = study.refine_space(cfg)
        tasks = [Task(k, 0, Compass(tuple(s), tuple(map(tuple, bounds)), tuple(steps), self.max_evals,
                                    self.objective, self.sign, k * IDS_PER_START))
                 for k, s in enumerate(self.starts) if k not in run.done_tasks()]
        return TaskList(len(self.starts), tasks, "starts")
