"""The cull plan: a study's exact argmax by culling (rcm-grid's Culling algorithm, Stocco & Salcudean), one task
whose rows are every candidate with its value or an upper bound. Named by the config (``search = "cull"``, or the
study's ``--cull`` flag), so the run's key is the config's."""
from __future__ import annotations

from surgopt.plans import Cull, Task, TaskList


class CullPlan:
    name = "cull"
    parts_known_up_front = True  # one part

    def key(self, study, cfg, base_key: str) -> str:
        return base_key

    def record(self) -> dict:
        return {"name": self.name}

    def estimate(self, study, cfg):
        return study.estimate(cfg)

    def chunk(self, study, cfg) -> int:
        return 1

    def n_parts(self, study, cfg, chunk: int) -> int:
        return 1

    def session(self, study, cfg, chunk: int, run, workers: int) -> TaskList:
        return TaskList(1, [] if 0 in run.done_tasks() else [Task(0, 0, Cull())], "chunks")
