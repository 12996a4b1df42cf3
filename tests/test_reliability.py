"""Reliability, second round (issue #25): the store never discards a complete run, readers say "partial",
files that are not what they claim are never read whole, names never reach out of the store. Each test
fails on c728bb9. Bounded: small rcm-grid runs (under a second each), no sleeps."""
import json
import os
import shutil

import pytest

from surgopt.config import load_config, study_key
from surgopt.errors import StoreError
from surgopt.runner import run_study
from surgopt.store import STAGING, Store
from surgopt.studies import get_study

from conftest import fault_lines, invoke, single_run

RCM = get_study("rcm-grid")


def _run(cfg, store, **kw):
    return run_study(RCM, load_config(cfg, RCM.config_model), config_name="small", store=Store(store), jobs=1,
                     quiet=True, say=lambda m: None, **kw)


# --- data loss ---------------------------------------------------------------------------------------------

def test_a_run_of_an_unknown_store_format_is_never_rewritten_read_or_collected(stored):
    cfg, store, _ = stored
    run = single_run(store)
    m = json.loads((run.path / "_manifest.json").read_text())
    m["format"] = 2  # written by a later surgopt
    (run.path / "_manifest.json").write_text(json.dumps(m))
    parts = sorted(p.name for p in run.path.glob("part-*"))
    for force in (False, True):
        with pytest.raises(StoreError, match="store format 2"):
            _run(cfg, store, force=force)
    code, out = invoke("rcm-grid", cfg, "--store", store, "--quiet")
    assert code == 1 and "store format 2" in out and len(fault_lines(out)) == 1, out
    code, out = invoke("summarize", run.key[:12], "--store", store)
    assert code != 0 and "Traceback" not in out
    assert invoke("runs", "gc", "--store", store)[0] == 0
    code, out = invoke("runs", "--store", store)
    assert "UNREADABLE" in out and "store format 2" in out
    assert sorted(p.name for p in run.path.glob("part-*")) == parts  # nothing deleted
    assert json.loads((run.path / "_manifest.json").read_text())["format"] == 2


def test_a_swap_killed_between_its_two_renames_is_restored_and_never_collected(stored):
    """--force builds the new run in .staging, moves the old one aside, then moves the new one in: killed
    between the two renames, both complete runs sit in .staging and no run is in place."""
    cfg, store, table = stored
    run = single_run(store)
    staging = store / "study=rcm-grid" / STAGING
    staging.mkdir()
    shutil.copytree(run.path, staging / f"{run.key}-4242")  # the rebuilt run, complete
    os.rename(run.path, staging / f"{run.key}-old-4242")  # the first rename happened, the second did not
    assert not run.path.exists()
    code, out = invoke("runs", "--store", store)
    assert code == 0 and run.key[:12] in out and "complete" in out, out
    assert run.path.exists() and single_run(store).read_table(RCM.schema()).equals(table)
    invoke("runs", "gc", "--store", store)
    assert single_run(store).complete
    # gc alone (no reader first) restores too
    os.rename(run.path, staging / f"{run.key}-9")
    assert invoke("runs", "gc", "--store", store)[0] == 0
    assert run.path.exists() and _run(cfg, store).cache_hit


# --- silent wrong answers ------------------------------------------------------------------------------------

def _make_partial(store, keep):
    run = single_run(store)
    for i in list(run.manifest["parts"])[keep:]:
        (run.path / run.manifest["parts"].pop(i)["file"]).unlink()
    (run.path / "_manifest.json").write_text(json.dumps(run.manifest))
    return run


