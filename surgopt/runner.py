"""Runner: budget -> cache hit -> lock -> a plan's session -> tasks on a backend -> the parent writes each part.

Knows nothing of kinematics or of how a space is explored: a ``Study`` (``surgopt.studies``) says what is
evaluated, a plan (``surgopt.plans``) which tasks to run and which parts they make, a backend
(``surgopt.backends``) where they run. One path for every plan: the budget with every worker counted, the cache
hit, the lock, retries of dead workers, the compile notice, the swap of a --force rebuild. One module (~530
lines) because those steps share one run's state (its lock, its parts written, its retries) in order.
"""
from __future__ import annotations

import contextlib
import logging
import math
import os
import time
from dataclasses import dataclass, field

from surgopt.backends import get_backend
from surgopt.config import study_key
from surgopt.errors import ConfigError, SurgoptError, UsageError, out_of_memory
from surgopt.interrupts import raise_if_stopped
from surgopt.jit import numba_cache_dir
from surgopt.store import Run, Store

DEFAULT_JOBS = 2
log = logging.getLogger("surgopt.runner")


class WorkerLost(SurgoptError):
    """Worker processes kept dying (exit code 1)."""


class OutOfMemory(SurgoptError):
    """The run ran out of memory; the message says how many chunks are stored (exit code 1)."""


@dataclass
class RunResult:
    """A stored run: ``parts`` streams its rows (what reports use); ``table`` reads them all at once."""

    run: Run
    parts: object  # surgopt.parts.Parts
    cache_hit: bool
    computed_tasks: int
    elapsed_s: float
    messages: list[str] = field(default_factory=list)

    @property
    def table(self):
        """The whole run as one Arrow table (read, and verified, on each access)."""
        return self.parts.table()


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
        TextColumn("{task.fields[unit]}"),
        TextColumn("{task.fields[rate]}"),
        TimeElapsedColumn(),
        TimeRemainingColumn(),
        console=Console(stderr=True),
        disable=quiet,
        transient=False,
    )
    return progress


#: Work a run may imply without the user saying so (--max-hours), in hours of wall time on --jobs cores.
DEFAULT_MAX_HOURS = 1.0
#: Share of this machine's memory a run may need without the user saying so (--max-memory-gb).
DEFAULT_MEMORY_SHARE = 0.5


def physical_memory_bytes() -> int | None:
    try:
        return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (ValueError, OSError, AttributeError):
        return None


def duration_text(seconds: float) -> str:
    """"40 s", "12 min", "8 h 35 min", "149 days"."""
    if seconds < 10:
        return f"{seconds:.1f} s"
    if seconds < 120:
        return f"{seconds:.0f} s"
    if seconds < 7200:
        return f"{seconds / 60:.0f} min"
    if seconds < 2 * 86400:
        return f"{int(seconds // 3600)} h {int(seconds % 3600 // 60)} min"
    return f"{seconds / 86400:,.0f} days"


#: A warm run's own time besides its kernels' work: loading the kernels, the store, the closing report (measured
#: 0.9-1.5 s on runs of a fraction of a second's work; benchmarks/bench_readme_estimates.py).
RUN_OVERHEAD_S = 1.0
#: Writing a row to Parquet (zstd) and reading it back for the closing report (measured ~1.5 us a row over
#: port-place's 2.2 M rows and raven-sweep's 250,000).
STORE_SECONDS_PER_ROW = 1.5e-6


def wall_seconds(est, jobs: int, overhead: bool = True) -> float:
    """An estimate's wall time: its single-core seconds spread over ``jobs`` workers (at most this machine's
    cores), plus its rows' storing and reading back and (``overhead``: the first run of a command, which loads the
    kernels) the run's fixed overhead (warm: no compile)."""
    return (est.seconds_one_core / max(1, min(jobs, os.cpu_count() or 1)) + (RUN_OVERHEAD_S if overhead else 0.0)
            + (est.rows if est.stored_rows is None else est.stored_rows) * STORE_SECONDS_PER_ROW)


