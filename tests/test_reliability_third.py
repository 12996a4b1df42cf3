"""Reliability, third round (issue 43): memory limits end cleanly, manifests cannot lie, workers are quiet on a
stop, the last bad inputs are one line. Each test fails on the main this round started from (8fbe8ca). Bounded:
small runs, one dask cluster, no sleeps but the ones a signal needs."""
from __future__ import annotations

import json
import os
import resource
import signal
import subprocess
import sys
import time
import warnings

import numpy as np
import pytest

from surgopt.config import load_config
from surgopt.runner import OutOfMemory, run_study
from surgopt.store import Store
from surgopt.studies import get_study

from conftest import RCM_SLOW, RCM_SMALL, cli, fault_lines, invoke, single_run, single_table

RCM = get_study("rcm-grid")


def _cfg(tmp_path, text=RCM_SMALL, name="small.toml"):
    path = tmp_path / name
    path.write_text(text)
    return path


# --- 1. memory limits ------------------------------------------------------------------------------------------

def test_an_address_space_limit_below_the_runs_need_is_one_line_before_anything_runs(tmp_path):
    """Under ``ulimit -v`` 700 MB a run spun for minutes holding the compile lock, aborted (134) or said a library
    "could not be loaded". It is refused before the store or the lock is touched, in one line naming the limit."""
    from filelock import FileLock

    from surgopt.jit import numba_cache_dir

    limit = 700 * 2 ** 20

    def cap():
        resource.setrlimit(resource.RLIMIT_AS, (limit, limit))

    store = tmp_path / "store"
    r = subprocess.run([sys.executable, "-m", "surgopt", "rcm-grid", "--store", str(store), "--quiet"],
                       capture_output=True, text=True, timeout=120, preexec_fn=cap)
    err = "\n".join(line for line in r.stderr.splitlines() if not line.startswith("OpenBLAS"))
    assert r.returncode == 1, r.stderr
    assert len(fault_lines(err)) == 1 and "ulimit -v" in err and "700 MB" in err, err
    assert not list(store.rglob("*.parquet"))
    lock = FileLock(str(numba_cache_dir() / ".surgopt-compile.lock"))
    lock.acquire(timeout=5)  # not left held
    lock.release()


def test_out_of_memory_after_every_part_is_stored_says_the_run_is_complete(tmp_path, monkeypatch):
    """Under 800 MB every part was stored and the run then ended "out of memory": the run is complete, and the
    line says so instead of asking for a resume."""
    store = Store(tmp_path / "s")
    real = Store.write_part

    def write_then_fail(self, run, index, table):
        real(self, run, index, table)
        if run.complete:
            raise MemoryError

    monkeypatch.setattr(Store, "write_part", write_then_fail)
    cfg = load_config(_cfg(tmp_path), RCM.config_model)
    with pytest.raises(OutOfMemory, match="after all .* parts were stored: the run is complete"):
        run_study(RCM, cfg, config_name="small", store=store, jobs=1, quiet=True, say=lambda m: None)
    (run,) = store.runs()
    assert run.complete


def test_a_thread_that_cannot_start_and_enomem_are_out_of_memory():
    import errno

    from surgopt.errors import out_of_memory

    assert out_of_memory(RuntimeError("can't start new thread"))
    assert out_of_memory(OSError(errno.ENOMEM, "Cannot allocate memory"))
    assert not out_of_memory(RuntimeError("something else")) and not out_of_memory(OSError(errno.ENOENT, "x"))


# --- 2. a manifest that contradicts its parts --------------------------------------------------------------------

