"""Figures of stored runs in the style of the papers, one module per study (matplotlib, Agg backend).

Each module's ``figures(cfg, table, out_dir, design_id)`` writes PNG files and returns their paths;
its study declares it as ``Study.figures``. Shared here: the backend, saving, and a table's columns
as plain numpy arrays.
"""
from __future__ import annotations

import contextlib

from pathlib import Path

import numpy as np


def columns(table) -> dict[str, np.ndarray]:
    """An Arrow table's columns as numpy arrays (strings as object arrays, not pandas' string dtype)."""
    import pyarrow as pa

    return {name: (col.to_numpy(zero_copy_only=False) if not pa.types.is_string(col.type) else
                   np.array(col.to_pylist(), dtype=object)) for name, col in zip(table.column_names, table.columns)}


def pyplot():
    """matplotlib.pyplot on the Agg backend (no screen needed)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


#: File formats ``plot --format`` offers (matplotlib writes each without extra packages).
FORMATS = ("png", "pdf", "svg")
_format = ["png"]


def set_format(fmt: str) -> None:
    """The format ``save`` writes (its path's suffix is replaced): png, pdf or svg."""
    if fmt not in FORMATS:
        raise ValueError(f"format {fmt!r}: one of {', '.join(FORMATS)}")
    _format[0] = fmt


_stamp: list[str] = []


@contextlib.contextmanager
def stamped(text: str):
    """Every figure ``save`` writes inside carries ``text`` in its bottom right corner (``surgopt plot``: the
    run's key and config, so that a figure pasted elsewhere says which run it shows)."""
    _stamp.append(text)
    try:
        yield
    finally:
        _stamp.pop()


def save(fig, path: Path) -> Path:
    path = path.with_suffix(f".{_format[0]}")
    if _stamp:  # under everything drawn (an axis label at the bottom edge would sit under a stamp inside it)
        low = fig.get_tightbbox(fig.canvas.get_renderer()).y0 / fig.get_figheight()
        fig.text(0.995, min(low, 0.0) - 0.005, _stamp[-1], ha="right", va="top", fontsize=6, color="0.45")
    fig.savefig(path, dpi=110, bbox_inches="tight")
    pyplot().close(fig)
    return path


def search_figures(cfg, table, out: Path, plan, reference=None, feasible=None, objective=None) -> list[Path]:
    """An optimiser's run: best objective against trials (one objective; ``reference`` = (label, value)
    draws e.g. the grid's best as a line), or the Pareto front of the feasible trials (several; ``feasible``, a
    mask of the rows, default all), trials in grey, infeasible ones as crosses. ``objective`` (column,
    direction): what a person reads the search by when the optimiser's is a penalised stand-in
    (``Study.reported_objective``): drawn for the feasible trials only, on its own scale."""
    from surgopt.plans.search import best_so_far, pareto_front

    plt = pyplot()
    c = columns(table)
    order = np.argsort(c[next(iter(c))], kind="stable")  # the first column is the trial number
    if len(plan.objectives) == 1:
        col, direction = objective or plan.objectives[0]
        ok = (np.ones(len(order), bool) if feasible is None else np.asarray(feasible, bool))[order]
        y = np.where(ok, c[col][order].astype(float), np.nan) if objective else c[col][order]
        fig, ax = plt.subplots(figsize=(5.6, 3.8))
        ax.plot(np.arange(1, len(order) + 1), y, ".", color="0.75", ms=3,
                label="feasible trials" if objective else "trials")
        ax.plot(np.arange(1, len(order) + 1), best_so_far(y, direction), "-", label="best so far")
        if reference is not None:
            ax.axhline(reference[1], color="C3", ls="--", lw=1, label=f"{reference[0]}: {reference[1]:.6g}")
        ax.set_xlabel("trial")
        ax.set_ylabel(col)
        best = (np.nanmax(y) if direction == "maximize" else np.nanmin(y)) if np.isfinite(y).any() else np.nan
        ax.set_title(f"{plan.spec.method}: best {col} {best:.6g} after {len(order)} trials"
                     + (f", {int(ok.sum())} feasible" if objective else "") + f" (seed {plan.spec.seed})", fontsize=9)
        ax.legend(fontsize=8)
        return [save(fig, out / "search_convergence.png")]
    (cx, dx), (cy, dy) = plan.objectives[:2]
    ok = np.ones(len(c[cx]), bool) if feasible is None else np.asarray(feasible, bool)
    kept = np.flatnonzero(ok)
    idx = kept[pareto_front(np.column_stack([c[cx][kept], c[cy][kept]]), [dx, dy])]
    fig, ax = plt.subplots(figsize=(5.6, 4.2))
    ax.plot(c[cx][ok], c[cy][ok], ".", color="0.75", ms=3, label="trials")
    if not ok.all():
        ax.plot(c[cx][~ok], c[cy][~ok], "x", color="0.85", ms=3, label="infeasible trials")
    f = idx[np.argsort(c[cx][idx])]
    ax.plot(c[cx][f], c[cy][f], "o-", ms=4, label=f"Pareto front ({len(idx)})")
    ax.set_xlabel(f"{cx} ({dx})")
    ax.set_ylabel(f"{cy} ({dy})")
    ax.set_title(f"{plan.spec.method}: {len(c[cx])} trials", fontsize=9)
    ax.legend(fontsize=8)
    return [save(fig, out / "search_pareto_front.png")]