def test_export_and_load_refuse_a_partial_run_unless_asked(stored, tmp_path):
    import surgopt

    cfg, store, table = stored
    run = _make_partial(store, 4)
    code, out = invoke("export", run.key[:12], "--store", store, "--out", tmp_path / "x.csv")
    assert code == 1 and "partial: 4 of 14 chunks" in out and "--partial" in out, out
    assert not (tmp_path / "x.csv").exists()
    with pytest.raises(StoreError, match="partial: 4 of 14 chunks"):
        surgopt.load(run.key[:12], store=store)
    df = surgopt.load(run.key[:12], store=store, allow_partial=True)
    assert len(df) == run.rows < table.num_rows
    code, out = invoke("export", run.key[:12], "--store", store, "--out", tmp_path / "x.csv", "--partial")
    assert code == 0 and f"({run.rows} rows" in out


# --- files that are not what they claim ----------------------------------------------------------------------

def test_a_part_or_manifest_that_is_a_device_or_oversized_is_never_read(stored, tmp_path):
    cfg, store, table = stored
    run = single_run(store)
    part = run.part_files()[1]
    part.unlink()
    part.symlink_to("/dev/zero")
    code, out = invoke("summarize", "--store", store)
    assert code == 1 and "not a regular file" in out, out
    part.unlink()
    big = tmp_path / "big"
    with open(big, "wb") as f:
        f.truncate(8 * 2 ** 30)  # 8 GB, sparse: a read of it would take minutes and 8 GB of memory
    part.symlink_to(big)
    code, out = invoke("summarize", "--store", store)
    assert code == 1 and "8589934592 bytes where" in out, out
    mpath = run.path / "_manifest.json"
    mpath.unlink()
    mpath.symlink_to("/dev/zero")
    code, out = invoke("runs", "--store", store)
    assert code == 0 and "UNREADABLE" in out and "not a regular file" in out, out


# --- names ---------------------------------------------------------------------------------------------------

@pytest.mark.parametrize("command", ["summarize", "plot", "export", "runs"])
def test_a_study_name_never_reaches_out_of_the_store(stored, command):
    _, store, _ = stored
    outside = store.parent / "outside" / "k"
    outside.mkdir(parents=True)
    shutil.copy(single_run(store).path / "_manifest.json", outside / "_manifest.json")
    args = [command] + (["x"] if command == "export" else []) + ["--study", "../outside", "--store", store]
    code, out = invoke(*args)
    assert code == 2 and "study" in out and "Traceback" not in out, out


def test_a_key_in_both_layouts_is_one_run(stored):
    _, store, table = stored
    run = single_run(store)
    shutil.copytree(run.path, store / "rcm-grid" / run.key)  # the older layout, same run
    assert len(Store(store).runs()) == 1
    code, out = invoke("summarize", run.key, "--store", store)
    assert code == 0, out


def test_minus_zero_and_zero_are_one_config():
    a = RCM.config_model.model_validate({"candidates": {"grid": {"z_max_m": 0.0}}})
    b = RCM.config_model.model_validate({"candidates": {"grid": {"z_max_m": -0.0}}})
    assert study_key("rcm-grid", a, "v") == study_key("rcm-grid", b, "v")


# --- configs: bounded before they are validated ---------------------------------------------------------------

YAML_BOMB = "a: &a [1, 1, 1, 1, 1, 1, 1, 1, 1, 1]\n" + "".join(
    f"{c}: &{c} [{', '.join(['*' + p] * 10)}]\n" for p, c in zip("abcdefgh", "bcdefghi")) + \
    "candidates:\n  list_m: *i\n"

BAD_CONFIGS = {
    "toml nested 5,000 deep": ("deep.toml", "x = " + "[" * 5000 + "]" * 5000 + "\n", "nests deeper than 32"),
    "yaml nested 5,000 deep": ("deep.yaml", "x: " + "[" * 5000 + "]" * 5000 + "\n", "nests deeper than 32"),
    "yaml alias bomb": ("bomb.yaml", YAML_BOMB, "more than 1,000,000 values"),
    "absurd depth": ("far.toml", "[workspace]\ndepth_below_rcm_m = 1e307\n", "workspace.depth_below_rcm_m: 1e+307 is beyond"),
    "megabyte key": ("long.toml", "[workspace]\n" + "k" * 2 ** 20 + " = 1\n", "characters)"),
}


