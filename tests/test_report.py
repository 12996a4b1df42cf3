"""summarize, plot, check and runs rm/gc on stored runs; CI regression against the Parquet baselines."""
import json
import shutil
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from surgopt.store import Store

from conftest import cli

BASE = Path(__file__).parent / "baselines"
STUDY_OF = {"rcm_small": "rcm-grid", "raven_small": "raven-sweep", "suture_small": "suture-sim",
            "port_small": "port-place"}


@pytest.fixture(scope="module")
def store(tmp_path_factory):
    """One store with a run of each baseline config."""
    from conftest import invoke

    s = tmp_path_factory.mktemp("reports") / "store"
    for name, study in STUDY_OF.items():  # in this process: no start-up and kernel loading per run
        code, output = invoke(study, BASE / f"{name}.toml", "--store", s, "--quiet")
        assert code == 0, output
    return s


@pytest.mark.parametrize("name", sorted(STUDY_OF))
def test_check_passes_on_the_stored_baseline(store, name):
    r = cli("check", BASE / f"{name}.toml", "--baseline", BASE / f"{name}.parquet", "--store", store)
    assert r.stdout.startswith("OK:")


#: numba targeting a CPU without AVX-512 (Haswell: AVX2 and FMA, 4-wide vectors), whatever this machine has
NO_AVX512 = {"NUMBA_CPU_NAME": "haswell", "NUMBA_CPU_FEATURES": ""}
#: compiles a loop the way every kernel is compiled and says whether AVX-512 registers appear in it
ZMM_PROBE = ("import surgopt.kinematics, numpy as np\nfrom numba import njit\n"
             "@njit\ndef f(a):\n    for i in range(a.size): a[i] = a[i] * a[i] + 1.0\n"
             "f(np.ones(64)); print('zmm' in next(iter(f.inspect_asm().values())))")


@pytest.mark.parametrize("name", sorted(STUDY_OF))
def test_every_baseline_holds_on_a_cpu_without_avx512(tmp_path, name):
    """CI may run on any x86-64 CPU: the kernels compiled for Haswell (into their own cache) reproduce every
    baseline (one test each, so that the workers share them). The premise, that this target has no AVX-512 code,
    is checked first."""
    import contextlib
    import os
    import subprocess
    import sys

    flags = set()
    with contextlib.suppress(OSError), open("/proc/cpuinfo") as cpuinfo:
        flags = {f for line in cpuinfo if line.startswith("flags") for f in line.split(":")[1].split()}
    if flags and not {"avx2", "fma"} <= flags:
        pytest.skip("this CPU cannot run Haswell code (no AVX2/FMA): the baselines run on its own target above")
    if flags and "avx512f" not in flags:
        pytest.skip("this CPU has no AVX-512: the whole suite (every baseline included) already ran without it")
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "numba-haswell"), **NO_AVX512)
    probe = subprocess.run([sys.executable, "-c", ZMM_PROBE], capture_output=True, text=True, env=env, check=True)
    assert probe.stdout.strip() == "False"
    r = cli("check", BASE / f"{name}.toml", "--baseline", BASE / f"{name}.parquet", "--store", tmp_path / "s",
            env=env)
    assert r.stdout.startswith("OK:"), r.stdout


@pytest.mark.parametrize("name", sorted(STUDY_OF))
def test_check_fails_on_a_perturbed_baseline(store, tmp_path, name):
    t = pq.read_table(BASE / f"{name}.parquet")
    col = {"rcm_small": "gii", "raven_small": "zeta_cm", "suture_small": "q4_rad", "port_small": "cost"}[name]
    v = t[col].to_numpy().copy()
    i = int(np.argmax(np.abs(v)))
    v[i] *= 1 + 1e-6
    bad = tmp_path / "bad.parquet"
    pq.write_table(t.set_column(t.column_names.index(col), col, pa.array(v)), bad)
    r = cli("check", BASE / f"{name}.toml", "--baseline", bad, "--store", store, check=False)
    assert r.returncode == 1
    assert "FAIL: 1 value(s) differ" in r.stdout and col in r.stdout
    # a looser tolerance accepts it
    assert cli("check", BASE / f"{name}.toml", "--baseline", bad, "--store", store, "--rtol", "1e-5").returncode == 0


def test_check_takes_overrides(tmp_path):
    """#27 item 10: KEY=VALUE after the config, as for the study commands: one that changes the rows fails the
    baseline, one equal to the config's value is the same run and passes. (Its own store: the module's shared
    one must keep exactly the baselines' runs.)"""
    args = ["check", BASE / "rcm_small.toml", "--baseline", BASE / "rcm_small.parquet", "--store", tmp_path / "s"]
    r = cli(*args, "robot.tool_length_m=0.5", check=False)
    assert r.returncode == 1 and "value(s) differ" in r.stdout
    assert cli(*args, "robot.tool_length_m=0.587").stdout.startswith("OK:")
    assert cli(*args, "nonsense", check=False).returncode == 2


