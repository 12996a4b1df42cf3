"""Issue 55 items 1 and 2: what ``--out`` names is never one of the store's own files, what is not a regular file is
written through (never replaced by a file), ``-`` is standard output, and a link to a file keeps being a link.
(``surgopt/outputs.py``: one rule for every writer.)"""
import hashlib
import os
import stat
import threading

import pytest

from conftest import invoke


@pytest.fixture(scope="module")
def stored(tmp_path_factory):
    """One small rcm-grid run for the module (every test here only reads it or is refused before writing):
    (config path, store path, table), as ``conftest.stored``."""
    from surgopt.config import load_config
    from surgopt.runner import run_study
    from surgopt.store import Store
    from surgopt.studies import get_study

    from conftest import RCM_SMALL

    tmp = tmp_path_factory.mktemp("outputs")
    rcm = get_study("rcm-grid")
    cfg = tmp / "small.toml"
    cfg.write_text(RCM_SMALL)
    res = run_study(rcm, load_config(cfg, rcm.config_model), config_name="small", store=Store(tmp / "store"),
                    jobs=1, quiet=True, chunk=4)
    return cfg, tmp / "store", res.table


def _sha(path):
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _run_folder(store):
    (folder,) = [p.parent for p in store.rglob("_manifest.json")]
    return folder


@pytest.mark.parametrize("command", ["csv", "parquet", "json", "report", "plot", "baseline"])
def test_an_output_into_the_store_is_refused_in_one_line_and_nothing_changes(stored, command, tmp_path):
    cfg, store, _ = stored
    run = _run_folder(store)
    before = {p: _sha(p) for p in run.rglob("*") if p.is_file()}
    assert any(p.name.startswith("part-") for p in before)  # the premise: a run with parts
    for target in (run / "part-00000.parquet", run / "_manifest.json", run / "mine.out", run,
                   store / "study=rcm-grid" / "_hits" / "x", store / "study=rcm-grid" / ".locks" / "x"):
        if command == "report":
            args = ("report", "latest", "--store", store, "--out", target)
        elif command == "plot":
            args = ("plot", "latest", "--store", store, "--out", target)
        elif command == "baseline":
            args = ("check", cfg, "--store", store, "--baseline", target, "--write")
        else:
            args = ("export", "latest", "--store", store, "--format", command, "--out", target)
        if target == run and command != "plot":
            continue  # a folder is refused for a file anyway
        if command == "plot" and target.name.startswith(("part-", "_manifest")):
            continue  # a file is refused for the figures' folder anyway
        code, output = invoke(*args)
        lines = [line for line in output.strip().splitlines() if line.strip()]
        assert code == 2 and len(lines) == 1 and "result store" in lines[0] and "nothing was written" in lines[0], \
            (target, output)
    assert {p: _sha(p) for p in run.rglob("*") if p.is_file()} == before


def test_a_fifo_is_written_through_and_stays_a_fifo(stored, tmp_path):
    _, store, table = stored
    fifo = tmp_path / "rows.csv"
    os.mkfifo(fifo)
    got = []
    reader = threading.Thread(target=lambda: got.append(fifo.read_bytes()))
    reader.start()
    code, output = invoke("export", "latest", "--store", store, "--format", "csv", "--out", fifo)
    reader.join(timeout=60)
    assert code == 0 and got and got[0].count(b"\n") == table.num_rows + 1
    assert stat.S_ISFIFO(os.stat(fifo).st_mode)  # not replaced by a regular file


def test_dash_is_standard_output_and_a_link_stays_a_link(stored, tmp_path):
    _, store, table = stored
    code, output = invoke("export", "latest", "--store", store, "--format", "csv", "--out", "-")
    assert code == 0 and output.count("\n") >= table.num_rows + 1 and "wrote" not in output
    target = tmp_path / "target.csv"
    target.write_text("old\n")
    link = tmp_path / "link.csv"
    link.symlink_to(target)
    code, _ = invoke("export", "latest", "--store", store, "--format", "csv", "--out", link)
    assert code == 0 and link.is_symlink() and target.read_text().count("\n") == table.num_rows + 1
    code, _ = invoke("export", "latest", "--store", store, "--format", "parquet", "--out", "-")
    assert code == 2  # binary Parquet is not written to a terminal


def test_an_empty_or_folder_out_is_one_line(stored, tmp_path):
    """#55 item 7: ``--out ''`` (a folder: '.') for a study's own format was a 'Is a directory' error naming a
    temporary file in the folder's parent; it is one line naming --out."""
    _, store, _ = stored
    for out in ("", tmp_path):
        code, output = invoke("export", "latest", "--store", store, "--format", "csv", "--out", out)
        assert code == 2 and output.strip().count("\n") == 0 and "--out" in output and "folder" in output
    from surgopt.errors import UsageError
    from surgopt.outputs import write_text_out

    for out in ("", tmp_path):  # a study's own format (--format dvrk, ports) writes through this
        with pytest.raises(UsageError, match="is a folder; give a file"):
            write_text_out(out, "x")


