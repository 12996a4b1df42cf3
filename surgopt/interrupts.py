"""Signals: SIGINT, SIGTERM and SIGHUP stop a command the same way, at any instant, with one line and the
conventional exit code (130, 143, 129); whatever was stored stays stored and the next command resumes.

The handlers raise ``Stopped`` (a ``KeyboardInterrupt``) in the main thread and remember the signal: a
handler's exception can be swallowed when the signal lands inside a callback that ignores exceptions (a
garbage-collection callback of dask's ``distributed``, a ``__del__``) or printed by C code that catches it
(``PyErr_Print``: both hooks stay quiet about a stop), so the runner asks
``raise_if_stopped()`` between chunks and the CLI once more at the end. Nothing here runs on import.

A Python handler runs only when the main thread is between two bytecodes; a thread that is inside a compiled
kernel (a chunk that takes minutes) cannot be interrupted at all. So a stop never waits for one: the orderly
path stores what finished, prints its line and ends the process at once (``exit_now``: no join of the worker
threads), and a watchdog thread, woken by the C-level signal handler through ``signal.set_wakeup_fd`` even
while the main thread is inside a compile or a kernel, ends it ``STOP_GRACE_S`` after the signal if the
orderly path has not (one line, the child processes killed). Every part a store holds is written by an
atomic rename, so an end at any instant loses only the chunks that were computing.
"""
from __future__ import annotations

import os
import signal
import sys
import threading
from contextlib import contextmanager

#: The signals that stop a command, and the exit code each ends with (128 + the signal's number).
STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)

_received: list[int] = []
_reported: list[bool] = []


class Stopped(KeyboardInterrupt):
    """A stop signal was received (``signum``)."""

    def __init__(self, signum: int):
        super().__init__(signum)
        self.signum = signum


#: How long the orderly stop (store what finished, one line) may take after the signal before the watchdog ends
#: the process anyway (s). A job scheduler sends SIGKILL after a grace period of its own (SLURM: 30 s).
STOP_GRACE_S = 3.0

#: What a stopped command's line says a resume will find.
RESUME = "finished chunks are stored, run the same command again to resume"
#: ... said instead by a command that stores nothing (report, export, summarize, plot, diff, runs, a dry run, a
#: study command before its run begins; issue 55 item 7: it has no chunks to resume).
UNCHANGED = "this command stores nothing: the store's runs are as they were; run it again"
#: ... said instead once a study command's run is stored complete (issue 56 item 10: nothing to resume).
COMPLETE = "the run is stored complete; the same command again prints its report from the store"
#: What the command in hand says now (``on_stop``): its line changes as it goes from reading to storing to done
#: (before a command's guard: nothing stored).
_on_stop = [UNCHANGED]
_report_lock = threading.Lock()


#: How deep the main thread is in ``deferred()`` regions (where a stop is recorded, not raised).
_deferring = [0]


def _on_signal(signum, _frame):
    _received.append(signum)
    try:
        _quiet()
    except Exception:  # noqa: BLE001 - the stop itself must be what is raised, whatever the handler lands in
        pass
    if _deferring[0]:
        return  # raised where the region ends (``deferred``)
    if _inside_numba(_frame):
        return  # recorded: the watchdog ends the process once the stop's grace has passed (``_inside_numba``)
    raise Stopped(signum)


def _inside_numba(frame) -> bool:
    """Whether the signal landed inside numba (or llvmlite): a frame of theirs on the interrupted stack, or this
    thread holding numba's global compiler lock (compiling, or loading a kernel from the on-disk cache). An
    exception raised there leaves a dispatcher or LLVM's state half-built, and the process then dies of a
    segmentation fault with no word when it is torn down (a Ctrl-C 0.7-1.2 s into ``surgopt report`` of a
    port-place run, while a kernel module was imported: 8 of 8 times). Such a stop is recorded, not raised; the
    watchdog ends the process with the one line. Imports nothing (numba is asked only when already loaded)."""
    roots = tuple(os.path.dirname(m.__file__) + os.sep for m in (sys.modules.get("numba"), sys.modules.get("llvmlite"))
                  if m is not None and getattr(m, "__file__", None))
    if not roots:
        return False
    while frame is not None:
        if frame.f_code.co_filename.startswith(roots):
            return True
        frame = frame.f_back
    lock = getattr(sys.modules.get("numba.core.compiler_lock"), "global_compiler_lock", None)
    try:
        return lock is not None and lock.is_locked()
    except Exception:  # noqa: BLE001 - a numba without it: raise as usual
        return False


@contextmanager
def deferred(raising: bool = True):
    """A region where a stop signal is recorded and raised only when the region ends: around library calls that
    hold locks across Python code, so that the exception cannot leave one held. ``concurrent.futures.wait``
    takes each future's lock in turn: a ``Stopped`` raised between two of them leaves one held, the worker
    finishing that future then waits on it forever, and so does the pool's shutdown (the likely cause of a
    SIGTERM that hung a run in one CI run). ``raising=False``: a region on the way out of a stop already
    raised (the pool's shutdown)."""
    _deferring[0] += 1
    try:
        yield
    finally:
        _deferring[0] -= 1
    if raising:
        raise_if_stopped()


def _quiet() -> None:
    """From a stop on, libraries' complaints about work cut short (joblib's and distributed's warnings, their
    and asyncio's logged errors while the cluster winds down) are not printed: the one line is ours. Imports
    nothing: the signal may land while ``logging`` itself is being imported (half-initialised: a seeded
    random SIGINT in the suite found it), so only modules that are already whole are touched."""
    import sys

    warnings = sys.modules.get("warnings")
    if warnings is not None and hasattr(warnings, "simplefilter"):
        warnings.simplefilter("ignore")
    logging = sys.modules.get("logging")
    if logging is not None and hasattr(logging, "disable") and hasattr(logging, "CRITICAL"):
        logging.disable(logging.CRITICAL)


