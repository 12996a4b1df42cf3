"""A cache hit answered before the study loads (issue 42 item 5: a cache hit of any run in at most 0.5 s).

A study command's store key is a function of its config once validated, and validating it imports the study,
pydantic and numpy (~0.25 s of a ~0.55 s cache hit). A plain command line answered once before (``surgopt STUDY
[CONFIG ...] [KEY=VALUE ...] [--store PATH]``: the same study and arguments, from the same folder, with the same
SURGOPT_* environment and the same package code) names the same run as long as every file its configs were read
from or named (the config files, meshes, URDFs, point files: ``files.recording``) still has the sha256 it had. Such
a command's run is recorded in the store's ``_hits/<sha256 of the command line>.json``; the next identical command
reads that, checks each file's sha256, that the run is complete with the recorded task count and its headline,
every part's size, sha256 and row count (``Run.damaged``, as any cache hit), and that the closing report's numbers
are kept beside the run for these parts and this code (``surgopt.derived.kept``), and prints the closing report
from them. If anything is not so (a file changed or gone, the run removed, partial or damaged, a kept number
missing) nothing has been printed and the command runs the usual way, which records it again.

Options other than --store take the usual way (they change what is run or how it is shown).
"""
from __future__ import annotations

import hashlib
import json
import os
import sys
import time
from pathlib import Path

#: 2: each file recorded as named and as resolved (issue 55 item 3); a format-1 entry is not answered from.
FORMAT = 2
#: The environment that changes what a path names (``~``) or which package runs: part of a command's identity.
PATH_ENVIRONMENT = ("HOME", "PYTHONPATH")
#: Recorded command lines kept per store (each a few hundred bytes); the least recently written go first.
MAX_HITS = 256
MAX_HIT_BYTES = 1 << 20


def plain_command(argv: list[str]) -> tuple[str, list[str], str | None] | None:
    """(study, positional arguments, --store value) of ``surgopt STUDY [ARG ...] [--store PATH]``, else None."""
    from surgopt.studies import STUDIES

    if not argv or argv[0] not in STUDIES:
        return None
    args, store, rest = [], None, list(argv[1:])
    while rest:
        a = rest.pop(0)
        if a == "--store" and rest:
            store = rest.pop(0)
        elif a.startswith("--store="):
            store = a.partition("=")[2]
        elif a.startswith("-"):
            return None
        else:
            args.append(a)
    return argv[0], args, store


def command_sha256(study: str, args: list[str]) -> str:
    """sha256 of what a plain command line's run depends on besides the files it reads: the study, its
    arguments, the working folder (relative paths), the SURGOPT_* environment, HOME and PYTHONPATH (what ``~`` and
    the package mean) and the package's code."""
    from surgopt.derived import package_sha256

    env = {k: v for k, v in os.environ.items() if k.startswith("SURGOPT_") or k in PATH_ENVIRONMENT}
    text = json.dumps({"format": FORMAT, "study": study, "args": list(args), "cwd": os.getcwd(), "env": env,
                       "code": package_sha256()}, sort_keys=True)
    return hashlib.sha256(text.encode()).hexdigest()


def _path(store, digest: str) -> Path:
    from surgopt.store import HITS  # the store's layout names it (imported here: the CLI's start-up reads this module)

    return Path(store.root) / HITS / f"{digest}.json"


def record(store, study: str, args: list[str], run, files_read: list, notes: list[str]) -> None:
    """Note that this plain command line answers with ``run`` (complete) while ``files_read`` keep their sha256s;
    ``notes``: the lines printed before the run. Best effort (a read-only store is not an error)."""
    from surgopt.store import atomic_write

    entry = {"format": FORMAT, "study": study, "key": run.key, "n_tasks": run.manifest["n_tasks"],
             "files": sorted(set(map(tuple, files_read))), "notes": list(notes)}
    path = _path(store, command_sha256(study, args))
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        atomic_write(path, lambda tmp: tmp.write_text(json.dumps(entry, sort_keys=True)))
        kept = sorted(path.parent.glob("*.json"), key=lambda p: p.stat().st_mtime_ns)
        for old in kept[:-MAX_HITS]:
            old.unlink(missing_ok=True)
    except OSError:
        pass


def _unchanged(files_read) -> bool:
    """Whether every file read names the same file now, resolved again from the path as the command (or its config)
    named it, and that file has the same sha256."""
    for named, resolved, sha in files_read:
        try:
            if str(Path(named).resolve()) != resolved:  # a link (a file's, a folder's) retargeted
                return False
            if not sha:  # a name recorded for where it led (``files.config_file_path``); its file is checked apart
                continue
            with open(named, "rb") as f:
                if hashlib.file_digest(f, "sha256").hexdigest() != sha:
                    return False
        except OSError:
            return False
    return True


def answered(argv: list[str]) -> bool:
    """Print the closing report of a plain command line's run from what the store keeps, when everything is as
    recorded (the module's docstring); False, having printed nothing, otherwise."""
    t0 = time.perf_counter()
    plain = plain_command(argv)
    if plain is None:
        return False
    study, args, store_arg = plain
    found = _found(study, args, store_arg)
    if found is None:
        return False
    run, entry, summary, edges, front = found
    from surgopt.cli_common import guard, print_report

    with guard():  # as the usual way prints (a closed pipe is one line)
        for note in entry["notes"]:
            print(f"note: {note}", file=sys.stderr)
        print_report(study, run, summary, edges, front, rows=run.rows, elapsed_s=time.perf_counter() - t0,
                     cache_hit=True)
    return True


def _found(study: str, args: list[str], store_arg):
    """(run, entry, summary, edges, front) of a recorded command line whose files and run check out, else None."""
    from surgopt.derived import kept
    from surgopt.errors import StoreError
    from surgopt.files import FileProblem, read_bounded
    from surgopt.store import Store
    from surgopt.studies import Summary

    try:
        store = Store(store_arg)
        entry = json.loads(read_bounded(_path(store, command_sha256(study, args)), MAX_HIT_BYTES))
        if not isinstance(entry, dict) or entry.get("format") != FORMAT or entry.get("study") != study:
            return None
        if not _unchanged(entry["files"]):
            return None
        run = store.open(study, entry["key"])
        if run is None or not run.complete or run.manifest.get("n_tasks") != entry["n_tasks"] \
                or "headline" not in run.manifest or run.damaged():
            return None
        numbers = [kept(run, "summary"), kept(run, "best_edges"), kept(run, "search_front")]
    except (OSError, ValueError, KeyError, TypeError, StoreError, FileProblem):
        return None
    if any(n is None for n in numbers):
        return None
    (got,), (edges,), (front,) = numbers
    summary = Summary(got["headline"], got["feasibility"], [tuple(t) for t in got["tables"]])
    return run, entry, summary, edges, (tuple(front) if front is not None else None)
