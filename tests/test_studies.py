"""The study protocol (surgopt/studies/__init__.py): a study the orchestration has never seen runs,
is stored, resumed from the store and summarised through the registry alone."""
import pytest

from surgopt.config import study_key
from surgopt.report import summary_sections
from surgopt.results import resolve_run
from surgopt.runner import run_study
from surgopt.store import Store
from surgopt.studies import STUDIES, Flag, chunk_for_seconds, get_study


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
    assert chunk_for_seconds(10_000, 1.0) == 2  # ~2 s each


@pytest.mark.parametrize("name, overrides", [
    ("rcm-grid", {"candidates": {"grid": {"x_count": 41, "z_count": 41}}}),
    ("raven-sweep", {"sweep": {"alpha_deg": [25.0, 45.0, 65.0], "beta_deg": [45.0, 65.0], "phi_x_deg": [0.0],
                               "iso_min": [0.3, 0.5]}}),
    ("suture-sim", {}),
])
def test_the_estimate_is_within_a_factor_of_2_of_the_computation(name, overrides):
    """What --dry-run and the budget use, against the CPU time of the same tasks in this process."""
    import time

    study = get_study(name)
    cfg = study.config_model.model_validate(overrides)
    study.warm_up(cfg)
    if name == "raven-sweep":
        from surgopt.kinematics.raven_workspace import clear_memo

        clear_memo()
    chunk = study.auto_chunk(cfg)
    t = time.process_time()
    rows = sum(len(next(iter(study.compute_task(cfg, chunk, i).values()))) for i in range(study.n_tasks(cfg, chunk)))
    cpu = time.process_time() - t
    est = study.estimate(cfg)
    assert est.rows == rows
    assert 0.5 <= est.seconds_one_core / cpu <= 2.0, (est.seconds_one_core, cpu)
