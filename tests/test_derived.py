"""What the readers derive from a complete run, kept beside it (``surgopt.derived``, issue 42 item 5): asked again,
no row is read; the kept value is the computed one; a damaged entry, other code or other parts are never served;
a partial run is never kept. And ``surgopt --help`` lists the studies without importing one."""
from __future__ import annotations

import json
import subprocess
import sys

import pytest

#: A small rcm-grid map (tests/test_cli.py's)
SMALL_OVERRIDES = ["candidates.grid.x_count=5", "candidates.grid.z_count=4", "workspace.points_per_side=3"]

from surgopt import derived as D
from surgopt.report import run_record, run_sections, summary_sections
from surgopt.runner import run_study
from surgopt.store import Run, Store
from surgopt.studies import STUDIES, get_study


@pytest.fixture
def toy_run(monkeypatch, tmp_path):
    monkeypatch.setitem(STUDIES, "toy", "toy_study")
    toy = get_study("toy")
    store = Store(tmp_path / "s")
    run_study(toy, toy.config_model(n=30), config_name="t", store=store, jobs=1, quiet=True)
    (run,) = store.runs("toy")
    return toy, run


@pytest.fixture
def part_reads(monkeypatch):
    """How many stored parts have been read since the test began."""
    count = {"n": 0}
    read = Run.part_table

    def counted(self, *a, **k):
        count["n"] += 1
        return read(self, *a, **k)

    monkeypatch.setattr(Run, "part_table", counted)
    return count


def test_summarize_of_a_complete_run_is_derived_once_and_the_same(toy_run, part_reads):
    toy, run = toy_run
    fresh = summary_sections(toy, run, run.parts(toy.schema()), top=5)
    first_reads = part_reads["n"]
    assert first_reads > 0  # the premise: deriving reads the parts
    kept = run_sections(toy, run, top=5)
    assert part_reads["n"] > first_reads and (run.path / D.DERIVED).is_file()
    before = part_reads["n"]
    again = run_sections(toy, run, top=5)
    assert part_reads["n"] == before  # asked again: no part read
    assert again == kept == json.loads(json.dumps(fresh))  # what was computed, as JSON reads it back
    record = run_record(toy, run, top=3)
    assert run_record(toy, run, top=3) == record and record["top"][0]["square"] == 29.0 ** 2
    other = run_sections(toy, run, top=2)  # other arguments: their own entry
    assert part_reads["n"] > before and len(other[1][2]) == 2


def test_a_damaged_entry_other_code_or_other_parts_are_derived_again(toy_run, part_reads, monkeypatch):
    toy, run = toy_run
    kept = run_sections(toy, run)
    path = run.path / D.DERIVED
    data = json.loads(path.read_text())
    assert set(data["entries"]) >= {"summary:{}", "best_edges:{}"}  # kept by the sections' own derivation
    entry = next(e for e in data["entries"] if e.startswith("summary_sections:"))
    data["entries"][entry]["value"] = data["entries"][entry]["value"].replace("841.0", "842.0")
    assert "842.0" in data["entries"][entry]["value"]  # the premise: the tampering changed a number
    path.write_text(json.dumps(data))
    n = part_reads["n"]
    assert run_sections(toy, run) == kept and part_reads["n"] > n  # its sha256 failed: derived again
    path.write_bytes(b"\x00not json")
    n = part_reads["n"]
    assert run_sections(toy, run) == kept and part_reads["n"] > n
    n = part_reads["n"]
    monkeypatch.setattr(D, "package_sha256", lambda: "other code")
    assert run_sections(toy, run) == kept and part_reads["n"] > n
    n = part_reads["n"]
    run.manifest["parts"]["0"] = {**run.manifest["parts"]["0"], "sha256": "0" * 64}  # other rows than derived from
    assert D._read(run) is None


def test_a_partial_run_is_never_kept(toy_run):
    toy, run = toy_run
    run.manifest["n_tasks"] += 1  # as a run that has not finished
    assert not run.complete
    calls = []
    assert D.derived(run, "x", lambda: calls.append(1) or {"a": 1}) == {"a": 1}
    assert D.derived(run, "x", lambda: calls.append(1) or {"a": 1}) == {"a": 1}
    assert calls == [1, 1] and not (run.path / D.DERIVED).exists()


def test_the_closing_report_of_a_cache_hit_reads_no_row(tmp_path):
    """``surgopt rcm-grid`` twice (a small map): the second is a cache hit whose closing report is the first's,
    with no part read (the parts are checked, by sha256, not read as rows)."""
    from conftest import cli

    store = tmp_path / "s"
    first = cli("rcm-grid", *SMALL_OVERRIDES, "--store", store).stdout
    code = ("import sys; from surgopt.store import Run; read = Run.part_table; n = [0]\n"
            "def counted(self, *a, **k):\n    n[0] += 1\n    return read(self, *a, **k)\n"
            "Run.part_table = counted\n"
            f"sys.argv = ['surgopt', 'rcm-grid', *{SMALL_OVERRIDES!r}, '--store', {str(store)!r}]\n"
            "from surgopt.cli import run\ntry:\n    run()\nexcept SystemExit:\n    pass\n"
            "print('PARTS READ', n[0])")
    second = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert "cache hit" in second and "PARTS READ 0" in second
    def report(out):  # from the closing report's title on, its time left out
        lines = out.replace("PARTS READ 0", "").rstrip().splitlines()
        start = next(i for i, x in enumerate(lines) if "rcm-grid (embedded" in x)
        return [x for x in lines[start:] if "time_s" not in x]

    assert report(second) == report(first) and len(report(first)) > 10


def test_help_lists_every_study_without_importing_one():
    """``surgopt --help``: every registered study listed with its help's first line, and neither a study's
    declaration nor numpy nor pydantic imported (what made it take 0.8 s)."""
    code = ("import sys; sys.argv = ['surgopt', '--help']\nfrom surgopt.cli import run\ntry:\n    run()\n"
            "except SystemExit:\n    pass\n"
            "print('LOADED', sorted(m for m in sys.modules if m.endswith('.study') or m in ('numpy', 'pydantic')))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                         env={"COLUMNS": "200", "PATH": "/usr/bin:/bin"}).stdout
    assert "LOADED []" in out
    for name, module in STUDIES.items():
        package = __import__(module.rpartition(".")[0], fromlist=["HELP"])
        assert f" {name} " in out and package.HELP.split("\n")[0][:60] in out
        assert get_study(name).help == package.HELP  # the declaration's help is the package's


def test_the_kept_entries_are_bounded(toy_run, monkeypatch):
    """Each set of arguments is an entry; past MAX_ENTRIES the oldest are dropped (the file does not grow with
    every --top a user tries), the newest kept."""
    toy, run = toy_run
    monkeypatch.setattr(D, "MAX_ENTRIES", 3)
    for k in range(5):
        assert D.derived(run, "x", lambda: {"k": k}, k=k) == {"k": k}
    kept = D._read(run)
    assert list(kept) == [f'x:{{"k": {k}}}' for k in (2, 3, 4)]
