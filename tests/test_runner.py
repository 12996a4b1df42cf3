"""The runner (surgopt/runner.py): same rows on every backend, job count and chunk size; resume after
interrupts; automatic chunking."""
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from surgopt.config import load_config
from surgopt.errors import UsageError
from surgopt.runner import run_study
from surgopt.store import Store
from surgopt.studies import get_study

from conftest import RCM_SLOW, cli, single_run, single_table, slowed, wait_for_parts

BASE = Path(__file__).parent / "baselines"
CONFIGS = {"rcm-grid": "rcm_small", "raven-sweep": "raven_small", "suture-sim": "suture_small"}


def _run(tmp_path, name, tag, **kw):
    study = get_study(name)
    cfg = load_config(BASE / f"{CONFIGS[name]}.toml", study.config_model)
    return run_study(study, cfg, config_name=tag, store=Store(tmp_path / tag), quiet=True, **kw).table


@pytest.mark.parametrize("name", sorted(CONFIGS))
def test_rows_independent_of_backend_jobs_and_chunk_size(tmp_path, name):
    a = _run(tmp_path, name, "j1", jobs=1, chunk=1)
    b = _run(tmp_path, name, "j2", jobs=2, chunk=7)  # threads, the default
    c = _run(tmp_path, name, "auto", jobs=2)
    d = _run(tmp_path, name, "loky", jobs=2, chunk=5, backend="loky")
    assert a.equals(b) and a.equals(c) and a.equals(d)


@pytest.fixture(scope="module")
def dask_cluster():
    distributed = pytest.importorskip("distributed", reason="dask[distributed] not installed (pip install 'surgopt[dask]')")
    cluster = distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None)
    yield cluster
    cluster.close()


@pytest.mark.parametrize("name", sorted(CONFIGS))
def test_dask_local_cluster_equals_threads(tmp_path, name, dask_cluster):
    threads = _run(tmp_path, name, "threads", jobs=2)
    dask = _run(tmp_path, name, "dask", jobs=2, backend="dask", scheduler=dask_cluster.scheduler_address, chunk=3)
    assert threads.equals(dask)


def test_three_psm_port_placement_on_dask_equals_threads_and_its_feasible_rows(tmp_path, dask_cluster):
    """port-place's 3-PSM + ECM enumeration (issue #29) with the Classic cart on a grid of floor poses (issue 40)
    at reduced size (18 sites: 36,720 designs) on a local Dask cluster, chunk by chunk, gives the threads' rows
    (each worker solves the setup joints itself); storing only the feasible rows stores exactly those of the full
    table (the premises: some are feasible, most are not, and some fail on docking alone); two PSMs with the arms'
    links in feasible (the default) likewise, each worker building the link tables itself."""
    study = get_study("port-place")
    small = {"patient": {"port_region": {"site_spacing_mm": 50.0}}, "target": {"spacing_mm": 15.0},
             "robot": {"instrument_count": 3}, "constraints": {"min_link_clearance_mm": "off"},  # docking alone:
             "cart": {"model": "classic", "around_step_deg": 30.0, "distance_step_mm": 300.0}}  # with the links
    cfg = study.config_model.model_validate(small)  # no 3-PSM layout of this size clears (test_link_tables)

    def run(tag, cfg, **kw):
        return run_study(study, cfg, config_name=tag, store=Store(tmp_path / tag), quiet=True, **kw).table

    threads = run("threads", cfg, jobs=2, chunk=4_000)  # the same chunks: the parts, and so the rows, in one order
    dask = run("dask", cfg, jobs=2, backend="dask", scheduler=dask_cluster.scheduler_address, chunk=4_000)
    # pandas' equals: NaN (an undocked layout's cart columns) equals NaN at the same place; pyarrow's does not
    assert threads.num_rows == 36_720 and threads.to_pandas().equals(dask.to_pandas())
    feasible = run("feasible", study.config_model.model_validate({**small, "rows_stored": "feasible"}), jobs=2,
                   chunk=4_000)
    expected = threads.filter(threads["feasible"])
    assert 0 < expected.num_rows < threads.num_rows // 2
    assert (threads["infeasible"].to_numpy() == 128).any() and (threads["cart_pose"].to_numpy() > 0).any()
    assert feasible.select(expected.column_names).to_pandas().equals(expected.to_pandas())
    # two PSMs with the arms' links in feasible (the default's 0 mm): each worker builds the link tables itself
    links = study.config_model.model_validate({**small, "robot": {"instrument_count": 2, "docking_roll_deg": -45.0},
                                               "constraints": {},  # at roll 0 none keeps its links clear
                                               "bedside": {"arms": "none"},  # out on boards they leave none
                                               "patient": {"port_region": {"site_spacing_mm": 36.0}}})
    threads = run("links-threads", links, jobs=2, chunk=20_000)
    dask = run("links-dask", links, jobs=2, backend="dask", scheduler=dask_cluster.scheduler_address, chunk=20_000)
    bad = threads["infeasible"].to_numpy()
    assert (bad == 0).any() and (bad == 16).any()  # the premise: some clear, some fail on their links alone
    assert threads.to_pandas().equals(dask.to_pandas())


