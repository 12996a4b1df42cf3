"""Content-addressed Parquet result store.

Layout: ``STORE/study=<study>/key=<key>/_manifest.json`` + ``part-00000.parquet`` ... (hive-style
folder names, so duckdb, polars and pyarrow datasets get ``study`` and ``key`` columns from the path
with ``hive_partitioning``), and one lock file per key in ``STORE/study=<study>/.locks/<key>.lock``
(outside the run folder, so that replacing or deleting a run never touches a lock someone holds).
Stores written before the hive layout (``STORE/<study>/<key>/``) are still read, and runs whose manifest
is ``manifest.json`` (before it took the leading ``_`` that Parquet readers skip, so that
``pandas.read_parquet(run_folder)`` reads the rows alone); resuming such a run renames it.

A part counts as done only once it was written to a temporary file, fsynced, renamed into place,
read back, and listed in the manifest (itself replaced atomically) with its row count, size and
sha256. Only the parent process writes. An exclusive lock on the key (``filelock``) keeps two
processes from writing one key at once; the second waits and then finds the parts the first wrote.

Readers verify what they read: every part against its size and sha256 in the manifest (hashed from
the same bytes that are parsed, so one read per part); a damaged run is an error that names the
part and the command that repairs it. ``--force`` builds the new run in ``STORE/<study>/.staging/``
and swaps it in when complete, so a reader of the old run is never left with half of each; a reader
that loses the race re-reads the manifest. Clean-up (``gc``, ``remove``) leaves locked runs alone.

One module of ~670 lines: the layout, the manifest's shape, what makes a part count as done, its
verification on read, the lock, who may delete what, and the recovery of an interrupted swap are one
contract, changed together.
"""
from __future__ import annotations

import contextlib
import datetime as _dt
import errno
import hashlib
import json
import math
import os
import time
import re
import shutil
import threading
from dataclasses import dataclass, field
from pathlib import Path

from surgopt._version import __version__
from surgopt import files
from surgopt.errors import StoreError, UsageError

DEFAULT_STORE = "surgopt-store"
MANIFEST = "_manifest.json"
#: The manifest's name before it took the leading "_" that every Parquet reader skips: still read.
LEGACY_MANIFEST = "manifest.json"
#: The longest a stored part goes unlisted in the manifest (s): rewriting the manifest for every part made a run of
#: 3,000 one-candidate parts quadratic (10.7 ms a part against 4.4 ms for 300). A part written but not yet listed
#: when the process dies is removed on resume and computed again (``begin``), so a crash costs at most this much
#: work; a stop, an error and the end of a run write the manifest at once (``sync_manifest``, ``finish``).
MANIFEST_EVERY_S = 0.25
LOCKS = ".locks"
#: A run's derived numbers (``derived.py``) and a study folder's recorded command lines (``hits.py``): names the
#: store reserves, defined here with its layout so that what guards it (``outputs.py``) reads them from one place.
DERIVED = "_derived.json"
HITS = "_hits"
STAGING = ".staging"
FORMAT_VERSION = 1
#: What a study name may be (it becomes a folder name): a plain word.
STUDY_NAME = r"[A-Za-z0-9][A-Za-z0-9_-]{0,63}"
#: How often a reader re-reads a run whose parts were replaced under it (a --force rerun) before giving up.
READ_RETRIES = 3
#: The largest part a reader accepts when the manifest gives no size (a part is one chunk: ~2 s of work).
MAX_PART_BYTES = 4 * 2 ** 30


def store_root(path: str | os.PathLike | None = None) -> Path:
    """--store flag > SURGOPT_STORE > ./surgopt-store. An empty path is refused (it would mean '.')."""
    if path is not None and str(path) == "":
        raise UsageError("--store: an empty path; give a folder (it is created if missing)")
    env = os.environ.get("SURGOPT_STORE")
    if path is None and env is not None and env == "":
        raise UsageError("$SURGOPT_STORE is set but empty; unset it or give a folder")
    root = Path(path or env or DEFAULT_STORE)
    for p in (root, *root.parents):
        if p.exists():
            if not p.is_dir():
                what = "is a file" if p == root else f"is under {p}, which is a file"
                raise UsageError(f"--store: {root} {what}; give a folder")
            break
    return root