def local_workers(backend: str, jobs: int, scheduler: str | None = None) -> int:
    """How many worker processes the backend starts on this machine (a --scheduler's cluster is elsewhere)."""
    return get_backend(backend).local_workers(jobs, scheduler)


def run_bytes(est, backend: str = "threads", jobs: int = 1, scheduler: str | None = None) -> int:
    """The whole process tree's peak memory: the parent's estimate plus every worker process it starts."""
    b = get_backend(backend)
    n = b.local_workers(jobs, scheduler)
    return est.peak_bytes + n * b.worker_bytes + (b.helper_bytes if n else 0)


def usable_jobs(jobs: int, backend: str, scheduler: str | None = None, say=print) -> int:
    """``jobs`` capped at this machine's cores for the local backends (more workers than cores only cost
    memory and start-up), with one line saying so; a --scheduler's cluster takes what it is given."""
    cores = os.cpu_count() or 1
    if jobs > cores and not (get_backend(backend).takes_scheduler and scheduler):
        say(f"--jobs {jobs}: this machine has {cores} core(s); running {cores} worker(s)")
        return cores
    return jobs


#: Virtual memory a study process reserves beyond what it keeps resident (LLVM, thread stacks, OpenBLAS's and
#: numba's threads, allocator arenas): under ``ulimit -v`` a run needs its resident peak plus this. Measured:
#: rcm-grid (275 MB resident) fails below 900 MB, port-place (450 MB) below 1,200 MB, each in a different way
#: (a thread not started, OpenBLAS raising SIGINT, LLVM spinning): so the run is refused before it starts.
ADDRESS_SPACE_OVERHEAD_BYTES = 700 * 2 ** 20


def address_space_limit_bytes() -> int | None:
    """This process's address-space limit (RLIMIT_AS, ``ulimit -v``), or None when unlimited."""
    try:
        import resource

        soft, _ = resource.getrlimit(resource.RLIMIT_AS)
    except (ImportError, OSError, ValueError):
        return None
    return None if soft == resource.RLIM_INFINITY or soft <= 0 else soft


def check_budget(study, cfg, jobs: int, max_hours: float | None, max_memory_bytes: int | None, est=None,
                 backend: str = "threads", scheduler: str | None = None, plan=None) -> None:
    """Refuse, before anything runs or is written, a config whose estimated work or memory is past the
    budget; the message gives the estimate and the flag that lifts the limit. ``est``: the study's
    estimate of ``cfg`` when already computed. Memory counts every worker process the backend starts."""
    from surgopt.plans import estimate

    est = est or estimate(study, cfg, plan)
    if est is None:
        return
    wall = wall_seconds(est, jobs)
    if max_hours is not None and wall > max_hours * 3600:
        raise UsageError(f"this config is {est.items:,} {est.what}, about {duration_text(wall)} on {jobs} core(s) "
                         f"(estimate), past the {max_hours:g} h budget; pass --max-hours "
                         f"{math.ceil(wall / 3600 * 1.2)} to run it anyway, or {est.smaller}")
    if max_memory_bytes is None:
        ram = physical_memory_bytes()
        max_memory_bytes = int(ram * DEFAULT_MEMORY_SHARE) if ram else None
    need = run_bytes(est, backend, jobs, scheduler)
    limit = address_space_limit_bytes()
    if limit is not None and est.peak_bytes + ADDRESS_SPACE_OVERHEAD_BYTES > limit:
        raise OutOfMemory(f"this run would run out of memory: the address-space limit (ulimit -v) is "
                          f"{limit / 2 ** 20:,.0f} MB, below the "
                          f"{(est.peak_bytes + ADDRESS_SPACE_OVERHEAD_BYTES) / 2 ** 20:,.0f} MB of virtual memory this "
                          f"run needs (its estimated {est.peak_bytes / 2 ** 20:,.0f} MB resident and "
                          f"{ADDRESS_SPACE_OVERHEAD_BYTES / 2 ** 20:,.0f} MB that numba's compiler and the numerical "
                          f"libraries' threads reserve); nothing was run: raise the limit, or {est.smaller}")
    if max_memory_bytes is not None and need > max_memory_bytes:
        workers = local_workers(backend, jobs, scheduler)
        with_workers = f" with {workers} {backend} worker process(es)" if workers else ""
        raise UsageError(f"this config is {est.items:,} {est.what} ({est.rows:,} rows), about "
                         f"{need / 2 ** 30:,.1f} GiB of memory{with_workers} (estimate), past the "
                         f"{max_memory_bytes / 2 ** 30:,.1f} GiB budget; pass --max-memory-gb "
                         f"{math.ceil(need / 2 ** 30 * 1.2)} to run it anyway, or {est.smaller}")