def test_check_structural_failures_and_bad_input(store, tmp_path):
    t = pq.read_table(BASE / "rcm_small.parquet")
    pq.write_table(t.slice(0, 100), tmp_path / "short.parquet")
    r = cli("check", BASE / "rcm_small.toml", "--baseline", tmp_path / "short.parquet", "--store", store, check=False)
    assert r.returncode == 1 and "row count differs" in r.stdout
    r = cli("check", BASE / "rcm_small.toml", "--baseline", tmp_path / "missing.parquet", "--store", store, check=False)
    assert r.returncode == 2 and "baseline not found" in r.stderr
    (tmp_path / "junk.parquet").write_text("not parquet")
    r = cli("check", BASE / "rcm_small.toml", "--baseline", tmp_path / "junk.parquet", "--store", store, check=False)
    assert r.returncode == 2 and "not a readable Parquet file" in r.stderr
    (tmp_path / "bad.toml").write_text("[workspace]\npoints_per_side = -1\n")
    r = cli("check", tmp_path / "bad.toml", "--baseline", BASE / "rcm_small.parquet", "--store", store, check=False)
    assert r.returncode == 2


def test_baselines_are_small_and_explicit():
    total = sum(p.stat().st_size for p in BASE.glob("*.parquet"))
    assert total < 300_000
    for p in BASE.glob("*.parquet"):
        schema = pq.read_schema(p)
        assert not any(pa.types.is_temporal(f.type) for f in schema)
        assert all(pa.types.is_float64(f.type) for f in schema if pa.types.is_floating(f.type))
        assert 100 <= pq.read_metadata(p).num_rows <= 500


def test_summarize_formats(store):
    r = cli("summarize", BASE / "rcm_small.toml", "--store", store, "--format", "json", "--top", "3")
    data = json.loads(r.stdout)
    assert data["objective"] == "gii" and len(data["top"]) == 3
    gii = [row["gii"] for row in data["top"]]
    assert gii == sorted(gii, reverse=True)
    stats = data["distribution"]
    assert stats["all"]["count"] == 150 and stats["feasible"]["max"] == gii[0] == data["headline"]["best_gii"]
    assert set(data["feasibility"]) == {"feasible", "infeasible"} and data["complete"] is True
    r = cli("summarize", BASE / "raven_small.toml", "--store", store, "--format", "csv", "--sort", "zeta_cm", "--top", "2")
    assert r.stdout.startswith("design_id,alpha_deg,") and len(r.stdout.strip().splitlines()) == 3  # header + 2
    r = cli("summarize", BASE / "suture_small.toml", "--store", store, "--format", "markdown")
    assert "W1 range" in r.stdout and "W2 range" in r.stdout and "\\|q/qmax\\|" in r.stdout
    r = cli("summarize", "--store", store, "--study", "rcm-grid")
    assert "top 10 by gii" in r.stdout
    assert cli("summarize", "--store", store, "--sort", "nope", "--study", "rcm-grid", check=False).returncode == 2
    assert cli("summarize", "ffffffffff", "--store", store, check=False).returncode == 2
    assert cli("summarize", "--store", store, "--format", "xml", check=False).returncode == 2


def test_summarize_says_when_a_run_is_partial(store, tmp_path):
    s2 = tmp_path / "store"
    shutil.copytree(store, s2)
    run = next(r for r in Store(s2).runs() if r.study == "rcm-grid")
    manifest = json.loads((run.path / "_manifest.json").read_text())
    manifest["n_tasks"] = len(manifest["parts"]) + 3  # three chunks still to come
    (run.path / "_manifest.json").write_text(json.dumps(manifest))
    r = cli("summarize", run.key[:10], "--store", s2)
    assert "PARTIAL" in r.stdout
    # runs lists it as partial; gc removes it and nothing else
    assert "partial" in cli("runs", "--store", s2).stdout
    cli("runs", "gc", "--store", s2)
    left = Store(s2).runs()
    assert len(left) == len(STUDY_OF) - 1 and all(r.complete for r in left)


def test_runs_filter_and_rm(store, tmp_path):
    s2 = tmp_path / "store"
    shutil.copytree(store, s2)
    out = cli("runs", "--store", s2, "--study", "suture-sim").stdout
    assert "suture-sim" in out and "rcm-grid" not in out
    key = next(r.key for r in Store(s2).runs() if r.study == "raven-sweep")
    cli("runs", "rm", key[:12], "--store", s2)
    assert {r.study for r in Store(s2).runs()} == set(STUDY_OF.values()) - {"raven-sweep"}
    assert cli("runs", "rm", "zzzz", "--store", s2, check=False).returncode == 2
    # several keys at once, with a dry run first; one bad key removes nothing
    keys = [r.key[:12] for r in Store(s2).runs() if r.study in ("rcm-grid", "suture-sim")]
    dry = cli("runs", "rm", *keys, "--dry-run", "--store", s2).stdout
    assert dry.count("would remove") == 2 and len(Store(s2).runs()) == len(STUDY_OF) - 1
    assert cli("runs", "rm", *keys, "ffff0000", "--store", s2, check=False).returncode == 2
    assert len(Store(s2).runs()) == len(STUDY_OF) - 1
    cli("runs", "rm", *keys, "--store", s2)
    assert {r.study for r in Store(s2).runs()} == set(STUDY_OF.values()) - {"raven-sweep", "rcm-grid", "suture-sim"}