def install(watchdog: bool = True) -> None:
    """Handle every STOP_SIGNALS in this (main) thread: raise ``Stopped``, and remember it; with ``watchdog``
    (a command's process, not a host such as a test runner), start the watchdog that ends the process
    ``STOP_GRACE_S`` after a stop signal whatever the main thread is doing."""
    _received.clear()
    _reported.clear()
    for sig in STOP_SIGNALS:
        signal.signal(sig, _on_signal)
    if watchdog:
        _start_watchdog()
    previous = sys.unraisablehook

    def quiet_about_stops(unraisable):
        """A ``Stopped`` raised inside a callback that swallows exceptions (distributed's gc callback) is
        remembered (``received``) and acted on by the runner; Python would otherwise print its traceback."""
        if _received or (unraisable.exc_type is not None and issubclass(unraisable.exc_type, Stopped)):
            return  # after a stop, whatever a library's callback or atexit handler fails at is not news
        previous(unraisable)

    sys.unraisablehook = quiet_about_stops
    previous_excepthook = sys.excepthook

    def quiet_excepthook(exc_type, exc, tb):
        """C code that calls Python and prints what it raises (``PyErr_Print``; Cython's unraisable path with
        a full traceback prints through here before the unraisable hook) would print a stop's traceback: a
        seeded random SIGINT in CI landed on an import that such code made. The stop is remembered and acted
        on all the same; the one line is ours."""
        if _received or (exc_type is not None and issubclass(exc_type, Stopped)):
            return
        previous_excepthook(exc_type, exc, tb)

    sys.excepthook = quiet_excepthook


def _start_watchdog() -> None:
    """A daemon thread blocked on the read end of the signal module's wakeup pipe: the C-level handler writes
    each signal's number there at once, even while the main thread is inside a compile or a kernel."""
    if any(t.name == "surgopt-stop-watchdog" for t in threading.enumerate()):
        return
    read_fd, write_fd = os.pipe()
    os.set_blocking(write_fd, False)
    try:
        signal.set_wakeup_fd(write_fd, warn_on_full_buffer=False)
    except ValueError:  # not the main thread: the handlers alone
        os.close(read_fd)
        os.close(write_fd)
        return
    threading.Thread(target=_watch, args=(read_fd,), name="surgopt-stop-watchdog", daemon=True).start()


def _watch(read_fd: int) -> None:
    stops = {int(s) for s in STOP_SIGNALS}
    while True:
        try:
            data = os.read(read_fd, 64)
        except OSError:
            return
        if not data:
            return
        signums = [b for b in data if b in stops]
        if signums:
            break
    threading.Event().wait(STOP_GRACE_S)  # the orderly path ends the process first, as a rule
    exit_now(report(None, signum=signums[0]))


def exit_now(code: int) -> None:
    """End the process now with ``code``: output flushed, child processes (workers) killed, no wait for threads
    still inside a kernel (their chunks are lost, the stored ones kept), no interpreter shutdown (which would
    join them, or abort the process under a kernel)."""
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except Exception:  # noqa: BLE001 - a closed pipe: nothing more to say
            pass
    kill_children()
    os._exit(code)


def kill_children() -> None:
    """SIGKILL every descendant process of this one (loky and dask workers, their helpers); Linux's /proc only."""
    try:
        entries = os.listdir("/proc")
    except OSError:
        return
    parent_of = {}
    for entry in entries:
        if entry.isdigit():
            try:
                with open(f"/proc/{entry}/stat", "rb") as f:
                    stat = f.read()
                parent_of[int(entry)] = int(stat[stat.rindex(b")") + 2:].split()[1])
            except (OSError, ValueError, IndexError):
                continue
    mine, frontier = set(), {os.getpid()}
    while frontier:
        frontier = {pid for pid, ppid in parent_of.items() if ppid in frontier} - mine
        mine |= frontier
    for pid in mine:
        try:
            os.kill(pid, signal.SIGKILL)
        except OSError:
            pass


def received() -> int | None:
    """The first stop signal received since ``install``, or None."""
    return _received[0] if _received else None


def raise_if_stopped() -> None:
    """Raise ``Stopped`` if a stop signal arrived and its exception was swallowed on the way."""
    if _received:
        raise Stopped(_received[0])


def on_stop(hint: str) -> None:
    """What a stop's line says from now on (RESUME, UNCHANGED or COMPLETE): set by a command as it goes."""
    _on_stop[0] = hint


def stop_hint() -> str:
    """What a stop's line says now."""
    return _on_stop[0]


def report(exc: BaseException | None, resume: str | None = None, signum: int | None = None) -> int:
    """Say on stderr that the command was stopped (and that ``resume`` holds, by default what the command in hand
    said last, ``on_stop``), once whoever says it (the command's guard, the CLI's last word, the watchdog); the
    exit code."""
    resume = resume or _on_stop[0]
    signum = signum or (exc.signum if isinstance(exc, Stopped) else (received() or signal.SIGINT))
    with _report_lock:  # the main thread and the watchdog: one line
        if not _reported:
            _quiet()
            _reported.append(True)
            what = f"stopped by {signal.Signals(signum).name}" if signum != signal.SIGINT else "interrupted"
            sys.stderr.write(f"surgopt: {what}; {resume}\n")
            sys.stderr.flush()
    return 128 + signum


def ignore() -> None:
    """The command has ended: a stop signal that lands while the process exits changes nothing."""
    for sig in STOP_SIGNALS:
        signal.signal(sig, signal.SIG_IGN)
