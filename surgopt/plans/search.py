"""Searches over a study's continuous design space that any study can use (the grid is the default).

``compass_search``: derivative-free coordinate search inside box bounds (Kolda, Lewis & Torczon 2003,
"Optimization by direct search", Sec. 3.5), a cheap local refinement of a grid's best designs.
``SearchSpec`` / ``SearchPlan`` and the helpers below: the vocabulary of a [search] section (its method, trials,
objectives) and of the space a study offers, which the studies declare and the optimiser plans
(``optuna_plan``, ``cmaes_plan``) run; the Pareto front and best-so-far curves the reports draw.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Annotated, Any, Callable, Literal, Sequence, Union

import numpy as np
from pydantic import Field, model_validator

from surgopt.config import StrictModel


def compass_search(objective: Callable[[np.ndarray], float], start: Sequence[float],
                   bounds: Sequence[tuple[float, float]], steps: Sequence[float], max_evals: int,
                   min_step_fraction: float = 1e-3) -> list[np.ndarray]:
    """Maximise ``objective`` from ``start``: every evaluated point, in order (the start first).

    Each coordinate is tried at +-step (clipped to its bounds); the first improvement moves there;
    when a sweep over all coordinates improves nothing, every step halves. Stops after
    ``max_evals`` evaluations or when each step is below ``min_step_fraction`` of its range.
    A coordinate with step 0 stays fixed.
    """
    x = np.array(start, float)
    steps = np.array(steps, float)
    ranges = np.maximum(1e-9, [hi - lo for lo, hi in bounds])
    best = objective(x)
    visited = [x.copy()]
    evals = 1
    while evals < max_evals and np.any(steps > min_step_fraction * ranges):
        improved = False
        for i in range(len(x)):
            if steps[i] == 0:
                continue
            for sign in (1.0, -1.0):
                y = x.copy()
                y[i] = min(bounds[i][1], max(bounds[i][0], y[i] + sign * steps[i]))
                if y[i] == x[i]:
                    continue
                value = objective(y)
                evals += 1
                visited.append(y.copy())
                if value > best:
                    best, x, improved = value, y, True
                    break
            if evals >= max_evals:
                break
        if not improved:
            steps = steps / 2
    return visited


# ---------------------------------------------------------------------------
# A study's design space searched by an optimiser ([search] method = "cmaes" | "tpe" | ...)
# ---------------------------------------------------------------------------


#: [search] method -> the plan that runs it (``surgopt.plans.PLANS``): the one list of methods.
METHOD_PLANS = {"cmaes": "cmaes", "tpe": "optuna", "nsga2": "optuna", "random": "optuna"}
#: The values of [search] method: the grid (no optimiser), then every optimiser.
METHODS = ("grid", *METHOD_PLANS)
#: Trials per stored part when ``batch`` is left out. Optuna asks a batch at a time (its size shapes the search);
#: CMA-ES asks a generation at a time, so its part is only the unit of durability: 256 trials a part store a
#: 5,000-trial Table II search in 20 parts instead of 71, which takes ~0.4 s (a fifth of the search's own time
#: on 2 cores; benchmarks/bench_search.py) off the parent, at the cost of up to 256 trials recomputed on resume.
DEFAULT_BATCH = {"cmaes": 256}
DEFAULT_BATCH_OTHERS = 64


class SearchSpec(StrictModel):
    """``[search]``: an optimiser over the study's design space (ranges as continuous bounds, lists categorical).

    How each method explores it is a plan (``surgopt.plans``): "cmaes" the ``cmaes`` package with ``restarts``,
    "tpe" / "nsga2" / "random" Optuna's samplers. ``batch``: trials per stored part (Optuna: per ask, seeded by
    (seed, batch); CMA-ES: a part holds whole generations, at least ``batch`` trials); left out, ``DEFAULT_BATCH``
    of the method (``trials_per_part``). An interrupted search resumes to the same trials as an uninterrupted one.
    """

    method: Literal[METHODS] = "grid"
    trials: int = Field(1000, ge=1, le=1_000_000)
    batch: int | None = Field(None, ge=1, le=10_000, description="trials per stored part (Optuna: per ask); "
                              "default 64, cmaes 256")
    seed: int = Field(0, ge=0, le=2 ** 31 - 1)
    objectives: list[Annotated[str, Field(min_length=1, max_length=64)]] | None = Field(
        None, min_length=1, max_length=4,
        description="row columns to maximise ('-name' to minimise); default: the study's objective")
    population: int | None = Field(
        None, ge=4, le=10_000, description="cmaes: the first run's population (default 4 + 3 ln n for n dimensions); "
                                           "restarts double it")
    restarts: Literal["ipop", "bipop", "none"] = Field(
        "ipop", description="cmaes: restart with twice the population (ipop), alternating with small local "
                            "runs (bipop), or never (none)")

    @property
    def trials_per_part(self) -> int:
        """``batch``, or the method's default (``DEFAULT_BATCH``)."""
        return self.batch if self.batch is not None else DEFAULT_BATCH.get(self.method, DEFAULT_BATCH_OTHERS)

    @model_validator(mode="before")
    @classmethod
    def _legacy_points(cls, data):
        """Manifests written before plans held an empty ``points`` (runtime data no longer in the config)."""
        if isinstance(data, dict) and "points" in data:
            if data["points"] is not None:
                raise ValueError("points: a search's trials are no longer given in the config")
            data = {k: v for k, v in data.items() if k != "points"}
        return data

    @model_validator(mode="after")
    def _methods_and_objectives(self):
        n = len(self.objectives or [None])
        if self.method == "nsga2" and n < 2:
            raise ValueError("method 'nsga2' is multi-objective: give two or more objectives")
        if self.method in ("cmaes",) and n > 1:
            raise ValueError("method 'cmaes' takes one objective (use 'nsga2' or 'tpe' for several)")
        return self


