"""Worker processes under signals and memory (issue #30): a stop signal swallowed by a library callback still
stops the run; the memory budget counts every worker process; --jobs beyond the cores is capped; a run
under an address-space limit ends, in one line, instead of hanging. Bounded: small configs, timeouts."""
import os
import resource
import subprocess
import sys

import pytest

from surgopt.errors import UsageError
from surgopt.runner import check_budget, run_bytes, usable_jobs
from surgopt.studies import get_study

from conftest import RCM_SMALL, cli, fault_lines, single_run

SWALLOWED_SIGTERM = """
import gc, os, signal, sys
from surgopt import interrupts
interrupts.install()
fired = []
def callback(phase, info):  # what distributed's gc diagnosis does: a callback whose exceptions are ignored
    if not fired:
        fired.append(1)
        os.kill(os.getpid(), signal.SIGTERM)
gc.callbacks.append(callback)
gc.collect()
assert fired and interrupts.received() == signal.SIGTERM  # the premise: the handler ran inside the callback
sys.argv = ["surgopt", "rcm-grid", sys.argv[1], "--store", sys.argv[2], "--quiet"]
from surgopt.cli import run
run()
"""


def test_a_sigterm_swallowed_by_a_callback_still_stops_the_run(tmp_path):
    cfg = tmp_path / "small.toml"
    cfg.write_text(RCM_SMALL)
    r = subprocess.run([sys.executable, "-c", SWALLOWED_SIGTERM, str(cfg), str(tmp_path / "store")],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 143, (r.returncode, r.stderr)
    assert fault_lines(r.stderr) == ["surgopt: stopped by SIGTERM; finished chunks are stored, run the same "
                                             "command again to resume"]


def test_the_memory_budget_counts_every_worker_process():
    study = get_study("rcm-grid")
    cfg = study.config_model.model_validate({})
    est = study.estimate(cfg)
    threads, loky = run_bytes(est, "threads", 2), run_bytes(est, "loky", 2)
    assert threads == est.peak_bytes and loky > threads + 2 * 100 * 2 ** 20
    assert run_bytes(est, "dask", 2, scheduler="tcp://elsewhere:8786") == est.peak_bytes  # workers elsewhere
    budget = (threads + loky) // 2
    check_budget(study, cfg, 2, None, budget, backend="threads")
    with pytest.raises(UsageError, match="2 loky worker process"):
        check_budget(study, cfg, 2, None, budget, backend="loky")


def test_jobs_beyond_the_cores_are_capped_with_one_line(tmp_path):
    said = []
    cores = os.cpu_count() or 1
    assert usable_jobs(cores + 100, "loky", say=said.append) == cores and len(said) == 1
    assert usable_jobs(cores + 100, "dask", "tcp://elsewhere:8786", say=said.append) == cores + 100
    cfg = tmp_path / "small.toml"
    cfg.write_text(RCM_SMALL)
    r = cli("rcm-grid", cfg, "--store", tmp_path / "store", "--quiet", "--backend", "loky", "--jobs", "200")
    assert f"--jobs 200: this machine has {cores} core(s); running {cores}" in r.stderr
    assert single_run(tmp_path / "store").manifest["jobs"] == cores


def _limit_address_space(megabytes):
    def apply():
        resource.setrlimit(resource.RLIMIT_AS, (megabytes * 2 ** 20, megabytes * 2 ** 20))
    return apply


@pytest.mark.parametrize("megabytes", [860, 960])
def test_a_loky_run_under_an_address_space_limit_ends_in_one_line(tmp_path, megabytes):
    """Whether it fits depends on the machine's allocators and thread stacks: it must end (not hang), with
    exit 0, or exit 1 and one line that says how much is stored; and resume once the limit is gone.
    (At 760 MB the first Arrow allocation runs out inside Arrow's C++ allocator, which terminates the process in
    some runs (SIGABRT, not catchable from Python): a knife edge that depends on the machine. The one-line
    out-of-memory report is held deterministically by the test below.)"""
    cfg = tmp_path / "small.toml"
    cfg.write_text(RCM_SMALL)
    args = [sys.executable, "-m", "surgopt", "rcm-grid", str(cfg), "--store", str(tmp_path / "store"), "--quiet",
            "--backend", "loky"]
    r = subprocess.run(args, capture_output=True, text=True, timeout=240, preexec_fn=_limit_address_space(megabytes))
    assert r.returncode in (0, 1), (r.returncode, r.stderr[-2000:])
    if r.returncode == 1:
        lines = fault_lines(r.stderr)
        assert len(lines) == 1 and "out of memory" in lines[0] and "Traceback" not in r.stderr, r.stderr[-2000:]
    r = subprocess.run(args[:-2], capture_output=True, text=True, timeout=240)
    assert r.returncode == 0 and single_run(tmp_path / "store").complete


MAP_FAILED = ImportError("The pyarrow installation is not built with support for the Parquet file format (.../_parquet"
                         ".cpython-311-x86_64-linux-gnu.so: failed to map segment from shared object)")


@pytest.mark.parametrize("fault", [MemoryError(), MAP_FAILED], ids=["MemoryError", "import-map-failed"])
def test_running_out_of_memory_while_storing_is_one_line_saying_what_is_stored(tmp_path, monkeypatch, fault):
    """The out-of-memory report without an address-space limit: a MemoryError at the third part's write (where
    the limit hits the parent: Arrow's first table), or an import whose shared object cannot be mapped (what an
    address-space limit did to a lazy ``pyarrow.parquet`` import in one run), ends in OutOfMemory saying how many
    parts are stored, and the same command resumes to the whole table."""
    from conftest import RCM_SMALL

    from surgopt.config import load_config
    from surgopt.runner import OutOfMemory, run_study
    from surgopt.store import Store
    from surgopt.studies import get_study

    rcm = get_study("rcm-grid")
    (tmp_path / "small.toml").write_text(RCM_SMALL)
    cfg = load_config(tmp_path / "small.toml", rcm.config_model)
    real = Store.write_part

    def fail_third(self, run, index, table):
        if len(run.manifest["parts"]) == 2:
            raise fault
        return real(self, run, index, table)

    monkeypatch.setattr(Store, "write_part", fail_third)
    with pytest.raises(OutOfMemory, match=r"out of memory with 2 of \d+ parts stored; run the same command again"):
        run_study(rcm, cfg, config_name="s", store=Store(tmp_path / "s"), jobs=1, quiet=True)
    monkeypatch.undo()
    again = run_study(rcm, cfg, config_name="s", store=Store(tmp_path / "s"), jobs=1, quiet=True)
    assert again.run.complete and again.computed_tasks == again.run.manifest["n_tasks"] - 2


def test_only_an_import_that_cannot_map_its_library_counts_as_out_of_memory():
    from surgopt.errors import out_of_memory

    assert out_of_memory(MemoryError()) and out_of_memory(MAP_FAILED)
    assert not out_of_memory(ImportError("No module named 'pyarrow'")) and not out_of_memory(OSError("disk"))


SEARCH = """
[workspace]
points_per_side = 7
[search]
method = "tpe"
trials = 200
batch = 20
seed = 5
"""


@pytest.mark.parametrize("kind", ["study", "search"])
def test_sigint_at_random_instants_on_threads_is_one_line_and_resumes_identically(tmp_path, kind):
    """A bounded, seeded sample of docs/interrupt_trials.py (which runs 20 per backend and kind): Ctrl-C at a
    random instant of the run, from start-up to the closing report."""
    import random
    import signal
    import time

    from conftest import RCM_SLOW, single_table

    cfg = tmp_path / "c.toml"
    cfg.write_text(RCM_SLOW if kind == "study" else SEARCH)
    base = [sys.executable, "-m", "surgopt", "rcm-grid", str(cfg), "--quiet", "--store"]
    t0 = time.perf_counter()
    subprocess.run(base + [str(tmp_path / "ref")], check=True, capture_output=True, timeout=300)
    duration = time.perf_counter() - t0
    rng = random.Random(7)
    for trial in range(2):
        store = tmp_path / f"s{trial}"
        p = subprocess.Popen(base + [str(store)], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        time.sleep(rng.uniform(0, duration))
        p.send_signal(signal.SIGINT)
        err = p.communicate(timeout=300)[1]
        assert p.returncode in (0, 130), (p.returncode, err)
        if p.returncode == 130:  # what the line says depends on the instant: reading, storing, or stored
            from surgopt.interrupts import COMPLETE, RESUME, UNCHANGED

            assert fault_lines(err) in ([f"surgopt: interrupted; {h}"] for h in (RESUME, UNCHANGED, COMPLETE)) \
                or "nothing was run" in err, err
        subprocess.run(base + [str(store)], check=True, capture_output=True, timeout=300)
        assert single_table(store).equals(single_table(tmp_path / "ref"))


def test_a_stop_while_a_module_is_half_imported_is_still_one_line(tmp_path):
    """The handler silences logging without importing it: a SIGINT that lands while ``logging`` is being
    imported (found by the random series above: 'partially initialized module logging has no attribute
    disable', exit 1 with a traceback) still ends in the stop's one line and 130."""
    code = """
import os, signal, sys
from surgopt import interrupts
interrupts.install()
import types
half = types.ModuleType("logging")  # what sys.modules holds mid-import: no disable() yet
sys.modules["logging"] = half
try:
    os.kill(os.getpid(), signal.SIGINT)
    import time; time.sleep(1)
except KeyboardInterrupt as exc:
    sys.exit(interrupts.report(exc, "resume"))
"""
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert r.returncode == 130 and r.stderr.strip() == "surgopt: interrupted; resume", (r.returncode, r.stderr)


def test_a_stop_a_library_wraps_in_its_own_error_is_still_the_stop(tmp_path):
    """A SIGINT landing inside pydantic-core while it builds a validator comes out as a SchemaError, not a
    KeyboardInterrupt (found by the seeded random SIGINT test): whatever error a received stop causes is
    reported as the stop, one line and 130, wherever it surfaces (here: while the CLI loads its studies)."""
    code = """
import os, signal, sys, time
sys.argv = ["surgopt", "--help"]
import builtins
orig_import = builtins.__import__
fired = []
def wrapping_import(name, *a, **k):
    if name == "surgopt.cli" and not fired:
        fired.append(1)
        try:  # the stop arrives while this module loads, and a library turns it into its own error
            os.kill(os.getpid(), signal.SIGINT)
            time.sleep(1)
        except KeyboardInterrupt as exc:
            raise RuntimeError("Error building validator") from exc
    return orig_import(name, *a, **k)
builtins.__import__ = wrapping_import
from surgopt.__main__ import main
main()
"""
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert r.returncode == 130 and r.stderr.strip() == "surgopt: interrupted; nothing was run", (r.returncode,
                                                                                                r.stderr[-800:])
