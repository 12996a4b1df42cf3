"""Content-addressed Parquet result store.

Layout: ``STORE/<study>/<key>/manifest.json`` + ``part-00000.parquet`` ...
A part counts as done only once it was written to a temporary file, fsynced,
renamed into place, read back, and listed in the manifest (itself replaced
atomically) with its row count and sha256. Only the parent process writes.
An exclusive ``flock`` on ``<key>/.lock`` keeps two processes from writing
one key at once; the second waits and then finds the parts the first wrote.
"""
from __future__ import annotations

import contextlib
import datetime as _dt
import fcntl
import hashlib
import json
import os
import shutil
from dataclasses import dataclass
from pathlib import Path

from surgopt.errors import StoreError

DEFAULT_STORE = "surgopt-store"
MANIFEST = "manifest.json"
LOCK = ".lock"
FORMAT_VERSION = 1


def store_root(path: str | os.PathLike | None = None) -> Path:
    """--store flag > SURGOPT_STORE > ./surgopt-store."""
    return Path(path or os.environ.get("SURGOPT_STORE") or DEFAULT_STORE)


def _sha256(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


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


def _fsync_dir(path: Path) -> None:
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def _now() -> str:
    return _dt.datetime.now(_dt.timezone.utc).replace(microsecond=0).isoformat()


@dataclass
class Run:
    """One stored study: a folder holding a manifest and Parquet parts."""

    path: Path
    manifest: dict

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

    def read_table(self, schema=None):
        """All parts in task order as one Arrow table."""
        import pyarrow as pa
        import pyarrow.parquet as pq

        files = self.part_files()
        if not files:
            if schema is None:
                raise StoreError(f"{self.path}: no parts written yet")
            return schema.empty_table()
        return pa.concat_tables([pq.read_table(f, schema=schema) for f in files])


class Store:
    def __init__(self, root: str | os.PathLike | None = None):
        self.root = store_root(root)

    def run_dir(self, study: str, key: str) -> Path:
        return self.root / study / key

    def open(self, study: str, key: str) -> Run | None:
        path = self.run_dir(study, key)
        mpath = path / MANIFEST
        if not mpath.exists():
            return None
        try:
            manifest = json.loads(mpath.read_text())
        except (OSError, json.JSONDecodeError) as exc:
            raise StoreError(f"{mpath}: unreadable manifest ({exc}); delete the folder to recompute") from None
        return Run(path, manifest)

    @contextlib.contextmanager
    def lock(self, study: str, key: str, on_wait=None):
        """Exclusive lock on one key; ``on_wait(holder)`` is called before blocking."""
        path = self.run_dir(study, key)
        path.mkdir(parents=True, exist_ok=True)
        fd = os.open(path / LOCK, os.O_RDWR | os.O_CREAT, 0o644)
        try:
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                if on_wait is not None:
                    holder = os.pread(fd, 64, 0).decode(errors="replace").strip()
                    on_wait(holder or "another process")
                fcntl.flock(fd, fcntl.LOCK_EX)
            os.ftruncate(fd, 0)
            os.pwrite(fd, f"pid {os.getpid()}".encode(), 0)
            yield
        finally:
            fcntl.flock(fd, fcntl.LOCK_UN)
            os.close(fd)

    def begin(self, study: str, key: str, *, config: dict, config_name: str,
              kernel_version: str, n_tasks: int, chunk: int, force: bool) -> Run:
        """Open (or with ``force`` reset) a run for writing; call under ``lock``.

        Parts listed in the manifest are checked (present, sha256); a part that
        fails the check is dropped from the manifest and will be recomputed.
        """
        path = self.run_dir(study, key)
        run = None if force else self.open(study, key)
        for f in path.glob(".*.tmp-*"):  # left by a killed writer; we hold the lock
            f.unlink()
        if force:
            for f in path.glob("part-*.parquet"):
                f.unlink()
        if run is not None and run.manifest.get("format") == FORMAT_VERSION:
            for i in self.bad_parts(run):
                del run.manifest["parts"][i]
            return run
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
        }
        run = Run(path, manifest)
        self._write_manifest(run)
        return run

    def bad_parts(self, run: Run) -> list[str]:
        """Manifest entries whose file is missing or fails its sha256."""
        bad = []
        for i, meta in run.manifest["parts"].items():
            f = run.path / meta["file"]
            if not f.exists() or _sha256(f) != meta["sha256"]:
                bad.append(i)
        return bad

    def write_part(self, run: Run, index: int, table) -> None:
        """Write one task's rows atomically and record them in the manifest."""
        import pyarrow.parquet as pq

        name = f"part-{index:05d}.parquet"
        final = run.path / name
        atomic_write(final, lambda tmp: pq.write_table(table, tmp, compression="zstd"))
        rows = pq.read_metadata(final).num_rows  # readable?
        if rows != table.num_rows:
            raise StoreError(f"{final}: wrote {table.num_rows} rows, read back {rows}")
        run.manifest["parts"][str(index)] = {"file": name, "rows": rows, "sha256": _sha256(final)}
        if run.complete:
            run.manifest["completed"] = _now()
        self._write_manifest(run)

    def _write_manifest(self, run: Run) -> None:
        data = json.dumps(run.manifest, indent=1, sort_keys=True).encode()
        atomic_write(run.path / MANIFEST, lambda tmp: tmp.write_bytes(data))

    def runs(self, study: str | None = None) -> list[Run]:
        if not self.root.exists():
            return []
        out = []
        for mpath in sorted(self.root.glob(f"{study or '*'}/*/{MANIFEST}")):
            with contextlib.suppress(OSError, json.JSONDecodeError):
                out.append(Run(mpath.parent, json.loads(mpath.read_text())))
        return sorted(out, key=lambda r: r.manifest.get("created", ""))

    def gc(self) -> list[Path]:
        """Delete partial runs and stray temporary files; returns what was removed."""
        removed = []
        if not self.root.exists():
            return removed
        for run in self.runs():
            if not run.complete:
                self.remove(run)
                removed.append(run.path)
        for tmp in self.root.glob("*/*/.*.tmp-*"):
            tmp.unlink(missing_ok=True)
            removed.append(tmp)
        return removed

    def remove(self, run: Run) -> None:
        root = self.root.resolve()
        target = run.path.resolve()
        if root not in target.parents:
            raise StoreError(f"{target} is not inside the store {root}")
        shutil.rmtree(target)