def test_a_manifest_row_count_that_is_not_the_parts_is_damage(tmp_path):
    """A part's row count edited in manifest.json: `runs`, `summarize` and a cache hit said 1,900 rows while
    `export` wrote 900. The count is checked against the part's Parquet footer."""
    cfg = _cfg(tmp_path)
    store = tmp_path / "store"
    cli("rcm-grid", cfg, "--store", store, "--quiet")
    run = single_run(store)
    ref = single_table(store)
    manifest = json.loads((run.path / "_manifest.json").read_text())
    first = sorted(manifest["parts"], key=int)[0]
    manifest["parts"][first]["rows"] += 1000
    (run.path / "_manifest.json").write_text(json.dumps(manifest))
    assert Store(store).runs()[0].damaged()  # the premise: only the manifest was changed, and it is caught
    r = cli("summarize", run.key[:12], "--store", store, check=False)
    assert r.returncode != 0 and "rows where the manifest says" in r.stderr, r.stderr
    r = cli("rcm-grid", cfg, "--store", store, "--quiet")  # not a cache hit: the damaged part is recomputed
    assert "cache hit" not in r.stdout and "damaged" in r.stderr
    assert single_run(store).rows == ref.num_rows and single_table(store).equals(ref)


def test_a_partial_run_whose_task_count_was_edited_is_not_a_cache_hit(tmp_path):
    cfg = _cfg(tmp_path)
    store = tmp_path / "store"
    cli("rcm-grid", cfg, "--store", store, "--quiet", "--chunk-size", "5")
    run = single_run(store)
    ref = single_table(store)
    manifest = json.loads((run.path / "_manifest.json").read_text())
    for k in sorted(manifest["parts"], key=int)[3:]:
        (run.path / manifest["parts"].pop(k)["file"]).unlink()
    manifest["n_tasks"] = len(manifest["parts"])  # claims to be complete
    (run.path / "_manifest.json").write_text(json.dumps(manifest))
    assert Store(store).runs()[0].complete  # the premise: the edit makes it look complete
    r = cli("rcm-grid", cfg, "--store", store, "--quiet")
    assert "cache hit" not in r.stdout and "tasks where the config and its chunk size" in r.stderr, r.stderr
    assert single_table(store).equals(ref)


# --- 3. worker noise on a stop ----------------------------------------------------------------------------------

@pytest.mark.parametrize("backend", ["loky", "dask"])
def test_a_ctrl_c_to_the_process_group_is_one_line_on_process_backends(tmp_path, backend):
    """A terminal's Ctrl-C reaches every process of the group: dask's workers and nannies printed ~67 lines of
    KeyboardInterrupt tracebacks. They ignore it now; the parent says the one line and ends them."""
    if backend == "dask":
        pytest.importorskip("distributed")
    from conftest import wait_for_parts

    cfg = _cfg(tmp_path, RCM_SLOW, "slow.toml")
    store = tmp_path / "store"
    p = subprocess.Popen([sys.executable, "-m", "surgopt", "rcm-grid", str(cfg), "--store", str(store), "--quiet",
                          "--chunk-size", "10", "--backend", backend], stdout=subprocess.DEVNULL,
                         stderr=subprocess.PIPE, text=True, start_new_session=True)
    try:
        wait_for_parts(store, "rcm-grid", 3, p)  # workers running
    except AssertionError:
        p.kill()
        raise
    os.killpg(p.pid, signal.SIGINT)
    err = p.communicate(timeout=60)[1]
    assert p.returncode == 130, err
    assert fault_lines(err) == ["surgopt: interrupted; finished chunks are stored, run the same command again to "
                                "resume"], err


# --- 4. the last tracebacks on bad input -----------------------------------------------------------------------

