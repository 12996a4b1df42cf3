"""The lane walk (kinematics/serial_lanes) against the scalar walk it generalises and against textbook
linear algebra: same feasible set, GII to 1e-9, IK solutions that satisfy the five equations."""
from __future__ import annotations

import numpy as np

from surgopt.config import validate
from surgopt.kinematics import chain_candidates as cc
from surgopt.kinematics import serial_chain as sc
from surgopt.kinematics import serial_lanes as SL
from surgopt.metrics import POSE_METRICS
from surgopt.studies.rcm_grid import study as S


def pa10_generic():
    cfg = validate({"robot": {"kernel": "generic"}, "workspace": {"points_per_side": 9}}, S.Config, "test")
    chain, _, seed = cfg.robot.chain()
    walk = np.ascontiguousarray(S.workspace_offsets(cfg.workspace)[sc.serpentine_order(9)])
    return chain, np.asarray(seed, float), walk


def test_segments_start_where_the_walk_turns():
    """On a serpentine every segment starts a line (the lanes stay in phase); a straight walk, with no
    turn, is split evenly."""
    assert SL.segments(np.arange(60.0).reshape(20, 3), 8).tolist() == [0, 2, 5, 8, 10, 12, 15, 18, 20]
    n = 17
    cube = np.stack(np.meshgrid(*[np.arange(n)] * 3, indexing="ij"), axis=-1).reshape(-1, 3) * 0.00625
    b = SL.segments(np.ascontiguousarray(cube[sc.serpentine_order(n)]))
    assert b[0] == 0 and b[-1] == n ** 3 and (np.diff(b) > 0).all()
    assert (b[:-1] % n == 0).all() and np.ptp(np.diff(b)) <= 2 * n
    assert SL.line_starts(np.ascontiguousarray(cube[sc.serpentine_order(n)]))[:3].tolist() == [17, 34, 51]


def test_lane_solver_and_jacobian_match_numpy_and_the_scalar_kernel():
    """lane_eval's residual and Jacobian equal rcm_residual_jacobian lane by lane; the lanes' LU
    (newton_step_lanes) equals np.linalg.solve, and flags a singular matrix."""
    chain, seed, _ = pa10_generic()
    rot, pos, pri = sc.kernel_arrays(chain)[:3]
    rng = np.random.default_rng(3)
    S_ = np.zeros(SL.ROWS * SL.W)
    view = lambda row, n: S_[row * SL.W:(row + n) * SL.W].reshape(n, SL.W)  # noqa: E731
    q = seed[:, None] + 0.3 * rng.normal(size=(5, SL.W))
    view(SL.Q, 5)[:] = q
    view(SL.TGT, 3)[:] = rng.normal(size=(3, SL.W))
    view(SL.C, 3)[:] = rng.normal(size=(3, SL.W))
    view(SL.REF, 3)[1] = 1.0
    view(SL.CS, 5)[:], view(SL.SN, 5)[:] = np.cos(q), np.sin(q)
    SL.lane_eval(rot, pos, pri, S_)
    for lane in range(SL.W):
        res, jac = np.empty(5), np.empty((5, 5))
        sc.rcm_residual_jacobian(rot, pos, pri, q[:, lane].copy(), view(SL.TGT, 3)[:, lane].copy(),
                                 view(SL.C, 3)[:, lane].copy(), np.array([0.0, 1.0, 0.0]), np.empty((5, 3)),
                                 np.empty((5, 3)), jac, res, sc.new_trig_cache())
        np.testing.assert_allclose(view(SL.RES, 5)[:, lane], res, rtol=1e-13, atol=1e-15)
        np.testing.assert_allclose(view(SL.JAC, 25)[:, lane].reshape(5, 5), jac, rtol=1e-13, atol=1e-15)
    a = rng.normal(size=(SL.W, 5, 5))
    a[3, 4] = a[3, 0] * 2.0  # lane 3 singular
    b = rng.normal(size=(5, SL.W))
    view(SL.JAC, 25)[:] = a.reshape(SL.W, 25).T
    view(SL.RES, 5)[:] = b
    SL.newton_step_lanes(S_)
    ok = view(SL.OK, 1)[0]
    assert ok.tolist() == [1, 1, 1, 0, 1, 1, 1, 1]
    for lane in (0, 1, 2, 4, 5, 6, 7):
        np.testing.assert_allclose(view(SL.STEP, 5)[:, lane], np.linalg.solve(a[lane], b[:, lane]), rtol=1e-10)