def test_cli_dask_backend_with_its_own_local_cluster(tmp_path):
    pytest.importorskip("distributed", reason="dask[distributed] not installed")
    r = subprocess.run([sys.executable, "-m", "surgopt", "suture-sim", str(BASE / "suture_small.toml"), "--store",
                        str(tmp_path / "s"), "--backend", "dask", "--jobs", "2", "--quiet"],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    (run,) = Store(tmp_path / "s").runs()
    assert run.read_table(get_study("suture-sim").schema()).equals(_run(tmp_path, "suture-sim", "ref", jobs=1))


def test_dask_backend_without_distributed_says_how_to_install(tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "distributed", None)  # import distributed -> ImportError
    with pytest.raises(UsageError, match=r"pip install 'surgopt\[dask\]'"):
        _run(tmp_path, "rcm-grid", "x", backend="dask")
    with pytest.raises(UsageError, match="--backend"):
        _run(tmp_path, "rcm-grid", "y", backend="spark")


def test_cli_unknown_backend_exits_2(tmp_path):
    r = subprocess.run([sys.executable, "-m", "surgopt", "rcm-grid", str(BASE / "rcm_small.toml"), "--store",
                        str(tmp_path / "s"), "--backend", "spark"], capture_output=True, text=True)
    assert r.returncode == 2 and "--backend" in r.stderr
    assert not (tmp_path / "s").exists()


def test_auto_chunk_aims_at_seconds_and_enough_tasks():
    from surgopt.config import load_embedded

    for name in ("rcm-grid", "raven-sweep"):
        study = get_study(name)
        cfg = load_embedded(study.default_config, study.config_model)
        chunk = study.auto_chunk(cfg)
        assert study.n_tasks(cfg, chunk) >= 32
    raven = get_study("raven-sweep")
    cfg = load_embedded(raven.default_config, raven.config_model)
    # Table II: 2000 geometries, ~0.02 s each -> ~50 per task
    assert 10 <= raven.auto_chunk(cfg) <= 250


@pytest.mark.parametrize("how", ["SIGKILL", "SIGINT"])
def test_interrupted_run_resumes_to_the_same_table(tmp_path, how):
    cfg = tmp_path / "slow.toml"
    cfg.write_text(RCM_SLOW)
    store = tmp_path / "store"
    jobs = "1" if how == "SIGKILL" else "2"
    proc = subprocess.Popen(slowed("rcm-grid", cfg, "--store", store, "--quiet", "--jobs", jobs, "--chunk-size", "40"),
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    wait_for_parts(store, "rcm-grid", 2, proc)  # stopped while the third chunk spins
    proc.send_signal(getattr(signal, how))
    _, err = proc.communicate(timeout=60)
    if how == "SIGINT":
        assert proc.returncode == 130, err
        assert "resume" in err
    else:
        assert proc.returncode == -signal.SIGKILL
    run = single_run(store)
    assert not run.complete
    done = len(run.manifest["parts"])
    assert 2 <= done < run.manifest["n_tasks"]
    r = cli("rcm-grid", cfg, "--store", store, "--quiet", "--jobs", "2")
    assert f"resuming: {done} of {run.manifest['n_tasks']} chunks already stored" in r.stdout
    resumed = single_table(store)
    fresh_store = tmp_path / "fresh"
    cli("rcm-grid", cfg, "--store", fresh_store, "--quiet", "--chunk-size", "40")
    assert resumed.equals(single_table(fresh_store))
    assert not list(store.glob("study=rcm-grid/key=*/.*.tmp-*"))


def test_compile_lock_serialises_processes(tmp_path, monkeypatch):
    """The numba cache's compile lock: held by one process, another's acquisition waits (here: times out)."""
    import time

    from surgopt.jit import compile_lock

    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path / "nc"))
    with compile_lock():
        assert (tmp_path / "nc" / ".surgopt-compile.lock").exists()
        t = time.perf_counter()
        code = ("import sys; from filelock import FileLock, Timeout\n"
                f"l = FileLock({str(tmp_path / 'nc' / '.surgopt-compile.lock')!r})\n"
                "try:\n    l.acquire(timeout=0.3); sys.exit(0)\nexcept Timeout:\n    sys.exit(3)\n")
        r = subprocess.run([sys.executable, "-c", code])
        assert r.returncode == 3 and time.perf_counter() - t >= 0.3
    r = subprocess.run([sys.executable, "-c", code])
    assert r.returncode == 0
    with compile_lock(timeout_s=0.1):  # and it is released again
        pass


HOLD_UNTIL = """
import os, sys, time
from filelock import FileLock
lock, release = FileLock(sys.argv[1]), sys.argv[2]
with lock:
    open(release + ".held", "w").close()
    while not os.path.exists(release):
        time.sleep(0.01)
"""


