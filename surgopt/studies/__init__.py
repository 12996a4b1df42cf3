"""One module per study: config -> tasks (chunks) -> kernel calls -> Arrow table; summaries.

A study module provides:
  NAME, KERNEL_VERSION, Config (pydantic model), DEFAULT_CONFIG (file name in
  surgopt/defaults), SCHEMA (pyarrow schema, built lazily by ``schema()``),
  ``n_tasks(cfg, chunk)``, ``warm_up(cfg)``, ``compute_task(cfg, chunk, i)`` ->
  dict of numpy columns, and ``summarize(table)``.
"""
from __future__ import annotations

import importlib

STUDIES = {"rcm-grid": "surgopt.studies.rcm_grid"}


def get_study(name: str):
    return importlib.import_module(STUDIES[name])
