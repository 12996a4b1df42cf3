import os
import sys
from pathlib import Path
from typing import NamedTuple

import pytest

HERE = Path(__file__).parent
sys.path.insert(0, str(HERE))  # tests/reference.py

REPO = HERE.parent

# pytest-xdist's workers run with COLUMNS=80 and LINES=24 in their environment (execnet sets them); a piped table
# honours a COLUMNS the user set (issue 56 item 8), so the tests run as a plain pipe does, without them; a test
# that means a width sets it
os.environ.pop("COLUMNS", None)
os.environ.pop("LINES", None)

# property tests: the same examples on every CI run (locally, new ones each run)
from hypothesis import settings as _hypothesis_settings  # noqa: E402

_hypothesis_settings.register_profile("ci", derandomize=True, print_blob=True)
if os.environ.get("CI"):
    _hypothesis_settings.load_profile("ci")

# the CLI's numba settings (8-wide vectors on AVX-512) before any test imports numba, so that tests and CLI
# subprocesses compile the same kernels into one cache: NUMBA_CACHE_DIR, set here to $NUMBA_CACHE_DIR or
# ~/.cache/surgopt/numba and shared by the pytest-xdist workers (a kernel is compiled once; a process that finds
# another compiling waits on the cache's lock and says so: COMPILE_NOTES below)
from surgopt.jit import configure_numba  # noqa: E402

configure_numba()


#: The notes a run prints while it compiles the kernels or waits for another process compiling them into the
#: shared cache (surgopt.runner._warm_up): under two test workers they can come before a fault's one line.
COMPILE_NOTES = ("waiting for ", "waited ", "compiling the ", "loading the ",
                 "kernels compiled", "kernels loaded")


def fault_lines(text: str) -> list[str]:
    """The lines of a run's output but its compile notes (``COMPILE_NOTES``): what a fault must say in one."""
    return [line for line in text.strip().splitlines() if not line.startswith(COMPILE_NOTES)]


#: A small rcm-grid config (54 candidates, 5^3 points): the store and CLI tests' workhorse.
RCM_SMALL = """
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
#: rcm-grid, ~3 s of single-core work in 124 chunks: long enough to interrupt for real
RCM_SLOW = """
[candidates.grid]
x_min_m = 0.2
x_max_m = 0.8
x_count = 121
z_min_m = -0.4
z_max_m = 0.0
z_count = 41
"""


@pytest.fixture
def small_cfg(tmp_path):
    """RCM_SMALL written to a file."""
    p = tmp_path / "small.toml"
    p.write_text(RCM_SMALL)
    return p


def single_run(store):
    """The one run in a store (fails if there are several)."""
    from surgopt.store import Store

    runs = Store(store).runs()
    assert len(runs) == 1
    return runs[0]


def single_table(store):
    """The table of the one run in a store, read with its study's schema."""
    from surgopt.studies import get_study

    run = single_run(store)
    return run.read_table(get_study(run.study).schema())


@pytest.fixture
def store_dir(tmp_path):
    return tmp_path / "store"


def slowed(*args, seconds=60):
    """The command line of ``surgopt ARGS`` whose third chunk spins ``seconds`` (tests/slow_cli.py): a stop or a
    kill after ``wait_for_parts(..., 2, ...)`` lands in that chunk whatever the machine's speed. A plain run of a
    test's small grid finished before the kill on a fast CI machine (the manifest is written every 0.25 s, and a
    whole run takes ~0.8 s)."""
    return [sys.executable, str(Path(__file__).parent / "slow_cli.py"), str(seconds), "chunk", *map(str, args)]


def wait_for_parts(store, study, n, proc, timeout=120):
    """Block until a run of ``study`` in ``store`` has n parts; fail if ``proc`` ends first."""
    import json
    import time

    t0 = time.time()
    while time.time() - t0 < timeout:
        for m in Path(store).glob(f"study={study}/key=*/_manifest.json"):
            try:
                if len(json.loads(m.read_text())["parts"]) >= n:
                    return
            except (OSError, ValueError):
                pass
        if proc.poll() is not None:
            raise AssertionError("finished before it could be interrupted")
        time.sleep(0.005)
    raise AssertionError("no parts appeared")


class Ran(NamedTuple):
    """What ``cli`` gives back: a finished ``subprocess.run``'s three fields."""

    returncode: int
    stdout: str
    stderr: str


