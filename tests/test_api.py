"""The Python API (surgopt/api.py) and its example script (docs/api_example.py)."""
import subprocess
import sys

import pytest

import surgopt
from surgopt.errors import ConfigError, UsageError

from conftest import REPO


def test_the_documented_example_runs(tmp_path):
    r = subprocess.run([sys.executable, str(REPO / "docs" / "api_example.py"), str(tmp_path / "store")],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert "169 candidates, best GII" in r.stdout and "complete" in r.stdout


def test_run_load_runs_and_errors(tmp_path):
    store = tmp_path / "store"
    small = {"candidates.grid.x_count": 5, "candidates.grid.z_count": 4, "workspace.points_per_side": 3}
    df = surgopt.run("rcm-grid", overrides=small, store=store)
    assert len(df) == 20 and {"gii", "x_rcm_m", "feasible"} <= set(df.columns)
    assert surgopt.load(store=store).equals(df)
    assert df.attrs["config"]["workspace"]["points_per_side"] == 3 and df.attrs["plan"] == {"name": "grid"}
    listing = surgopt.runs(store=store)
    assert listing.loc[0, "key"] == df.attrs["key"]
    assert listing.loc[0, "state"] == "complete" and listing.loc[0, "backend"] == "threads"
    with pytest.raises(ConfigError, match=r"workspace.points_per_side: Input should be greater than or equal to 1"):
        surgopt.run("rcm-grid", overrides={"workspace.points_per_side": 0}, store=store)
    with pytest.raises(UsageError, match="unknown study"):
        surgopt.run("nosuch")
    with pytest.raises(UsageError, match="does not follow a run"):
        surgopt.run("rcm-grid", overrides=small, store=store, plan="cmaes")
    with pytest.raises(UsageError, match="needs a design space"):
        surgopt.run("suture-sim", store=store, plan="refine", overrides={"task.arc_deg": 20.0})
    assert surgopt.__version__ and "run" in surgopt.__all__


def test_the_api_can_do_what_the_result_commands_do(tmp_path):
    """#27 item 10: summarize, plot and diff from Python, the same facts as the commands' JSON."""
    import json
    import subprocess
    import sys

    store = tmp_path / "store"
    small = {"candidates.grid.x_count": 5, "candidates.grid.z_count": 4, "workspace.points_per_side": 3}
    a = surgopt.run("rcm-grid", overrides=small, store=store).attrs["key"]
    b = surgopt.run("rcm-grid", overrides={**small, "robot.tool_length_m": 0.5}, store=store).attrs["key"]
    rec = surgopt.summarize(a, store=store)
    cli = json.loads(subprocess.run([sys.executable, "-m", "surgopt", "summarize", a[:12], "--store", str(store),
                                     "--format", "json"], capture_output=True, text=True, check=True).stdout)
    assert rec["headline"] == cli["headline"] and rec["key"] == a
    d = surgopt.diff(a, b, store=store)
    assert list(d["config"]) == ["robot.tool_length_m"]
    paths = surgopt.plot(b, store=store)
    assert paths and all(p.is_file() and p.parent.name == "_figures" for p in paths)
