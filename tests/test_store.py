"""The result store (surgopt/store.py): corrupt parts, locking between processes."""
import subprocess
import sys
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq

from conftest import RCM_SLOW, cli, single_run, single_table, wait_for_parts


def test_corrupt_part_is_recomputed(tmp_path, small_cfg):
    store = tmp_path / "store"
    cli("rcm-grid", small_cfg, "--store", store, "--quiet", "--chunk-size", "10")
    good = single_table(store)
    part = single_run(store).part_files()[1]
    part.write_bytes(b"garbage")
    r = cli("rcm-grid", small_cfg, "--store", store, "--quiet")
    assert "resuming" in r.stdout
    assert single_table(store).equals(good)


def test_two_processes_on_one_key(tmp_path):
    cfg = tmp_path / "slow.toml"
    cfg.write_text(RCM_SLOW.replace("x_count = 121", "x_count = 15"))  # 16 chunks of 40: the spin is the wait
    store = tmp_path / "store"
    args = ["rcm-grid", str(cfg), "--store", str(store), "--quiet", "--jobs", "1", "--chunk-size", "40"]
    # the first holds the run's lock for 5 s whatever the machine's load (its third chunk spins: tests/slow_cli.py),
    # so the second always finds it held (under load, a plain run had finished before the second started)
    a = subprocess.Popen([sys.executable, str(Path(__file__).parent / "slow_cli.py"), "5", "chunk", *args],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    wait_for_parts(store, "rcm-grid", 2, a)
    b = subprocess.Popen([sys.executable, "-m", "surgopt", *args], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                         text=True)
    out_a, err_a = a.communicate(timeout=120)
    out_b, err_b = b.communicate(timeout=120)
    assert a.returncode == 0 and b.returncode == 0, err_a + err_b
    assert "waiting for pid" in err_b
    run = single_run(store)
    assert run.complete
    for f, meta in zip(run.part_files(), [run.manifest["parts"][k] for k in sorted(run.manifest["parts"], key=int)]):
        assert pq.read_metadata(f).num_rows == meta["rows"]


def test_hive_layout_reads_in_duckdb_with_study_and_key_columns(tmp_path, small_cfg):
    import duckdb

    store = tmp_path / "store"
    cli("rcm-grid", small_cfg, "--store", store, "--quiet")
    run = single_run(store)
    got = duckdb.sql(f"SELECT study, key, count(*) AS n, max(gii) AS best FROM read_parquet("
                     f"'{store}/study=rcm-grid/*/*.parquet', hive_partitioning = true) GROUP BY study, key").fetchall()
    assert got == [("rcm-grid", run.key, run.rows, max(single_table(store)["gii"].to_pylist()))]


def test_the_readmes_python_snippets_read_a_real_store(tmp_path, small_cfg, monkeypatch):
    """README, "Results": the duckdb and pandas code blocks, run as written in a folder with a store: a plain ``pd.read_parquet(run_folder)`` reads the rows alone (the manifest, the figures and
    the page are named with the leading "_" Parquet readers skip; issue 42 item 8)."""
    import re

    from conftest import REPO

    store = tmp_path / "surgopt-store"
    cli("rcm-grid", small_cfg, "--store", store, "--quiet")
    run = single_run(store)
    # figures kept with the run (#27 item 10: `plot` wrote ./figures, the same names for every run): in the
    # run's own folder, which the readers below skip and surgopt's verified reads ignore
    figures = cli("plot", "--store", store).stdout.split()
    assert figures and all(Path(f).parent == run.path / "_figures" and Path(f).is_file() for f in figures)
    assert cli("export", run.key[:12], "--store", store).returncode == 0 and not run.damaged()
    readme = (REPO / "README.md").read_text()
    block = next(b for b in re.findall(r"```python\n(.*?)```", readme, re.S) if "duckdb.sql" in b)
    assert "597ae5d5" not in block  # #42 item 11: no key that a fresh store lacks; the code finds the run itself
    code = block.replace(".show()", ".fetchall()")
    monkeypatch.chdir(tmp_path)
    scope = {}
    exec(code, scope)  # noqa: S102 - the README's own code
    df = scope["df"]
    assert len(df) == run.rows and np.array_equal(df["gii"].to_numpy(), single_table(store)["gii"].to_numpy())


def test_a_store_in_the_older_layout_is_still_read(tmp_path, small_cfg):
    import shutil

    store = tmp_path / "store"
    cli("rcm-grid", small_cfg, "--store", store, "--quiet")
    run = single_run(store)
    table = single_table(store)
    legacy = store / "rcm-grid" / run.key
    legacy.parent.mkdir()
    shutil.move(str(run.path), legacy)
    shutil.rmtree(store / "study=rcm-grid")
    assert single_run(store).path == legacy and single_table(store).equals(table)
    assert "cache hit" in cli("rcm-grid", small_cfg, "--store", store, "--quiet").stdout
    assert "complete" in cli("runs", "--store", store).stdout


def test_a_run_whose_manifest_has_its_older_name_is_still_read_and_renamed_on_resume(tmp_path, small_cfg):
    """A run written before the manifest took its leading "_" (``manifest.json``): listed, a cache hit, read
    verified; resumed after a part is lost, its manifest is rewritten as ``_manifest.json`` and the old name
    goes. A plain ``pd.read_parquet`` of a new run's folder reads its rows (the premise of the rename)."""
    import pandas as pd

    store = tmp_path / "store"
    cli("rcm-grid", small_cfg, "--store", store, "--quiet", "--chunk-size", "2")
    run = single_run(store)
    table = single_table(store)
    assert len(pd.read_parquet(run.path)) == run.rows  # item 8: the natural call
    (run.path / "_manifest.json").rename(run.path / "manifest.json")
    assert single_run(store).path == run.path and single_table(store).equals(table)
    assert "cache hit" in cli("rcm-grid", small_cfg, "--store", store, "--quiet", "--chunk-size", "2").stdout
    assert "complete" in cli("runs", "--store", store).stdout
    assert len(run.manifest["parts"]) > 1  # the premise: a part can be lost and the run still have some
    (run.path / "part-00001.parquet").unlink()
    cli("rcm-grid", small_cfg, "--store", store, "--quiet", "--chunk-size", "2")
    assert (run.path / "_manifest.json").exists() and not (run.path / "manifest.json").exists()
    assert single_table(store).equals(table)


def test_a_runs_headline_is_kept_in_its_manifest_for_readers_without_the_rows(tmp_path, small_cfg):
    """Issue 42 item 4: the closing report keeps the run's headline in ``_manifest.json``: its best GII is the
    best of the feasible rows and its count theirs, duckdb's ``read_json`` of the manifests reads it, and
    ``runs --compare`` shows it; a malformed kept headline is not trusted (read from the rows again)."""
    import json

    import duckdb

    from surgopt.results import headline_of
    from surgopt.store import Store
    from surgopt.studies import get_study

    store = tmp_path / "store"
    cli("rcm-grid", small_cfg, "--store", store, "--quiet")
    run = single_run(store)
    table = single_table(store).to_pandas()
    head = json.loads((run.path / "_manifest.json").read_text())["headline"]
    assert head["best_gii"] == table[table.feasible]["gii"].max() and head["feasible"] == int(table.feasible.sum())
    assert table["gii"].max() > 0 and not table.feasible.all()  # the premise: some rows are not feasible
    got = duckdb.sql(f"SELECT key, headline.best_gii FROM read_json('{store}/study=rcm-grid/*/_manifest.json')")
    assert got.fetchall() == [(run.key, head["best_gii"])]
    assert f"{head['best_gii']:.6g}" in cli("runs", "--compare", "--study", "rcm-grid", "--store", store).stdout
    m = json.loads((run.path / "_manifest.json").read_text())
    m["headline"] = {"best_gii": [1, 2]}
    (run.path / "_manifest.json").write_text(json.dumps(m))
    again = headline_of(Store(store), get_study("rcm-grid"), single_run(store))
    assert again == head and json.loads((run.path / "_manifest.json").read_text())["headline"] == head


def test_parts_are_read_from_arrow_owned_memory():
    """Arrow's readers must not hold the Python bytes of a part: a pool thread dropping such a reference
    while the interpreter exits aborts the process (exit -6 after a clean run; see ``arrow_owned``)."""
    import sys

    import pyarrow as pa
    import pyarrow.parquet as pq

    from surgopt.store import arrow_owned

    sink = pa.BufferOutputStream()
    pq.write_table(pa.table({"x": [1.5, 2.5]}), sink)
    data = sink.getvalue().to_pybytes()
    before = sys.getrefcount(data)
    held = pa.BufferReader(data)
    assert sys.getrefcount(data) > before  # what a reader over the bytes themselves does
    del held
    reader = pa.BufferReader(arrow_owned(data))
    assert sys.getrefcount(data) == before
    assert pq.read_table(reader).column("x").to_pylist() == [1.5, 2.5]


def test_the_key_knows_the_code_that_computes_rows(tmp_path, monkeypatch):
    """An edited kernel, model or study (an editable install) is a new key, never the old rows as a cache hit;
    figures are not row code. The manifest records the code's sha256 and the checkout's commit."""
    import shutil

    import surgopt
    from surgopt import code_identity as C
    from surgopt.config import load_config, study_key
    from surgopt.runner import run_study
    from surgopt.store import Store
    from surgopt.studies import get_study

    rcm = get_study("rcm-grid")
    cfg = load_config(Path(__file__).parent / "baselines" / "rcm_small.toml", rcm.config_model)
    key = study_key("rcm-grid", cfg, rcm.kernel_version)
    copy = tmp_path / "surgopt"
    shutil.copytree(Path(surgopt.__file__).parent, copy, ignore=shutil.ignore_patterns("__pycache__"))
    hashes = {}
    for what, path in (("as is", None), ("metrics.py", "metrics.py"), ("a figure", "studies/rcm_grid/figures.py")):
        if path:
            (copy / path).write_text((copy / path).read_text() + "\n# edited\n")
        monkeypatch.setattr(C, "PACKAGE", copy)
        C.code_sha256.cache_clear()
        hashes[what] = C.code_sha256()
    C.code_sha256.cache_clear()
    monkeypatch.undo()
    assert hashes["as is"] == C.code_sha256()  # the copy hashes like the package
    assert hashes["metrics.py"] != hashes["as is"] and hashes["a figure"] == hashes["metrics.py"]
    store = Store(tmp_path / "store")
    first = run_study(rcm, cfg, config_name="s", store=store, jobs=1, quiet=True)
    assert first.run.key == key and first.run.manifest["code_sha256"] == C.code_sha256()
    assert "git_commit" in first.run.manifest
    monkeypatch.setattr(C, "code_sha256", lambda: hashes["metrics.py"])
    again = run_study(rcm, cfg, config_name="s", store=store, jobs=1, quiet=True)
    assert not again.cache_hit and again.run.key != key


def test_a_part_written_without_a_column_the_study_now_has_is_said_not_read_as_nulls(tmp_path, small_cfg):
    """A run stored by an earlier surgopt, before a column was added: read with the study's schema of today the
    column would be nulls (pyarrow fills missing fields); the store says which column is missing instead."""
    import pyarrow as pa
    import pytest

    from surgopt.errors import StoreError
    from surgopt.studies import get_study

    store = tmp_path / "store"
    cli("rcm-grid", small_cfg, "--store", store, "--quiet")
    run = single_run(store)
    schema = get_study("rcm-grid").schema_for(run.manifest["config"])
    run.part_table(0, schema)  # the schema it was written with reads
    newer = schema.append(pa.field("added_later_m", pa.float64()))
    with pytest.raises(StoreError, match="without the column 'added_later_m'; run the study again"):
        run.part_table(0, newer)
    assert run.part_table(0, newer, ["gii"]).num_rows > 0  # columns it has still read


def test_of_two_runs_created_within_one_second_the_latest_is_the_one_written_last(tmp_path):
    """`latest` took the last of the runs sorted by their creation time, written to the second: two runs of one
    second (a script's, in-process tests') came in the order the folders were listed. The manifest written last
    now decides; both orders are tried, so the folders' listing order cannot be what passes it."""
    import json
    import os

    from conftest import RCM_SMALL
    from surgopt.results import resolve_run
    from surgopt.store import Store, manifest_of

    cfg = tmp_path / "c.toml"
    cfg.write_text(RCM_SMALL)
    for extra in ([], ["candidates.grid.x_count=7"]):
        cli("rcm-grid", cfg, *extra, "--store", tmp_path / "s", "--quiet")
    store = Store(tmp_path / "s")
    runs = store.runs()
    paths = [manifest_of(r.path) for r in runs]
    for path in paths:  # one second for both
        doc = json.loads(path.read_text())
        doc["created"] = "2026-12-05T12:00:00+00:00"
        path.write_text(json.dumps(doc))
    for newer in (paths[0], paths[1]):
        older = paths[1] if newer == paths[0] else paths[0]
        os.utime(older, ns=(1_000_000_000_000_000_000, 1_000_000_000_000_000_000))
        os.utime(newer, ns=(1_000_000_000_500_000_000, 1_000_000_000_500_000_000))
        assert manifest_of(resolve_run(store, "latest")[1].path) == newer
