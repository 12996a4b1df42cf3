"""Signals: SIGINT, SIGTERM and SIGHUP stop a command the same way, at any instant, with one line and the
conventional exit code (130, 143, 129); whatever was stored stays stored and the next command resumes.

The handlers raise ``Stopped`` (a ``KeyboardInterrupt``) in the main thread and remember the signal: a
handler's exception can be swallowed when the signal lands inside a callback that ignores exceptions (a
garbage-collection callback of dask's ``distributed``, a ``__del__``), so the runner asks
``raise_if_stopped()`` between chunks and the CLI once more at the end. Nothing here runs on import.
"""
from __future__ import annotations

import signal
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
    raise Stopped(signum)


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


def install() -> None:
    """Handle every STOP_SIGNALS in this (main) thread: raise ``Stopped``, and remember it."""
    import sys

    _received.clear()
    _reported.clear()
    for sig in STOP_SIGNALS:
        signal.signal(sig, _on_signal)
    previous = sys.unraisablehook

    def quiet_about_stops(unraisable):
        """A ``Stopped`` raised inside a callback that swallows exceptions (distributed's gc callback) is
        remembered (``received``) and acted on by the runner; Python would otherwise print its traceback."""
        if _received or (unraisable.exc_type is not None and issubclass(unraisable.exc_type, Stopped)):
            return  # after a stop, whatever a library's callback or atexit handler fails at is not news
        previous(unraisable)

    sys.unraisablehook = quiet_about_stops


def received() -> int | None:
    """The first stop signal received since ``install``, or None."""
    return _received[0] if _received else None


def raise_if_stopped() -> None:
    """Raise ``Stopped`` if a stop signal arrived and its exception was swallowed on the way."""
    if _received:
        raise Stopped(_received[0])


def report(exc: BaseException | None, resume: str, once: bool = False) -> int:
    """Say on stderr that the command was stopped (and that ``resume`` holds; with ``once``, only if nothing
    said it yet); the exit code."""
    import sys

    signum = exc.signum if isinstance(exc, Stopped) else (received() or signal.SIGINT)
    if not (once and _reported):
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
