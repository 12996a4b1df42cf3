"""One module per study: config -> tasks (chunks) -> kernel calls -> Arrow table; summaries.

A study module provides:
  NAME, KERNEL_VERSION, Config (pydantic model), DEFAULT_CONFIG (file name in
  surgopt/defaults), SCHEMA (pyarrow schema, built lazily by ``schema()``),
  ``auto_chunk(cfg)``, ``n_tasks(cfg, chunk)``, ``warm_up(cfg)``, ``compute_task(cfg, chunk, i)`` ->
  dict of numpy columns, ``summarize(table)`` -> dict and ``tables(table)`` ->
  [(title, header, rows)] for the command's closing report.
"""
from __future__ import annotations

import importlib

STUDIES = {"rcm-grid": "surgopt.studies.rcm_grid", "suture-sim": "surgopt.studies.suture_sim",
           "raven-sweep": "surgopt.studies.raven_sweep"}


def get_study(name: str):
    return importlib.import_module(STUDIES[name])


#: Work per task the automatic chunk size aims at (s on one core), and the fewest tasks it makes.
TARGET_TASK_S = 2.0
MIN_TASKS = 32


def chunk_for_seconds(n_items: int, seconds_per_item: float) -> int:
    """Items per task for ~TARGET_TASK_S of work each, but at least MIN_TASKS tasks when possible."""
    import math

    by_time = max(1, int(TARGET_TASK_S / max(seconds_per_item, 1e-12)))
    by_count = max(1, math.ceil(n_items / MIN_TASKS))
    return min(by_time, by_count)
