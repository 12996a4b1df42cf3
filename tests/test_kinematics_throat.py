"""Throat-arm kernels (surgopt/kinematics/throat.py) against the reference, quadrature and finite differences."""
import numpy as np
import pytest

from surgopt.kinematics import throat as T

import reference as R

LINKS = (60.0, 60.0, 110.0, 90.0, 80.0, 180.0)
Q0 = np.array([1.4522, 2.4707, 50, 0, np.pi / 2, -np.pi / 3, 0, -np.pi / 3])


def _geo(arm=550.0, fulcrum=None):
    geo = T.ThroatGeometry(*LINKS, arm, 25.0, 12.0, np.zeros(3), 1.0)
    P, *_ = T.five_bar(Q0[0], Q0[1], geo)
    return geo._replace(fulcrum_mm=np.asarray(fulcrum if fulcrum is not None else [P[0], P[1], -(arm + 50 - 150)], float))


def _random_q(rng):
    q = Q0 + np.array([rng.uniform(-0.15, 0.15), rng.uniform(-0.15, 0.15), rng.uniform(-20, 20),
                       rng.uniform(-3, 3), rng.uniform(-1.2, 1.2), rng.uniform(-3, 3),
                       rng.uniform(0.1, 2.5), rng.uniform(-3, 3)])
    return q


def test_five_bar_closure_and_reference():
    rng = np.random.default_rng(20)
    geo = _geo()
    for _ in range(100):
        q1, q2 = Q0[0] + rng.uniform(-0.3, 0.3), Q0[1] + rng.uniform(-0.3, 0.3)
        P, u, dP, du, det = T.five_bar(q1, q2, geo)
        D, B, C = R.five_bar_point_c(q1, q2, LINKS)
        assert np.isclose(np.linalg.norm(C - D), 90.0) and np.isclose(np.linalg.norm(C - B), 110.0)
        Pref, uref = R.five_bar_end(q1, q2, LINKS)
        assert np.allclose(P, Pref, atol=1e-10) and np.allclose(u, uref, atol=1e-12)
        assert abs(det) > 0


def test_five_bar_jacobian_against_finite_differences():
    rng = np.random.default_rng(21)
    geo = _geo()
    h = 1e-6
    for _ in range(50):
        q1, q2 = Q0[0] + rng.uniform(-0.3, 0.3), Q0[1] + rng.uniform(-0.3, 0.3)
        _, _, dP, du, _ = T.five_bar(q1, q2, geo)
        for j, (a, b) in enumerate(((h, 0), (0, h))):
            Pp, up = R.five_bar_end(q1 + a, q2 + b, LINKS)
            Pm, um = R.five_bar_end(q1 - a, q2 - b, LINKS)
            assert np.allclose(dP[:, j], (Pp - Pm) / (2 * h), atol=1e-6)
            assert np.allclose(du[:, j], (up - um) / (2 * h), atol=1e-8)


def test_straight_segment():
    for delta in (0.0, 0.7, -2.0):
        p, Rm, dpt, dpd, wt, wd = T.segment_kinematics(np.pi / 2, delta, 25.0)
        assert np.allclose(p, [0, 0, 25.0], atol=1e-12)
        assert np.allclose(Rm, np.eye(3), atol=1e-12)
        assert np.allclose(dpd, 0) and np.allclose(wd, 0)  # the delta column vanishes
        assert np.all(np.isfinite(dpt)) and np.allclose(np.linalg.norm(dpt), 12.5)  # dx/dtheta = -L/2


def test_bent_segment_checked_by_hand():
    # L = 25, theta_L = pi/3, delta = pi/4: x1 = L (sin(pi/3) - 1)/(-pi/6) = 6.3967,
    # z1 = L cos(pi/3)/(pi/6) = 23.8732, rotated by -delta about z.
    p, *_ = T.segment_kinematics(np.pi / 3, np.pi / 4, 25.0)
    assert np.allclose(p, [4.523, -4.523, 23.873], atol=5e-4)


def test_segment_against_quadrature_and_series_switch():
    rng = np.random.default_rng(22)
    for th in list(rng.uniform(0.1, 3.0, 30)) + [np.pi / 2 + 0.99e-4, np.pi / 2 - 1.01e-4, np.pi / 2 + 1e-9]:
        de = rng.uniform(-3, 3)
        p, Rm, *_ = T.segment_kinematics(th, de, 25.0)
        pr, Rr = R.segment_by_quadrature(th, de, 25.0)
        assert np.allclose(p, pr, atol=1e-9) and np.allclose(Rm, Rr, atol=1e-12)


