"""PA10 RCM kernels (surgopt/kinematics/pa10_rcm.py) against the numpy reference and closed forms."""
import numpy as np
import pytest

from surgopt.kinematics import pa10_rcm as K
from surgopt.metrics import global_isotropy_index

import reference as R

LINKS = (0.317, 0.45, 0.48, 0.07)
TOOL = 0.587
LINKS3 = np.array(LINKS[:3])
OFFSET = LINKS[3] + TOOL
QDOT = np.array([1.0, 1.0, 2.0, 2 * np.pi, 2 * np.pi])
LIM = np.radians([177.0, 91.0, 137.0, 255.0, 165.0])
COSLIM = np.cos(np.minimum(LIM, np.pi))
ARM = K.Pa10Arm(LINKS3, OFFSET, 1.0, QDOT, COSLIM)

def _points(rng, n, spread=0.05):
    rcm = np.array([rng.uniform(0.25, 0.75), 0.0, rng.uniform(-0.6, 0.05) + LINKS[0]])
    tips = rcm + np.column_stack([rng.uniform(-spread, spread, n), rng.uniform(-spread, spread, n),
                                  -0.1 + rng.uniform(-spread, spread, n)])
    return rcm, tips


def _reference(rcm, tip):
    k = (tip - rcm) / np.linalg.norm(tip - rcm)
    q = R.pa10_ik(tip, k, LINKS, TOOL)
    if q is None or np.any(np.abs(q) > LIM):
        return None
    return q, R.scaled_singular_values(q, LINKS, TOOL, rcm, QDOT)


def test_pose_singular_values_match_reference():
    rng = np.random.default_rng(10)
    checked = 0
    for _ in range(40):
        rcm, tips = _points(rng, 25)
        smin, smax, status = K.pose_singular_values(tips, rcm, ARM)
        for t, lo, hi, st in zip(tips, smin, smax, status):
            ref = _reference(rcm, t)
            if ref is None:
                assert st == K.STATUS_UNREACHABLE
                continue
            assert st == K.STATUS_OK
            s = ref[1]  # singular values of Q^-1 J_r: reciprocals of the kernel's
            assert lo == pytest.approx(1 / s[0], rel=1e-10)
            assert hi == pytest.approx(1 / s[-1], rel=1e-10)
            checked += 1
    assert checked > 500


def test_alternative_jacobian_matches_reference_and_finite_differences():
    rng = np.random.default_rng(11)
    for _ in range(20):
        rcm, tips = _points(rng, 1, 0.025)
        tip = tips[0]
        ref = _reference(rcm, tip)
        if ref is None:
            continue
        q = ref[0]
        A, ok = K.alternative_jacobian(tip, rcm, ARM._replace(qdot_max=np.ones(5)))
        assert ok
        h = 1e-6
        Jfd = np.column_stack([
            (R.pa10_alternative_fk(q + h * e, LINKS, TOOL, rcm) - R.pa10_alternative_fk(q - h * e, LINKS, TOOL, rcm)) / (2 * h)
            for e in np.eye(5)])
        assert np.allclose(A, Jfd, atol=1e-8)
        # scaling: column j of J_a Q is qdot_max[j] times column j of J_a
        As, _ = K.alternative_jacobian(tip, rcm, ARM)
        assert np.allclose(As, A * QDOT, atol=1e-15)


def test_worked_example_in_docstring():
    rcm = np.array([0.535, 0.0, 0.107])
    smin, smax, status = K.pose_singular_values(np.array([[0.535, 0.0, 0.007]]), rcm, ARM)
    assert status[0] == K.STATUS_OK
    assert smin[0] == pytest.approx(0.070968, abs=5e-7)
    assert smax[0] == pytest.approx(1.019961, abs=5e-7)


