"""Raven IV kernels of one arm (surgopt/kinematics/raven.py): kinematics against DH matrices and finite
differences, isotropy, the theta2 interval."""
import math

import numpy as np
import pytest

from surgopt.kinematics import raven as K

import reference as R

AL, BE, A5 = math.radians(75), math.radians(52), 13.0  # Raven II link angles, wrist offset


@pytest.mark.parametrize("left", [True, False])
def test_fk_ik_round_trip(left):
    rng = np.random.default_rng(30 + left)
    for _ in range(300):
        q = np.array([rng.uniform(-math.pi, math.pi), math.radians(rng.uniform(20, 140)),
                      math.radians(rng.uniform(-86, 86)), rng.uniform(30, 250),
                      rng.uniform(-1.0, 1.0), math.radians(rng.uniform(-86, 86))])
        T = K.forward_kinematics(q, AL, BE, A5, left)
        q2, ok = K.inverse_kinematics(T, AL, BE, A5, left)
        assert ok
        assert np.allclose(q2, q, atol=1e-8), (q, q2)


def test_fk_matches_plain_dh_products():
    rng = np.random.default_rng(32)
    for left in (True, False):
        for _ in range(20):
            q = rng.uniform(-1, 1, 6)
            q[3] = rng.uniform(10, 200)
            z3, _ = R.raven_tool_axis(q[0], q[1], AL, BE, left)
            T = K.forward_kinematics(np.array([q[0], q[1], 0.0, q[3], q[4], q[5]]), AL, BE, A5, left)
            # the wrist sits d4 along the tool axis from the remote centre
            T4 = K.forward_kinematics(np.array([q[0], q[1], 0.0, q[3], 0.0, 0.0]), AL, BE, 0.0, left)
            assert np.allclose(T4[:3, 3], q[3] * z3, atol=1e-9)
            assert np.isfinite(T).all()


def test_ik_flags_poses_outside_the_joint_ranges():
    q = np.array([0.3, math.radians(150), 0.2, 100.0, 0.1, 0.2])  # theta2 beyond 140 deg
    _, ok = K.inverse_kinematics(K.forward_kinematics(q, AL, BE, A5, True), AL, BE, A5, True)
    assert not ok


@pytest.mark.parametrize("left", [True, False])
def test_spherical_jacobian_against_tool_axis_finite_differences(left):
    """J_s (eqs. 41-42) against d z3 / d(theta1, theta2) by finite differences.

    The printed J_s (velocity propagation in frame 3 with the paper's simplified DH:
    theta3 = 0, alpha4 = 0) is not the tool-axis Jacobian column for column, but the two
    differ only by orthogonal factors: they share their singular values, which is all
    the isotropy (eq. 35) uses."""
    rng = np.random.default_rng(33)
    h = 1e-6
    for _ in range(30):
        t1, t2 = rng.uniform(-3, 3), rng.uniform(0.2, 2.9)
        al, be = rng.uniform(0.2, 1.5), rng.uniform(0.2, 1.5)
        d1 = (R.raven_tool_axis(t1 + h, t2, al, be, left)[0] - R.raven_tool_axis(t1 - h, t2, al, be, left)[0]) / (2 * h)
        d2 = (R.raven_tool_axis(t1, t2 + h, al, be, left)[0] - R.raven_tool_axis(t1, t2 - h, al, be, left)[0]) / (2 * h)
        G_fd = np.array([[d1 @ d1, d1 @ d2], [d2 @ d1, d2 @ d2]])
        Js = K.spherical_jacobian(t2, al, be, left)[:2, :2]
        assert np.trace(Js.T @ Js) == pytest.approx(np.trace(G_fd), abs=1e-8)
        sv_fd = np.linalg.svd(np.column_stack([d1, d2]), compute_uv=False)
        assert np.allclose(np.linalg.svd(Js, compute_uv=False), sv_fd, atol=1e-8)
        assert K.isotropy_at(t2, al, be) == pytest.approx(R.isotropy_2x2(Js), rel=1e-12)
        # and the third column is the insertion: a unit vector along frame 3's z
        assert np.allclose(K.spherical_jacobian(t2, al, be, left)[:, 2], [0, 0, 1])


def test_isotropy_is_the_same_for_every_theta1():
    # Fig. 6b: J_s depends on theta2 only
    al, be = math.radians(55), math.radians(40)
    t2 = 1.1
    vals = []
    h = 1e-6
    for t1 in np.linspace(-3, 3, 7):
        d1 = (R.raven_tool_axis(t1 + h, t2, al, be)[0] - R.raven_tool_axis(t1 - h, t2, al, be)[0]) / (2 * h)
        d2 = (R.raven_tool_axis(t1, t2 + h, al, be)[0] - R.raven_tool_axis(t1, t2 - h, al, be)[0]) / (2 * h)
        s = np.linalg.svd(np.column_stack([d1, d2]), compute_uv=False)
        vals.append(s[-1] / s[0])
    assert np.allclose(vals, K.isotropy_at(t2, al, be), rtol=1e-6)


def test_isotropy_has_one_maximum_for_every_link_pair():
    t = np.radians(np.linspace(0, 180, 1441))
    for a in range(5, 91, 5):
        for b in range(5, 91, 5):
            v = np.array([K.isotropy_at(x, math.radians(a), math.radians(b)) for x in t])
            d = np.sign(np.diff(v))
            d = d[d != 0]
            assert np.sum((d[1:] < 0) & (d[:-1] > 0)) <= 1


def test_theta2_interval_fig6():
    """Fig. 6a (alpha = 55, beta = 40 deg): the theta2 range shrinks as Iso_min grows."""
    al, be = math.radians(55), math.radians(40)
    t = np.radians(np.linspace(0, 180, 180001))
    iso = np.array([K.isotropy_at(x, al, be) for x in t])
    prev = (0.0, math.pi)
    for m in (0.1, 0.3, 0.5, 0.7, 0.9):
        lo, hi, ok = K.theta2_interval(al, be, m, 0.0, math.pi)
        assert ok
        dense = t[iso >= m]
        assert lo == pytest.approx(dense.min(), abs=2e-5) and hi == pytest.approx(dense.max(), abs=2e-5)
        assert K.isotropy_at(lo, al, be) == pytest.approx(m, abs=1e-9)
        assert K.isotropy_at(hi, al, be) == pytest.approx(m, abs=1e-9)
        assert prev[0] <= lo < hi <= prev[1]
        prev = (lo, hi)
    # the numbers, for docs/reproduction.md: Iso_min 0.5 keeps theta2 in [79.6, 153.7] deg
    lo, hi, _ = K.theta2_interval(al, be, 0.5, 0.0, math.pi)
    assert math.degrees(lo) == pytest.approx(79.6, abs=0.1) and math.degrees(hi) == pytest.approx(153.7, abs=0.1)
    assert not K.theta2_interval(al, be, 0.99, 0.0, math.pi)[2]
