"""Backends: where tasks run, in one registry (``BACKENDS``). Each backend opens once per run (a thread pool, loky's
worker processes, a dask client), prepares its workers (compiled kernels), and maps tasks to rows, handing each
task's rows to ``record`` in the calling thread, which alone writes to the store. A new backend is a ``Backend``
with those three functions and one line in ``BACKENDS``; the runner and the plans do not change.

- threads: a thread pool in this process; every kernel is compiled ``nogil``, so tasks run in parallel and
  nothing has to start or load kernels;
- loky: local worker processes (joblib's loky) that die with this process;
- dask: joblib's dask backend on a ``distributed`` cluster (``--scheduler``) or a LocalCluster of single-threaded
  workers.
"""
from __future__ import annotations

import contextlib
import logging
import os
import signal
import warnings
from collections.abc import Callable
from dataclasses import dataclass

from surgopt.errors import UsageError
from surgopt.jit import numba_cache_dir


def compute(study_name: str, cfg, chunk: int, task):
    """Worker entry point: one task (``surgopt.plans.Task``) and its rows as a dict of numpy columns."""
    from surgopt.plans import run_task
    from surgopt.studies import get_study

    return task, run_task(get_study(study_name), cfg, chunk, task)




@contextlib.contextmanager
def _thread_pool(jobs: int):
    """The threads backend's pool, one for the whole run (a search dispatches a batch at a time).

    On a stop (Ctrl-C, SIGTERM) the tasks not started are cancelled and the running ones are not waited for:
    a chunk inside a compiled kernel cannot be interrupted and may take minutes. The CLI then ends the process
    without an interpreter shutdown (``interrupts.exit_now``), which would join those threads (or abort under
    one); in a Python session they finish in the background and their rows are dropped. On any other error
    the running chunks are waited for.
    """
    from concurrent.futures import ThreadPoolExecutor

    from surgopt.interrupts import deferred

    pool = ThreadPoolExecutor(max_workers=jobs, thread_name_prefix="surgopt")
    stopping = False
    try:
        yield pool
    except KeyboardInterrupt:
        stopping = True
        raise
    finally:
        with deferred(raising=False):  # a second signal here must not leave the pool's locks held either
            pool.shutdown(wait=not stopping, cancel_futures=True)


#: Chunks submitted ahead per worker: enough to keep workers busy, few enough that finished rows
#: waiting to be written never pile up in memory.
IN_FLIGHT_PER_WORKER = 2


#: The longest a stop waits to be raised while the threads compute (s).
WAIT_S = 0.25


def _run_bounded(pool, study_name, cfg, chunk, missing, jobs, record, idle=None):
    """Submit chunks a few at a time and record each as it finishes, dropping it right after: memory
    holds about ``jobs * IN_FLIGHT_PER_WORKER`` chunks' rows, whatever the number of chunks. ``idle()`` runs
    once the first chunks are submitted, while the workers compute them (the runner stores the last batch's
    parts then)."""
    from concurrent.futures import FIRST_COMPLETED, wait

    from surgopt.interrupts import deferred

    todo = iter(missing)
    running = set()

    def submit_more():
        with deferred():  # the pool's locks are never left held by a stop
            for i in todo:
                running.add(pool.submit(compute, study_name, cfg, chunk, i))
                if len(running) >= jobs * IN_FLIGHT_PER_WORKER:
                    break

    submit_more()
    if idle is not None:
        idle()
    while running:
        with deferred():  # nor the futures' (a stop is raised within WAIT_S, outside them)
            done, running = wait(running, timeout=WAIT_S, return_when=FIRST_COMPLETED)
        for f in done:
            record(*f.result())
        submit_more()
        del done


def _die_with_parent(parent_pid: int) -> None:
    """loky worker initializer: end this worker when the parent dies, even by kill -9 (Linux
    PR_SET_PDEATHSIG; elsewhere loky's own idle timeout ends it); a Ctrl-C sent to the process group is the
    parent's to handle (``_ignore_stop_signals``)."""
    _ignore_stop_signals()
    try:
        import ctypes

        ctypes.CDLL("libc.so.6", use_errno=True).prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG
    except (OSError, AttributeError):
        return
    if os.getppid() != parent_pid:  # the parent died before the call above took effect
        os._exit(1)


#: Environment of loky workers: one thread per numerical library (the workers are the parallelism).
WORKER_ENV = {v: "1" for v in ("NUMBA_NUM_THREADS", "OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")}


#: The warning the resource trackers of loky and multiprocessing print when worker processes were killed (an
#: interrupted run kills them on purpose): passed to the trackers, which inherit this process's -W options.
QUIET_TRACKER = "ignore:resource_tracker:UserWarning"


