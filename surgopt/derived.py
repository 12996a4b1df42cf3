"""What the readers derive from a complete run's rows (its closing report, ``summarize``'s sections), kept beside
the run in ``_derived.json`` so that asking again does not read millions of rows again (issue 42 item 5: a
cache hit of port-place read its 2.2 M rows back for the report, 4-28 s; summarize 5-51 s).

An entry is used only when all three still hold, else it is computed again and replaced: the run's parts are
the ones it was derived from (their checksums, from the manifest), the package's code is the one that derived it
(a sha256 over every source file: a reader's change changes what it shows), and the entry's own sha256 matches
(a damaged file is never read as numbers). Writing is best effort and atomic, by the reading process (the
parent; workers never read the store), only for a complete run; the leading "_" keeps Parquet readers off it.
"""
from __future__ import annotations

import hashlib
import json
import math
from functools import lru_cache
from pathlib import Path
from typing import Any, Callable

from surgopt.store import DERIVED  # the store's layout names it

#: A derived file larger than this is not one surgopt wrote (a port-place report's entries are ~20 kB).
MAX_DERIVED_BYTES = 16 * 2 ** 20
FORMAT = 1
#: Entries kept per run (each summarize's --top/--sort/--columns is one): the oldest are dropped past this.
MAX_ENTRIES = 32


@lru_cache(maxsize=1)
def package_sha256() -> str:
    """sha256 over the names and bytes of every source file of the package (what derives, renders and reads)."""
    package = Path(__file__).resolve().parent
    h = hashlib.sha256()
    for f in sorted(package.rglob("*.py")) + sorted(package.rglob("*.toml")):
        h.update(str(f.relative_to(package)).encode() + b"\0" + f.read_bytes() + b"\0")
    return h.hexdigest()


def parts_sha256(manifest: dict) -> str:
    """sha256 of a run's list of parts (each with its own checksum): what its rows are."""
    return hashlib.sha256(json.dumps(manifest.get("parts", {}), sort_keys=True).encode()).hexdigest()


def derived(run, name: str, compute: Callable[[], Any], **args) -> Any:
    """``compute()`` for this run, or the value kept from an earlier call with the same ``name`` and ``args`` (see
    the module's docstring for when a kept value is used). The value is returned as JSON reads it back (lists for
    tuples, plain floats), the same on the first call as on later ones."""
    value = kept(run, name, **args)
    if value is not None:
        return value[0]
    entry = _entry(name, args)
    text = json.dumps(compute(), default=_plain, allow_nan=True)  # keys in their order: tables show it
    if run.complete:  # the entries as they are now (``compute`` may have kept others meanwhile), the newest last
        entries = {k: v for k, v in (_read(run) or {}).items() if k != entry}
        entries[entry] = {"sha256": hashlib.sha256(text.encode()).hexdigest(), "value": text}
        _write(run, dict(list(entries.items())[-MAX_ENTRIES:]))
    return json.loads(text)


def kept(run, name: str, **args) -> tuple[Any] | None:
    """(value,) kept for this run under ``name`` and ``args``, used on the terms of the module's docstring; None
    when there is none to use (nothing is computed: ``surgopt.hits`` answers a cache hit only from kept values)."""
    entries = _read(run) if run.complete else None
    entry = _entry(name, args)
    return _checked(entries[entry]) if entries is not None and entry in entries else None


def _entry(name: str, args: dict) -> str:
    return f"{name}:{json.dumps(args, sort_keys=True)}"


def _checked(item) -> tuple[Any] | None:
    """(value,) of an entry whose sha256 matches its text, else None."""
    try:
        text = item["value"]
        if hashlib.sha256(text.encode()).hexdigest() != item["sha256"]:
            return None
        return (json.loads(text),)
    except (TypeError, KeyError, ValueError, AttributeError):
        return None


def _read(run) -> dict | None:
    """The run's kept entries when its file is for these parts and this code; None otherwise."""
    from surgopt import files

    path = Path(run.path) / DERIVED
    try:
        data = json.loads(files.read_bounded(path, MAX_DERIVED_BYTES))
    except (OSError, ValueError, files.FileProblem):
        return None
    if not isinstance(data, dict) or data.get("format") != FORMAT or data.get("code") != package_sha256() \
            or data.get("parts") != parts_sha256(run.manifest) or not isinstance(data.get("entries"), dict):
        return None
    return data["entries"]


def _write(run, entries: dict) -> None:
    from surgopt.store import atomic_write

    data = json.dumps({"format": FORMAT, "code": package_sha256(), "parts": parts_sha256(run.manifest),
                       "entries": entries}, sort_keys=True).encode()
    try:
        atomic_write(Path(run.path) / DERIVED, lambda tmp: tmp.write_bytes(data))
    except OSError:
        pass  # a read-only store: computed again next time


def _plain(x):
    """numpy scalars and arrays, and other number-likes, as JSON values."""
    if hasattr(x, "tolist"):
        return x.tolist()
    if isinstance(x, (set, frozenset)):
        return sorted(x)
    if isinstance(x, float) and not math.isfinite(x):
        return x
    return str(x)