def test_unreachable_and_joint_limits_agree_with_reference():
    # RCM candidates close to the shoulder and far away: many poses outside reach or limits
    rng = np.random.default_rng(12)
    seen = set()
    for rcm in ([0.05, 0, 0.5], [0.9, 0, 0.0], [0.2, 0, 0.9], [0.75, 0, -0.35], [0.3, 0, -0.55]):
        rcm = np.array(rcm, float)
        tips = rcm + np.column_stack([rng.uniform(-0.1, 0.1, 200), rng.uniform(-0.1, 0.1, 200), rng.uniform(-0.3, -0.02, 200)])
        _, _, status = K.pose_singular_values(tips, rcm, ARM)
        for t, st in zip(tips, status):
            ref = _reference(rcm, t)
            assert (ref is None) == (st == K.STATUS_UNREACHABLE)
            seen.add(ref is None)
    assert seen == {True, False}


def test_elbow_down_branch_matches_reference():
    rng = np.random.default_rng(13)
    rcm, tips = _points(rng, 30, 0.02)
    smin, smax, status = K.pose_singular_values(tips, rcm, K.Pa10Arm(LINKS3, OFFSET, -1.0, QDOT, np.full(5, -1.0)))
    for t, lo, st in zip(tips, smin, status):
        k = (t - rcm) / np.linalg.norm(t - rcm)
        q = R.pa10_ik(t, k, LINKS, TOOL, elbow_up=False)
        if q is None:
            assert st == K.STATUS_UNREACHABLE
            continue
        s = R.scaled_singular_values(q, LINKS, TOOL, rcm, QDOT)
        assert lo == pytest.approx(1 / s[0], rel=1e-10)


@pytest.mark.parametrize("log_cond", [0, 2, 4, 6, 8])
def test_singular_values_3x3_against_lapack(log_cond):
    rng = np.random.default_rng(14 + log_cond)
    eps = np.finfo(float).eps
    for _ in range(300):
        U, _ = np.linalg.qr(rng.normal(size=(3, 3)))
        V, _ = np.linalg.qr(rng.normal(size=(3, 3)))
        s = np.sort(10.0 ** rng.uniform(-log_cond, 0, 3))[::-1]
        s[0], s[-1] = 1.0, 10.0 ** -log_cond
        B = U @ np.diag(s) @ V.T
        lo, hi = K.singular_values_3x3(*B.ravel())
        ref = np.linalg.svd(B, compute_uv=False)
        assert hi == pytest.approx(ref[0], rel=1e-14)
        # sigma_min = |det B| / (sigma_1 sigma_2): error ~ eps sigma_1^2 / sigma_2 absolute,
        # i.e. relative eps * cond when only sigma_3 is small. (B^T B would give
        # sqrt(eps) sigma_1 absolute: no digits at all at cond 1e8.)
        assert abs(lo - ref[-1]) <= 1e-12 * ref[-1] + 16 * eps * ref[0] ** 2 / ref[1]


def test_singular_values_3x3_special_cases():
    # isotropic (triple singular value), rank one, zero, diagonal
    Q, _ = np.linalg.qr(np.random.default_rng(5).normal(size=(3, 3)))
    assert np.allclose(K.singular_values_3x3(*(2.5 * Q).ravel()), (2.5, 2.5), rtol=1e-14)
    assert K.singular_values_3x3(*np.outer([1, 2, 3], [0, 1, 1]).ravel())[0] == 0.0
    assert K.singular_values_3x3(*np.zeros(9)) == (0.0, 0.0)
    lo, hi = K.singular_values_3x3(*np.diag([3.0, -0.5, 2.0]).ravel())
    assert (lo, hi) == (pytest.approx(0.5, rel=1e-15), pytest.approx(3.0, rel=1e-15))


def test_cos_third_acos_and_lambda_max():
    x = np.linspace(-1, 1, 20001)
    g = np.array([K.cos_third_acos(v) for v in x[::50]])
    assert np.allclose(g, np.cos(np.arccos(x[::50]) / 3), rtol=1e-14, atol=0)
    rng = np.random.default_rng(6)
    for _ in range(200):
        M = rng.normal(size=(3, 3))
        S = M @ M.T
        lam = K.sym3_lambda_max(S[0, 0], S[1, 1], S[2, 2], S[0, 1], S[0, 2], S[1, 2])
        assert lam == pytest.approx(np.linalg.eigvalsh(S)[-1], rel=1e-13)
    # a double largest eigenvalue (x -> -1, the hardest case for the series)
    Q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    S = Q @ np.diag([2.0, 2.0, 0.5]) @ Q.T
    assert K.sym3_lambda_max(S[0, 0], S[1, 1], S[2, 2], S[0, 1], S[0, 2], S[1, 2]) == pytest.approx(2.0, rel=1e-13)