def _quiet_resource_trackers() -> None:
    """A run stopped on purpose ends in one line: the helpers that clean up after killed workers say nothing."""
    import sys

    if QUIET_TRACKER not in sys.warnoptions:
        sys.warnoptions.append(QUIET_TRACKER)


#: The name of loky's thread that feeds its workers (``loky.process_executor._ExecutorManagerThread``).
LOKY_MANAGER_THREAD = "ExecutorManagerThread"


def _quiet_loky_manager() -> None:
    """A stopped run ends in one line: when the executor is shut down under a stop, loky's manager thread can trip
    on the work items the shutdown took from under it (a KeyError in ``add_call_item_to_queue``, seen once in
    ~50 CI runs after a Ctrl-C) and print its traceback. That thread's exceptions are not shown from then on (the
    run's own outcome reaches the runner through its futures); every other thread's are, as before."""
    import threading

    previous = threading.excepthook
    if getattr(previous, "quiet_loky", False):
        return

    def hook(args):
        if args.thread is not None and args.thread.name == LOKY_MANAGER_THREAD:
            return
        previous(args)

    hook.quiet_loky = True
    threading.excepthook = hook


def _map_loky(handle, study_name, cfg, chunk, missing, jobs, record, idle=None):
    """Tasks on ``jobs`` loky worker processes that die with this process; rows recorded here.

    The executor is loky's reusable one, taken on each call: a worker that dies (killed, out of memory) breaks
    it, the exception reaches the runner, which retries the tasks not yet recorded on a fresh one. On Ctrl-C
    the workers are killed.
    """
    from joblib.externals.loky import get_reusable_executor

    if jobs == 1 or len(missing) == 1:
        _serial(study_name, cfg, chunk, missing, record, idle)
        return
    _quiet_resource_trackers()
    pool = get_reusable_executor(max_workers=jobs, timeout=30, initializer=_die_with_parent,
                                 initargs=(os.getpid(),), env=WORKER_ENV)
    try:
        _run_bounded(pool, study_name, cfg, chunk, missing, jobs, record, idle)
    except BaseException:
        _quiet_loky_manager()
        pool.shutdown(wait=False, kill_workers=True)
        raise


DASK_HINT = "--backend dask needs the optional extra: pip install 'surgopt[dask]'"


def _require_distributed() -> None:
    try:
        import distributed  # noqa: F401
    except ImportError:
        raise UsageError(DASK_HINT) from None


#: How long --scheduler may take to answer before the run is refused (s).
SCHEDULER_TIMEOUT_S = 10


@contextlib.contextmanager
def _dask_client(scheduler: str | None, jobs: int):
    """A distributed.Client on ``scheduler``, or on a LocalCluster of ``jobs`` one-thread workers."""
    from distributed import Client, LocalCluster

    _quiet_resource_trackers()
    if scheduler:
        try:
            client = Client(scheduler, timeout=SCHEDULER_TIMEOUT_S)
        except (OSError, TimeoutError, ValueError, TypeError) as exc:
            msg = " ".join(str(exc).split())[:200] or exc.__class__.__name__
            raise UsageError(f"--scheduler {scheduler}: cannot connect ({msg}); nothing was written") from None
        try:
            yield client
        finally:
            client.close()
        return
    # worker processes inherit this environment: one numba thread each, our numba cache, and distributed's
    # own log at critical only: its info and warnings about nannies and cancelled tasks are not the user's, and
    # its errors are a worker losing this process's scheduler when a stop ends it (Ctrl-C while the cluster
    # starts: 24 lines of heartbeat tracebacks, issue 55 item 7); a task's own error reaches this process
    os.environ.setdefault("NUMBA_NUM_THREADS", "1")
    os.environ.setdefault("DASK_LOGGING__DISTRIBUTED", "critical")
    logging.getLogger("distributed").setLevel(logging.ERROR)
    with warnings.catch_warnings():  # its scheduler's HTTP server takes another port when 8787 is busy (another
        # cluster): distributed warns of it on stderr, which is not the user's business (no dashboard is asked for)
        warnings.filterwarnings("ignore", message=r"Port \d+ is already in use", category=UserWarning)
        cluster = LocalCluster(n_workers=jobs, threads_per_worker=1, processes=True, dashboard_address=None)
    client = Client(cluster)
    _quiet_on_stop_signals(client)
    try:
        yield client
    finally:
        client.close()
        cluster.close()


