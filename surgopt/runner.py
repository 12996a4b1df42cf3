"""Runner: tasks -> joblib workers -> progress bar -> single writer (the parent).

Knows nothing of kinematics: a study module supplies ``n_tasks``,
``warm_up``, ``compute_task`` and ``schema`` (see ``surgopt.studies``).
"""
from __future__ import annotations

import os
import time
from dataclasses import dataclass, field
from pathlib import Path

from surgopt.config import study_key
from surgopt.store import Run, Store

DEFAULT_JOBS = 2


def numba_cache_dir() -> Path:
    """Where numba keeps compiled kernels: $NUMBA_CACHE_DIR or ~/.cache/surgopt/numba."""
    if os.environ.get("NUMBA_CACHE_DIR"):
        return Path(os.environ["NUMBA_CACHE_DIR"])
    base = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache")
    return base / "surgopt" / "numba"


def configure_numba() -> Path:
    """Set NUMBA_CACHE_DIR before numba is imported (worker processes inherit it).

    (Tried and dropped: asking LLVM for 8-wide AVX-512 vectors through
    NUMBA_CPU_FEATURES gained only 8% on the rcm-grid kernel here.)
    """
    path = numba_cache_dir()
    os.environ["NUMBA_CACHE_DIR"] = str(path)
    return path


@dataclass
class RunResult:
    run: Run
    table: object  # pyarrow.Table
    cache_hit: bool
    computed_tasks: int
    elapsed_s: float
    messages: list[str] = field(default_factory=list)


def _compute(study_name: str, cfg, chunk: int, index: int):
    """Worker entry point: one task's rows as a dict of numpy columns."""
    from surgopt.studies import get_study

    return index, get_study(study_name).compute_task(cfg, chunk, index)


def _progress(quiet: bool):
    from rich.console import Console
    from rich.progress import (BarColumn, MofNCompleteColumn, Progress, TextColumn,
                               TimeElapsedColumn, TimeRemainingColumn)

    progress = Progress(
        TextColumn("[bold]{task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        TextColumn("chunks"),
        TextColumn("{task.fields[rate]}"),
        TimeElapsedColumn(),
        TimeRemainingColumn(),
        console=Console(stderr=True),
        disable=quiet,
        transient=False,
    )
    return progress


def run_study(study, cfg, *, config_name: str, store: Store, jobs: int = DEFAULT_JOBS,
              force: bool = False, quiet: bool = False, chunk: int | None = None,
              say=print) -> RunResult:
    """Compute (or fetch from the store) the table of one study config."""
    import pyarrow as pa

    t0 = time.perf_counter()
    schema = study.schema()
    key = study_key(study.NAME, cfg, study.KERNEL_VERSION)
    run = store.open(study.NAME, key)
    if run is not None and run.complete and not force and not store.bad_parts(run):
        table = run.read_table(schema)
        return RunResult(run, table, True, 0, time.perf_counter() - t0)

    with store.lock(study.NAME, key, on_wait=lambda who: say(f"waiting for {who} to finish this study ...")):
        chunk = chunk or study.DEFAULT_CHUNK
        existing = None if force else store.open(study.NAME, key)
        if existing is not None:
            chunk = existing.manifest["chunk"]  # parts already cut this way
        run = store.begin(study.NAME, key, config=cfg.model_dump(mode="json"),
                          config_name=config_name, kernel_version=study.KERNEL_VERSION,
                          n_tasks=study.n_tasks(cfg, chunk), chunk=chunk, force=force)
        total = run.manifest["n_tasks"]
        missing = [i for i in range(total) if i not in run.done_tasks()]
        messages = []
        if len(missing) < total:
            messages.append(f"resuming: {total - len(missing)} of {total} chunks already stored")
        if missing:
            study.warm_up(cfg)  # compile once in the parent; workers load the cache
            _dispatch(study, cfg, chunk, missing, run, store, jobs, quiet, total, schema, pa)
        table = run.read_table(schema)
    return RunResult(run, table, False, len(missing), time.perf_counter() - t0, messages)


def _dispatch(study, cfg, chunk, missing, run, store, jobs, quiet, total, schema, pa):
    progress = _progress(quiet)
    t_start = time.perf_counter()
    with progress:
        bar = progress.add_task(study.NAME, total=total, completed=total - len(missing), rate="")
        done_now = 0

        def record(index, cols):
            nonlocal done_now
            store.write_part(run, index, pa.Table.from_pydict(cols, schema=schema))
            done_now += 1
            dt = time.perf_counter() - t_start
            progress.update(bar, advance=1, rate=f"{done_now / dt:.1f} chunks/s" if dt > 0 else "")

        if jobs == 1 or len(missing) == 1:
            for i in missing:
                record(*_compute(study.NAME, cfg, chunk, i))
            return
        from joblib import Parallel, delayed, parallel_config

        with parallel_config(backend="loky", n_jobs=jobs, inner_max_num_threads=1):
            results = Parallel(return_as="generator_unordered")(
                delayed(_compute)(study.NAME, cfg, chunk, i) for i in missing)
            for index, cols in results:
                record(index, cols)