@pytest.mark.parametrize("fault", ["disk full", "out of memory"])
def test_a_command_that_stores_nothing_does_not_say_resume(stored, tmp_path, monkeypatch, fault):
    """#55 item 7: export, report and summarize store no chunk: a full disk or running out of memory there says the
    store's runs are as they were, not "finished chunks are stored, run the same command again to resume"."""
    import errno

    from surgopt import export

    def broken(*_):
        if fault == "disk full":
            raise OSError(errno.ENOSPC, "No space left on device", str(tmp_path / "rows.csv"))
        raise MemoryError()

    monkeypatch.setattr(export, "write_csv", broken)
    _, store, _ = stored
    code, output = invoke("export", "latest", "--store", store, "--format", "csv", "--out", tmp_path / "rows.csv")
    assert code == 1 and "stores nothing" in output and "resume" not in output and output.strip().count("\n") == 0
    assert ("disk is full" in output) == (fault == "disk full")


def test_an_output_this_user_may_not_write_is_refused_before_anything_is_read(stored, tmp_path, monkeypatch):
    """#55, outputs as a non-root user: a folder this user may not write into and a file it may not write (another
    user's, in a folder anyone may write to: a rename would have replaced it) are refused in one line, exit 2,
    naming --out and the owner, nothing written (before: "Permission denied writing .../.rows.csv.tmp-NNN", exit
    1, or the other user's file replaced). Run as root (who may write anything) the user's view is what
    ``os.access`` answers, made to answer as for another user."""
    from pathlib import Path

    from surgopt import outputs

    _, store, _ = stored
    ro, theirs = tmp_path / "ro", tmp_path / "theirs.csv"
    ro.mkdir()
    theirs.write_text("theirs")
    if os.geteuid() == 0:
        real = os.access
        monkeypatch.setattr(outputs.os, "access",
                            lambda p, mode: real(p, mode) and not (mode & os.W_OK and Path(p) in (ro, theirs)))
    else:
        ro.chmod(0o555)
        theirs.chmod(0o444)
    assert not os.access(ro, os.W_OK) or os.geteuid() == 0  # the premise, as the code sees it
    for args, out in ((("export", "latest", "--format", "csv"), ro / "rows.csv"),
                      (("export", "latest", "--format", "json"), ro / "sub" / "rows.json"),
                      (("report", "latest"), ro / "page.html"), (("plot", "latest"), ro / "figures"),
                      (("export", "latest", "--format", "csv"), theirs)):
        code, output = invoke(*args, "--store", store, "--out", out)
        assert code == 2 and output.strip().count("\n") == 0 and output.startswith(f"surgopt: error: --out: {out}"), \
            (args, output)
        assert ("cannot write in the folder" if out != theirs else "cannot be written by this user") in output
    assert sorted(p.name for p in tmp_path.rglob("*")) == ["ro", "theirs.csv"] and theirs.read_text() == "theirs"


def test_a_full_disk_names_the_file_and_leaves_nothing_behind(stored, tmp_path, monkeypatch):
    """A write that fails for want of space (the error names no file: ``write`` does not) says which output, in one
    line, and leaves no temporary file beside it."""
    import errno

    from surgopt import export

    def full(*_):  # the header is written, then the disk fills up
        raise OSError(errno.ENOSPC, "No space left on device")
        yield

    monkeypatch.setattr(export, "_in_order", full)
    _, store, _ = stored
    out = tmp_path / "rows.csv"
    code, output = invoke("export", "latest", "--store", store, "--format", "csv", "--out", out)
    assert code == 1 and output.strip() == (f"surgopt: error: the disk is full writing {out}; this command stores "
                                            "nothing: the store's runs are as they were; run it again once there "
                                            "is space"), output
    assert list(tmp_path.iterdir()) == []


def test_a_lock_this_user_may_not_open_for_writing_still_tells_a_run_being_written(tmp_path):
    """A store this user may read but not write (a lab's shared store): ``runs`` asked each run's lock by opening
    it read-write and ended in "Permission denied writing .../.locks/KEY.lock". A lock file it may only read is
    asked through a shared ``flock`` on a read-only descriptor: held while the writer holds it, free after."""
    from filelock import FileLock

    from surgopt.store import _held_exclusively

    path = tmp_path / "k.lock"
    writer = FileLock(path)
    writer.acquire()
    try:
        assert _held_exclusively(path)
    finally:
        writer.release()
    assert path.exists() and not _held_exclusively(path)