@dataclass(frozen=True)
class RunOptions:
    """How one run is carried out, none of it in the store key: ``jobs`` workers on ``backend`` ("threads": a
    thread pool in this process, every kernel compiled ``nogil``, so tasks run in parallel and nothing has to start
    or load kernels; "loky": local worker processes; "dask": joblib's dask backend on a ``distributed`` cluster at
    ``scheduler``, or a LocalCluster of ``jobs`` single-threaded workers), ``chunk`` items a task (None: the
    plan's), ``force`` (recompute a stored run), ``quiet`` (no progress bar), the budget ``check_budget`` holds
    the estimate to (``max_hours``; ``max_memory_bytes``, None: half this machine's memory), and the ``name`` and
    ``tags`` recorded in the manifest (a cache hit given another name or new tags records them)."""

    jobs: int = DEFAULT_JOBS
    backend: str = "threads"
    scheduler: str | None = None
    chunk: int | None = None
    force: bool = False
    quiet: bool = False
    max_hours: float | None = DEFAULT_MAX_HOURS
    max_memory_bytes: int | None = None
    name: str | None = None
    tags: dict | None = None


def run_study(study, cfg, *, config_name: str, store: Store, options: RunOptions | None = None, plan=None,
              say=print, **fields) -> RunResult:
    """Compute (or fetch from the store) the table of one study config explored by one plan.

    ``options``: how (``RunOptions``; ``fields`` replace some of its values: ``run_study(..., jobs=1)``).
    ``plan``: how the design space is explored (``surgopt.plans``); None: the plan the config names (its
    [search] method, else the study's grid). Every plan runs the same way: its session gives tasks, the backend
    computes them, the session turns their rows into parts, and only this process writes them to the store.
    """
    from dataclasses import replace

    from surgopt.plans import plan_for

    o = replace(options or RunOptions(), **fields)
    jobs, force, quiet, chunk, backend, scheduler = o.jobs, o.force, o.quiet, o.chunk, o.backend, o.scheduler
    max_hours, max_memory_bytes, name, tags = o.max_hours, o.max_memory_bytes, o.name, o.tags

    where = get_backend(backend)
    if scheduler is not None and not where.takes_scheduler:
        raise UsageError(f"--scheduler goes with --backend dask (the {backend} backend runs on this machine)")
    where.require()
    jobs = usable_jobs(jobs, backend, scheduler, say)
    t0 = time.perf_counter()
    schema = study.schema_for(cfg)
    plan = plan if plan is not None else plan_for(study, cfg)
    key = plan.key(study, cfg, study_key(study.name, cfg, study.kernel_version))
    if not force:
        run = _stored_run(store, study, key, say, cfg, plan)
        if run is not None:  # nothing to compute: no budget to hold it to
            log.info("cache hit: %s %s in %s", study.name, key[:12], run.path)
            label = {**({"name": name} if name is not None else {}),
                     **({"tags": {**run.manifest.get("tags", {}), **tags}} if tags else {})}
            if any(run.manifest.get(k) != v for k, v in label.items()):
                with store.lock(study.name, key):
                    run = store.finish(run, **label)
            return RunResult(run, run.parts(schema), True, 0, time.perf_counter() - t0)
    check_budget(study, cfg, jobs, max_hours, max_memory_bytes, backend=backend, scheduler=scheduler, plan=plan)
    if study.preflight is not None:  # a config the kernels refuse: before the store is touched
        _warm_up(study, cfg, say)
        try:
            study.preflight(cfg)
        except ValueError as exc:
            raise ConfigError(config_name, str(exc)) from None

    lock = store.lock(study.name, key, on_wait=lambda who: say(f"waiting for {who} to finish this study ..."))
    with where.open(jobs, scheduler) as handle, lock:  # connect to a cluster before anything is written
        chunk = chunk or plan.chunk(study, cfg)
        existing = None if force else _open_or_discard(store, study.name, key, say)
        if existing is not None and _task_count_problem(study, cfg, plan, existing):
            existing = None  # its parts cannot be trusted to be the tasks they claim: the run starts anew
        if existing is not None:
            chunk = existing.manifest["chunk"]  # parts already cut this way
        run = store.begin(study.name, key, config=cfg.model_dump(mode="json"),
                          config_name=config_name, kernel_version=study.kernel_version,
                          n_tasks=plan.n_parts(study, cfg, chunk), chunk=chunk, force=force,
                          fresh=existing is None, meta={**provenance(backend, jobs), "plan": plan.record(),
                                                        **({"name": name} if name else {}),
                                                        **({"tags": tags} if tags else {})})
        log.info("%s %s: %s plan, %d parts of %d, %d stored", study.name, key[:12], plan.name,
                 run.manifest["n_tasks"], chunk, len(run.manifest["parts"]))
        stored = len(run.manifest["parts"])
        session = plan.session(study, cfg, chunk, run, workers=jobs)
        messages = []
        if stored and session.remaining:
            messages.append(f"resuming: {session.done:,} of {session.total:,} {session.unit} already stored")
        try:
            computed = _execute(study, cfg, chunk, session, run, store, jobs, quiet, schema, where, handle, say)
        except (MemoryError, ImportError, RuntimeError, OSError) as exc:
            if not out_of_memory(exc):
                raise
            stored, total = len(run.done_tasks()), run.manifest["n_tasks"]
            if stored == total:
                raise OutOfMemory(f"out of memory after all {total} parts were stored: the run is complete "
                                  f"(`surgopt summarize {key[:12]}` reports it, with more memory)") from None
            raise OutOfMemory(f"out of memory with {stored} of {total} parts stored; run the same command "
                              f"again to resume (with more memory, a smaller config or --jobs 1)") from None
        run = store.finish(run, wall_time_s=round(time.perf_counter() - t0, 3), last_backend=backend,
                           last_jobs=jobs, **session.final_meta())
    return RunResult(run, run.parts(schema), False, computed, time.perf_counter() - t0, messages)