#: A manifest larger than this is not one surgopt wrote (a 10^6-task run's is ~150 MB; the default studies' < 1 MB).
MAX_MANIFEST_BYTES = 512 * 2 ** 20


#: Threads that check a run's parts at once (a cache hit checks every part of the run before it answers).
VERIFY_THREADS = 2


def read_bounded(path: Path, limit: int, expected: int | None = None) -> bytes:
    """``surgopt.files.read_bounded``, its refusals as StoreErrors."""
    try:
        return files.read_bounded(path, limit, expected)
    except files.FileProblem as exc:
        raise StoreError(str(exc)) from None


def manifest_of(folder: Path) -> Path:
    """The manifest file of a run folder: ``_manifest.json``, or an older run's ``manifest.json`` when only
    that exists (where a new one is written when neither does)."""
    path = folder / MANIFEST
    if not path.exists() and (folder / LEGACY_MANIFEST).exists():
        return folder / LEGACY_MANIFEST
    return path


def plain_headline(headline) -> dict | None:
    """A headline as JSON values (numpy scalars made plain; None for anything else, or for a headline that is
    not a flat mapping of names to numbers, text or booleans): what a manifest may hold as ``headline``."""
    if not isinstance(headline, dict):
        return None
    out = {}
    for k, v in headline.items():
        v = v.item() if hasattr(v, "item") and not isinstance(v, (str, bytes)) else v
        if not isinstance(k, str) or not (v is None or isinstance(v, (bool, int, float, str))):
            return None
        if isinstance(v, float) and not math.isfinite(v):
            v = None
        out[k] = v
    return out


def load_manifest(mpath: Path) -> dict:
    """A run's manifest, read within its size bound and checked (``check_manifest``). OSError for a file that
    cannot be opened, ValueError for one that is not JSON, StoreError otherwise."""
    return check_manifest(json.loads(read_bounded(mpath, MAX_MANIFEST_BYTES)), mpath)


def _footer_rows(data: bytes) -> int | None:
    """The row count a Parquet file's footer records (None if it has none readable): ``parquet_footer``'s
    reading of its FileMetaData, without loading pyarrow (and numpy) for it (a cache hit checks every part)."""
    from surgopt.parquet_footer import footer_num_rows

    return footer_num_rows(data)


def _sha256_bytes(data: bytes) -> str:
    return hashlib.sha256(data).hexdigest()


def arrow_owned(data: bytes):
    """``data`` copied into memory Arrow allocates, for Arrow's readers.

    A reader over Python ``bytes`` holds a Python buffer, and Arrow's thread pool may drop its last
    reference after ``read_table`` has returned; if that happens while the interpreter is exiting,
    the worker blocks on the GIL, is unwound by ``pthread_exit`` and the process aborts with
    "terminate called without an active exception" (exit -6, after all output was written: seen in
    CI on ``summarize`` and on a cache hit; apache/arrow#34314, #36389). Arrow-owned memory frees
    without the GIL. The copy costs a memcpy of a compressed part.
    """
    import numpy as np
    import pyarrow as pa

    buf = pa.allocate_buffer(len(data))
    np.frombuffer(buf, dtype=np.uint8)[:] = np.frombuffer(data, dtype=np.uint8)
    return buf


def atomic_write(path: Path, write) -> None:
    """Create or replace ``path`` atomically: ``write(tmp)`` fills a temporary file beside it, which is
    fsynced and renamed into place (readers see the old file or the new one, never a part), then the
    folder is fsynced. The temporary file is removed if anything fails."""
    tmp = path.with_name(f".{path.name}.tmp-{os.getpid()}")
    try:
        write(tmp)
        with open(tmp, "rb") as f:
            os.fsync(f.fileno())
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)
    _fsync_dir(path.parent)


def _held_exclusively(path: Path) -> bool:
    """Whether a process holds ``path``'s lock (filelock's exclusive ``flock``), asked through a read-only
    descriptor with a shared lock that cannot be granted beside it: for a lock file this user may not open to
    write (filelock's own test opens it read-write)."""
    import fcntl

    try:
        fd = os.open(path, os.O_RDONLY)
    except OSError:
        return False
    try:
        fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
    except BlockingIOError:
        return True
    except OSError:
        return False
    finally:
        os.close(fd)  # (closing the descriptor releases the shared lock)
    return False


def _fsync_dir(path: Path) -> None:
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def _now() -> str:
    return _dt.datetime.now(_dt.timezone.utc).replace(microsecond=0).isoformat()


