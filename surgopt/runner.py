"""Runner: tasks -> joblib workers -> progress bar -> single writer (the parent).

Knows nothing of kinematics: a ``Study`` (``surgopt.studies``) supplies ``n_tasks``,
``warm_up``, ``compute_task`` and ``schema``; workers look the study up by name.
"""
from __future__ import annotations

import contextlib
import os
import time
from dataclasses import dataclass, field

from surgopt.config import study_key
from surgopt.errors import UsageError
from surgopt.jit import numba_cache_dir
from surgopt.store import Run, Store

DEFAULT_JOBS = 2


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
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        TextColumn,
        TimeElapsedColumn,
        TimeRemainingColumn,
    )

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


BACKENDS = ("threads", "loky", "dask")


def run_study(study, cfg, *, config_name: str, store: Store, jobs: int = DEFAULT_JOBS,
              force: bool = False, quiet: bool = False, chunk: int | None = None,
              backend: str = "threads", scheduler: str | None = None, say=print) -> RunResult:
    """Compute (or fetch from the store) the table of one study config.

    ``backend`` "threads" (a thread pool in this process; every kernel is
    compiled ``nogil``, so chunks run in parallel and nothing has to start or
    load kernels), "loky" (local worker processes) or "dask" (joblib's dask
    backend on a ``distributed`` cluster: ``scheduler`` address, or a
    LocalCluster of ``jobs`` single-threaded workers). Either way the same chunks run the same
    kernels and only this process writes to the store, part by part as chunks
    complete, so memory does not grow with the design grid.
    """
    if backend not in BACKENDS:
        raise UsageError(f"--backend: {backend!r} is not one of {', '.join(BACKENDS)}")
    if backend == "dask":
        _require_distributed()
    t0 = time.perf_counter()
    schema = study.schema()
    key = study_key(study.name, cfg, study.kernel_version)
    run = store.open(study.name, key)
    if run is not None and run.complete and not force and not store.bad_parts(run):
        table = run.read_table(schema)
        return RunResult(run, table, True, 0, time.perf_counter() - t0)

    with store.lock(study.name, key, on_wait=lambda who: say(f"waiting for {who} to finish this study ...")):
        chunk = chunk or study.auto_chunk(cfg)
        existing = None if force else store.open(study.name, key)
        if existing is not None:
            chunk = existing.manifest["chunk"]  # parts already cut this way
        run = store.begin(study.name, key, config=cfg.model_dump(mode="json"),
                          config_name=config_name, kernel_version=study.kernel_version,
                          n_tasks=study.n_tasks(cfg, chunk), chunk=chunk, force=force)
        total = run.manifest["n_tasks"]
        missing = [i for i in range(total) if i not in run.done_tasks()]
        messages = []
        if len(missing) < total:
            messages.append(f"resuming: {total - len(missing)} of {total} chunks already stored")
        if missing:
            study.warm_up(cfg)  # compile once in the parent; workers load the cache
            _dispatch(study, cfg, chunk, missing, run, store, jobs, quiet, total, schema, backend, scheduler)
        table = run.read_table(schema)
    return RunResult(run, table, False, len(missing), time.perf_counter() - t0, messages)


def _dispatch(study, cfg, chunk, missing, run, store, jobs, quiet, total, schema, backend="threads",
              scheduler=None):
    import pyarrow as pa

    progress = _progress(quiet)
    t_start = time.perf_counter()
    with progress:
        bar = progress.add_task(study.name, total=total, completed=total - len(missing), rate="")
        done_now = 0

        def record(index, cols):
            nonlocal done_now
            store.write_part(run, index, pa.Table.from_pydict(cols, schema=schema))
            done_now += 1
            dt = time.perf_counter() - t_start
            progress.update(bar, advance=1, rate=f"{done_now / dt:.1f} chunks/s" if dt > 0 else "")

        if backend in ("threads", "loky") and (jobs == 1 or len(missing) == 1):
            for i in missing:
                record(*_compute(study.name, cfg, chunk, i))
            return
        if backend == "threads":
            _dispatch_threads(study.name, cfg, chunk, missing, jobs, record)
            return
        from joblib import Parallel, delayed, parallel_config

        tasks = (delayed(_compute)(study.name, cfg, chunk, i) for i in missing)
        if backend == "loky":
            with parallel_config(backend="loky", n_jobs=jobs, inner_max_num_threads=1):
                for index, cols in Parallel(return_as="generator_unordered")(tasks):
                    record(index, cols)
            return
        with _dask_client(scheduler, jobs) as client:
            _prepare_dask_workers(client, study.name, cfg)
            with parallel_config(backend="dask"):
                for index, cols in Parallel(return_as="generator_unordered")(tasks):
                    record(index, cols)


def _dispatch_threads(study_name, cfg, chunk, missing, jobs, record):
    """Chunks on ``jobs`` threads of this process; rows recorded here, in the calling thread.

    On an interrupt (Ctrl-C) the chunks not started are cancelled and the running ones are waited
    for before the exception goes on: a thread still inside a compiled kernel when the interpreter
    shuts down would abort the process (SIGABRT) instead of letting it exit with code 130.
    """
    from concurrent.futures import ThreadPoolExecutor, as_completed

    pool = ThreadPoolExecutor(max_workers=jobs, thread_name_prefix="surgopt")
    futures = [pool.submit(_compute, study_name, cfg, chunk, i) for i in missing]
    try:
        for f in as_completed(futures):
            record(*f.result())
    finally:
        pool.shutdown(wait=True, cancel_futures=True)


DASK_HINT = "--backend dask needs the optional extra: pip install 'surgopt[dask]'"


def _require_distributed() -> None:
    try:
        import distributed  # noqa: F401
    except ImportError:
        raise UsageError(DASK_HINT) from None


@contextlib.contextmanager
def _dask_client(scheduler: str | None, jobs: int):
    """A distributed.Client on ``scheduler``, or on a LocalCluster of ``jobs`` one-thread workers."""
    from distributed import Client, LocalCluster

    if scheduler:
        client = Client(scheduler)
        try:
            yield client
        finally:
            client.close()
        return
    # worker processes inherit this environment: one numba thread each, our numba cache
    os.environ.setdefault("NUMBA_NUM_THREADS", "1")
    cluster = LocalCluster(n_workers=jobs, threads_per_worker=1, processes=True, dashboard_address=None)
    client = Client(cluster)
    try:
        yield client
    finally:
        client.close()
        cluster.close()


def _worker_setup(cache_dir: str, study_name: str, cfg) -> str:
    """On a dask worker: one numba thread (dask does not set NUMBA_NUM_THREADS), a numba cache, compiled kernels."""
    os.environ.setdefault("NUMBA_CACHE_DIR", cache_dir)
    import numba

    numba.set_num_threads(1)
    from surgopt.studies import get_study

    get_study(study_name).warm_up(cfg)
    return os.environ["NUMBA_CACHE_DIR"]


def _prepare_dask_workers(client, study_name: str, cfg) -> None:
    """Compile or load the kernels on one worker first, then on the rest, so that workers sharing a
    cache folder find it written instead of all compiling into it at once."""
    workers = sorted(client.scheduler_info()["workers"])
    cache = str(numba_cache_dir())
    if workers:
        client.run(_worker_setup, cache, study_name, cfg, workers=workers[:1])
    if len(workers) > 1:
        client.run(_worker_setup, cache, study_name, cfg, workers=workers[1:])

