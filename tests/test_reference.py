"""The references themselves (tests/reference.py) against hand-checked poses and finite differences."""
import numpy as np
import pytest

import reference as R

LINKS = (0.317, 0.45, 0.48, 0.07)
TOOL = 0.587


def test_fk_zero_pose_points_straight_up():
    p, k = R.pa10_tool_tip(np.zeros(5), LINKS, TOOL)
    assert np.allclose(k, [0, 0, 1])
    assert np.allclose(p, [0, 0, 0.317 + 0.45 + 0.48 + 0.07 + 0.587])


def test_fk_hand_checked_elbow_at_90_deg():
    # S2 = 0, E1 = +90 deg: upper arm up, forearm along +x (rotation about +y).
    q = np.array([0.0, 0.0, np.pi / 2, 0.0, 0.0])
    p, k = R.pa10_tool_tip(q, LINKS, TOOL)
    assert np.allclose(k, [1, 0, 0], atol=1e-12)
    assert np.allclose(p, [0.48 + 0.07 + 0.587, 0, 0.317 + 0.45], atol=1e-12)
    # S1 = 90 deg swings that into +y
    p2, _ = R.pa10_tool_tip(np.array([np.pi / 2, 0, np.pi / 2, 0, 0]), LINKS, TOOL)
    assert np.allclose(p2, [0, 0.48 + 0.07 + 0.587, 0.317 + 0.45], atol=1e-12)


def _random_rcm_pose(rng):
    rcm = np.array([rng.uniform(0.35, 0.65), 0.0, rng.uniform(-0.45, 0.05) + LINKS[0]])
    tip = rcm + np.array([rng.uniform(-0.025, 0.025), rng.uniform(-0.025, 0.025), -0.1 + rng.uniform(-0.025, 0.025)])
    return rcm, tip


def test_ik_fk_round_trip():
    rng = np.random.default_rng(1)
    n = 0
    for _ in range(200):
        rcm, tip = _random_rcm_pose(rng)
        k = (tip - rcm) / np.linalg.norm(tip - rcm)
        q = R.pa10_ik(tip, k, LINKS, TOOL)
        if q is None:
            continue
        p, kk = R.pa10_tool_tip(q, LINKS, TOOL)
        assert np.allclose(p, tip, atol=1e-12)
        assert np.allclose(kk, k, atol=1e-12)
        n += 1
    assert n > 150


def test_alternative_jacobian_matches_finite_differences():
    rng = np.random.default_rng(2)
    for _ in range(20):
        rcm, tip = _random_rcm_pose(rng)
        q = R.pa10_ik(tip, (tip - rcm) / np.linalg.norm(tip - rcm), LINKS, TOOL)
        if q is None:
            continue
        J = R.pa10_alternative_jacobian(q, LINKS, TOOL, rcm)
        h = 1e-6
        Jfd = np.column_stack([
            (R.pa10_alternative_fk(q + h * e, LINKS, TOOL, rcm) - R.pa10_alternative_fk(q - h * e, LINKS, TOOL, rcm)) / (2 * h)
            for e in np.eye(5)])
        assert np.allclose(J, Jfd, atol=1e-8)
        # at an IK solution the tool passes through the RCM: e = 0
        assert np.allclose(R.pa10_alternative_fk(q, LINKS, TOOL, rcm)[3:], 0, atol=1e-12)


def test_reverse_jacobian_keeps_rcm_error_zero():
    """J_r x_dot is a joint velocity that moves the tip by x_dot and keeps e at zero (eqs. 5-6)."""
    rng = np.random.default_rng(3)
    rcm, tip = np.array([0.535, 0, 0.107]), np.array([0.545, -0.01, 0.0])
    q = R.pa10_ik(tip, (tip - rcm) / np.linalg.norm(tip - rcm), LINKS, TOOL)
    Jr = R.reverse_jacobian(R.pa10_alternative_jacobian(q, LINKS, TOOL, rcm))
    for _ in range(5):
        xdot = rng.normal(size=3)
        qdot = Jr @ xdot
        h = 1e-5
        f = lambda s: R.pa10_alternative_fk(q + s * qdot, LINKS, TOOL, rcm)
        rate = (f(h) - f(-h)) / (2 * h)
        tol = 1e-7 * np.linalg.norm(qdot)  # central differences, O(h^2 |qdot|^3)
        assert np.allclose(rate[:3], xdot, atol=tol)
        assert np.allclose(rate[3:], 0, atol=tol)
        # a generic joint velocity of that size would move e by O(|qdot|)
        assert np.linalg.norm(R.pa10_alternative_jacobian(q, LINKS, TOOL, rcm)[3:] @ rng.normal(size=5)) > 1e-3


def test_gii_of_known_matrix_set():
    # three "workspace points" with known singular values
    mats = [np.diag([1.0, 2.0, 3.0]), np.diag([0.5, 1.0, 1.5]), np.diag([2.0, 4.0, 6.0])]
    s = [np.linalg.svd(m, compute_uv=False) for m in mats]
    gii = R.global_isotropy_index([x[-1] for x in s], [x[0] for x in s])
    assert gii == pytest.approx(0.5 / 6.0)