@pytest.mark.parametrize("case", sorted(BAD_CONFIGS))
def test_a_config_is_bounded_before_it_is_validated(tmp_path, case):
    name, text, words = BAD_CONFIGS[case]
    (tmp_path / name).write_text(text)
    code, out = invoke("rcm-grid", tmp_path / name, "--store", tmp_path / "store", "--dry-run")
    assert code == 2 and words in out and "Traceback" not in out, out[:500]
    assert len(out.strip().splitlines()) == 1 and len(out) < 3000
    assert not (tmp_path / "store").exists()


def test_a_deeply_nested_override_is_one_line(tmp_path):
    code, out = invoke("rcm-grid", "workspace.points_per_side=" + "[" * 5000 + "]" * 5000, "--dry-run")
    assert code == 2 and "nests deeper" in out and "Traceback" not in out, out[:500]


@pytest.mark.parametrize("kind", ["fifo", "device"])
def test_a_config_path_that_is_not_a_regular_file_is_never_read(tmp_path, kind):
    path = tmp_path / "c.toml"
    if kind == "fifo":
        os.mkfifo(path)  # nobody writes to it: a plain read would block for ever
    else:
        path.symlink_to("/dev/zero")  # a plain read would fill memory
    code, out = invoke("rcm-grid", path, "--dry-run")
    assert code == 2 and "not a regular file" in out, out


# --- readers: one line for whatever the store holds -----------------------------------------------------------

BAD_MANIFEST_FIELDS = {
    "chunk 0": (lambda m: m.update(chunk=0), "'chunk' and 'n_tasks' must be at least 1"),
    "unknown study": (lambda m: m.update(study="nosuch"), "which this surgopt does not have"),
    "config of the wrong shape": (lambda m: m.update(config={"workspace": 5}), "not a valid rcm-grid config"),
}


@pytest.mark.parametrize("case", sorted(BAD_MANIFEST_FIELDS))
def test_a_manifest_with_bad_fields_is_one_line(stored, tmp_path, case):
    _, store, _ = stored
    run = single_run(store)
    change, words = BAD_MANIFEST_FIELDS[case]
    m = json.loads((run.path / "_manifest.json").read_text())
    change(m)
    (run.path / "_manifest.json").write_text(json.dumps(m))
    code, out = invoke("plot", run.key[:12], "--store", store, "--out", tmp_path / "figs")
    assert code in (1, 2) and words in out and "Traceback" not in out, out
    assert len(out.strip().splitlines()) == 1


def test_sort_by_a_text_column_is_one_line(tmp_path):
    from conftest import REPO

    store = tmp_path / "store"
    code, _ = invoke("suture-sim", REPO / "tests" / "baselines" / "suture_small.toml", "--store", store, "--quiet")
    assert code == 0
    code, out = invoke("summarize", "--store", store, "--sort", "mode")
    assert code == 2 and "'mode' is not a number column" in out and "Traceback" not in out, out


def test_no_feasible_candidate_is_never_called_best():
    """RCMs 1.3-1.5 m from the PA10's base: no candidate reaches the workspace; the headline names no
    unreachable RCM 'best'."""
    from surgopt.parts import Parts

    cfg = RCM.config_model.model_validate({"workspace": {"points_per_side": 3},
                                           "candidates": {"grid": {"x_min_m": 1.3, "x_max_m": 1.5, "x_count": 5,
                                                                   "z_count": 3}}})
    RCM.warm_up(cfg)
    cols = RCM.compute_task(cfg, 100, 0)
    import pyarrow as pa

    table = pa.Table.from_pydict(cols, schema=RCM.schema())
    assert not table["feasible"].to_numpy().any() and table["gii"].to_numpy().max() >= 0  # the premise
    s = RCM.summary(Parts(lambda columns=None: iter([table.select(columns) if columns else table]),
                          table.num_rows, table.schema))
    assert "best_gii" not in s.headline and s.headline["best"].startswith("none")