def test_a_yaml_key_that_is_a_list_is_one_line(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text("? [a, b]\n: 1\n")
    code, out = invoke("rcm-grid", str(bad), "--store", str(tmp_path / "s"))
    assert code == 2 and "a key must be a name, not a list" in out and "Traceback" not in out, out


@pytest.mark.parametrize("flag", ["--max-memory-gb", "--max-hours"])
@pytest.mark.parametrize("value", ["inf", "1e400", "-0.0", "0", "nan"])
def test_a_budget_must_be_positive_and_finite(tmp_path, flag, value):
    code, out = invoke("rcm-grid", flag, value, "--dry-run", "--store", str(tmp_path / "s"))
    assert code == 2 and "is not a budget" in out and "Traceback" not in out, out


# --- 5. misleading refusals -------------------------------------------------------------------------------------

def _closed_box(path, change=None):
    """A closed 200 x 200 x 100 mm box on z = 0, written as ``path`` (OBJ: text, so 1e300 and NaN stay as they are)
    after ``change(vertices, faces)``."""
    import trimesh

    box = trimesh.creation.box(extents=[200.0, 200.0, 100.0])
    box.apply_translation([0, 0, 50.0])
    v, f = np.array(box.vertices), np.array(box.faces)
    if change is not None:
        v, f = change(v, f)
    with warnings.catch_warnings(), np.errstate(all="ignore"):
        warnings.simplefilter("ignore")
        trimesh.Trimesh(v, f, process=False).export(path)
    return path


def _nan_vertex(v, f):
    v[0] = np.nan
    return v, f


def _far_vertex(v, f):
    v[0] = 1e300
    return v, f


def _zero_area(v, f):
    # a sliver: one extra triangle whose three corners are on a line, glued in by splitting an edge's face
    a, b = f[0][0], f[0][1]
    mid = len(v)
    v = np.vstack([v, (v[a] + v[b]) / 2])
    f = np.vstack([f, [[a, mid, b]]])
    return v, f


MESHES = {"a NaN vertex": (_nan_vertex, "not finite"), "a vertex at 1e300": (_far_vertex, "from the origin"),
          "a zero-area triangle": (_zero_area, "zero area")}


@pytest.mark.parametrize("case", sorted(MESHES))
def test_a_bad_mesh_is_named_for_what_is_wrong_with_it(tmp_path, case):
    from surgopt.config import validate
    from surgopt.errors import ConfigError

    change, words = MESHES[case]
    _closed_box(tmp_path / "body.obj", change)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no numpy RuntimeWarning before the refusal
        with pytest.raises(ConfigError) as e:
            validate({"patient": {"shape": "mesh", "mesh_file": "body.obj"}}, get_study("port-place").config_model,
                     "c.toml", {"config_dir": str(tmp_path)})
    assert words in str(e.value) and "watertight" not in str(e.value), str(e.value)


def test_a_self_intersecting_port_region_encloses_its_lobes(tmp_path):
    """A figure eight's signed area is 0, but under the even-odd rule (the docs' promise) its two lobes are
    inside: it is accepted and its sites lie in the lobes."""
    from surgopt.config import validate
    from surgopt.studies.port_place.geometry import inside_polygon, polygon_area_mm2

    eight = [[-120.0, -120.0], [120.0, 120.0], [120.0, -120.0], [-120.0, 120.0]]
    assert polygon_area_mm2(np.array(eight)) == 0.0  # the premise
    study = get_study("port-place")
    cfg = validate({"patient": {"port_region": {"polygon_mm": eight}}}, study.config_model, "c.toml")
    from surgopt.studies.port_place.geometry import sites_mm

    sites = sites_mm(cfg)
    assert len(sites) > 0 and inside_polygon(sites[:, 0], sites[:, 1], np.array(eight)).all()


# --- 6. smaller ----------------------------------------------------------------------------------------------

def test_a_repeated_override_is_refused(tmp_path):
    code, out = invoke("rcm-grid", "robot.tool_length_m=0.5", "robot.tool_length_m=0.6", "--dry-run", "--store",
                       str(tmp_path / "s"))
    assert code == 2 and "robot.tool_length_m is given twice (0.5 and 0.6)" in out, out


def test_a_config_file_named_with_an_equals_sign_is_the_config(tmp_path):
    path = _cfg(tmp_path, RCM_SMALL, "my=cfg.toml")
    code, out = invoke("rcm-grid", str(path), "--store", str(tmp_path / "s"), "--quiet")
    assert code == 0, out
    assert single_run(tmp_path / "s").manifest["config_name"] == "my=cfg"


def test_the_manifest_is_not_rewritten_for_every_part(tmp_path, monkeypatch):
    """3,000 one-candidate parts took 47x the time of one part: the manifest (growing with the parts) was
    rewritten after each. It is written at most every MANIFEST_EVERY_S while parts come, and at once at the end."""
    import pyarrow as pa

    import surgopt.store as S

    writes = []
    real = S.Store._write_manifest
    monkeypatch.setattr(S.Store, "_write_manifest", lambda self, run: (writes.append(1), real(self, run)))
    store = S.Store(tmp_path / "s")
    run = store.begin("toy", "a" * 64, config={}, config_name="t", kernel_version="1", n_tasks=200, chunk=1,
                      force=False, fresh=True)
    writes.clear()
    t0 = time.monotonic()
    for i in range(200):
        store.write_part(run, i, pa.table({"i": [i]}))
    elapsed = time.monotonic() - t0
    assert len(writes) <= 2 + elapsed / S.MANIFEST_EVERY_S  # at most one a second, and the last part's
    assert store.open("toy", "a" * 64).complete  # every part listed once the last is stored


def test_port_place_memory_estimate_is_above_its_measured_peak(tmp_path):
    """The estimate was 1.26-1.36x below the measured peak: on the wrong side of a budget. Memory, not time: the
    resident peak of a run with every part of the default's model (the cart, its setup joints and the links'
    tables) on a 24 mm grid of sites (the default itself, 741 MB against 982 MB: docs/performance.md), the
    child's own ru_maxrss from wait4, against the estimate the budget is held to. Measured on the second of two
    runs of that same config: the first compiles (or loads) every kernel it calls, whose LLVM memory a cold cache
    adds to the first run's peak (a coarser warm-up left some uncompiled: 867 MB against 739 MB once in CI)."""
    study = get_study("port-place")
    from surgopt.compose import variants

    grid = "patient.port_region.site_spacing_mm=30"
    (v,) = variants(study, None, [grid])
    assert v.config.cart.model != "none" and v.config.constraints.link_least_mm is not None  # the premise
    est = study.estimate(v.config).peak_bytes
    # every kernel the measured run calls, compiled into (or loaded from) the cache by the same command in a process
    # of its own (a run in this process had not compiled some of them: 692 MB against 677 MB once, a fresh clone)
    cli("port-place", grid, "--store", tmp_path / "w", "--quiet", process=True)
    p = subprocess.Popen([sys.executable, "-m", "surgopt", "port-place", grid, "--store", str(tmp_path / "s"),
                          "--quiet", "--force"], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    _, status, usage = os.wait4(p.pid, 0)
    assert os.waitstatus_to_exitcode(status) == 0
    peak = usage.ru_maxrss * 1024
    assert peak > 200 * 2 ** 20  # the premise: this is the study's process, not a wrapper
    assert est >= peak, (est / 2 ** 20, peak / 2 ** 20)


def test_a_run_removed_before_its_closing_report_is_a_note_not_damage(tmp_path, monkeypatch):
    """`runs rm` issued as a study finished made it exit 1 "damaged" (1 in 4): removed between its last part and
    the report's reading. The run did finish: a note, exit 0."""
    import shutil

    import surgopt.runner as R

    real = R.run_study

    def run_then_removed(*a, **kw):
        result = real(*a, **kw)
        shutil.rmtree(result.run.path)  # what `surgopt runs rm KEY` does once the study's lock is released
        return result

    monkeypatch.setattr(R, "run_study", run_then_removed)
    code, out = invoke("rcm-grid", str(_cfg(tmp_path)), "--store", str(tmp_path / "s"), "--quiet")
    assert code == 0, out
    assert "was removed (surgopt runs rm) before its report" in out and "damaged" not in out


def test_after_a_stop_loky_s_manager_thread_says_nothing_and_other_threads_still_do(monkeypatch, capsys):
    """loky's manager thread can trip on the work items a shutdown under a stop took from it (a KeyError seen once
    in CI after a Ctrl-C, its traceback beside the stop's one line): once the loky executor is shut down on an
    exception, that thread's exceptions are not shown; any other thread's still reach the hook before."""
    import threading

    from surgopt import backends

    seen = []  # the hook before (here a recorder; the default prints "Exception in thread ...")
    monkeypatch.setattr(threading, "excepthook", lambda args: seen.append((args.thread.name, args.exc_type)))
    backends._quiet_loky_manager()
    hook = threading.excepthook
    backends._quiet_loky_manager()  # twice (a retried run): one hook, not a chain of them
    assert threading.excepthook is hook

    def fail():
        raise KeyError(76)

    for name in (backends.LOKY_MANAGER_THREAD, "another thread"):
        t = threading.Thread(target=fail, name=name)
        t.start()
        t.join()
    assert seen == [("another thread", KeyError)]