def check_manifest(manifest, where: Path) -> dict:
    """The manifest if it has the shape this version writes, else a StoreError naming what is wrong."""
    def bad(what):
        return StoreError(f"{where}: not a valid surgopt manifest ({what}); delete the run "
                          f"(`surgopt runs rm KEY`) or its folder and run the study again")

    if not isinstance(manifest, dict):
        raise bad("not a JSON object")
    fmt = manifest.get("format")
    if isinstance(fmt, int) and not isinstance(fmt, bool) and fmt != FORMAT_VERSION:
        raise UnknownFormat(f"{where}: store format {fmt}, which this surgopt ({__version__}) does not know (it "
                            f"reads and writes format {FORMAT_VERSION}); the run is left as it is: use the "
                            f"surgopt that wrote it, or another --store")
    for k, t in (("format", int), ("study", str), ("key", str), ("n_tasks", int), ("chunk", int),
                 ("parts", dict), ("config", dict)):
        if not isinstance(manifest.get(k), t) or isinstance(manifest.get(k), bool):
            raise bad(f"'{k}' is missing or of the wrong type")
    if manifest["chunk"] < 1 or manifest["n_tasks"] < 1:
        raise bad("'chunk' and 'n_tasks' must be at least 1")
    if not re.fullmatch(STUDY_NAME, manifest["study"]) or not re.fullmatch(r"[0-9a-f]{64}", manifest["key"]):
        raise bad("'study' or 'key' is not a study name or a sha256 key")
    for i, meta in manifest["parts"].items():
        if not (isinstance(i, str) and i.isdigit() and isinstance(meta, dict)
                and isinstance(meta.get("file"), str) and isinstance(meta.get("rows"), int)
                and isinstance(meta.get("sha256"), str)
                and Path(meta["file"]).name == meta["file"] and meta["file"].startswith("part-")):
            raise bad(f"part entry {i!r} malformed")
    return manifest


class UnknownFormat(StoreError):
    """A manifest of a store format this version does not know (written by a later surgopt): never read,
    rewritten or deleted."""


class RunReplaced(StoreError):
    """The run was replaced (a --force rerun swapped it in) while it was being read."""


