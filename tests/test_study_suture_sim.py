"""Study suture-sim (surgopt/studies/suture_sim/study.py): the paper's runs, task modes, config and CLI."""
import math

import numpy as np
import pytest

from surgopt.config import load_embedded
from surgopt.studies.suture_sim import study as S

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


def test_paper_suture_runs_track_and_w2_cuts_five_bar_motion():
    cfg = load_embedded(S.DEFAULT_CONFIG, S.Config)
    runs = _runs(cfg)
    assert len(runs) == 4
    for r in runs:
        assert len(r["t_s"]) == 3771 and math.isclose(r["t_s"][-1], 37.70)
        # the integrator's closed-loop residual (numerics, not the robot's accuracy): broken feedback or a
        # wrong Jacobian leaves errors orders of magnitude above this
        assert r["pos_err_mm"].max() < 1e-4 and r["rot_err_deg"].max() < 1e-3
        assert np.all(np.isfinite(r["q1_rad"])) and r["run_completed"].all()
    rng_of = {(r["weight_set"][0], r["arm_length_mm"][0]): {c: np.ptp(r[c]) for c in S.JOINT_COLUMNS}
              for r in runs}
    for arm in (550.0, 800.0):
        w1, w2 = rng_of[("W1", arm)], rng_of[("W2", arm)]
        assert w2["q1_rad"] < 0.01 * w1["q1_rad"] and w2["q2_rad"] < 0.01 * w1["q2_rad"]
        # W2 does not push the five-bar's motion onto the stage or the snakes: every input the spin does not
        # force (q3, theta_L, delta, phi_L') moves less under W2 than under W1; q4 and psi carry the spin
        for c in ("q3_mm", "q5_rad", "q6_rad", "q7_rad"):
            assert w2[c] < 0.1 * w1[c], (arm, c)
        assert min(w1["q4_rad"], w2["q4_rad"], w1["q8_rad"], w2["q8_rad"]) > 2.9


def test_each_joint_is_held_to_its_own_range():
    """The limit check is each joint's [lower, upper] (theta_L and phi_L' in [0, pi]), not |q/q_max| <= 1 (which
    let phi_L' bend 109 deg past its stated range unseen). The PMU starts at phi_L' = 0, its lower limit, and
    every paper run takes it below: the runs are reported beyond their limits, W1 by more than W2."""
    cfg = load_embedded(S.DEFAULT_CONFIG, S.Config)
    runs = _runs(cfg)
    assert all(r["q7_rad"][0] == 0.0 and r["q7_margin_rad"][0] == 0.0 for r in runs)  # the premise
    worst = {(r["weight_set"][0], r["arm_length_mm"][0]): r["q7_margin_rad"].min() for r in runs}
    assert all(v < 0 for v in worst.values())
    assert worst[("W1", 550.0)] < worst[("W2", 550.0)] < 0
    import pyarrow as pa

    s = S.summary(pa.concat_tables([pa.Table.from_pydict(r, schema=S.schema()) for r in runs]))
    assert s.feasibility["runs_within_limits"] == 0 and s.headline["runs_with_limit_violations"] == 4
    # the old check would have passed them all
    assert all(max(r[c].max() for c in S.NORM_COLUMNS) <= 1.0 for r in runs)


def test_a_crossed_five_bar_is_refused():
    """At the paper's start pose, the "left" assembly closes the loop as a self-intersecting pentagon."""
    from surgopt.config import validate
    from surgopt.errors import ConfigError

    with pytest.raises(ConfigError, match=r"x.toml: robot: five_bar.branch: 'left' .* crossed .* edge A1-D crosses edge C-B"):
        validate({"robot": {"five_bar": {"branch": "left"}}}, S.Config, "x.toml")
    cfg = S.Config()
    assert cfg.robot.five_bar.branch == "right"
    pts = S.five_bar_pentagon(cfg.robot.five_bar, cfg.robot.start_pose.q1_rad, cfg.robot.start_pose.q2_rad)
    # the kernel's P_U is the simple pentagon's: B + l6 (C - B) / l3
    from surgopt.kinematics.throat import five_bar

    geo = S.geometry(cfg, 550.0, 150.0)
    P_U = five_bar(cfg.robot.start_pose.q1_rad, cfg.robot.start_pose.q2_rad, geo)[0]
    C, B = pts[2], pts[3]
    assert np.allclose(P_U, B + 180.0 * (C - B) / 110.0, atol=1e-9)
    assert np.allclose(P_U, [160.7, 114.1], atol=0.05)


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


def test_the_run_grid_is_counted_by_arithmetic_and_bounded():
    """#55 item 6: runs and steps by arithmetic (equal to walking the product), and a grid past MAX_RUNS refused
    in one line naming the lists (before: 9 M run dicts built to count them, 'out of memory')."""
    import itertools

    from surgopt.config import validate
    from surgopt.errors import ConfigError

    cfg = validate({"weights": {"A": [1.0] * 8, "B": [2.0] * 8}, "arm_length_mm": [550.0, 600.0],
                    "task": {"modes": ["spin", "orbit_tangent"], "radius_mm": [4.0, 6.0, 7.5], "speed_mm_s": [0.5, 2.0]}},
                   S.Config, "x.toml")
    t = cfg.task
    walked = list(itertools.product(cfg.weights.items(), cfg.arm_length_mm, cfg.fulcrum_to_tip_mm, t.modes,
                                    t.radius_mm, t.speed_mm_s))
    grid = S.run_grid(cfg)
    assert S.n_runs(cfg) == S.n_tasks(cfg, 1) == len(walked) == 48
    for i, ((w, wv), la, f, m, r, v) in enumerate(walked):
        g = grid[i]
        assert (g["run_id"], g["weight_set"], g["arm_length_mm"], g["fulcrum_to_tip_mm"], g["mode"], g["radius_mm"],
                g["speed_mm_s"]) == (i, w, la, f, m, r, v) and list(g["weights"]) == wv
    assert S.total_steps(cfg) == sum(S.run_steps(cfg, g) for g in grid) == S.estimate(cfg).rows
    many = [1.0 + k * 0.001 for k in range(200)]
    with pytest.raises(ConfigError, match=r"task.radius_mm 200 x task.speed_mm_s 200 make 160,000 runs, more "
                                          r"than the 10,000"):
        validate({"task": {"radius_mm": many, "speed_mm_s": many}}, S.Config, "x.toml")
