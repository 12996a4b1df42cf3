"""Study suture-sim (surgopt/studies/suture_sim.py): the paper's runs, task modes, config and CLI."""
import math

import numpy as np
import pytest

from surgopt.config import load_embedded
from surgopt.studies import suture_sim as S

LINKS = (60.0, 60.0, 110.0, 90.0, 80.0, 180.0)
Q0 = np.array([1.4522, 2.4707, 50, 0, np.pi / 2, -np.pi / 3, 0, -np.pi / 3])


def _runs(cfg):
    return [S.compute_task(cfg, 1, i) for i in range(S.n_tasks(cfg, 1))]


def test_five_bar_that_cannot_close_is_a_config_error():
    from surgopt.config import validate
    from surgopt.errors import ConfigError

    with pytest.raises(ConfigError, match=r"^x.toml: robot: the five-bar cannot close at the start pose"):
        validate({"robot": {"five_bar": {"l3_mm": 10.0, "l4_mm": 10.0}}}, S.Config, "x.toml")
    # the closed form agrees with the kernel on where closing stops: just inside and just outside
    from surgopt.kinematics.throat import five_bar

    for l3, closes in ((10.0, False), (80.0, True)):
        try:
            cfg = validate({"robot": {"five_bar": {"l3_mm": l3, "l4_mm": l3}}}, S.Config, "x.toml")
        except ConfigError:
            assert not closes
            continue
        assert closes and np.all(np.isfinite(five_bar(cfg.robot.start_pose.q1_rad, cfg.robot.start_pose.q2_rad,
                                                       S.geometry(cfg, 550.0, 150.0))[0]))


def test_paper_suture_runs_track_within_accuracy_and_w2_cuts_five_bar_motion():
    cfg = load_embedded(S.DEFAULT_CONFIG, S.Config)
    runs = _runs(cfg)
    assert len(runs) == 4
    for r in runs:
        assert len(r["t_s"]) == 3771 and math.isclose(r["t_s"][-1], 37.70)
        assert r["pos_err_mm"].max() < 0.1 and r["rot_err_deg"].max() < 1 / 3  # the paper's accuracy
        assert np.all(np.isfinite(r["q1_rad"])) and r["run_completed"].all()
    rng_of = {(r["weight_set"][0], r["arm_length_mm"][0]): {c: np.ptp(r[c]) for c in S.JOINT_COLUMNS}
              for r in runs}
    for arm in (550.0, 800.0):
        w1, w2 = rng_of[("W1", arm)], rng_of[("W2", arm)]
        assert w2["q1_rad"] < 0.01 * w1["q1_rad"] and w2["q2_rad"] < 0.01 * w1["q2_rad"]
        assert any(w2[c] > w1[c] for c in S.JOINT_COLUMNS[2:])  # some other joints grow
    # all joints within their limits (Fig. 7)
    assert all(max(r[c].max() for c in S.NORM_COLUMNS) <= 1.0 for r in runs)


@pytest.mark.parametrize("mode", ["orbit_parallel", "orbit_tangent"])
def test_other_task_modes_track(mode):
    cfg = S.Config.model_validate({"task": {"modes": [mode], "dt_s": 0.05}, "arm_length_mm": [550.0],
                                   "weights": {"W1": [1.0] * 8}})
    (r,) = _runs(cfg)
    assert r["pos_err_mm"].max() < 0.1 and r["rot_err_deg"].max() < 1 / 3


def test_gain_closes_the_loop():
    base = {"task": {"dt_s": 0.2}, "arm_length_mm": [550.0], "weights": {"W1": [1.0] * 8}}
    open_loop = _runs(S.Config.model_validate({**base, "task": {"dt_s": 0.2, "gain": 1e-9}}))[0]
    closed = _runs(S.Config.model_validate(base))[0]
    assert closed["pos_err_mm"][-1] < open_loop["pos_err_mm"][-1]


def test_embedded_default_equals_shipped_config():
    from surgopt.config import load_config

    from conftest import REPO

    assert load_embedded(S.DEFAULT_CONFIG, S.Config) == load_config(REPO / "configs" / S.DEFAULT_CONFIG, S.Config)
    assert load_embedded(S.DEFAULT_CONFIG, S.Config) == S.Config()


def test_cli_suture_sim_stores_caches_and_reports(tmp_path):
    import subprocess
    import sys

    from surgopt.store import Store

    cfg = tmp_path / "s.yaml"
    cfg.write_text("task:\n  dt_s: 0.1\n  modes: [spin, orbit_tangent]\narm_length_mm: [550.0]\n")
    store = tmp_path / "store"
    cmd = [sys.executable, "-m", "surgopt", "suture-sim", str(cfg), "--store", str(store), "--quiet"]
    r = subprocess.run(cmd, capture_output=True, text=True, check=True)
    assert "W1 range" in r.stdout and "W2 range" in r.stdout and "orbit_tangent" in r.stdout
    (run,) = Store(store).runs()
    table = run.read_table(S.schema())
    assert table.num_rows == 4 * 378  # 2 weight sets x 2 modes x (377 steps + start)
    lib = [S.compute_task(S.Config.model_validate({"task": {"dt_s": 0.1, "modes": ["spin", "orbit_tangent"]},
                                                   "arm_length_mm": [550.0]}), 1, i) for i in range(4)]
    assert np.array_equal(table["q4_rad"].to_numpy(), np.concatenate([x["q4_rad"] for x in lib]))
    r = subprocess.run(cmd, capture_output=True, text=True, check=True)
    assert "cache hit" in r.stdout