def _ignore_stop_signals() -> None:
    """In a worker process (or its nanny): a Ctrl-C at the terminal reaches the whole process group; the workers
    leave the stop to surgopt's process, which stores what finished and ends them (they printed 60-odd lines of
    KeyboardInterrupt tracebacks, issue 43)."""
    for sig in (signal.SIGINT, signal.SIGHUP):
        signal.signal(sig, signal.SIG_IGN)


def _quiet_on_stop_signals(client) -> None:
    """A LocalCluster's workers and nannies ignore the stop signals a terminal sends the process group."""
    with contextlib.suppress(Exception):  # a worker that cannot be reached is ended with the cluster anyway
        client.run(_ignore_stop_signals)
        client.run(_ignore_stop_signals, nanny=True)


def _worker_setup(cache_dir: str, study_name: str, cfg) -> str:
    """On a dask worker: one numba thread (dask does not set NUMBA_NUM_THREADS), a numba cache, compiled kernels."""
    os.environ.setdefault("NUMBA_CACHE_DIR", cache_dir)
    from surgopt.jit import configure_numba

    configure_numba()
    import numba

    numba.set_num_threads(1)
    from surgopt.jit import while_compiling
    from surgopt.studies import get_study

    with while_compiling(holder=f"pid {os.getpid()} (a dask worker of surgopt {study_name})"):
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


def _serial(study_name, cfg, chunk, tasks, record, idle=None) -> None:
    """One task, or one worker: computed in this thread (no hand-off; ``idle()`` first)."""
    if idle is not None:
        idle()
    for t in tasks:
        record(*compute(study_name, cfg, chunk, t))


def _map_threads(pool, study_name, cfg, chunk, tasks, jobs, record, idle=None) -> None:
    if jobs == 1 or len(tasks) == 1:
        _serial(study_name, cfg, chunk, tasks, record, idle)
        return
    _run_bounded(pool, study_name, cfg, chunk, tasks, jobs, record, idle)


def _map_dask(client, study_name, cfg, chunk, tasks, jobs, record, idle=None) -> None:
    from joblib import Parallel, delayed, parallel_config

    if idle is not None:
        idle()
    with parallel_config(backend="dask"):
        for task, cols in Parallel(return_as="generator_unordered")(
                delayed(compute)(study_name, cfg, chunk, t) for t in tasks):
            record(task, cols)


def _no_preparation(handle, study_name: str, cfg) -> None:
    """Threads share this process's compiled kernels; loky workers load them from the cache."""


@dataclass(frozen=True)
class Backend:
    """One place to run tasks: ``open(jobs, scheduler)`` a context manager yielding its handle (pool, client),
    ``prepare(handle, study_name, cfg)`` compiles or loads the kernels where they run, ``map(handle, study_name,
    cfg, chunk, tasks, jobs, record, idle)`` runs the tasks, calling ``idle()`` once while they compute (or before). ``worker_bytes`` / ``helper_bytes``: memory of each
    worker process it starts on this machine and of its helper processes (the budget counts them)."""

    name: str
    open: Callable
    prepare: Callable
    map: Callable
    in_process: bool = False
    takes_scheduler: bool = False
    worker_bytes: int = 0
    helper_bytes: int = 0
    require: Callable[[], None] = lambda: None

    def local_workers(self, jobs: int, scheduler: str | None = None) -> int:
        """How many worker processes it starts on this machine (a --scheduler's cluster is elsewhere)."""
        return 0 if self.in_process or (self.takes_scheduler and scheduler) else jobs


#: Memory of one worker process once it has loaded a study's kernels (proportional set size, measured on
#: rcm-grid: loky ~100 MB, a dask worker more with distributed loaded), and of the helper processes a process
#: backend starts (resource tracker, loky's or dask's manager).
BACKENDS = {
    "threads": Backend("threads", lambda jobs, scheduler: _thread_pool(jobs), _no_preparation, _map_threads,
                       in_process=True),
    "loky": Backend("loky", lambda jobs, scheduler: contextlib.nullcontext(), _no_preparation, _map_loky,
                    worker_bytes=120 * 2 ** 20, helper_bytes=40 * 2 ** 20),
    "dask": Backend("dask", lambda jobs, scheduler: _dask_client(scheduler, jobs), _prepare_dask_workers, _map_dask,
                    takes_scheduler=True, worker_bytes=200 * 2 ** 20, helper_bytes=60 * 2 ** 20,
                    require=lambda: _require_distributed()),
}


def get_backend(name: str) -> Backend:
    if name not in BACKENDS:
        raise UsageError(f"--backend: {name!r} is not one of {', '.join(BACKENDS)}")
    return BACKENDS[name]
