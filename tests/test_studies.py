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
