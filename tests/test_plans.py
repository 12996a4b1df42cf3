"""Plans (surgopt/plans): every plan explores a toy study (tests/toy_search_study.py) deterministically, within its
bounds, resumes to the same rows after a stop at any part, and finds the known maximum where it should."""
import numpy as np
import pytest

from surgopt.config import validate
from surgopt.plans import follow_up_plan
from surgopt.runner import run_study
from surgopt.store import Store

from conftest import single_run

SEARCHES = {
    "grid": None,
    "tpe": {"method": "tpe", "trials": 60, "batch": 12, "seed": 1},
    "random": {"method": "random", "trials": 60, "batch": 12, "seed": 1},
    "nsga2": {"method": "nsga2", "trials": 60, "batch": 12, "seed": 1, "objectives": ["f", "g"]},
    "cmaes-ipop": {"method": "cmaes", "trials": 1500, "batch": 100, "seed": 1},
    "cmaes-bipop": {"method": "cmaes", "trials": 1500, "batch": 100, "seed": 2, "restarts": "bipop"},
    "cmaes-none": {"method": "cmaes", "trials": 120, "batch": 30, "seed": 3, "restarts": "none"},
}


@pytest.fixture
def toy(monkeypatch):
    from surgopt import studies

    monkeypatch.setitem(studies.STUDIES, "toy-search", "toy_search_study")
    return studies.get_study("toy-search")


def _cfg(toy, name):
    return validate({} if SEARCHES[name] is None else {"search": SEARCHES[name]}, toy.config_model, "toy.toml")


def _run(toy, cfg, store, jobs=2, **kw):
    return run_study(toy, cfg, config_name="toy", store=Store(store), jobs=jobs, quiet=True, **kw)


def same_rows(a, b) -> bool:
    """Arrow tables equal value for value, NaN where NaN (``Table.equals`` counts NaN as unequal to itself)."""
    return a.schema == b.schema and a.to_pandas().equals(b.to_pandas())


def _stopped_at_part(toy, cfg, store, index):
    """Run until part ``index`` is about to be stored, then stop as Ctrl-C would."""
    real = Store.write_part

    def stop(self, run, i, table):
        if i == index:
            raise KeyboardInterrupt
        return real(self, run, i, table)

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(Store, "write_part", stop)
        with pytest.raises(KeyboardInterrupt):
            _run(toy, cfg, store, jobs=1)  # one worker: part 0 is stored before part 1 is attempted


@pytest.mark.parametrize("name", sorted(SEARCHES))
def test_every_plan_is_deterministic_bounded_and_resumes_to_the_same_rows(toy, tmp_path, name):
    cfg = _cfg(toy, name)
    ref = _run(toy, cfg, tmp_path / "a").table
    assert same_rows(_run(toy, cfg, tmp_path / "b").table, ref)  # same rows, another store
    t = ref.to_pydict()
    assert min(t["u"]) >= 0 and max(t["u"]) <= 1 and min(t["v"]) >= -1 and max(t["v"]) <= 0
    assert set(t["w"]) <= set(map(float, [0, 1, 2]))
    assert t["design_id"] == list(range(len(t["design_id"])))
    _stopped_at_part(toy, cfg, tmp_path / "c", 1)
    run = single_run(tmp_path / "c")
    assert run.done_tasks() == {0} and not run.complete  # the premise: stopped part-way
    again = _run(toy, cfg, tmp_path / "c")
    assert not again.cache_hit and same_rows(again.table, ref)


@pytest.mark.parametrize("name", ["cmaes-ipop", "cmaes-bipop"])
def test_cma_es_with_margin_finds_the_maximum_and_restarts(toy, tmp_path, name):
    res = _run(toy, _cfg(toy, name), tmp_path)
    t = res.table.to_pandas()
    best = t.loc[t["f"].idxmax()]
    assert best["f"] > 10 - 1e-6 and best["w"] == 2.0  # the categorical optimum, through CMA-ES with margin
    assert abs(best["u"] - 0.3) < 1e-3 and abs(best["v"] + 0.6) < 1e-3
    assert res.run.manifest["search_restarts"] >= 1  # the premise of "with restarts": one happened
    assert t["f"].isna().any()  # infeasible designs were asked, and ranked last (the optimum was still found)


def test_the_refine_follows_a_run_and_records_its_parent(toy, tmp_path):
    cfg = validate({"grid_count": 10}, toy.config_model, "toy.toml")  # a grid that misses the optimum
    grid = _run(toy, cfg, tmp_path)
    refined = _run(toy, cfg, tmp_path, plan=follow_up_plan("refine", toy, cfg, grid))
    m = refined.run.manifest
    assert m["plan"]["parent"] == grid.run.key and len(m["plan"]["starts"]) == 2
    f_grid, f_ref = np.nanmax(grid.table["f"].to_numpy()), np.nanmax(refined.table["f"].to_numpy())
    assert f_ref > f_grid and f_ref > 10 - 1e-3
    assert _run(toy, cfg, tmp_path, plan=follow_up_plan("refine", toy, cfg, grid)).cache_hit


def test_a_search_on_a_study_without_a_design_space_is_refused(tmp_path):
    from surgopt.errors import UsageError
    from surgopt.studies import get_study

    st = get_study("suture-sim")
    assert st.evaluate is None
    from surgopt.plans import plan_for

    class Cfg:
        search = validate({"search": {"method": "tpe"}}, get_study("rcm-grid").config_model, "x").search

    with pytest.raises(UsageError, match="no design space"):
        plan_for(st, Cfg())


def test_a_sequential_plans_part_is_stored_while_its_next_batch_computes(toy, tmp_path):
    """The parts a batch's last task gives are stored once the next batch is handed to the workers (the next
    generation needs the batch's result, not its storing), and a stop during that next batch still leaves them
    stored: the resumed search gives the uninterrupted rows."""
    from surgopt import backends

    cfg = _cfg(toy, "cmaes-none")
    events = []
    real_write, real_compute = Store.write_part, backends.compute

    def write(self, run, i, table):
        events.append(("write", i))
        return real_write(self, run, i, table)

    def compute(study_name, cfg, chunk, task):
        events.append(("compute", task.index))
        if sum(e == ("write", 1) for e in events) and task.index == 2:
            raise KeyboardInterrupt  # a stop while part 2's batch computes
        return real_compute(study_name, cfg, chunk, task)

    from concurrent.futures import ThreadPoolExecutor

    real_submit = ThreadPoolExecutor.submit

    def submit(self, fn, *args, **kw):  # in the parent, like the store's writes: their order is deterministic
        if args and hasattr(args[-1], "index"):
            events.append(("submit", args[-1].index))
        return real_submit(self, fn, *args, **kw)

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(Store, "write_part", write)
        mp.setattr(backends, "compute", compute)
        mp.setattr(ThreadPoolExecutor, "submit", submit)
        with pytest.raises(KeyboardInterrupt):
            _run(toy, cfg, tmp_path / "a", jobs=2)
    first_write = events.index(("write", 0))
    assert ("submit", 1) in events[:first_write]  # part 0 was stored after part 1's batch was handed out
    assert sorted(single_run(tmp_path / "a").done_tasks()) == [0, 1]  # what finished is stored
    resumed = _run(toy, cfg, tmp_path / "a").table
    assert same_rows(resumed, _run(toy, cfg, tmp_path / "b").table)
