"""Store and CLI end to end: cache hit, real interruption and resume, force, lock, parity."""
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pyarrow.parquet as pq
import pytest

from surgopt.config import load_config
from surgopt.runner import run_study
from surgopt.store import Store
from surgopt.studies import rcm_grid as S

from conftest import wait_for_parts

SMALL = """
[workspace]
points_per_side = 5
[candidates.grid]
x_min_m = 0.3
x_max_m = 0.7
x_count = 9
z_min_m = -0.5
z_max_m = 0.0
z_count = 6
"""
# ~3 s of single-core work in 124 chunks: long enough to interrupt for real
SLOW = """
[candidates.grid]
x_min_m = 0.2
x_max_m = 0.8
x_count = 121
z_min_m = -0.4
z_max_m = 0.0
z_count = 41
"""


def cli(*args, check=True, **kw):
    r = subprocess.run([sys.executable, "-m", "surgopt", *map(str, args)], capture_output=True, text=True, **kw)
    if check and r.returncode != 0:
        raise AssertionError(f"exit {r.returncode}\n{r.stdout}\n{r.stderr}")
    return r


def _single_run(store):
    runs = Store(store).runs()
    assert len(runs) == 1
    return runs[0]


def _table(store):
    return _single_run(store).read_table(S.schema())


@pytest.fixture
def small_cfg(tmp_path):
    p = tmp_path / "small.toml"
    p.write_text(SMALL)
    return p


def test_cli_stores_table_equal_to_library_call(tmp_path, small_cfg):
    store = tmp_path / "store"
    r = cli("rcm-grid", small_cfg, "--store", store, "--quiet", "--chunk-size", "7")
    assert "best_gii" in r.stdout
    cli_table = _table(store)
    cfg = load_config(small_cfg, S.Config)
    lib = run_study(S, cfg, config_name="x", store=Store(tmp_path / "lib"), jobs=1, quiet=True, chunk=1000)
    assert cli_table.equals(lib.table)
    # parts are plain Parquet: pandas reads them without surgopt
    import pandas as pd

    df = pd.concat([pd.read_parquet(f) for f in _single_run(store).part_files()], ignore_index=True)
    assert np.array_equal(df["gii"].to_numpy(), cli_table["gii"].to_numpy())
    assert df["candidate_id"].dtype == np.int64 and df["feasible"].dtype == bool


def test_cache_hit_is_fast_and_says_so(tmp_path, small_cfg):
    store = tmp_path / "store"
    cli("rcm-grid", small_cfg, "--store", store, "--quiet")
    mtimes = {f: f.stat().st_mtime_ns for f in _single_run(store).part_files()}
    t = time.perf_counter()
    r = cli("rcm-grid", small_cfg, "--store", store, "--quiet")
    assert time.perf_counter() - t < 5  # interpreter start + pyarrow read, no compute
    assert "cache hit" in r.stdout
    assert {f: f.stat().st_mtime_ns for f in _single_run(store).part_files()} == mtimes
    # --force recomputes (parts rewritten), same rows
    before = _table(store)
    r = cli("rcm-grid", small_cfg, "--store", store, "--quiet", "--force")
    assert "cache hit" not in r.stdout
    assert _table(store).equals(before)
    assert any(f.stat().st_mtime_ns != m for f, m in mtimes.items())


def test_store_from_environment(tmp_path, small_cfg):
    env = dict(os.environ, SURGOPT_STORE=str(tmp_path / "envstore"))
    cli("rcm-grid", small_cfg, "--quiet", env=env)
    assert len(Store(tmp_path / "envstore").runs()) == 1
    r = cli("runs", env=env)
    assert "rcm-grid" in r.stdout and "complete" in r.stdout and "small" in r.stdout


@pytest.mark.parametrize("how", ["SIGKILL", "SIGINT"])
def test_interrupted_run_resumes_to_the_same_table(tmp_path, how):
    cfg = tmp_path / "slow.toml"
    cfg.write_text(SLOW)
    store = tmp_path / "store"
    jobs = "1" if how == "SIGKILL" else "2"
    proc = subprocess.Popen([sys.executable, "-m", "surgopt", "rcm-grid", str(cfg), "--store", str(store),
                             "--quiet", "--jobs", jobs, "--chunk-size", "40"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    wait_for_parts(store, "rcm-grid", 3, proc)
    proc.send_signal(getattr(signal, how))
    _, err = proc.communicate(timeout=60)
    if how == "SIGINT":
        assert proc.returncode == 130, err
        assert "resume" in err
    else:
        assert proc.returncode == -signal.SIGKILL
    run = _single_run(store)
    assert not run.complete
    done = len(run.manifest["parts"])
    assert 3 <= done < run.manifest["n_tasks"]
    r = cli("rcm-grid", cfg, "--store", store, "--quiet", "--jobs", "2")
    assert f"resuming: {done} of {run.manifest['n_tasks']} chunks already stored" in r.stdout
    resumed = _table(store)
    fresh_store = tmp_path / "fresh"
    cli("rcm-grid", cfg, "--store", fresh_store, "--quiet", "--chunk-size", "40")
    assert resumed.equals(_table(fresh_store))
    assert not list(store.glob("rcm-grid/*/.*.tmp-*"))


def test_corrupt_part_is_recomputed(tmp_path, small_cfg):
    store = tmp_path / "store"
    cli("rcm-grid", small_cfg, "--store", store, "--quiet", "--chunk-size", "10")
    good = _table(store)
    part = _single_run(store).part_files()[1]
    part.write_bytes(b"garbage")
    r = cli("rcm-grid", small_cfg, "--store", store, "--quiet")
    assert "resuming" in r.stdout
    assert _table(store).equals(good)


def test_two_processes_on_one_key(tmp_path):
    cfg = tmp_path / "slow.toml"
    cfg.write_text(SLOW)
    store = tmp_path / "store"
    cmd = [sys.executable, "-m", "surgopt", "rcm-grid", str(cfg), "--store", str(store), "--quiet",
           "--jobs", "1", "--chunk-size", "40"]
    a = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    wait_for_parts(store, "rcm-grid", 1, a)
    b = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    out_a, err_a = a.communicate(timeout=120)
    out_b, err_b = b.communicate(timeout=120)
    assert a.returncode == 0 and b.returncode == 0, err_a + err_b
    assert "waiting for pid" in err_b
    run = _single_run(store)
    assert run.complete
    for f, meta in zip(run.part_files(), [run.manifest["parts"][k] for k in sorted(run.manifest["parts"], key=int)]):
        assert pq.read_metadata(f).num_rows == meta["rows"]


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
    code = ("import sys, surgopt.cli; "
            "print(sorted(m for m in ('numba', 'pyarrow', 'pandas', 'numpy', 'matplotlib') if m in sys.modules))")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert r.stdout.strip() == "[]"
    for args in (["--help"], ["rcm-grid", "--help"], ["runs", "--help"]):
        r = cli(*args)
        assert "Usage" in r.stdout
    assert "Global Isotropy Index" in cli("rcm-grid", "--help").stdout
