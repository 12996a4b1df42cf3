"""The result store (surgopt/store.py): corrupt parts, locking between processes."""
import subprocess
import sys

import pyarrow.parquet as pq
import pytest
from conftest import cli, wait_for_parts

from surgopt.store import Store
from surgopt.studies import rcm_grid as S

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