def _png_ok(path, min_px=300):
    import matplotlib.image as mpimg

    img = mpimg.imread(path)
    assert img.shape[0] >= min_px and img.shape[1] >= min_px
    assert img[..., :3].std() > 0.05  # not blank


def test_plots(store, tmp_path):
    for name in STUDY_OF:
        out = tmp_path / name
        r = cli("plot", BASE / f"{name}.toml", "--store", store, "--out", out)
        paths = [Path(p) for p in r.stdout.split()]
        assert paths and all(p.parent == out for p in paths)
        for p in paths:
            _png_ok(p)
    names = {p.name for p in (tmp_path / "rcm_small").iterdir()}
    assert "rcm_gii_map.png" in names
    names = {p.name for p in (tmp_path / "raven_small").iterdir()}
    assert {"raven_workspace.png", "raven_zeta_alpha_beta.png", "raven_theta2_iso.png"} <= names
    names = {p.name for p in (tmp_path / "suture_small").iterdir()}
    assert {"suture_joints_0.png", "suture_path_0.png"} <= names
    for fmt, magic in (("svg", b"<?xml"), ("pdf", b"%PDF")):
        r = cli("plot", BASE / "rcm_small.toml", "--store", store, "--out", tmp_path / fmt, "--format", fmt)
        paths = [Path(p) for p in r.stdout.split()]
        assert paths and all(p.suffix == f".{fmt}" and p.read_bytes().startswith(magic) for p in paths)
        if fmt == "svg":  # each figure names its run (the SVG keeps a text's string beside its glyphs)
            drew = r.stderr.split("drew rcm-grid run ", 1)[1][:12]
            assert all(f"rcm-grid run {drew} (" in p.read_text() for p in paths)


def test_summarize_csv_is_one_table_pandas_reads_and_sort_goes_both_ways(store):
    """--format csv: the top rows, every column, full precision, one table (it was several '# title' sections
    pandas could not read); --sort -COLUMN ranks the smallest first; --columns narrows the table."""
    import io

    import pandas as pd

    up = pd.read_csv(io.StringIO(cli("summarize", BASE / "raven_small.toml", "--store", store, "--format", "csv",
                                     "--sort", "zeta_cm", "--top", "5").stdout))
    down = pd.read_csv(io.StringIO(cli("summarize", BASE / "raven_small.toml", "--store", store, "--format", "csv",
                                       "--sort", "-zeta_cm", "--top", "5").stdout))
    full = pq.read_table(BASE / "raven_small.parquet").to_pandas()
    assert up.shape == (5, full.shape[1]) and list(up.columns) == list(full.columns)
    # full precision (the stored run and the baseline agree to check's rtol 1e-9, not to the bit)
    assert np.allclose(up["zeta_cm"], sorted(full["zeta_cm"], reverse=True)[:5], rtol=1e-12, atol=0)
    assert np.allclose(down["zeta_cm"], sorted(full["zeta_cm"])[:5], rtol=1e-12, atol=0)
    assert up["zeta_cm"].is_monotonic_decreasing and down["zeta_cm"].is_monotonic_increasing
    out = cli("summarize", BASE / "raven_small.toml", "--store", store, "--columns", "design_id,zeta_cm").stdout
    assert "zeta_cm" in out and "perimeter_cm" not in out


def test_a_best_design_on_an_edge_of_the_box_is_said_with_the_field_to_widen(tmp_path):
    """#27 item 2: the PA10 map's best (x = 0.535 m) inside the default box is not flagged; cut the box at
    x <= 0.45 m and the best moves onto that edge: the closing report, summarize (table and JSON) say so."""
    import json

    small = ["workspace.points_per_side=5"]
    r = cli("rcm-grid", *small, "--store", tmp_path)
    assert "edge of the box" not in r.stdout
    r = cli("rcm-grid", *small, "candidates.grid.x_max_m=0.45", "--store", tmp_path)
    assert "note: best design on the upper edge of the box: x_rcm_m = 0.45 (candidates.grid.x_max_m)" in \
        " ".join(r.stdout.split())
    out = json.loads(cli("summarize", "--store", tmp_path, "--format", "json").stdout)
    edges = [note for run in (out if isinstance(out, list) else [out]) for note in run["best_on_an_edge"]]
    assert any("x_rcm_m = 0.45" in note for note in edges)
    assert "x_rcm_m = 0.45 (candidates.grid.x_max_m)" in cli("plot", "--store", tmp_path).stderr
