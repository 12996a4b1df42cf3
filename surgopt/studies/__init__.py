"""One module per study: config -> tasks (chunks) -> kernel calls -> Arrow table; summaries.

A study module provides:
  NAME, KERNEL_VERSION, Config (pydantic model), DEFAULT_CONFIG (file name in
  surgopt/defaults), SCHEMA (pyarrow schema, built lazily by ``schema()``),
  ``n_tasks(cfg, chunk)``, ``warm_up(cfg)``, ``compute_task(cfg, chunk, i)`` ->
  dict of numpy columns, ``summarize(table)`` -> dict and ``tables(table)`` ->
  [(title, header, rows)] for the command's closing report.
"""
from __future__ import annotations

import importlib

STUDIES = {"rcm-grid": "surgopt.studies.rcm_grid", "suture-sim": "surgopt.studies.suture_sim",
           "raven-sweep": "surgopt.studies.raven_sweep"}


def get_study(name: str):
    return importlib.import_module(STUDIES[name])
