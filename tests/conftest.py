import os
import sys
from pathlib import Path

import pytest

HERE = Path(__file__).parent
sys.path.insert(0, str(HERE))  # tests/reference.py

REPO = HERE.parent

# the CLI's numba settings (8-wide vectors on AVX-512) before any test imports numba,
# so that tests and CLI subprocesses compile the same kernels into one cache
import surgopt.kinematics  # noqa: E402,F401  (configures numba on import)


@pytest.fixture(scope="session", autouse=True)
def numba_cache(tmp_path_factory):
    """One numba cache for the session, shared with CLI subprocesses."""
    if "NUMBA_CACHE_DIR" not in os.environ:
        os.environ["NUMBA_CACHE_DIR"] = str(tmp_path_factory.mktemp("numba-cache"))
    yield os.environ["NUMBA_CACHE_DIR"]


@pytest.fixture
def store_dir(tmp_path):
    return tmp_path / "store"


def wait_for_parts(store, study, n, proc, timeout=120):
    """Block until a run of ``study`` in ``store`` has n parts; fail if ``proc`` ends first."""
    import json
    import time

    t0 = time.time()
    while time.time() - t0 < timeout:
        for m in Path(store).glob(f"{study}/*/manifest.json"):
            try:
                if len(json.loads(m.read_text())["parts"]) >= n:
                    return
            except (OSError, ValueError):
                pass
        if proc.poll() is not None:
            raise AssertionError("finished before it could be interrupted")
        time.sleep(0.005)
    raise AssertionError("no parts appeared")


def cli(*args, check=True, **kw):
    """Run ``python -m surgopt ARGS`` in a subprocess; with ``check``, fail on a non-zero exit."""
    import subprocess

    r = subprocess.run([sys.executable, "-m", "surgopt", *map(str, args)], capture_output=True, text=True, **kw)
    if check and r.returncode != 0:
        raise AssertionError(f"exit {r.returncode}\n{r.stdout}\n{r.stderr}")
    return r
