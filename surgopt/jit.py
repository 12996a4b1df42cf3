"""Numba settings in one place: the compile flags every kernel uses and the process environment.

``configure_numba()`` must run before numba is imported (numba reads NUMBA_CACHE_DIR and
NUMBA_CPU_FEATURES once, at import): every kernel compiles with ``njit`` below, which calls it before it
first imports numba, so the first import of a kernel configures numba without the caller doing anything. Nothing else imports the kernels at
module level: ``import surgopt``, ``import surgopt.cli`` and every ``--help`` load no numba or llvmlite
and change no environment variable (tests/test_cli.py); a study imports its kernels when it first
computes, and worker processes do the same.

Flag sets (every kernel is ``nogil`` so the threads backend runs chunks in parallel, and ``cache``d
on disk so a second run loads instead of compiling):

- ``EXACT``: IEEE semantics, Python's error model (raises on division by zero). Scalar and small
  matrix code whose results are compared bit for bit with baselines.
- ``VECTOR``: as ``EXACT`` with numpy's error model, which lets LLVM vectorise loops that divide.
- ``CONTRACT``: as ``VECTOR`` and fused multiply-add allowed (the rcm-grid kernel: 1 rounding
  instead of 2 per a*b+c, no reassociation, so rows do not depend on the vector width).
"""
from __future__ import annotations

import os
from pathlib import Path

EXACT = dict(cache=True, nogil=True, fastmath=False)
VECTOR = dict(cache=True, nogil=True, fastmath=False, error_model="numpy")
CONTRACT = dict(cache=True, nogil=True, fastmath={"contract"}, error_model="numpy")


_configured = [False]


def njit(*args, **flags):
    """numba's ``njit``, numba configured first (``configure_numba``, once per process): the one way a kernel
    module reaches numba."""
    if not _configured[0]:
        configure_numba()
        _configured[0] = True
    import numba

    return numba.njit(*args, **flags)


def numba_cache_dir() -> Path:
    """Where numba keeps compiled kernels: $NUMBA_CACHE_DIR or ~/.cache/surgopt/numba."""
    if os.environ.get("NUMBA_CACHE_DIR"):
        return Path(os.environ["NUMBA_CACHE_DIR"])
    base = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache")
    return base / "surgopt" / "numba"


def configure_numba() -> Path:
    """Set numba's environment before numba is imported (worker processes inherit it), and its cache folder
    also when numba is already imported.

    NUMBA_CACHE_DIR: compiled kernels persist across runs. NUMBA_CPU_FEATURES:
    on an AVX-512 machine, let LLVM use 8-wide vectors (it prefers 4-wide by
    default). The rcm-grid kernel is 1.3x faster that way here, the others
    unchanged, and rows are identical (same operations per lane, no
    reassociation). A NUMBA_CPU_FEATURES already set, or SURGOPT_WIDE_VECTORS=0,
    leaves numba's default.
    """
    path = numba_cache_dir()
    os.environ["NUMBA_CACHE_DIR"] = str(path)
    use_wide_vectors()
    _set_loaded_numba_cache_dir(path)
    return path


def _set_loaded_numba_cache_dir(path: Path) -> None:
    """numba reads NUMBA_CACHE_DIR once, when it is imported; without it a kernel's cache goes beside its source
    (``__pycache__`` inside the installed package: files pip does not know of, which survive an uninstall and
    turn ``site-packages/surgopt`` into a namespace package that shadows a later editable install). Where
    something imported numba first, its configuration is told here; a kernel is never cached in the package."""
    import sys

    config = getattr(sys.modules.get("numba.core.config"), "__dict__", None)
    if config is not None:
        config["CACHE_DIR"] = str(path)


def use_wide_vectors() -> None:
    """Set NUMBA_CPU_FEATURES for 8-wide vectors on AVX-512 hosts, unless the user chose otherwise."""
    if "NUMBA_CPU_FEATURES" not in os.environ and os.environ.get("SURGOPT_WIDE_VECTORS", "1") != "0":
        features = wide_vector_features()
        if features:
            os.environ["NUMBA_CPU_FEATURES"] = features


def wide_vector_features() -> str | None:
    """The host's LLVM feature string without the 256-bit vector preference, if it has AVX-512."""
    try:
        import llvmlite.binding as ll

        features = ll.get_host_cpu_features().flatten()
    except Exception:  # noqa: BLE001 - no llvmlite or no host information: keep numba's default
        return None
    have = set(features.split(","))
    if not {"+avx512f", "+avx512vl", "+avx512dq"} <= have:
        return None
    return features + ",-prefer-256-bit"


#: How long a wait on another process's compile lock goes unannounced (s).
QUIET_WAIT_S = 2.0


def compile_lock(timeout_s: float = 600.0, on_wait=None, holder: str = ""):
    """A lock across processes on the numba cache folder, held while numba compiles into it
    (``while_compiling``).

    Two surgopt processes compiling the same kernels into one cache at once (e.g. two commands started
    together after an upgrade) race on the cache's index files; once a process was seen to abort
    (SIGABRT) loading a half-written entry. With the lock the second waits. Past ``timeout_s`` it compiles
    anyway (a stale holder must not block a run for ever). ``holder``: who takes it ("pid 123 (surgopt
    port-place)"), written beside the lock for a waiter to name; ``on_wait(holder)`` is called once when another
    process has held it for QUIET_WAIT_S.
    """
    import contextlib

    from filelock import FileLock, Timeout

    path = numba_cache_dir()
    path.mkdir(parents=True, exist_ok=True)
    lock = FileLock(str(path / ".surgopt-compile.lock"))
    named = path / ".surgopt-compile.holder"

    @contextlib.contextmanager
    def held():
        try:
            try:
                lock.acquire(timeout=min(QUIET_WAIT_S, timeout_s))  # another process compiling one kernel: a moment
            except Timeout:
                if on_wait is not None:
                    on_wait(_holder_of(named))  # another process compiles into this cache now: say who
                lock.acquire(timeout=max(0.0, timeout_s - QUIET_WAIT_S))
        except Timeout:
            yield
            return
        try:
            with contextlib.suppress(OSError):
                named.write_text(holder or f"pid {os.getpid()}")
            yield
        finally:
            lock.release()

    return held()


def _holder_of(path) -> str:
    try:
        return path.read_text().strip() or "another surgopt process"
    except OSError:
        return "another surgopt process"


def while_compiling(on_wait=None, holder: str = "", on_compile=None):
    """A region where numba's compiles take the cache's ``compile_lock`` (issue 56 item 6): the lock is held from
    the start of an outermost compile to its end (numba's "numba:compile" events; a kernel loaded from the cache
    compiles nothing and takes no lock), not through a study's whole warm-up (its tables built, minutes), so that
    an unrelated run loading its own kernels never queues behind it. ``on_compile()``: called at each outermost
    compile's start."""
    import contextlib

    from numba.core import event

    depth, taken = [0], []

    class Locking(event.Listener):
        def on_start(self, ev):
            depth[0] += 1
            if depth[0] == 1:
                if on_compile is not None:
                    on_compile()
                region = compile_lock(on_wait=on_wait, holder=holder)
                region.__enter__()
                taken.append(region)

        def on_end(self, ev):
            depth[0] -= 1
            if depth[0] == 0 and taken:
                taken.pop().__exit__(None, None, None)

    @contextlib.contextmanager
    def region():
        try:
            with event.install_listener("numba:compile", Locking()):
                yield
        finally:
            while taken:  # an error inside a compile: no end event came
                taken.pop().__exit__(None, None, None)

    return region()