def test_forward_kinematics_against_reference():
    rng = np.random.default_rng(23)
    geo = _geo()
    for _ in range(30):
        q = _random_q(rng)
        p, Rm = T.forward_kinematics(q, geo)
        pr, Rr = R.throat_fk(q, LINKS, 550.0, 25.0, 12.0, geo.fulcrum_mm)
        assert np.allclose(p, pr, atol=1e-8) and np.allclose(Rm, Rr, atol=1e-10)


@pytest.mark.parametrize("arm", [550.0, 800.0])
def test_full_jacobian_against_finite_differences(arm):
    rng = np.random.default_rng(24)
    geo = _geo(arm)
    for q in [Q0] + [_random_q(rng) for _ in range(15)]:
        J = T.jacobian(q, geo)
        Jfd = R.throat_jacobian_fd(q, LINKS, arm, 25.0, 12.0, geo.fulcrum_mm)
        assert np.allclose(J, Jfd, atol=2e-5 * max(1.0, np.abs(Jfd).max())), np.abs(J - Jfd).max()


def test_straight_snake_jacobian_has_no_nan():
    q = Q0.copy()
    q[6] = np.pi / 2  # both segments straight
    J = T.jacobian(q, _geo())
    assert np.all(np.isfinite(J))
    assert np.allclose(J[:, 5], 0) and np.allclose(J[:, 7], 0)


def test_weighted_least_norm_step_matches_constrained_solve():
    rng = np.random.default_rng(25)
    geo = _geo()
    for w in (np.ones(8), np.array([1000, 1000, 0.1, 0.1, 0.1, 0.1, 0.1, 0.1])):
        for _ in range(10):
            q = _random_q(rng)
            J = T.jacobian(q, geo)
            dx = rng.normal(size=6) * np.array([0.1, 0.1, 0.1, 0.01, 0.01, 0.01])
            dq = T.weighted_least_norm_step(J, w, dx, 0.0)
            assert np.allclose(J @ dq, dx, atol=1e-10)
            ref = R.weighted_least_norm_kkt(J, w, dx)
            assert np.allclose(dq, ref, atol=1e-9)
            # any other solution of J dq = dx costs more
            N = np.linalg.svd(J)[2][6:].T
            other = dq + N @ rng.normal(size=2) * 1e-3
            assert other @ (w * other) > dq @ (w * dq)


def test_damped_step_is_bounded_near_singularity():
    J = T.jacobian(Q0, _geo())
    J[4] = J[3] + 1e-9 * np.arange(8)  # two task rows nearly dependent: J W^-1 J^T ill-conditioned
    dx = np.array([0, 0, 0, 1e-3, 0, 0.0])
    undamped = T.weighted_least_norm_step(J, np.ones(8), dx, 0.0)
    damped = T.weighted_least_norm_step(J, np.ones(8), dx, 1e-2)
    assert not np.all(np.isfinite(undamped)) or np.linalg.norm(undamped) > 1e2
    assert np.linalg.norm(damped) < 1e-1 and np.all(np.isfinite(damped))


def test_suture_targets_half_circle():
    p0, R0 = T.forward_kinematics(Q0, _geo())
    for mode in (T.MODE_ORBIT_PARALLEL, T.MODE_ORBIT_TANGENT):
        pts = np.array([T.suture_target(mode, p0, R0, 6.0, a)[0] for a in np.linspace(0, np.pi, 50)])
        centre = pts[0] + (pts[-1] - pts[0]) / 2
        assert np.allclose(np.linalg.norm(pts - centre, axis=1), 6.0)
        assert np.isclose(np.linalg.norm(pts[-1] - pts[0]), 12.0)
    p, Rs = T.suture_target(T.MODE_SPIN, p0, R0, 6.0, np.pi)
    assert np.allclose(p, p0) and np.allclose(Rs[:, 2], R0[:, 2]) and np.allclose(Rs[:, 0], -R0[:, 0])
    # orbit_tangent keeps the gripper axis along the path's tangent
    a = 0.7
    pa, Ra = T.suture_target(T.MODE_ORBIT_TANGENT, p0, R0, 6.0, a)
    pb, _ = T.suture_target(T.MODE_ORBIT_TANGENT, p0, R0, 6.0, a + 1e-6)
    tangent = (pb - pa) / np.linalg.norm(pb - pa)
    assert np.allclose(tangent, Ra[:, 2], atol=1e-6)
