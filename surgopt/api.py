"""The Python API: run a study, load a stored run, list the store, as pandas DataFrames.

    import surgopt
    df = surgopt.run("rcm-grid", overrides={"workspace.points_per_side": 9})
    surgopt.runs()                       # what the store holds
    df = surgopt.load("597ae5d5")        # a run by key prefix (or a config file)
    surgopt.summarize("597ae5d5")        # headline, top designs, ... as a dict; plot(...), diff(a, b) likewise
    df[df.feasible].nsmallest(3, "cost")  # rank the feasible rows: an infeasible row keeps its terms' numbers

Configs and overrides are validated exactly as on the command line (the same errors); the store is
``store``, else $SURGOPT_STORE, else ./surgopt-store. Importing ``surgopt`` configures numba (its cache
folder and vector width) before numba loads.
"""
from __future__ import annotations

from pathlib import Path
from typing import Any


def run(study: str, config: str | Path | None = None, overrides: dict[str, Any] | list[str] | None = None,
        store: str | Path | None = None, jobs: int = 2, backend: str = "threads", force: bool = False,
        quiet: bool = True, max_hours: float | None = 1.0, plan: Any = None):
    """Run (or fetch from the store) one study and return its rows as a DataFrame.

    ``config``: a TOML/YAML file, or None for the paper's setup; ``overrides``: {"a.b": value} or
    ["a.b=value", ...] applied on top (one value each; use the CLI's --multirun for families).
    ``plan``: None (the plan the config names: its [search] method, else the study's grid); the name of a
    follow-up plan ("refine": the config's own run first, then a compass search from its best designs, as
    ``--refine`` does; its rows are returned); or a plan object (``surgopt.plans``).
    The DataFrame's ``attrs`` hold the run's ``key``, ``config`` (as validated and hashed), ``config_name`` and
    ``plan`` record. Every row is returned, the infeasible ones with the numbers of their terms (a port-place
    layout's ``cost`` among them): rank ``df[df.feasible]``.
    """
    from surgopt.compose import variants
    from surgopt.plans import follow_up_plan
    from surgopt.runner import run_study
    from surgopt.store import Store
    from surgopt.studies import get_study

    st = _study(study)
    (v,) = variants(st, config, overrides)
    kw = dict(config_name=v.config_name, store=Store(store), jobs=jobs, backend=backend, force=force, quiet=quiet,
              say=lambda m: None, max_hours=max_hours)
    st = get_study(st.name)
    if isinstance(plan, str):
        first = run_study(st, v.config, **kw)
        kw["config_name"] = f"{v.config_name}+{plan}"
        plan = follow_up_plan(plan, st, v.config, first)
    res = run_study(st, v.config, plan=plan, **kw)
    df = res.table.to_pandas()
    df.attrs.update(key=res.run.key, config=res.run.manifest["config"], config_name=res.run.manifest["config_name"],
                    plan=res.run.manifest.get("plan"))
    return df


def load(run: str | Path | None = None, store: str | Path | None = None, study: str | None = None,
         allow_partial: bool = False):
    """A stored run's rows (every part verified) as a DataFrame: by key prefix, config file, or the latest.
    A partial run (interrupted, or being written) raises ``StoreError`` saying how many chunks are stored,
    unless ``allow_partial``."""
    from surgopt.results import require_complete, resolve_run
    from surgopt.store import Store

    s = Store(store)
    st, r = resolve_run(s, None if run is None else str(run), study)
    return require_complete(s, r, allow_partial).read_table(st.schema_for(r.manifest["config"])).to_pandas()


def runs(store: str | Path | None = None, study: str | None = None):
    """The store's runs as a DataFrame: study, key, config_name, rows, state, created, and provenance."""
    import pandas as pd

    from surgopt.results import run_records
    from surgopt.store import Store

    return pd.DataFrame(run_records(Store(store), study))


def summarize(run: str | Path | None = None, store: str | Path | None = None, study: str | None = None,
              top: int = 10, sort: str | None = None) -> dict:
    """What ``surgopt summarize --format json`` prints, as a dict: headline, feasibility, the top designs, the
    objective's distribution, the study's tables, the best design's edges of the box."""
    from surgopt.report import run_record
    from surgopt.results import resolve_run
    from surgopt.store import Store

    st, r = resolve_run(Store(store), None if run is None else str(run), study)
    return run_record(st, r, top=top, sort=sort)


def plot(run: str | Path | None = None, store: str | Path | None = None, study: str | None = None,
         out: str | Path | None = None, fmt: str = "png") -> list[Path]:
    """The run's figures (``surgopt plot``): into ``out``, else the run's own folder in the store (``_figures``);
    returns their paths."""
    from surgopt.results import config_of, resolve_run
    from surgopt.store import Store
    from surgopt.studies.plotting import set_format

    s = Store(store)
    st, r = resolve_run(s, None if run is None else str(run), study)
    folder = Path(out) if out is not None else r.path / "_figures"
    folder.mkdir(parents=True, exist_ok=True)
    set_format(fmt)
    cfg = config_of(st, r)
    table = r.read_table(st.schema_for(r.manifest["config"]))
    plan = st.search_plan(cfg) if st.search_plan else None
    if plan is not None:
        from surgopt.studies.plotting import search_figures

        from surgopt.report import feasible_rows

        return search_figures(cfg, table, folder, plan, feasible=feasible_rows(st, table))
    return st.figures(cfg, table, folder, None)


def diff(run_a: str, run_b: str, store: str | Path | None = None, study: str | None = None, top: int = 5) -> dict:
    """Two runs of one study compared (``surgopt diff --format json``): differing config fields, per-metric
    changes on the rows joined by the key columns, the most changed rows, the best design of each."""
    from surgopt.results import diff_runs
    from surgopt.store import Store

    return diff_runs(Store(store), run_a, run_b, study, top)


def _study(name: str):
    from surgopt.errors import UsageError
    from surgopt.studies import STUDIES, get_study

    if name not in STUDIES:
        raise UsageError(f"unknown study {name!r} (one of {', '.join(STUDIES)})")
    return get_study(name)
