"""Where a command writes what the user named with ``--out`` (issue 55 items 1 and 2): one rule for every writer.

- ``-`` (or no ``--out`` where the command's default is standard output) is standard output, everywhere.
- An output never lands in the store's own files: a path that resolves into a run folder (one holding a manifest),
  onto a name the store reserves (``part-NNNNN.parquet``, the manifest, the derived numbers), or into its hits,
  locks or staging folders is refused in one line (exit 2), before anything is written.
- What exists and is not a regular file (a FIFO with a reader waiting, a character device, ``/dev/stdout``, which
  is a link to ``/proc/self/fd/1``) is written through, streamed into as it is; it is never replaced by a file.
- A regular file (or a new one) is replaced atomically (``store.atomic_write``), through any symbolic link to it:
  the link is kept and its target replaced. A file this user may not write, or a folder it may not write into, is
  refused in one line (exit 2) before anything is written: a rename would replace another user's file that
  ``open`` would not (a folder anyone may write to), and the temporary file's name is not what the user gave.
"""
from __future__ import annotations

import os
import re
import stat
import sys
from pathlib import Path
from typing import BinaryIO, Callable

from surgopt.errors import UsageError

STDOUT = "-"
#: A part of a run: what the store's readers read as rows.
PART = re.compile(r"part-\d+\.parquet")


def is_stdout(out) -> bool:
    return out is None or str(out) == STDOUT


def store_reserved(path: Path) -> str:
    """Why ``path`` (resolved) belongs to a store and must not be written by an export ("" where it does not): a
    part, a manifest or the derived numbers by name, or a place inside a run folder, its hits, locks or staging."""
    from surgopt.store import DERIVED, HITS, LEGACY_MANIFEST, LOCKS, MANIFEST, STAGING

    if PART.fullmatch(path.name) or path.name in (MANIFEST, LEGACY_MANIFEST, DERIVED):
        return f"is a name the result store keeps for its own files ({path.name})"
    for folder in (path, *path.parents):
        if folder.name in (HITS, LOCKS, STAGING):
            return f"lies in the result store's {folder.name} folder ({folder})"
        if (folder / MANIFEST).is_file() or (folder / LEGACY_MANIFEST).is_file():
            where = "is" if folder == path else "lies in"
            return f"{where} a run folder of a result store ({folder})"
    return ""


def checked(out: Path, option: str = "--out") -> Path:
    """``out`` resolved (links followed, ``~`` expanded), or a ``UsageError`` naming the option when it belongs to
    a store (``store_reserved``) or this user may not write it (``refused_unwritable``): before anything is read."""
    real = Path(out).expanduser().resolve(strict=False)
    why = store_reserved(real)
    if why:
        raise UsageError(f"{option}: {out} {why}; give a path outside the store's run folders (nothing was written)")
    refused_unwritable(real, out, option)
    return real


def refused_unwritable(path: Path, out, option: str) -> None:
    """A ``UsageError`` naming ``option`` where this user may not write ``path`` (an existing file) or create it
    (the nearest folder of it that exists)."""
    if path.exists():
        if not os.access(path, os.W_OK):
            raise UsageError(f"{option}: {out} cannot be written by this user (it belongs to "
                             f"{_owner(path)}); nothing was written")
        return
    folder = next(p for p in path.parents if p.exists())
    if not os.access(folder, os.W_OK | os.X_OK):
        raise UsageError(f"{option}: {out}: this user cannot write in the folder {folder} (it belongs to "
                         f"{_owner(folder)}); nothing was written")


def _owner(path: Path) -> str:
    try:
        return path.owner()
    except (KeyError, OSError):
        return f"user {path.stat().st_uid}"


def streamed(path: Path) -> bool:
    """Whether ``path`` exists and is neither a regular file nor a folder (a FIFO, a device, a socket): what is
    written there is streamed into it, never renamed over it."""
    try:
        mode = path.stat().st_mode
    except OSError:
        return False
    return not (stat.S_ISREG(mode) or stat.S_ISDIR(mode))


def write_out(out, write: Callable[[BinaryIO], None], option: str = "--out", own: bool = False) -> None:
    """``write(sink)`` to standard output (``out`` None or ``-``), through what is not a regular file, or into a
    regular file replaced atomically; refused before writing anything where ``out`` belongs to a store, unless it
    is ``own`` (a file the command itself keeps beside a run, e.g. the run's page)."""
    if is_stdout(out):
        write(sys.stdout.buffer)
        sys.stdout.buffer.flush()
        return
    path = Path(out).expanduser().resolve(strict=False) if own else checked(out, option)
    if own:
        refused_unwritable(path, out, option)
    if path.is_dir():  # '' reads as '.': a folder either way
        raise UsageError(f"{option}: {out} is a folder; give a file (nothing was written)")
    given = Path(out).expanduser()
    if streamed(given):  # stat follows the links as opening does (/dev/stdout's /proc/self/fd/1 included)
        with open(given, "wb") as sink:
            write(sink)
        return
    from surgopt.store import atomic_write

    def to_file(tmp: Path) -> None:
        with open(tmp, "wb") as sink:
            write(sink)

    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        atomic_write(path, to_file)
    except OSError as exc:  # a write error names no file: name the one the user gave (a full disk)
        if exc.filename is None and exc.errno is not None:
            raise OSError(exc.errno, exc.strerror, str(path)) from None
        raise


def write_text_out(out, text: str, option: str = "--out", own: bool = False) -> None:
    """``write_out`` of a text (UTF-8)."""
    data = text.encode("utf-8")
    write_out(out, lambda sink: sink.write(data), option, own)