@pytest.mark.parametrize("quiet_s, announced", [(60.0, False), (0.05, True)])
def test_a_wait_on_the_compile_lock_is_announced_only_when_it_lasts(tmp_path, monkeypatch, quiet_s, announced):
    """Another process holds the lock (as one that only loads cached kernels does, for a moment): a wait shorter
    than QUIET_WAIT_S is not announced, a longer one is, once. The holder lets go when told: at once for the
    short wait (60 s to spare), only once the wait was announced for the long one (so it cannot pass unseen)."""
    import threading
    import time

    from surgopt import jit

    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path / "nc"))
    monkeypatch.setattr(jit, "QUIET_WAIT_S", quiet_s)
    (tmp_path / "nc").mkdir()
    release = tmp_path / "release"
    holder = subprocess.Popen([sys.executable, "-c", HOLD_UNTIL, str(tmp_path / "nc" / ".surgopt-compile.lock"),
                               str(release)])
    try:
        while not (tmp_path / "release.held").exists():
            time.sleep(0.01)
        said = []

        def on_wait(holder):
            said.append(holder)
            release.touch()

        if not announced:
            threading.Timer(0.2, release.touch).start()
        with jit.compile_lock(on_wait=on_wait):
            pass
        assert said == (["another surgopt process"] if announced else [])  # the holder wrote no name
    finally:
        release.touch()
        holder.wait(timeout=60)


def test_the_slurm_recipe_writes_one_single_threaded_worker_per_job_with_the_shared_cache():
    """docs/slurm_cluster.py (README, "Running on a cluster"): the job script dask-jobqueue generates asks SLURM
    for one CPU and the memory given, exports the shared numba cache, and starts one worker with one thread on
    this Python, pointed at the cluster's scheduler. Nothing is submitted (the cluster is never scaled)."""
    import importlib.util

    pytest.importorskip("dask_jobqueue", reason="dask-jobqueue not installed (pip install 'surgopt[dask]')")
    spec = importlib.util.spec_from_file_location("slurm_cluster", Path(__file__).parents[1] / "docs" /
                                                  "slurm_cluster.py")
    recipe = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(recipe)
    cluster = recipe.slurm_cluster(6.0, "02:30:00", account="mylab", partition="normal", cache_dir="/shared/numba")
    try:
        script = cluster.job_script()
        lines = script.splitlines()
        for directive in ("#SBATCH -J surgopt-worker", "#SBATCH -A mylab", "#SBATCH -p normal", "#SBATCH -n 1",
                          "#SBATCH --cpus-per-task=1", "#SBATCH --mem=6G", "#SBATCH -t 02:30:00"):
            assert directive in lines, script
        assert "export NUMBA_CACHE_DIR=/shared/numba" in lines
        (worker,) = [line for line in lines if "distributed.cli.dask_worker" in line]
        assert worker.startswith(sys.executable) and cluster.scheduler_address in worker
        assert " --nthreads 1 " in worker + " " and not cluster.workers  # no job submitted
    finally:
        cluster.close()


HOLD_AND_NAME = """
import os, sys, time
from filelock import FileLock
folder, release = sys.argv[1], sys.argv[2]
with FileLock(os.path.join(folder, ".surgopt-compile.lock")):
    open(os.path.join(folder, ".surgopt-compile.holder"), "w").write(f"pid {os.getpid()} (surgopt port-place)")
    open(release + ".held", "w").close()
    while not os.path.exists(release):
        time.sleep(0.01)
"""


def test_the_compile_lock_is_held_only_while_numba_compiles_and_a_waiter_names_the_holder(tmp_path, monkeypatch):
    """#56 item 6: the numba cache's lock was held through a study's whole warm-up (port-place's tables built,
    minutes), so unrelated runs queued ("waiting for another surgopt process compiling kernels", no pid). Inside
    ``jit.while_compiling`` a call that compiles nothing (the kernel already built) runs while another process
    holds the lock, and a call that compiles waits for it, saying who holds it."""
    import time

    import numba

    from surgopt import jit

    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path / "nc"))
    monkeypatch.setattr(jit, "QUIET_WAIT_S", 0.05)
    (tmp_path / "nc").mkdir()
    built = numba.njit(lambda x: x * 2)
    assert built(2) == 4  # compiled now, before the lock is taken by the other process
    release = tmp_path / "release"
    holder = subprocess.Popen([sys.executable, "-c", HOLD_AND_NAME, str(tmp_path / "nc"), str(release)])
    try:
        while not (tmp_path / "release.held").exists():
            time.sleep(0.01)
        said, compiles = [], []
        with jit.while_compiling(on_wait=lambda who: (said.append(who), release.touch()),
                                 on_compile=lambda: compiles.append(1)):
            assert built(3) == 6
            assert said == [] and compiles == []  # no compile: no lock asked for, no wait
            assert not release.exists()  # the other process still holds it
            fresh = numba.njit(lambda x: x + 1)
            assert fresh(1) == 2  # compiles: waits until the holder lets go (told to when the wait is said)
        assert compiles == [1] and said == [f"pid {holder.pid} (surgopt port-place)"]
    finally:
        release.touch()
        holder.wait(timeout=60)
