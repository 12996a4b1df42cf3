"""A toy study for the plans' tests: a design space of two continuous dimensions and one categorical, an
objective with a known maximum, and nothing else (no kernel, no robot).

    f(u, v, w) = 10 - (u - 0.3)^2 - 4 (v + 0.6)^2 - (0 if w == 2 else 0.5)     (max 10 at u=0.3, v=-0.6, w=2)
    infeasible (f = NaN) where u > 0.9: a plan must rank such designs last.

Registered as "toy-search" in ``surgopt.studies.STUDIES`` by tests/test_plans.py's ``toy`` fixture (threads backend only: worker processes
do not see the registration).
"""
from __future__ import annotations

import math

import numpy as np
import pyarrow as pa
from pydantic import Field

from surgopt.config import StrictModel
from surgopt.studies import Study, Summary
from surgopt.plans.search import SearchPlan, objectives_of, optimiser_of, search_field

NAME = "toy-search"
DIMS = ("u", "v", "w")
W_CHOICES = [0.0, 1.0, 2.0]


class Refine(StrictModel):
    top_k: int = Field(2, ge=1, le=10)
    max_evals: int = Field(40, ge=10, le=1000)


class ToyConfig(StrictModel):
    grid_count: int = Field(11, ge=2, le=1000, description="grid points per continuous dimension")
    search: search_field("grid") = "grid"
    refine: Refine = Refine()


def objective(u, v, w):
    f = 10 - (u - 0.3) ** 2 - 4 * (v + 0.6) ** 2 - np.where(w == 2.0, 0.0, 0.5)
    return np.where(u > 0.9, np.nan, f)


def rows(x: np.ndarray, ids: np.ndarray) -> dict:
    x = np.asarray(x, dtype=np.float64).reshape(-1, 3)
    f = objective(x[:, 0], x[:, 1], x[:, 2])
    return {"design_id": np.asarray(ids, dtype=np.int64), "u": x[:, 0].copy(), "v": x[:, 1].copy(),
            "w": x[:, 2].copy(), "f": f, "g": -x[:, 0] ** 2}


def grid(cfg) -> np.ndarray:
    n = cfg.grid_count
    axes = [np.linspace(0, 1, n), np.linspace(-1, 0, n), np.asarray(W_CHOICES)]
    return np.stack([a.ravel() for a in np.meshgrid(*axes, indexing="ij")], axis=1)


def schema():
    return pa.schema([("design_id", pa.int64()), ("u", pa.float64()), ("v", pa.float64()), ("w", pa.float64()),
                      ("f", pa.float64()), ("g", pa.float64())])


def compute_task(cfg, chunk, index):
    x = grid(cfg)
    ids = np.arange(index * chunk, min(len(x), (index + 1) * chunk))
    return rows(x[ids], ids)


def evaluate(cfg, x, ids, source):
    return rows(x, ids)


def search_plan(cfg):
    spec = optimiser_of(cfg)
    if spec is None:
        return None
    return SearchPlan(spec, {"u": (0.0, 1.0), "v": (-1.0, 0.0), "w": list(W_CHOICES)}, objectives_of(spec, "f"))


def refine_space(cfg):
    return list(DIMS), [(0.0, 1.0), (-1.0, 0.0), (0.0, 2.0)], [0.05, 0.05, 0.0]


def summary(parts):
    f = parts.column("f")
    return Summary({"designs": len(f), "best_f": float(np.nanmax(f)) if np.isfinite(f).any() else math.nan},
                   {"feasible": int(np.isfinite(f).sum())})


STUDY = Study(
    name=NAME, kernel_version="toy-1", config_model=ToyConfig, default_config="", help="toy", config_help="toy",
    schema=schema, key_columns=("design_id",), objective="f",
    auto_chunk=lambda cfg: 50, n_tasks=lambda cfg, chunk: math.ceil(len(grid(cfg)) / chunk),
    warm_up=lambda cfg: None, compute_task=compute_task, summary=summary,
    feasible_mask=lambda t: np.isfinite(t["f"].to_numpy()), figures=lambda *a: [], search_plan=search_plan,
    evaluate=evaluate, refine_space=refine_space)
