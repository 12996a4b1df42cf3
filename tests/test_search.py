"""Searches any study can use (surgopt/plans/search.py)."""
import numpy as np

from surgopt.plans.search import compass_search


def test_compass_search_finds_the_maximum_of_a_concave_quadratic():
    peak = np.array([0.3, -1.2, 2.0])
    f = lambda x: -float(np.sum((x - peak) ** 2))  # noqa: E731
    visited = compass_search(f, [0.0, 0.0, 0.0], [(-2, 2), (-2, 2), (-2, 3)], [0.5, 0.5, 0.5], max_evals=2000,
                             min_step_fraction=1e-5)
    best = max(visited, key=f)
    assert np.allclose(best, peak, atol=1e-4)  # resolution: 1e-5 of each range
    assert np.array_equal(visited[0], [0.0, 0.0, 0.0])


def test_compass_search_respects_bounds_budget_and_fixed_coordinates():
    f = lambda x: float(x[0] + x[1])  # noqa: E731  (maximum on the upper corner)
    visited = compass_search(f, [0.0, 5.0], [(-1, 1), (5, 5)], [0.3, 0.0], max_evals=25)
    assert len(visited) <= 25
    pts = np.array(visited)
    assert pts[:, 0].min() >= -1 and pts[:, 0].max() <= 1
    assert np.all(pts[:, 1] == 5.0)  # step 0: never moved
    assert max(visited, key=f)[0] == 1.0


# --- Optuna searches ------------------------------------------------------------------------------

import json  # noqa: E402
import signal  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402

import pytest  # noqa: E402

from surgopt.config import validate  # noqa: E402
from surgopt.errors import ConfigError  # noqa: E402
from surgopt.runner import run_study  # noqa: E402
from surgopt.store import Store  # noqa: E402
from surgopt.studies import get_study  # noqa: E402
from surgopt.plans.search import pareto_front  # noqa: E402

from conftest import fault_lines, single_run, single_table, wait_for_parts  # noqa: E402

RCM_SEARCH = """
[workspace]
points_per_side = 9
[search]
method = "{method}"
trials = {trials}
batch = {batch}
seed = 3
"""


def _search(tmp_path, name, method="cmaes", trials=60, batch=10):
    cfg = tmp_path / f"{name}.toml"
    cfg.write_text(RCM_SEARCH.format(method=method, trials=trials, batch=batch))
    return cfg


@pytest.mark.parametrize("method", ["cmaes", "tpe", "random"])
def test_a_search_is_deterministic_bounded_and_same_on_one_or_two_workers(tmp_path, method):
    rcm = get_study("rcm-grid")
    cfg = validate({"workspace": {"points_per_side": 5},
                    "search": {"method": method, "trials": 50, "batch": 10, "seed": 1}}, rcm.config_model, "x")
    a = run_study(rcm, cfg, config_name="a", store=Store(tmp_path / "a"), jobs=1, quiet=True).table
    b = run_study(rcm, cfg, config_name="b", store=Store(tmp_path / "b"), jobs=2, quiet=True).table
    assert a.equals(b) and a.num_rows == 50
    assert a["candidate_id"].to_pylist() == list(range(50))
    g = cfg.candidates.grid
    x, z = a["x_rcm_m"].to_numpy(), a["z_rcm_m"].to_numpy()
    assert x.min() >= g.x_min_m and x.max() <= g.x_max_m and z.min() >= g.z_min_m and z.max() <= g.z_max_m
    assert len(set(x.tolist())) > 10  # it explores
    manifest = single_run(tmp_path / "a").manifest
    assert manifest["plan"]["name"] == ("cmaes" if method == "cmaes" else "optuna")
    assert single_run(tmp_path / "a").complete


def test_a_search_without_a_batch_stores_its_methods_default_part(tmp_path):
    """``batch`` left out: CMA-ES stores parts of at least 256 trials (whole generations; its parts are only the
    unit of durability), Optuna asks and stores 64 at a time; given, it is used as it is."""
    from surgopt.plans.search import SearchSpec

    assert SearchSpec(method="cmaes").trials_per_part == 256 and SearchSpec(method="tpe").trials_per_part == 64
    assert SearchSpec(method="cmaes", batch=12).trials_per_part == 12
    rcm = get_study("rcm-grid")
    cfg = validate({"workspace": {"points_per_side": 3}, "search": {"method": "cmaes", "trials": 600, "seed": 1}},
                   rcm.config_model, "x")
    run_study(rcm, cfg, config_name="a", store=Store(tmp_path), jobs=1, quiet=True)
    run = single_run(tmp_path)
    sizes = [run.part_table(k).num_rows for k in range(run.manifest["n_tasks"])]
    assert sum(sizes) == 600 and len(sizes) == 3 and all(256 <= n < 256 + 6 for n in sizes[:-1])  # 6 a generation