def _search_form(value) -> str:
    return "<optimiser>" if isinstance(value, (dict, SearchSpec)) else "<mode>"


def search_field(*modes: str):
    """The type of a study's ``search`` field: one of its own modes (a string, e.g. "full" | "cull") or a
    [search] table (an optimiser). The string default keeps existing configs' store keys unchanged."""
    from pydantic import Discriminator, Tag

    return Annotated[Union[Annotated[Literal[modes], Tag("<mode>")], Annotated[SearchSpec, Tag("<optimiser>")]],
                     Discriminator(_search_form)]


def optimiser_of(cfg) -> SearchSpec | None:
    """A config's [search] optimiser, or None (its study's own mode)."""
    s = getattr(cfg, "search", None)
    return s if isinstance(s, SearchSpec) and s.method != "grid" else None


def check_objectives(search, allowed: tuple[str, ...]) -> None:
    """A ValueError (for a model validator) if a [search] objective is not one of the ``allowed`` columns."""
    if isinstance(search, SearchSpec):
        bad = [o for o in search.objectives or [] if o.lstrip("-") not in allowed]
        if bad:
            raise ValueError(f"search.objectives: {bad[0]!r} is not one of {', '.join(allowed)}")


@dataclass(frozen=True)
class SearchPlan:
    """What a study offers a search: its space (name -> (low, high) or [choices]) and the columns of its
    objectives with their directions ("maximize" / "minimize")."""

    spec: SearchSpec
    space: dict[str, Any]
    objectives: list[tuple[str, str]]


def objectives_of(spec: SearchSpec, default: str) -> list[tuple[str, str]]:
    return [(o.lstrip("-"), "minimize" if o.startswith("-") else "maximize") for o in (spec.objectives or [default])]


def pareto_front(values: np.ndarray, directions: list[str]) -> np.ndarray:
    """Indices of the non-dominated rows of ``values`` (rows x objectives) for these directions."""
    v = np.asarray(values, dtype=float) * np.array([1.0 if d == "maximize" else -1.0 for d in directions])
    ok = np.all(np.isfinite(v), axis=1)
    keep = []
    for i in np.flatnonzero(ok):
        dominated = np.any(np.all(v[ok] >= v[i], axis=1) & np.any(v[ok] > v[i], axis=1))
        if not dominated:
            keep.append(i)
    return np.array(keep, dtype=int)


def best_so_far(values: np.ndarray, direction: str) -> np.ndarray:
    """Running best of one objective in trial order (for the convergence figure)."""
    v = np.asarray(values, dtype=float)
    v = np.where(np.isfinite(v), v, -np.inf if direction == "maximize" else np.inf)
    return np.maximum.accumulate(v) if direction == "maximize" else np.minimum.accumulate(v)