def test_near_singular_wrist_against_reference():
    """Tool axis nearly along the forearm (W1 -> 0): J_a nearly singular."""
    q = np.array([0.0, 0.6, 1.2, 0.3, 1e-5])  # W1 = 1e-5 rad
    p, k = R.pa10_tool_tip(q, LINKS, TOOL)
    rcm = p - 0.1 * k  # RCM 0.1 m back along the tool
    lo, hi, st = K.pose_singular_values(p[None, :], rcm, ARM)
    s = R.scaled_singular_values(q, LINKS, TOOL, rcm, QDOT)
    assert st[0] == K.STATUS_OK
    assert 1 / s[0] < 1e-4 * (1 / s[-1])  # badly conditioned indeed
    assert lo[0] == pytest.approx(1 / s[0], rel=1e-6)
    assert hi[0] == pytest.approx(1 / s[-1], rel=1e-10)


def test_exactly_singular_wrist_is_flagged_not_nan():
    q = np.array([0.0, 0.6, 1.2, 0.3, 0.0])  # W1 = 0: E2 spins the tool about its own axis
    p, k = R.pa10_tool_tip(q, LINKS, TOOL)
    rcm = p - 0.1 * k
    lo, hi, st = K.pose_singular_values(p[None, :], rcm, ARM)
    assert st[0] == K.STATUS_SINGULAR
    assert lo[0] == 0.0 and np.isfinite(hi[0])
    assert global_isotropy_index(lo, hi)[0] == 0.0


def test_candidates_extremes_equals_reference_gii():
    cands = np.array([[0.535, 0, -0.21 + LINKS[0]], [0.26, 0, -0.14 + LINKS[0]], [0.9, 0, 0.3]])
    off = R.workspace_cube(np.zeros(3), n=5)
    lo, hi, n_unr, n_sing = K.rcm_candidates_extremes(cands, off, ARM)
    for c, a, b, u in zip(cands, lo, hi, n_unr):
        ref = R.rcm_candidate_gii(c, LINKS, TOOL, QDOT, LIM, n=5)
        if ref is None:
            assert u > 0
        else:
            assert u == 0
            assert a / b == pytest.approx(ref, rel=1e-10)
    assert n_unr[2] > 0


def test_bounded_candidate_culls_and_completes():
    c = np.array([0.535, 0, -0.21 + LINKS[0]])
    off = R.workspace_cube(np.zeros(3), n=9)
    full = K.rcm_candidate_bounded(c, off, ARM, 0.0, 16)
    assert full[4] == off.shape[0]
    gii = full[0] / full[1]
    culled = K.rcm_candidate_bounded(c, off, ARM, gii * 1.5, 16)
    assert culled[4] < off.shape[0]
    assert culled[0] / culled[1] <= gii * 1.5


def test_kernel_ik_round_trip_through_reference_fk():
    """Random joint angles (elbow up, within limits) -> reference FK -> kernel IK geometry."""
    rng = np.random.default_rng(15)
    n = 0
    while n < 200:
        q = np.array([rng.uniform(-1.5, 1.5), rng.uniform(-1.5, 1.5), rng.uniform(0.05, 2.3),
                      rng.uniform(-3, 3), rng.uniform(0.05, 2.8)])
        frames = R.pa10_frames(np.array([q[0], q[1], 0, q[2], q[3], q[4], 0]), LINKS)
        p, k = R.pa10_tool_tip(q, LINKS, TOOL)
        if k[2] > -0.05:  # the skin-plane RCM error needs a tool that crosses the skin plane
            continue
        w_ref = frames[5][:3, 3]
        if w_ref[0] * np.cos(q[0]) + w_ref[1] * np.sin(q[0]) <= 0.01:
            continue  # the other shoulder branch (S1 + pi, S2 and E1 negated): not the one we solve for
        rcm = p - 0.12 * k
        out = K.rcm_ik(*p, *rcm, *LINKS3, OFFSET, 1.0, *COSLIM)
        kk, w, nn, e, f, ok = out[0:3], out[3:6], out[6:9], out[9:12], out[12:15], out[15]
        assert np.allclose(kk, k, atol=1e-12)
        assert np.allclose(w, frames[5][:3, 3], atol=1e-12)  # wrist centre
        assert np.allclose(e, frames[3][:3, 3], atol=1e-12)  # elbow
        assert np.allclose(f, frames[4][:3, 2], atol=1e-12)  # forearm = E2 axis
        assert np.allclose(abs(np.dot(nn, frames[1][:3, 2])), 1.0)  # S2 axis
        assert ok == bool(np.all(np.abs(q) <= LIM))
        n += 1