@pytest.mark.parametrize("method", ["tpe", "random"])
def test_an_optuna_search_parts_are_optunas_record(tmp_path, method):
    import optuna
    from optuna.storages import JournalStorage
    from optuna.storages.journal import JournalFileBackend

    rcm = get_study("rcm-grid")
    cfg = validate({"workspace": {"points_per_side": 5},
                    "search": {"method": method, "trials": 30, "batch": 10, "seed": 1}}, rcm.config_model, "x")
    a = run_study(rcm, cfg, config_name="a", store=Store(tmp_path), jobs=2, quiet=True).table
    study = optuna.load_study(study_name="surgopt", storage=JournalStorage(JournalFileBackend(
        str(single_run(tmp_path).path / "_optuna.journal"))))
    trials = study.get_trials()
    assert [t.number for t in trials] == list(range(30))
    assert [t.params["x_rcm_m"] for t in trials] == a["x_rcm_m"].to_pylist()
    assert [t.value for t in trials] == a["gii"].to_pylist()


def test_the_cmaes_plan_is_the_cmaes_package_asked_and_told(tmp_path):
    """The plan's trials are those of ``cmaes.CMA`` driven by hand (same seed, [0, 1] coordinates, the box's
    centre, sigma 0.3, GII maximised, an infeasible candidate ranked last) until its first restart."""
    import cmaes
    import numpy as np

    rcm = get_study("rcm-grid")
    cfg = validate({"workspace": {"points_per_side": 5},
                    "search": {"method": "cmaes", "trials": 42, "batch": 12, "seed": 4}}, rcm.config_model, "x")
    t = run_study(rcm, cfg, config_name="a", store=Store(tmp_path), jobs=2, quiet=True).table
    g = cfg.candidates.grid
    lo, hi = np.array([g.x_min_m, g.z_min_m]), np.array([g.x_max_m, g.z_max_m])
    opt = cmaes.CMA(mean=np.full(2, 0.5), sigma=0.3, bounds=np.tile([0.0, 1.0], (2, 1)), seed=4 * 1_000_003)
    assert opt.population_size == 6  # 4 + floor(3 ln 2): seven generations
    rows, values = [], []
    while len(rows) < 42:
        u = [opt.ask() for _ in range(opt.population_size)]
        x = np.array([lo + ui * (hi - lo) for ui in u])
        gii = rcm.evaluate(cfg, x, np.arange(len(u)), "hand")["gii"]
        rows += x.tolist()
        values += gii.tolist()
        opt.tell([(ui, -v if np.isfinite(v) else 1e300) for ui, v in zip(u, gii)])
        assert not opt.should_stop()  # the premise: no restart within these trials
    assert np.column_stack([t["x_rcm_m"].to_numpy(), t["z_rcm_m"].to_numpy()]).tolist() == rows
    np.testing.assert_array_equal(t["gii"].to_numpy(), values)
    # parts hold whole generations, at least `batch` trials each: 12, 12, 12, 6 (the last, cut at the budget)
    assert single_run(tmp_path).manifest["n_tasks"] == 4


