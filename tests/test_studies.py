"""The study protocol (surgopt/studies/__init__.py): a study the orchestration has never seen runs,
is stored, resumed from the store and summarised through the registry alone."""
import pytest

from surgopt.config import study_key
from surgopt.report import summary_sections
from surgopt.results import resolve_run
from surgopt.runner import run_study
from surgopt.store import Store
from surgopt.studies import STUDIES, TARGET_TASK_S, Flag, chunk_for_seconds, get_study


@pytest.fixture
def toy(monkeypatch):
    monkeypatch.setitem(STUDIES, "toy", "toy_study")
    return get_study("toy")


def test_a_new_study_needs_only_its_module_and_a_registry_line(toy, tmp_path):
    cfg = toy.config_model(n=10)
    store = Store(tmp_path)
    res = run_study(toy, cfg, config_name="t", store=store, jobs=2, quiet=True)
    assert res.table.num_rows == 10 and res.computed_tasks == 4
    assert res.table["square"].to_pylist() == [float(i * i) for i in range(10)]
    again = run_study(toy, cfg, config_name="t", store=store, jobs=2, quiet=True)
    assert again.cache_hit and again.table.equals(res.table)
    assert store.open("toy", study_key("toy", cfg, "toy-1")) is not None
    study, run = resolve_run(store, None)
    assert study is toy
    sections = dict((title, rows) for title, _, rows in summary_sections(study, run, run.read_table(toy.schema())))
    assert dict(sections["run"])["positive"] == 9 and dict(sections["run"])["zero"] == 1
    assert sections["top 10 by square"][0][2] == 81.0


def test_flags_and_chunking_helpers():
    f = Flag("--dry-spell", "x")
    assert f.dest == "dry_spell"
    assert chunk_for_seconds(1000, 0.001) == 32  # at least 32 tasks
    assert chunk_for_seconds(10_000, 1.0) == max(1, int(TARGET_TASK_S))  # ~TARGET_TASK_S each


#: (study, a small config, the same config with exactly twice the work: twice the candidates, the
#: geometries or the runs). The estimate's absolute speed is a property of a machine, measured by
#: benchmarks/bench_estimate.py; what a test can hold on any CPU is its rows and how it scales.
SIZES = [
    ("rcm-grid", {"candidates": {"grid": {"x_count": 9, "z_count": 3}}, "workspace": {"points_per_side": 5}},
     {"candidates": {"grid": {"x_count": 9, "z_count": 6}}, "workspace": {"points_per_side": 5}}),
    ("raven-sweep", {"sweep": {"alpha_deg": [45.0], "beta_deg": [45.0, 65.0], "phi_x_deg": [0.0], "phi_y_deg": [0.0],
                               "phi_z_deg": [0.0], "bx_mm": [100.0], "by_mm": [100.0], "iso_min": [0.3]}},
     {"sweep": {"alpha_deg": [45.0], "beta_deg": [45.0, 65.0], "phi_x_deg": [0.0, 10.0], "phi_y_deg": [0.0],
                "phi_z_deg": [0.0], "bx_mm": [100.0], "by_mm": [100.0], "iso_min": [0.3]}}),
    ("suture-sim", {"task": {"arc_deg": 20.0}}, {"task": {"arc_deg": 20.0, "radius_mm": [6.0, 6.0]}}),
]


@pytest.mark.parametrize("name, small, double", SIZES, ids=[s[0] for s in SIZES])
def test_the_estimate_counts_the_rows_and_scales_with_the_work(name, small, double):
    """What --dry-run and the budget use: the exact row count the tasks produce, and seconds and memory that
    grow with the work (twice the work, twice the seconds; more rows, more memory)."""
    study = get_study(name)
    a, b = (study.config_model.model_validate(o) for o in (small, double))
    chunk = study.auto_chunk(a)
    rows = sum(len(next(iter(study.compute_task(a, chunk, i).values()))) for i in range(study.n_tasks(a, chunk)))
    ea, eb = study.estimate(a), study.estimate(b)
    assert ea.rows == rows > 0
    assert eb.rows == 2 * ea.rows
    assert eb.seconds_one_core == pytest.approx(2 * ea.seconds_one_core, rel=1e-9)
    assert eb.peak_bytes > ea.peak_bytes