def _cube(n, side=0.05, depth=0.1):
    t = np.linspace(-side / 2, side / 2, n)
    t = 0.5 * (t - t[::-1])
    X, Y, Z = np.meshgrid(t, t, t - depth, indexing="ij")
    return np.stack([X.ravel(), Y.ravel(), Z.ravel()], axis=1)


def test_mirror_half_keeps_y_nonnegative_points_with_multiplicity():
    off = _cube(5)
    half, mult = K.mirror_half(off)
    assert half.shape[0] == 5 * 3 * 5 and np.all(half[:, 1] >= 0)
    assert mult.sum() == off.shape[0] and set(mult[half[:, 1] == 0]) == {1} and set(mult[half[:, 1] > 0]) == {2}
    # not symmetric: unchanged, multiplicity one
    skew = off + np.array([0.0, 1e-9, 0.0])
    same, ones = K.mirror_half(skew)
    assert np.array_equal(same, skew) and np.all(ones == 1)


def test_mirror_reduction_equals_the_whole_cube():
    """The y >= 0 half with multiplicity gives the full cube's extremes and counts (mirror symmetry)."""
    off = _cube(7)
    rng = np.random.default_rng(21)
    cands = np.column_stack([rng.uniform(0.15, 0.85, 60), np.zeros(60), rng.uniform(-0.65, 0.1, 60) + LINKS[0]])
    cands = np.vstack([cands, [[0.535, 0, -0.21 + LINKS[0]], [0.26, 0, -0.14 + LINKS[0]]]])
    full = K.rcm_candidates_extremes(cands, off, ARM, mirror=False)
    half = K.rcm_candidates_extremes(cands, off, ARM, mirror=True)
    feasible = full[2] == 0
    assert 5 < feasible.sum() < 60  # both kinds are exercised
    assert np.array_equal(full[2], half[2]) and np.array_equal(full[3], half[3])
    assert np.allclose(half[0], full[0], rtol=1e-12, atol=0) and np.allclose(half[1], full[1], rtol=1e-12, atol=0)
    # the corner/face probes only choose the order of work: without them the result is the same
    no_probe = K.rcm_candidates_extremes(cands, off, ARM, mirror=False, probe_first=False)
    for a, b in zip(full, no_probe):
        assert np.array_equal(a, b)


def test_partially_reachable_candidate_counts_every_unreachable_point():
    """Probes all reachable, some interior/edge points not: the full pass still counts them exactly."""
    off = _cube(9)
    rng = np.random.default_rng(22)
    for _ in range(400):
        c = np.array([rng.uniform(0.15, 0.9), 0.0, rng.uniform(-0.7, 0.2) + LINKS[0]])
        _, _, st = K.pose_singular_values(c + off, c, ARM)
        n_bad = int(np.sum(st == K.STATUS_UNREACHABLE))
        probes = K.probe_points(off)
        if 0 < n_bad and np.all(st[probes] != K.STATUS_UNREACHABLE):
            break
    else:
        pytest.skip("no candidate with reachable probes but unreachable points found")
    lo, hi, n_unr, n_sing = K.rcm_candidates_extremes(c[None], off, ARM)
    assert n_unr[0] == n_bad and lo[0] == 0.0 and hi[0] == 0.0