@pytest.mark.parametrize("limit", [3, 100])
def test_a_generation_asked_at_once_is_cmaes_asked_point_by_point(limit):
    """ask_generation against ``cmaes.CMA.ask`` on a twin optimiser (same seed, told the same values): bit for
    bit the same points over 40 generations of a search pressed against its bounds, and the random state left
    where the asks leave it; the premises: draws rejected, and with a resampling limit of 3 points clipped onto
    the bounds. CMAwM is not batched (None)."""
    import cmaes
    import numpy as np

    from surgopt.plans.cmaes_plan import ask_generation

    def make(cls=cmaes.CMA, **kw):
        return cls(mean=np.full(8, 0.9), sigma=0.3, bounds=np.tile([0.0, 1.0], (8, 1)), seed=7, population_size=10,
                   **kw)

    opt, twin = make(n_max_resampling=limit), make(n_max_resampling=limit)
    sample, draws = twin._sample_solution, []
    twin._sample_solution = lambda: (draws.append(1), sample())[1]  # counts the twin's draws
    clipped = 0
    for _ in range(40):
        one_by_one = np.array([twin.ask() for _ in range(10)])
        batch = ask_generation(opt, 10)
        assert np.array_equal(batch, one_by_one)
        clipped += int(np.any((batch == 0.0) | (batch == 1.0)))
        values = ((batch - 0.97) ** 2).sum(axis=1)
        opt.tell(list(zip(batch, values)))
        twin.tell(list(zip(one_by_one, values)))
    assert np.array_equal(opt._rng.randn(5), twin._rng.randn(5))
    assert len(draws) > 400 and (clipped > 0) == (limit == 3)  # draws rejected; points clipped
    assert ask_generation(make(cmaes.CMAwM, steps=np.zeros(8)), 10) is None