def _execute(study, cfg, chunk, session, run, store, jobs, quiet, schema, where, handle, say) -> int:
    """The one path of every plan: ask the session for tasks, compute them on the backend (``where``, opened as
    ``handle``), hand each task's rows back and store the parts it gives, until it has no more; the tasks of
    worker processes that died are retried. Returns how many tasks were computed."""
    import pyarrow as pa

    if not session.remaining:
        return 0
    _warm_up(study, cfg, say)  # compile once in the parent; workers load the cache
    where.prepare(handle, study.name, cfg)
    progress = _progress(quiet)
    t_start = time.perf_counter()
    done_before = session.done
    computed = 0
    with progress:
        bar = progress.add_task(study.name, total=session.total, completed=session.done, rate="",
                                unit=session.unit)

        deferred: list = []  # the parts a batch's last task gave: stored while the next batch computes

        def write(parts):
            for index, part in parts:
                store.write_part(run, index, pa.Table.from_pydict(part, schema=schema))
                log.debug("stored part %d (%d rows)", index, len(next(iter(part.values()))))

        def flush():
            parts, deferred[:] = list(deferred), []
            write(parts)

        def record(task, cols, last=False):
            nonlocal computed
            raise_if_stopped()  # a stop signal whose exception a callback swallowed still stops the run
            computed += 1
            parts = session.on_result(task, cols)
            if last:  # a sequential plan's next batch waits on this one's result, not on its storing
                deferred.extend(parts)
            else:
                write(parts)
            dt = time.perf_counter() - t_start
            rate = (session.done - done_before) / dt if dt > 0 else 0
            progress.update(bar, completed=session.done, rate=f"{rate:,.1f} {session.unit}/s" if dt > 0 else "")

        try:
            while True:
                tasks = session.next_tasks()
                if not tasks:
                    flush()
                    return computed
                _with_retries(study, cfg, chunk, tasks, jobs, where, handle, record, say, flush)
        except BaseException:
            with contextlib.suppress(Exception):  # what finished is stored (a failed write: computed again)
                flush()
            with contextlib.suppress(Exception):  # and listed: a resume keeps it
                store.sync_manifest(run)
            raise