def cli(*args, check=True, process=False, **kw):
    """``surgopt ARGS`` as a user types it; with ``check``, fail on a non-zero exit. In this process (Typer's
    runner: the exit code, standard output and standard error apart, ``cwd`` by a chdir) unless ``process`` or a
    subprocess's own keyword (``env``, ``timeout`` ...) asks for ``python -m surgopt`` in a process of its own:
    a process's start-up and kernel loading cost ~1 s a call, ~200 calls (the suite's time, issue 56)."""
    import subprocess

    if process or set(kw) - {"cwd"}:
        r = subprocess.run([sys.executable, "-m", "surgopt", *map(str, args)], capture_output=True, text=True, **kw)
    else:
        r = _in_process([str(a) for a in args], kw.get("cwd"))
    if check and r.returncode != 0:
        raise AssertionError(f"exit {r.returncode}\n{r.stdout}\n{r.stderr}")
    return r


def _in_process(args: list[str], cwd) -> Ran:
    import traceback

    from typer.testing import CliRunner

    from surgopt.cli import app

    here = os.getcwd()
    try:
        if cwd is not None:
            os.chdir(cwd)
        r = CliRunner().invoke(app, args)
    finally:
        os.chdir(here)
    err = r.stderr
    if r.exception is not None and not isinstance(r.exception, SystemExit):  # a traceback, as a process prints it
        err += "".join(traceback.format_exception(r.exception))
    return Ran(r.exit_code, r.stdout, err)


def invoke(*args):
    """The CLI in this process (no start-up cost): (exit code, stdout + stderr)."""
    from typer.testing import CliRunner

    from surgopt.cli import app

    r = CliRunner().invoke(app, [str(a) for a in args])
    return r.exit_code, r.output


@pytest.fixture
def stored(tmp_path):
    """A complete small rcm-grid run (RCM_SMALL) in 14 parts: (config path, store path, table)."""
    from surgopt.config import load_config
    from surgopt.runner import run_study
    from surgopt.store import Store
    from surgopt.studies import get_study

    rcm = get_study("rcm-grid")
    cfg = tmp_path / "small.toml"
    cfg.write_text(RCM_SMALL)
    store = tmp_path / "store"
    res = run_study(rcm, load_config(cfg, rcm.config_model), config_name="small", store=Store(store),
                    jobs=1, quiet=True, chunk=4)
    return cfg, store, res.table


# --- the report pages in a real browser (tests/test_html_report.py): Debian's Chromium, through pytest-playwright --

#: Chromium's software WebGL (these machines have no GPU) for Plotly's 3-D scenes.
CHROMIUM_ARGS = ["--enable-unsafe-swiftshader", "--no-sandbox"]


def chromium_path() -> str | None:
    import shutil

    return shutil.which("chromium") or shutil.which("chromium-browser")


@pytest.fixture(scope="session")
def browser_type_launch_args(browser_type_launch_args):
    """pytest-playwright launches the system Chromium (Playwright's own browser download does not work here)."""
    path = chromium_path()
    if path is None:
        if os.environ.get("CI"):
            pytest.fail("no chromium on PATH: .ci/run installs Debian's (apt-get install chromium)")
        pytest.skip("no chromium on PATH (apt-get install chromium)")
    return {**browser_type_launch_args, "executable_path": path, "args": CHROMIUM_ARGS}


#: The longest tests (15-45 s each on 2 cores, measured with --durations): collected first, so that the two xdist
#: workers start on them together rather than one finishing alone on a long test while the other idles.
LONGEST_FIRST = (
    "test_reliability_third.py::test_port_place_memory_estimate_is_above_its_measured_peak",
    "test_warm.py::test_the_warm_up_compiles_every_kernel_the_first_chunk_calls",
    "test_report.py::test_every_baseline_holds_on_a_cpu_without_avx512",
    "test_port_place_cart.py::test_the_dvrk_export_puts_each_psm_rcm_on_its_port_by_the_reference_kinematics",
    "test_study_rcm_grid_config.py::test_a_file_arm_runs_with_the_tool_length_alone",
    "test_faults.py::test_kill_9_resumes_to_the_same_table_on_every_backend",
    "test_store.py::test_two_processes_on_one_key",
)


def pytest_collection_modifyitems(session, config, items):
    """The LONGEST_FIRST tests first, the rest in their order (a stable sort: the same on every worker)."""
    items.sort(key=lambda item: not any(name in item.nodeid for name in LONGEST_FIRST))