def test_the_budget_refuses_before_anything_runs(tmp_path):
    """A config estimated past --max-hours (or past --max-memory-gb) is refused with the estimate and the flag
    that lifts it; nothing is written. The same config within a raised budget passes the check."""
    from surgopt.errors import UsageError
    from surgopt.runner import check_budget

    study = get_study("rcm-grid")
    big = study.config_model.model_validate({"candidates": {"grid": {"x_count": 2001, "z_count": 2001}}})
    est = study.estimate(big)
    hours = est.seconds_one_core / 3600
    with pytest.raises(UsageError, match=r"4,004,001 RCM candidates.*--max-hours"):
        check_budget(study, big, 1, hours / 2, None)
    check_budget(study, big, 1, hours * 2, 10 * est.peak_bytes)
    with pytest.raises(UsageError, match="--max-memory-gb"):
        check_budget(study, big, 1, hours * 2, est.peak_bytes // 2)
    cfg = tmp_path / "big.toml"
    cfg.write_text("[candidates.grid]\nx_count = 2001\nz_count = 2001\n")
    from conftest import cli

    r = cli("rcm-grid", cfg, "--store", tmp_path / "store", "--max-hours", f"{hours / 2:.6f}", check=False)
    assert r.returncode == 2 and "--max-hours" in r.stderr
    assert not (tmp_path / "store").exists() or not any((tmp_path / "store").rglob("*.parquet"))


def test_a_slow_warm_up_is_announced_with_its_time(toy, tmp_path, monkeypatch):
    """Compiling the kernels on a first run takes a minute: the runner says so (and how long it took) once
    the warm-up takes longer than COMPILE_NOTICE_S, "compiling" only when numba compiles (its compile events)
    and "loading" otherwise, and what else it builds where the study says (``Study.warm_up_builds``); a fast one
    says nothing."""
    import time

    from numba import njit

    import surgopt.runner as R

    monkeypatch.setattr(R, "COMPILE_NOTICE_S", 0.05)

    @njit(cache=False)
    def fresh(x):  # never compiled before this test: the warm-up below compiles it
        return x + 1

    def compiles(cfg):
        assert not fresh.signatures  # the premise: a real compile happens here
        fresh(1)
        time.sleep(0.3)

    said = []
    slow = toy.__class__(**{**toy.__dict__, "warm_up": compiles})
    run_study(slow, slow.config_model(n=5), config_name="t", store=Store(tmp_path / "a"), jobs=1, quiet=True,
              say=said.append)
    assert any(m.startswith("compiling the toy kernels") for m in said), said
    assert said[-1].startswith("kernels compiled in")
    said.clear()
    slow = toy.__class__(**{**toy.__dict__, "warm_up": lambda cfg: time.sleep(0.3)})
    run_study(slow, slow.config_model(n=5), config_name="t", store=Store(tmp_path / "c"), jobs=1, quiet=True,
              say=said.append)
    assert any(m.startswith("loading the toy kernels") for m in said), said
    assert said[-1].startswith("kernels loaded in") and not any("compiling" in m for m in said)
    said.clear()
    # a study whose warm-up also builds its tables (port-place: the cart's setup joints, the links) says so
    slow = toy.__class__(**{**toy.__dict__, "warm_up": lambda cfg: time.sleep(0.3), "warm_up_builds": "its tables"})
    run_study(slow, slow.config_model(n=5), config_name="t", store=Store(tmp_path / "d"), jobs=1, quiet=True,
              say=said.append)
    assert any(m.startswith("loading the toy kernels") and m.endswith(" and building its tables ...") for m in said)
    assert said[-1].startswith("kernels loaded, tables built in"), said
    said.clear()
    run_study(toy, toy.config_model(n=5), config_name="t", store=Store(tmp_path / "b"), jobs=1, quiet=True,
              say=said.append)
    assert not said