@dataclass
class Run:
    """One stored study: a folder holding a manifest and Parquet parts."""

    path: Path
    manifest: dict
    #: when this process last wrote the manifest (``Store.write_part`` writes it at most every MANIFEST_EVERY_S;
    #: a timer writes what is left MANIFEST_EVERY_S later, so a part never goes unlisted longer, however long the
    #: next chunk takes), and the lock the writer and the timer share
    manifest_written_s: float = field(default=0.0, compare=False, repr=False)
    manifest_dirty: bool = field(default=False, compare=False, repr=False)
    manifest_lock: object = field(default_factory=threading.Lock, compare=False, repr=False)
    manifest_timer: object = field(default=None, compare=False, repr=False)

    @property
    def study(self) -> str:
        return self.manifest["study"]

    @property
    def key(self) -> str:
        return self.manifest["key"]

    @property
    def complete(self) -> bool:
        return len(self.manifest["parts"]) == self.manifest["n_tasks"]

    @property
    def rows(self) -> int:
        return sum(p["rows"] for p in self.manifest["parts"].values())

    def done_tasks(self) -> set[int]:
        return {int(i) for i in self.manifest["parts"]}

    def part_files(self) -> list[Path]:
        parts = self.manifest["parts"]
        return [self.path / parts[i]["file"] for i in sorted(parts, key=int)]

    def repair_hint(self) -> str:
        """The command that recomputes this run's damaged or missing parts."""
        name = self.manifest.get("config_name", "")
        if name.startswith("embedded:"):
            return f"`surgopt {self.study}`"
        return f"`surgopt {self.study} CONFIG` with the config it was made from ({name or 'unknown'})"

    def part_problem(self, index: str) -> tuple[str | None, bytes | None]:
        """(problem, bytes) of one listed part: problem None when its size and sha256 match."""
        meta = self.manifest["parts"][index]
        f = self.path / meta["file"]
        try:
            data = read_bounded(f, MAX_PART_BYTES, meta.get("bytes"))
        except FileNotFoundError:
            return "is missing", None
        except IsADirectoryError:
            return "is a folder, not a file", None
        except OSError as exc:
            return f"cannot be read ({exc.strerror})", None
        except StoreError as exc:
            return str(exc).split(": ", 1)[-1], None
        if _sha256_bytes(data) != meta["sha256"]:
            return "fails its sha256 check (damaged or replaced)", None
        rows = _footer_rows(data)
        if rows != meta.get("rows"):  # the manifest's own number against the part's Parquet footer
            return f"holds {rows if rows is not None else 'an unreadable number of'} rows where the manifest says " \
                   f"{meta.get('rows')} (the manifest was edited)", None
        return None, data

    def damaged(self) -> list[tuple[str, str]]:
        """(part file, problem) of every listed part that fails its check."""
        from concurrent.futures import ThreadPoolExecutor

        order = sorted(self.manifest["parts"], key=int)
        with ThreadPoolExecutor(VERIFY_THREADS) as pool:  # reading and hashing release the GIL
            problems = list(pool.map(lambda i: self.part_problem(i)[0], order))
        return [(self.manifest["parts"][i]["file"], p) for i, p in zip(order, problems) if p]

    def read_table(self, schema=None, columns=None):
        """All parts in task order as one Arrow table (only ``columns``, if given), each verified against the
        manifest.

        A part that fails its check raises StoreError naming it and the command that repairs it.
        If the run was replaced while being read (a ``--force`` rerun), the manifest is read again.
        """
        import pyarrow as pa

        for attempt in range(READ_RETRIES + 1):
            try:
                tables = list(self._iter_tables(schema, columns))
                break
            except RunReplaced:
                if attempt == READ_RETRIES:
                    raise
        if not tables:
            if schema is None:
                raise StoreError(f"{self.path}: no parts written yet")
            empty = schema.empty_table()
            return empty if columns is None else empty.select(columns)
        return pa.concat_tables(tables)

    def parts(self, schema=None):
        """The rows part by part (``surgopt.parts.Parts``), each part verified as it is read: what
        summaries use, so that memory does not grow with the run."""
        from surgopt.parts import Parts

        return Parts(lambda columns=None, which=None: self._iter_tables(schema, columns, which), self.rows,
                     schema if schema is not None else self._first_schema())

    def _first_schema(self):
        import pyarrow as pa
        import pyarrow.parquet as pq

        for i in sorted(self.manifest["parts"], key=int):
            return pq.read_schema(pa.BufferReader(arrow_owned(self._verified(i))))
        raise StoreError(f"{self.path}: no parts written yet")

    def _verified(self, i: str) -> bytes:
        """The bytes of part ``i`` once they pass their check; RunReplaced if the run changed under us."""
        problem, data = self.part_problem(i)
        if problem and self._reload():
            raise RunReplaced(f"{self.study} run {self.key[:12]} was replaced while it was read (a --force rerun); "
                              f"read it again")
        if problem:
            raise StoreError(f"{self.study} run {self.key[:12]} is damaged: {self.manifest['parts'][i]['file']} "
                             f"{problem}; run {self.repair_hint()} again to recompute it "
                             f"(the parts that check out are kept)")
        return data

    def part_table(self, index, schema=None, columns=None):
        """One stored part (task ``index``), verified, as an Arrow table (only ``columns``, if given)."""
        import pyarrow as pa
        import pyarrow.parquet as pq

        i = str(index)
        try:
            data = arrow_owned(self._verified(i))
            if schema is not None:  # a column the stored part lacks would read as nulls: say so instead
                have = set(pq.read_schema(pa.BufferReader(data)).names)
                missing = [c for c in (columns if columns is not None else schema.names) if c not in have]
                if missing:
                    more = f" and {len(missing) - 1} more" if len(missing) > 1 else ""
                    raise StoreError(f"{self.path / self.manifest['parts'][i]['file']}: written by an earlier "
                                     f"surgopt, without the column {missing[0]!r}{more}; run the study again to "
                                     f"recompute it")
            return pq.read_table(pa.BufferReader(data), schema=schema, columns=columns, use_threads=False)
        except (pa.ArrowException, ValueError) as exc:
            raise StoreError(f"{self.path / self.manifest['parts'][i]['file']}: passes its checksum but "
                             f"does not match the study's schema ({exc})") from None

    def _iter_tables(self, schema, columns=None, which=None):
        """The parts in task order (only those at the positions ``which``, sorted, when given)."""
        order = sorted(self.manifest["parts"], key=int)
        for i in order if which is None else [order[w] for w in which]:
            yield self.part_table(i, schema, columns)

    def _reload(self) -> bool:
        """Re-read the manifest from disk; True if it changed (the run was replaced)."""
        try:
            fresh = load_manifest(manifest_of(self.path))
        except UnknownFormat:
            raise
        except (OSError, ValueError, StoreError):
            import time

            time.sleep(0.05)  # between the two renames of a swap
            try:
                fresh = load_manifest(manifest_of(self.path))
            except UnknownFormat:
                raise
            except (OSError, ValueError, StoreError):
                return False
        changed = fresh != self.manifest
        self.manifest = fresh
        return changed