def test_a_killed_search_resumes_to_the_same_trials(tmp_path):
    ref = _search(tmp_path, "ref", trials=240, batch=20)
    cli_args = [sys.executable, "-m", "surgopt", "rcm-grid"]
    subprocess.run(cli_args + [str(ref), "--store", str(tmp_path / "ref"), "-q"], check=True, capture_output=True)
    cfg = _search(tmp_path, "ref", trials=240, batch=20)
    store = tmp_path / "killed"
    proc = subprocess.Popen(cli_args + [str(cfg), "--store", str(store), "-q"], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    try:
        wait_for_parts(store, "rcm-grid", 3, proc, timeout=60)
        proc.send_signal(signal.SIGKILL)
        proc.wait()
        assert not single_run(store).complete
    except AssertionError:
        proc.wait()  # finished first: the comparison below still holds
    r = subprocess.run(cli_args + [str(cfg), "--store", str(store), "-q"], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert single_table(store).equals(single_table(tmp_path / "ref"))


def test_a_categorical_list_stays_categorical():
    raven = get_study("raven-sweep")
    cfg = validate({"sweep": {"alpha_deg": [45.0, 65.0], "iso_min": [0.5]},
                    "geometry": {"step_mm": 8.0},
                    "search": {"method": "tpe", "trials": 24, "batch": 8}}, raven.config_model, "x")
    plan = raven.search_plan(cfg)
    assert plan.space["alpha_deg"] == [45.0, 65.0] and plan.space["beta_deg"] == (5.0, 90.0)
    import tempfile

    with tempfile.TemporaryDirectory() as tmp:
        t = run_study(raven, cfg, config_name="c", store=Store(tmp), jobs=1, quiet=True).table
    assert set(t["alpha_deg"].to_pylist()) <= {45.0, 65.0} and set(t["iso_min"].to_pylist()) == {0.5}
    assert len(set(t["beta_deg"].to_pylist())) > 5  # continuous
    assert set(t["source"].to_pylist()) == {"tpe"}


BAD_SEARCH = {
    "unknown method": ({"method": "bogus"}, "search.method"),
    "batch 0": ({"method": "tpe", "batch": 0}, "search.batch"),
    "nsga2 with one objective": ({"method": "nsga2"}, "multi-objective"),
    "cmaes with two": ({"method": "cmaes", "objectives": ["gii", "x_rcm_m"]}, "takes one objective"),
    "unknown objective": ({"method": "tpe", "objectives": ["speed"]}, "not one of"),
    "unknown key": ({"method": "tpe", "trails": 10}, "search.trails: unknown key (did you mean 'trials'?)"),
}


@pytest.mark.parametrize("case", sorted(BAD_SEARCH))
def test_a_bad_search_section_gets_a_field_named_error(case):
    section, words = BAD_SEARCH[case]
    with pytest.raises(ConfigError, match="x.toml: ") as e:
        validate({"search": section}, get_study("rcm-grid").config_model, "x.toml")
    assert words in str(e.value), str(e.value)


def test_pareto_front_and_the_nsga2_summary(tmp_path):
    v = [[1, 5], [2, 4], [3, 3], [2, 2], [1, 1], [3, 5]]
    assert sorted(pareto_front(v, ["maximize", "maximize"]).tolist()) == [5]
    assert sorted(pareto_front(v, ["maximize", "minimize"]).tolist()) == [2, 3, 4]  # (3,3), (2,2), (1,1)
    cfg = tmp_path / "n.toml"
    cfg.write_text('[workspace]\npoints_per_side = 5\n[search]\nmethod = "nsga2"\ntrials = 40\nbatch = 20\n'
                   'objectives = ["gii", "-x_rcm_m"]\n')
    store = tmp_path / "store"
    closing = subprocess.run([sys.executable, "-m", "surgopt", "rcm-grid", str(cfg), "--store", str(store), "-q"],
                             check=True, capture_output=True, text=True).stdout
    assert "Pareto front of gii (max) vs x_rcm_m (min)" in closing  # the closing report ranks by both (#27 item 9)
    r = subprocess.run([sys.executable, "-m", "surgopt", "summarize", "--store", str(store), "--format", "markdown"],
                       capture_output=True, text=True, check=True)
    assert "Pareto front of gii (max) vs x_rcm_m (min)" in r.stdout
    out = subprocess.run([sys.executable, "-m", "surgopt", "plot", "--store", str(store), "--out", str(tmp_path / "f")],
                         capture_output=True, text=True, check=True).stdout
    assert "search_pareto_front.png" in out
    assert json.loads(subprocess.run([sys.executable, "-m", "surgopt", "runs", "--store", str(store), "--format", "json"],
                                     capture_output=True, text=True).stdout)[0]["rows"] == 40


@pytest.mark.parametrize("method,stop_in", [("tpe", "evaluation"), ("tpe", "tell"), ("cmaes", "evaluation"),
                                            ("cmaes", "store")])
def test_a_search_stopped_between_ask_store_and_tell_resumes_to_the_same_trials(tmp_path, monkeypatch, method,
                                                                                 stop_in):
    """The windows a kill -9 rarely hits, made to happen: in a batch's evaluation (after its asks, before its
    part), in the middle of telling Optuna a batch, and after CMA-ES was told but before the part was stored."""
    from surgopt import backends
    from surgopt.plans import optuna_plan as S

    rcm = get_study("rcm-grid")
    cfg = validate({"workspace": {"points_per_side": 5},
                    "search": {"method": method, "trials": 60, "batch": 10, "seed": 2}}, rcm.config_model, "x")
    ref = run_study(rcm, cfg, config_name="ref", store=Store(tmp_path / "ref"), jobs=1, quiet=True).table
    real_tell, real_compute, real_write = S.tell, backends.compute, Store.write_part
    calls = {"n": 0}

    def tell_then_stop(study, trials, values):
        calls["n"] += 1
        if calls["n"] == 3:  # batch 2: tell 4 of its 10 trials, then stop
            real_tell(study, trials[:4], values[:4])
            raise KeyboardInterrupt
        real_tell(study, trials, values)

    def compute_then_stop(name, c, chunk, task):
        calls["n"] += 1
        if calls["n"] == 4:
            raise KeyboardInterrupt
        return real_compute(name, c, chunk, task)

    def write_then_stop(self, run, index, table):
        if index == 2:
            raise KeyboardInterrupt
        return real_write(self, run, index, table)

    monkeypatch.setattr(*{"tell": (S, "tell", tell_then_stop), "evaluation": (backends, "compute", compute_then_stop),
                          "store": (Store, "write_part", write_then_stop)}[stop_in])
    with pytest.raises(KeyboardInterrupt):
        run_study(rcm, cfg, config_name="x", store=Store(tmp_path / "x"), jobs=1, quiet=True)
    monkeypatch.undo()
    assert not single_run(tmp_path / "x").complete  # the premise: stopped part-way
    again = run_study(rcm, cfg, config_name="x", store=Store(tmp_path / "x"), jobs=1, quiet=True).table
    assert again.equals(ref)


def _tpe(tmp_path, trials=60, batch=10):
    rcm = get_study("rcm-grid")
    cfg = validate({"workspace": {"points_per_side": 5},
                    "search": {"method": "tpe", "trials": trials, "batch": batch, "seed": 3}}, rcm.config_model, "x")
    ref = run_study(rcm, cfg, config_name="ref", store=Store(tmp_path / "ref"), jobs=1, quiet=True).table
    return rcm, cfg, ref


def test_a_search_killed_after_recording_a_batch_but_before_storing_it_resumes(tmp_path, monkeypatch):
    """The window between the journal's append and the part's write: the batch is evaluated again from its
    recorded parameters (and must give the recorded values)."""
    rcm, cfg, ref = _tpe(tmp_path)
    real = Store.write_part

    def stop_at_2(self, run, index, table):
        if index == 2:
            raise KeyboardInterrupt
        return real(self, run, index, table)

    monkeypatch.setattr(Store, "write_part", stop_at_2)
    with pytest.raises(KeyboardInterrupt):
        run_study(rcm, cfg, config_name="x", store=Store(tmp_path / "x"), jobs=1, quiet=True)
    monkeypatch.undo()
    run = single_run(tmp_path / "x")
    assert sorted(run.done_tasks()) == [0, 1]
    from surgopt.plans.optuna_plan import Journal

    assert Journal.open(run.path / "_optuna.journal", rcm.search_plan(cfg)).batches == 3  # the premise
    assert run_study(rcm, cfg, config_name="x", store=Store(tmp_path / "x"), jobs=1, quiet=True).table.equals(ref)


def _partial(tmp_path, rcm, cfg, stop_at=3):
    real = Store.write_part

    def stop(self, run, index, table):
        if index == stop_at:
            raise KeyboardInterrupt
        return real(self, run, index, table)

    Store.write_part = stop
    try:
        with pytest.raises(KeyboardInterrupt):
            run_study(rcm, cfg, config_name="x", store=Store(tmp_path / "x"), jobs=1, quiet=True)
    finally:
        Store.write_part = real
    return single_run(tmp_path / "x")


@pytest.mark.parametrize("damage", ["deleted", "garbage inside", "half-written last line"])
def test_a_damaged_journal_is_refused_with_the_repair_or_resumed_exactly(tmp_path, damage):
    rcm, cfg, ref = _tpe(tmp_path)
    run = _partial(tmp_path, rcm, cfg)
    journal = run.path / "_optuna.journal"
    lines = journal.read_bytes().splitlines(keepends=True)
    if damage == "deleted":
        journal.unlink()
    elif damage == "garbage inside":
        journal.write_bytes(b"".join(lines[:5]) + b"{not json\n" + b"".join(lines[5:]))
    else:
        journal.write_bytes(b"".join(lines) + lines[-1][: len(lines[-1]) // 2])  # killed mid-append
    if damage == "half-written last line":
        again = run_study(rcm, cfg, config_name="x", store=Store(tmp_path / "x"), jobs=1, quiet=True).table
        assert again.equals(ref)
        return
    code, out = _invoke_cli(run, cfg, tmp_path)
    assert code == 1 and "runs rm" in out and "--force" in out and "Traceback" not in out, out
    assert len(fault_lines(out)) == 1
    assert sorted(single_run(tmp_path / "x").done_tasks()) == [0, 1, 2]  # nothing discarded


def _invoke_cli(run, cfg, tmp_path):
    from typer.testing import CliRunner

    from surgopt.cli import app
    from surgopt.config import to_toml

    path = tmp_path / "search.toml"
    path.write_text(to_toml(cfg.model_dump(mode="json", exclude_none=True)))
    r = CliRunner().invoke(app, ["rcm-grid", str(path), "--store", str(tmp_path / "x"), "--quiet"])
    return r.exit_code, r.output


def test_a_search_estimate_counts_the_optimisers_own_time(tmp_path):
    """A 5,000-trial TPE search on Table II was estimated at ~1 s (its evaluations) while Optuna's own ~8 ms a
    trial makes it ~40 s: the plan adds its time per trial, so the budget refuses it before anything is written."""
    from surgopt.errors import UsageError
    from surgopt.plans import estimate

    raven = get_study("raven-sweep")
    search = {"trials": 5000, "batch": 64, "seed": 0}
    tpe = validate({"search": {"method": "tpe", **search}}, raven.config_model, "x")
    cma = validate({"search": {"method": "cmaes", **search}}, raven.config_model, "x")
    evaluations = raven.estimate(tpe).seconds_one_core
    assert estimate(raven, tpe).seconds_one_core >= evaluations + 5000 * 0.005
    assert estimate(raven, cma).seconds_one_core < evaluations + 5000 * 0.001  # cmaes's ask/tell is cheap
    with pytest.raises(UsageError, match="past the 0.005 h budget"):
        run_study(raven, tpe, config_name="x", store=Store(tmp_path), jobs=1, quiet=True, max_hours=0.005)
    assert not any(tmp_path.iterdir())  # nothing written
