"""The result store (surgopt/store.py): corrupt parts, locking between processes."""
import subprocess
import sys

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
    cfg.write_text(RCM_SLOW)
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
    run = single_run(store)
    assert run.complete
    for f, meta in zip(run.part_files(), [run.manifest["parts"][k] for k in sorted(run.manifest["parts"], key=int)]):
        assert pq.read_metadata(f).num_rows == meta["rows"]
