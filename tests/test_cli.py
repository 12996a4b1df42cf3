"""The command line (surgopt/cli.py): stored tables equal library calls, cache hits, the store from the
environment, study flags, --help."""
import os
import subprocess
import sys
import time

import numpy as np

from surgopt.config import load_config
from surgopt.runner import run_study
from surgopt.store import Store
from surgopt.studies import rcm_grid as S

from conftest import cli, single_run, single_table


def test_cli_stores_table_equal_to_library_call(tmp_path, small_cfg):
    store = tmp_path / "store"
    r = cli("rcm-grid", small_cfg, "--store", store, "--quiet", "--chunk-size", "7")
    assert "best_gii" in r.stdout
    cli_table = single_table(store)
    cfg = load_config(small_cfg, S.Config)
    lib = run_study(S.STUDY, cfg, config_name="x", store=Store(tmp_path / "lib"), jobs=1, quiet=True, chunk=1000)
    assert cli_table.equals(lib.table)
    # parts are plain Parquet: pandas reads them without surgopt
    import pandas as pd

    df = pd.concat([pd.read_parquet(f) for f in single_run(store).part_files()], ignore_index=True)
    assert np.array_equal(df["gii"].to_numpy(), cli_table["gii"].to_numpy())
    assert df["candidate_id"].dtype == np.int64 and df["feasible"].dtype == bool


def test_cache_hit_is_fast_and_says_so(tmp_path, small_cfg):
    store = tmp_path / "store"
    cli("rcm-grid", small_cfg, "--store", store, "--quiet")
    mtimes = {f: f.stat().st_mtime_ns for f in single_run(store).part_files()}
    t = time.perf_counter()
    r = cli("rcm-grid", small_cfg, "--store", store, "--quiet")
    assert time.perf_counter() - t < 5  # interpreter start + pyarrow read, no compute
    assert "cache hit" in r.stdout
    assert {f: f.stat().st_mtime_ns for f in single_run(store).part_files()} == mtimes
    # --force recomputes (parts rewritten), same rows
    before = single_table(store)
    r = cli("rcm-grid", small_cfg, "--store", store, "--quiet", "--force")
    assert "cache hit" not in r.stdout
    assert single_table(store).equals(before)
    assert any(f.stat().st_mtime_ns != m for f, m in mtimes.items())


def test_store_from_environment(tmp_path, small_cfg):
    env = dict(os.environ, SURGOPT_STORE=str(tmp_path / "envstore"))
    cli("rcm-grid", small_cfg, "--quiet", env=env)
    assert len(Store(tmp_path / "envstore").runs()) == 1
    r = cli("runs", env=env)
    assert "rcm-grid" in r.stdout and "complete" in r.stdout and "small" in r.stdout


def test_cull_flag_is_a_separate_cached_study(tmp_path, small_cfg):
    store = tmp_path / "store"
    cli("rcm-grid", small_cfg, "--store", store, "--quiet")
    r = cli("rcm-grid", small_cfg, "--store", store, "--quiet", "--cull")
    assert "cache hit" not in r.stdout
    runs = Store(store).runs()
    assert len(runs) == 2
    full, cull = sorted(runs, key=lambda r: r.manifest["config"]["search"] == "cull")
    a, b = full.read_table(S.schema()), cull.read_table(S.schema())
    ga, gb = a["gii"].to_numpy(), b["gii"].to_numpy()
    assert ga.max() == gb[b["gii_is_exact"].to_numpy()].max()


def test_help_is_fast_and_imports_nothing_heavy():
    """The commands are built from the studies' declarations (their pydantic config models and numpy
    helpers: ~0.1 s to import), but no kernel, Arrow, pandas or matplotlib is loaded for --help."""
    code = ("import sys, surgopt.cli; "
            "print(sorted(m for m in ('numba', 'llvmlite', 'pyarrow', 'pandas', 'matplotlib') if m in sys.modules))")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert r.stdout.strip() == "[]"
    for args in (["--help"], ["rcm-grid", "--help"], ["runs", "--help"]):
        r = cli(*args)
        assert "Usage" in r.stdout
    assert "Global Isotropy Index" in cli("rcm-grid", "--help").stdout