def test_lane_walk_gives_the_scalar_walk_results():
    """Candidates across the PA10's map (feasible, infeasible, near the boundary): same feasibility and
    singular counts, sigma within 1e-9; every solution satisfies the five equations to 1e-10 and is
    the scalar walk's branch (joints within 1e-6 rad)."""
    chain, seed, walk = pa10_generic()
    xs, zs = np.linspace(0.25, 0.8, 7), np.linspace(-0.5, 0.3, 5) + 0.317
    rcms = np.array([[x, 0.0, z] for x in xs for z in zs])
    a = cc.chain_candidates_extremes(rcms, walk, chain, seed, lanes=True)
    b = cc.chain_candidates_extremes(rcms, walk, chain, seed, lanes=False)
    feasible = b[2] == 0
    assert 5 < feasible.sum() < len(rcms) - 5
    assert (a[2] == b[2]).all() and (a[3] == b[3]).all()
    np.testing.assert_allclose(a[0][feasible], b[0][feasible], rtol=1e-9)
    np.testing.assert_allclose(a[1][feasible], b[1][feasible], rtol=1e-9)
    assert (a[4][feasible] == walk.shape[0]).all()
    # the joints of one feasible candidate, point by point
    i = int(np.nonzero(feasible)[0][0])
    q_lanes = np.empty((walk.shape[0], 5))
    args = (sc.kernel_arrays(chain), seed, sc.default_restarts(seed), rcms[i], walk, walk.mean(axis=0))
    SL.walk_lanes(*args, np.empty((0, 3)), 0.0, q_lanes, SL.segments(walk))
    q_scalar = sc.rcm_walk(chain, rcms[i], walk, seed)["q"]
    np.testing.assert_allclose(q_lanes, q_scalar, atol=1e-6)
    for j in range(0, walk.shape[0], 37):
        res, _ = sc.rcm_jacobian(chain, q_lanes[j], rcms[i] + walk[j], rcms[i])
        assert np.abs(res).max() < 1e-10


def test_lane_walk_culls_and_keeps_the_standard_metric():
    chain, seed, walk = pa10_generic()
    rcm = np.array([[0.535, 0.0, 0.107]])
    lo, hi, _, _, n = cc.chain_candidates_extremes(rcm, walk, chain, seed, lanes=True)
    lo2, hi2, _, _, n2 = cc.chain_candidates_extremes(rcm, walk, chain, seed, gii_to_beat=[2 * lo[0] / hi[0]],
                                                      lanes=True)
    assert n2[0] < n[0] and lo2[0] / hi2[0] >= lo[0] / hi[0]
    standard, scale = POSE_METRICS["standard"], (1.0, 1.0, 1.0)
    a = cc.chain_candidates_extremes(rcm, walk, chain, seed, metric=standard, metric_params=scale, lanes=True)
    b = cc.chain_candidates_extremes(rcm, walk, chain, seed, metric=standard, metric_params=scale, lanes=False)
    assert not np.allclose(a[0], lo)  # the standard metric, not the RCM one
    np.testing.assert_allclose(a[0], b[0], rtol=1e-9)
    np.testing.assert_allclose(a[1], b[1], rtol=1e-9)


def test_a_point_lost_in_lanes_gets_the_scalar_walks_verdict():
    """LBR iiwa at (0.46, 0, -0.2) m, next to a singular region: the lanes, reaching a segment's points
    along another path, lose one; the candidate is walked again by the scalar walk, which reaches every
    point (GII ~5e-4), so both paths report it feasible with the same extremes."""
    cfg = validate({"robot": {"model": "lbr_iiwa_14"}}, S.Config, "test")
    kernel = S.kernel_for(cfg)
    walk = kernel._walk(S.workspace_offsets(cfg.workspace), cfg.workspace.points_per_side)
    rcm = np.array([[0.46, 0.0, -0.2], [0.40, 0.0, 0.44]])
    a = cc.chain_candidates_extremes(rcm, walk, kernel.chain, kernel.seed, lanes=True)
    b = cc.chain_candidates_extremes(rcm, walk, kernel.chain, kernel.seed, lanes=False)
    assert a[2].tolist() == b[2].tolist() == [0, 0]
    np.testing.assert_allclose(a[0], b[0], rtol=1e-9)
    np.testing.assert_allclose(a[1], b[1], rtol=1e-9)
