"""The grid plan: the study's own chunks (every study's default; rcm-grid's cull is its one-chunk mode)."""
from __future__ import annotations

from surgopt.plans import Task, TaskList


class GridPlan:
    """Every chunk of the study's grid once; resuming computes the chunks not stored."""

    name = "grid"
    #: its part count follows from the config and the chunk size alone (a manifest that says otherwise was edited)
    parts_known_up_front = True

    def key(self, study, cfg, base_key: str) -> str:
        return base_key  # the config's own plan: the config's key (unchanged from before plans)

    def record(self) -> dict:
        return {"name": self.name}

    def estimate(self, study, cfg):
        return study.estimate(cfg)

    def chunk(self, study, cfg) -> int:
        return study.auto_chunk(cfg)

    def n_parts(self, study, cfg, chunk: int) -> int:
        return study.n_tasks(cfg, chunk)

    def session(self, study, cfg, chunk: int, run, workers: int) -> TaskList:
        total, stored = run.manifest["n_tasks"], run.done_tasks()
        return TaskList(total, [Task(i) for i in range(total) if i not in stored], "chunks")