def _with_retries(study, cfg, chunk, tasks, jobs, where, handle, record, say, idle=None) -> None:
    """Compute ``tasks`` on the backend, recording each as it finishes (the last with ``last=True``); ``idle()``
    runs once while they compute. The tasks not recorded when a worker process died are computed again on a
    fresh pool (WORKER_RETRIES times)."""
    pending = {(t.index, t.sub): t for t in tasks}

    def record_once(task, cols):
        pending.pop((task.index, task.sub), None)
        record(task, cols, last=not pending)

    for attempt in range(WORKER_RETRIES + 1):
        try:
            where.map(handle, study.name, cfg, chunk, list(pending.values()), jobs, record_once, idle)
            idle = None  # once: what it stores is stored
            return
        except Exception as exc:
            if not _worker_died(exc):
                raise
            if attempt == WORKER_RETRIES:
                raise WorkerLost(f"a worker process died {WORKER_RETRIES + 1} times ({exc.__class__.__name__}); "
                                 f"what finished is stored, run the same command again to resume") from None
            say(f"a worker process died ({exc.__class__.__name__}); retrying its {len(pending)} unfinished task(s)")


def provenance(backend: str, jobs: int) -> dict:
    """What made a run, for its manifest: versions, backend, jobs, host."""
    import platform
    import socket
    from importlib.metadata import version

    from surgopt._version import __version__
    from surgopt.code_identity import code_sha256, git_commit

    # numba's version from its metadata: importing numba here, before a kernel configured it, would fix its
    # cache folder to the package's own __pycache__ (surgopt.jit)
    return {"versions": {"surgopt": __version__, "numba": version("numba"), "numpy": version("numpy"),
                         "python": platform.python_version()},
            "code_sha256": code_sha256(), "git_commit": git_commit(),
            "backend": backend, "jobs": jobs, "host": socket.gethostname()}


#: How many times the chunks of a worker process that died (killed, out of memory) are retried.
WORKER_RETRIES = 2


def _worker_died(exc: BaseException) -> bool:
    """A worker process that ended under joblib/loky (TerminatedWorkerError, BrokenProcessPool)."""
    names = {c.__name__ for c in type(exc).__mro__}
    return bool(names & {"TerminatedWorkerError", "BrokenProcessPool", "BrokenExecutor"})


def _task_count_problem(study, cfg, plan, run) -> str | None:
    """What is wrong with a stored run's task count, for a plan whose part count follows from the config and the
    chunk size (a grid): an edited ``n_tasks`` would serve a partial run as complete."""
    if not getattr(plan, "parts_known_up_front", False):
        return None
    expected = plan.n_parts(study, cfg, run.manifest["chunk"])
    if run.manifest.get("n_tasks") != expected:
        return (f"its manifest lists {run.manifest.get('n_tasks')} tasks where the config and its chunk size "
                f"({run.manifest['chunk']}) give {expected}")
    return None