class Store:
    def __init__(self, root: str | os.PathLike | None = None):
        self.root = store_root(root)

    def study_dir(self, study: str) -> Path:
        check_study_name(study)
        return self.root / f"study={study}"

    def run_dir(self, study: str, key: str) -> Path:
        """Where a run lives: the hive-style folder, or an older store's ``<study>/<key>`` if only that exists."""
        path = self.study_dir(study) / f"key={key}"
        legacy = self.root / study / key
        return legacy if (not path.exists() and manifest_of(legacy).exists()) else path

    def lock_path(self, study: str, key: str) -> Path:
        return self.study_dir(study) / LOCKS / f"{key}.lock"

    def _manifests(self, study: str | None) -> list[Path]:
        """Manifest files of every run (hive-style folders, then an older store's for keys not in the former)."""
        check_study_name(study)
        folders = {m.parent for name in (MANIFEST, LEGACY_MANIFEST)
                   for m in self.root.glob(f"study={study or '*'}/key=*/{name}")}
        new = sorted(manifest_of(f) for f in folders)
        seen = {folder_study_key(m.parent) for m in new}
        old = {m.parent for name in (MANIFEST, LEGACY_MANIFEST) for m in self.root.glob(f"{study or '*'}/*/{name}")
               if not m.parent.parent.name.startswith("study=") and folder_study_key(m.parent) not in seen}
        return new + sorted(manifest_of(f) for f in old)

    def open(self, study: str, key: str) -> Run | None:
        path = self.run_dir(study, key)
        mpath = manifest_of(path)
        if not mpath.exists() and self.recover_swaps(study, key):
            path = self.run_dir(study, key)
            mpath = manifest_of(path)
        if not mpath.exists():
            return None
        try:
            return Run(path, load_manifest(mpath))
        except (OSError, ValueError) as exc:
            raise StoreError(f"{mpath}: unreadable manifest ({exc}); delete the folder to recompute") from None

    @staticmethod
    def _refuse_unknown_format(mpath: Path) -> None:
        """UnknownFormat if ``mpath`` is a manifest of another store format (anything else passes)."""
        try:
            manifest = json.loads(read_bounded(mpath, MAX_MANIFEST_BYTES))
        except (ValueError, StoreError):
            return
        if isinstance(manifest, dict):
            fmt = manifest.get("format")
            if isinstance(fmt, int) and not isinstance(fmt, bool) and fmt != FORMAT_VERSION:
                check_manifest(manifest, mpath)

    def _mkdir(self, path: Path) -> None:
        try:
            path.mkdir(parents=True, exist_ok=True)
        except (PermissionError, OSError) as exc:
            raise StoreError(f"cannot create {path} in the store ({exc.strerror or exc}); "
                             f"give a writable --store") from None
        if not os.access(path, os.W_OK):
            raise StoreError(f"the store {self.root} is not writable ({path}); give a writable --store")

    @contextlib.contextmanager
    def lock(self, study: str, key: str, on_wait=None):
        """Exclusive lock on one key (``filelock``: an OS file lock wherever Python runs); ``on_wait(holder)``
        is called before blocking. The holder's pid is kept beside the lock file for messages."""
        from filelock import FileLock, Timeout

        path = self.lock_path(study, key)
        self._mkdir(path.parent)
        lock = FileLock(path)
        try:
            lock.acquire(timeout=0)
        except Timeout:
            if on_wait is not None:
                on_wait(self._holder_text(path))
            lock.acquire()
        try:
            path.with_suffix(".pid").write_text(f"pid {os.getpid()}")
            yield
        finally:
            lock.release()

    @staticmethod
    def _holder_text(path: Path) -> str:
        try:
            return path.with_suffix(".pid").read_text().strip() or "another process"
        except OSError:
            return "another process"

    def holder(self, study: str, key: str) -> str | None:
        """Who holds the key's lock ("pid N"), or None when nobody does."""
        from filelock import FileLock, Timeout

        path = self.lock_path(study, key)
        if not path.exists():
            return None
        lock = FileLock(path)
        try:
            lock.acquire(timeout=0)
        except Timeout:
            return self._holder_text(path)
        except PermissionError:  # a store this user may read but not write (a lab's shared store)
            return self._holder_text(path) if _held_exclusively(path) else None
        lock.release()
        return None

    def begin(self, study: str, key: str, *, config: dict, config_name: str,
              kernel_version: str, n_tasks: int, chunk: int, force: bool, fresh: bool = False,
              meta: dict | None = None) -> Run:
        """Open (or with ``force`` start anew, beside the old run) a run for writing; call under ``lock``.

        Parts listed in the manifest are checked (present, size, sha256); a part that fails the check
        is dropped from the manifest and will be recomputed. Part files the manifest does not list
        (left by an older manifest or another chunk size) are deleted. ``fresh``: start a new manifest
        in place, whatever is there (the caller found no usable one).
        """
        import pyarrow.parquet  # noqa: F401  the part writer's modules, loaded before any work: under a tight
        # memory limit a lazy import halfway through a run fails as an ImportError, not as out of memory

        path = self.run_dir(study, key)
        if force or fresh:
            run = None
            with contextlib.suppress(FileNotFoundError):
                self._refuse_unknown_format(manifest_of(path))
        else:
            run = self.open(study, key)
        if force:
            path = self.study_dir(study) / STAGING / f"{key}-{os.getpid()}"
            if path.exists():
                shutil.rmtree(path)
        self._mkdir(path)
        for f in path.glob(".*.tmp-*"):  # left by a killed writer; we hold the lock
            f.unlink()
        if run is not None and run.manifest.get("format") == FORMAT_VERSION:
            for i in self.bad_parts(run):
                _remove_path(path / run.manifest["parts"].pop(i)["file"])
            self._remove_unlisted_parts(run)
            return run
        for f in path.glob("part-*"):
            _remove_path(f)
        manifest = {
            "format": FORMAT_VERSION,
            "study": study,
            "key": key,
            "kernel_version": kernel_version,
            "config_name": config_name,
            "config": config,
            "created": _now(),
            "n_tasks": n_tasks,
            "chunk": chunk,
            "parts": {},
            **(meta or {}),
        }
        run = Run(path, manifest)
        self._write_manifest(run)
        return run

    def finish(self, run: Run, **meta) -> Run:
        """Record ``meta`` (e.g. wall time) in the manifest, and move a run built in the staging area
        (``--force``) into place, replacing the stored one; call under ``lock``."""
        with run.manifest_lock:
            if run.manifest_timer is not None:
                run.manifest_timer.cancel()
            if meta or run.manifest_dirty:
                run.manifest.update(meta)
                if run.complete and "completed" not in run.manifest:  # a search that set its part count at its end
                    run.manifest["completed"] = _now()
                self._write_manifest(run)
        if run.path.parent.name != STAGING:
            return run
        final = self.study_dir(run.study) / f"key={run.key}"
        legacy = self.root / run.study / run.key
        if legacy.exists() and not final.exists():
            shutil.rmtree(legacy, ignore_errors=True)  # the rebuilt run moves to the current layout
        trash = run.path.with_name(f"{run.key}-old-{os.getpid()}")
        if final.exists():
            os.rename(final, trash)
        os.rename(run.path, final)
        _fsync_dir(final.parent)
        shutil.rmtree(trash, ignore_errors=True)
        return Run(final, run.manifest)

    def record_headline(self, run: Run, headline: dict) -> bool:
        """Keep a complete run's headline numbers (its summary's: best, feasible count, ...) in its manifest as
        ``headline``, which ``runs --compare``, the store index and any JSON reader (duckdb's ``read_json``) read
        without the rows. Best effort: False, and nothing written, when the run is not complete, its lock is held
        (it is being written), it was replaced since it was read, or the store cannot be written."""
        from filelock import FileLock, Timeout

        clean = plain_headline(headline)
        if not run.complete or clean is None:
            return False
        lock = FileLock(self.lock_path(run.study, run.key))
        try:
            lock.acquire(timeout=0)
        except (Timeout, OSError):
            return False
        try:
            fresh = load_manifest(manifest_of(run.path))
            if fresh.get("parts") != run.manifest.get("parts"):
                return False  # replaced meanwhile: its own report records its own
            fresh["headline"] = clean
            data = json.dumps(fresh, indent=1, sort_keys=True).encode()
            atomic_write(run.path / MANIFEST, lambda tmp: tmp.write_bytes(data))
            (run.path / LEGACY_MANIFEST).unlink(missing_ok=True)
            run.manifest["headline"] = clean
            return True
        except (OSError, ValueError, StoreError):
            return False
        finally:
            lock.release()

    def _remove_unlisted_parts(self, run: Run) -> list[Path]:
        listed = {m["file"] for m in run.manifest["parts"].values()}
        stale = [f for f in run.path.glob("part-*") if f.name not in listed]
        for f in stale:
            _remove_path(f)
        return stale

    def bad_parts(self, run: Run) -> list[str]:
        """Manifest entries whose file is missing or fails its size or sha256."""
        return [i for i in run.manifest["parts"] if run.part_problem(i)[0]]

    def write_part(self, run: Run, index: int, table) -> None:
        """Write one task's rows atomically and record them in the manifest."""
        import pyarrow.parquet as pq

        name = f"part-{index:05d}.parquet"
        final = run.path / name
        atomic_write(final, lambda tmp: pq.write_table(table, tmp, compression="zstd"))
        data = final.read_bytes()
        rows = pq.read_metadata(final).num_rows  # readable?
        if rows != table.num_rows:
            raise StoreError(f"{final}: wrote {table.num_rows} rows, read back {rows}")
        with run.manifest_lock:
            run.manifest["parts"][str(index)] = {"file": name, "rows": rows, "bytes": len(data),
                                                 "sha256": _sha256_bytes(data)}
            run.manifest_dirty = True
            if run.complete:
                run.manifest["completed"] = _now()
            if run.complete or time.monotonic() - run.manifest_written_s >= MANIFEST_EVERY_S:
                self._write_manifest(run)
            elif run.manifest_timer is None or not run.manifest_timer.is_alive():
                run.manifest_timer = threading.Timer(MANIFEST_EVERY_S, self._flush_manifest, args=(run,))
                run.manifest_timer.daemon = True
                run.manifest_timer.start()

    def _flush_manifest(self, run: Run) -> None:
        """The timer's write: the parts stored since the last write, listed (a failure is the next write's)."""
        with run.manifest_lock:
            if run.manifest_dirty:
                with contextlib.suppress(OSError):
                    self._write_manifest(run)

    def sync_manifest(self, run: Run) -> None:
        """Write the manifest if parts were stored since it was last written (a run that stops, or ends)."""
        with run.manifest_lock:
            if run.manifest_timer is not None:
                run.manifest_timer.cancel()
            if run.manifest_dirty:
                self._write_manifest(run)

    def _write_manifest(self, run: Run) -> None:
        data = json.dumps(run.manifest, indent=1, sort_keys=True).encode()
        atomic_write(run.path / MANIFEST, lambda tmp: tmp.write_bytes(data))
        (run.path / LEGACY_MANIFEST).unlink(missing_ok=True)  # an older run resumed: its manifest renamed
        run.manifest_written_s, run.manifest_dirty = time.monotonic(), False

    def recover_swaps(self, study: str | None = None, key: str | None = None) -> list[Path]:
        """Put back the runs a ``--force`` swap left in the staging area when it was killed between its two
        renames (the old run moved aside, the new one not yet in place): for each key with no run in place
        and nobody holding its lock, the complete staged run (the rebuilt one before the old one) is
        renamed into place. Returns the folders restored. A store that cannot be written is left as it is."""
        from filelock import FileLock, Timeout

        restored = []
        staged = sorted(self.root.glob(f"study={study or '*'}/{STAGING}/{key or ''}*"),
                        key=lambda p: ("-old-" in p.name, p.name))  # the rebuilt run first
        for folder in staged:
            try:
                manifest = load_manifest(manifest_of(folder))
            except (OSError, ValueError, StoreError):
                continue
            s, k = manifest["study"], manifest["key"]
            final = self.study_dir(s) / f"key={k}"
            if not folder.name.startswith(k) or final.exists() or not Run(folder, manifest).complete:
                continue
            lock = FileLock(self.lock_path(s, k))
            try:
                lock.acquire(timeout=0)
            except (Timeout, OSError):
                continue  # a study is writing it now: its own swap completes it
            try:
                if not final.exists():
                    os.rename(folder, final)
                    _fsync_dir(final.parent)
                    restored.append(final)
            except OSError:
                continue
            finally:
                lock.release()
        return restored

    def runs(self, study: str | None = None) -> list[Run]:
        """Every run with a valid manifest, oldest first (``unreadable`` lists the others)."""
        if not self.root.exists():
            return []
        self.recover_swaps(study)
        out = []
        for mpath in self._manifests(study):
            with contextlib.suppress(OSError, ValueError, StoreError):
                out.append((Run(mpath.parent, load_manifest(mpath)), mpath.stat().st_mtime_ns))
        # by creation (to the second), then by when the manifest was last written: two runs created within one
        # second (a script's, a test's) were in the order the folder listed them, so "latest" was either
        return [run for run, _ in sorted(out, key=lambda r: (r[0].manifest.get("created", ""), r[1]))]

    def unreadable(self, study: str | None = None) -> list[tuple[Path, str]]:
        """(run folder, why) of run folders whose manifest cannot be used."""
        if not self.root.exists():
            return []
        out = []
        for mpath in self._manifests(study):
            try:
                load_manifest(mpath)
            except (OSError, ValueError) as exc:
                out.append((mpath.parent, f"unreadable manifest ({exc.__class__.__name__})"))
            except StoreError as exc:
                out.append((mpath.parent, str(exc).split(": ", 1)[-1].split(";")[0]))
        return out

    def gc(self) -> list[Path]:
        """Delete partial runs, stray part and temporary files, and abandoned --force staging folders.

        A run whose lock is held (a study writing it now) is skipped. Returns what was removed.
        """
        removed: list[Path] = []
        if not self.root.exists():
            return removed
        for run in self.runs():
            if self.holder(run.study, run.key):
                continue
            if not run.complete:
                self.remove(run)
                removed.append(run.path)
                continue
            removed += self._remove_unlisted_parts(run)
            for tmp in run.path.glob(".*.tmp-*"):
                tmp.unlink(missing_ok=True)
                removed.append(tmp)
        self.recover_swaps()  # a complete run left by an interrupted swap is put back, never collected
        for staged in self.root.glob(f"study=*/{STAGING}/*"):
            key = staged.name.split("-")[0]
            study = staged.parent.parent.name.removeprefix("study=")
            if not manifest_of(self.study_dir(study) / f"key={key}").exists():
                continue  # no run in place for this key: what is staged is all there is (partial: resumable)
            if not self.holder(study, key):
                shutil.rmtree(staged, ignore_errors=True)
                removed.append(staged)
        return removed

    def remove(self, run: Run) -> None:
        """Delete one run; refused while a study holds its lock."""
        root = self.root.resolve()
        target = run.path.resolve()
        if root not in target.parents:
            raise StoreError(f"{target} is not inside the store {root}")
        who = self.holder(run.study, run.key)
        if who:
            raise StoreError(f"{run.study} run {run.key[:12]} is being written now ({who} holds its lock); "
                             f"wait for it to finish or stop it first")
        shutil.rmtree(target)


def check_study_name(study: str | None) -> None:
    """A study name is a plain word (letters, digits, '-', '_'): never a path or a pattern that could reach
    out of the store."""
    if study is not None and not re.fullmatch(STUDY_NAME, study):
        raise UsageError(f"--study: {study[:80]!r} is not a study name")


def folder_study_key(path: Path) -> tuple[str, str]:
    """(study, key) a run folder's names say (hive-style ``study=X/key=Y`` or an older ``X/Y``)."""
    return path.parent.name.removeprefix("study="), path.name.removeprefix("key=")


def _remove_path(p: Path) -> None:
    if p.is_dir() and not p.is_symlink():
        shutil.rmtree(p)
    else:
        p.unlink(missing_ok=True)


def is_disk_full(exc: BaseException) -> bool:
    return isinstance(exc, OSError) and exc.errno in (errno.ENOSPC, errno.EDQUOT)
