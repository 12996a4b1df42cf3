import os
import sys
from pathlib import Path

import pytest

HERE = Path(__file__).parent
sys.path.insert(0, str(HERE))  # tests/reference.py

REPO = HERE.parent


@pytest.fixture(scope="session", autouse=True)
def numba_cache(tmp_path_factory):
    """One numba cache for the session, shared with CLI subprocesses."""
    if "NUMBA_CACHE_DIR" not in os.environ:
        os.environ["NUMBA_CACHE_DIR"] = str(tmp_path_factory.mktemp("numba-cache"))
    yield os.environ["NUMBA_CACHE_DIR"]


@pytest.fixture
def store_dir(tmp_path):
    return tmp_path / "store"