def _stored_run(store: Store, study, key: str, say, cfg=None, plan=None):
    """The run if the store holds it complete, its task count is the config's and every part checks out (size,
    sha256, row count), else None."""
    from surgopt.errors import StoreError
    from surgopt.store import UnknownFormat

    try:
        run = store.open(study.name, key)
    except UnknownFormat:
        raise  # never rebuilt over: a later surgopt's run
    except StoreError:
        return None  # an unusable manifest: the locked path says so and starts anew
    if run is None:
        return None
    wrong = None if plan is None else _task_count_problem(study, cfg, plan, run)
    if wrong:
        say(f"{study.name} run {key[:12]} is damaged: {wrong}; computing it anew")
        return None
    if not run.complete:
        return None
    damaged = run.damaged()
    if damaged:
        say(f"{study.name} run {key[:12]} is damaged: {damaged[0][0]} {damaged[0][1]}"
            + (f" (and {len(damaged) - 1} more)" if len(damaged) > 1 else "") + "; recomputing what is damaged")
        return None
    return run


def _open_or_discard(store: Store, study_name: str, key: str, say):
    """The stored run, or None (and a message) when its manifest is unusable: it is then rebuilt."""
    from surgopt.errors import StoreError
    from surgopt.store import UnknownFormat

    try:
        return store.open(study_name, key)
    except UnknownFormat:
        raise
    except StoreError as exc:
        say(f"{exc}".split(";")[0] + "; starting this run anew")
        return None


#: How long loading the kernels may take before the user is told what is happening (s).
COMPILE_NOTICE_S = 2.0


def warm_up(study, cfg, say=None) -> tuple[float, bool]:
    """Compile or load ``cfg``'s kernels now (``surgopt warm``): see ``_warm_up``."""
    return _warm_up(study, cfg, say)


def _warm_up(study, cfg, say=None) -> tuple[float, bool]:
    """``study.warm_up``, numba's compiles in it under the numba cache's compile lock (``surgopt.jit.while_compiling``:
    held only while numba compiles, not while the study builds its tables): the seconds it took and whether numba
    compiled anything (else it loaded every kernel from the cache).

    With ``say``: a word when the lock is held by another process (naming it, and how long it was waited for),
    and, when the kernels take over COMPILE_NOTICE_S, whether they are being compiled (a first run after an
    install or an update: numba's compile events say so) or loaded from the cache, with the time it took; a
    compile that starts after the word said "loading" is said too (issue 56 item 6)."""
    import os
    import threading

    from surgopt.jit import configure_numba, while_compiling

    configure_numba()  # before numba is imported here
    compiling = threading.Event()
    told = []

    def on_wait(holder):
        if say is not None:
            say(f"waiting for {holder}, compiling kernels into {numba_cache_dir()} ...")

    def compile_notice():
        builds = f" and building {study.warm_up_builds}" if study.warm_up_builds else ""
        return (f"compiling the {study.name} kernels (the first run after an install or an update; later runs load "
                f"them from {numba_cache_dir()}){builds} ...")

    def on_compile():
        if not compiling.is_set() and told and not told[0] and say is not None:
            say(compile_notice())  # the word said "loading": a kernel turned out not to be in the cache
            told[0] = True
        compiling.set()

    t0 = time.perf_counter()

    def notice():
        told.append(compiling.is_set())
        builds = f" and building {study.warm_up_builds}" if study.warm_up_builds else ""
        say(compile_notice() if told[0] else f"loading the {study.name} kernels from {numba_cache_dir()}{builds} ...")

    timer = None
    if say is not None:
        timer = threading.Timer(COMPILE_NOTICE_S, notice)
        timer.daemon = True
        timer.start()
    try:
        with while_compiling(on_wait=on_wait, holder=f"pid {os.getpid()} (surgopt {study.name})",
                             on_compile=on_compile):
            study.warm_up(cfg)
    finally:
        if timer is not None:
            timer.cancel()
    took = time.perf_counter() - t0
    if told and say is not None:
        say(f"kernels {'compiled' if compiling.is_set() else 'loaded'}"
            f"{', tables built' if study.warm_up_builds else ''} in {took:.0f} s")
    return took, compiling.is_set()
