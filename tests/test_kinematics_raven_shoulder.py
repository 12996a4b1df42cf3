"""The Raven shoulder range (surgopt/kinematics/raven_shoulder.py): theta1 at a node against plain DH products,
and the sweep's theta1-limited membership against the arm's own IK on random nodes and designs."""
import math

import numpy as np
import pytest

from surgopt.kinematics import raven as K
from surgopt.kinematics import raven_plane as P
from surgopt.kinematics import raven_shoulder as SH
from surgopt.kinematics import raven_workspace as W
from surgopt.studies.raven_sweep import study as S

import reference as R


def _layout(**kw):
    return S.arm_layout(S.Geometry(**kw))


def test_theta1_of_a_node_inverts_the_dh_tool_axis():
    """theta1 from the node's direction (cos psi, azimuth) equals the theta1 that put the tool axis there
    (Table I's DH by plain matrix products), both arm sides; the docstring's worked example too."""
    rng = np.random.default_rng(161)
    for left in (True, False):
        sigma = 1.0 if left else -1.0
        for _ in range(200):
            t1, t2 = rng.uniform(-math.pi, math.pi), rng.uniform(0.2, 2.9)
            al, be = np.radians(rng.uniform(10, 90, 2))
            z3, _ = R.raven_tool_axis(t1, t2, al, be, left)
            rho = rng.uniform(0.5, 3.0)  # the direction's scale does not matter
            got = SH.theta1_of_node(z3[2], rho * z3[0], rho * sigma * z3[1], al, be)
            assert abs(math.remainder(got - t1, 2 * math.pi)) < 1e-9
    z3, _ = R.raven_tool_axis(0.7, math.pi / 2, math.pi / 2, math.pi / 2, True)
    assert math.atan2(z3[1], z3[0]) == pytest.approx(0.7, abs=1e-12)  # theta1 = az


def test_zero_directions_are_frames_and_mirror_images():
    for g in [(0, 0, 0, 100, 50), (20, 10, -20, 100, 50), (-15, 35, 80, 60, 170)]:
        for zero in ("y", "x", "-x", "-y"):
            _, axes, x0 = W.arm_frames(_layout(theta1_zero_toward=zero), *g)
            assert np.allclose(np.linalg.norm(x0, axis=1), 1.0) and np.allclose((axes * x0).sum(axis=1), 0, atol=1e-12)
            assert np.allclose(x0, R.raven_four_arm_zero_axes(*g[:3], zero=W.ZERO_DIRECTIONS[zero]), atol=1e-12)
            # the y-z mirror maps a right arm's frame 0 onto its left neighbour's at phi = 0
        _, a0, x00 = W.arm_frames(_layout(), 0, 0, 0, 100, 50)
        assert np.allclose(x00[0], x00[1] * [-1, 1, 1]) and np.allclose(a0[0], a0[1] * [-1, 1, 1])


def _ik_membership(node, ports, axes, x0, left, alpha, beta, t2_interval, t1_range_deg, d4_max):
    """All arms reach ``node`` with theta1 inside its range (strictly), theta2 inside the Iso_min-narrowed
    interval and d4 at most d4_max, by each arm's analytic IK (eqs. 9-32) of a pose in its frame 0; the IK's
    joints are checked against plain DH products (the tool axis passes through the node)."""
    lo1, hi1 = np.radians(t1_range_deg)
    for a in range(len(ports)):
        y0 = np.cross(axes[a], x0[a])
        p = np.array([x0[a], y0, axes[a]]) @ (node - ports[a])
        d4 = np.linalg.norm(p)
        z3 = p / d4
        x3 = np.cross([0.3, 0.5, 0.8], z3)
        x3 /= np.linalg.norm(x3)
        T03 = np.eye(4)
        T03[:3, :3] = np.column_stack([x3, np.cross(z3, x3), z3])
        q, _ = K.inverse_kinematics(T03 @ K.wrist_transform(d4, 0.0, 0.0, 13.0), alpha, beta, 13.0, bool(left[a]))
        c2 = (z3[2] + math.cos(alpha) * math.cos(beta)) / (math.sin(alpha) * math.sin(beta))  # eq. 22
        if abs(c2) > 1:  # the tool axis cannot point there: no joints reach the node
            return False
        assert np.allclose(R.raven_tool_axis(q[0], q[1], alpha, beta, bool(left[a]))[0], z3, atol=1e-7)
        assert abs(q[3] - d4) < 1e-9
        t1 = (q[0] - lo1) % (2 * math.pi)
        reach = np.sum((node - ports[a]) ** 2) <= d4_max ** 2  # closed (Table I); exact for nodes on the sphere
        if not (0 < t1 < hi1 - lo1 and t2_interval[0] < q[1] < t2_interval[1] and reach):
            return False
    return True


CASES = [  # layout fields, geometry (phi_x, phi_y, phi_z, bx, by), theta1 range
    ({}, (20.0, 10.0, -20.0, 100.0, 50.0), (0.0, 90.0)),
    ({"theta1_zero_toward": "x"}, (0.0, -10.0, 10.0, 60.0, 80.0), (-120.0, 100.0)),
    ({"shoulder_tilt_deg": -30.0, "shoulder_tilt_toward": "y", "theta1_zero_toward": "y"},
     (10.0, 5.0, -15.0, 80.0, 60.0), (90.0, 240.0)),
]


@pytest.mark.parametrize("fields, geometry, t1_range", CASES)
def test_theta1_limited_membership_equals_the_arms_ik(fields, geometry, t1_range):
    """The sweep counts exactly the nodes where every arm's IK gives joints inside their ranges, for
    random (alpha, beta, Iso_min); the figure fields mark the same nodes (on 300 random ones)."""
    rng = np.random.default_rng(hash(t1_range) % 2 ** 32)
    layout, plane = _layout(**fields), P.PlaneGrid(150.0, 6.0, 250.0)
    ports, axes, x0 = W.arm_frames(layout, *geometry)
    left = W.left_arms(layout)
    xs, ys = P.plane_grid(ports, plane.depth_mm, plane.d4_max_mm, plane.step_mm)
    nodes = [np.array([x, y, -plane.depth_mm]) for x in xs for y in ys]
    checked = 0
    for _ in range(4):
        al, be = rng.uniform(50, 90, 2)
        iso = float(rng.uniform(0.0, 0.5))
        got = W.evaluate_many(layout, plane, (20.0, 140.0), [geometry], [al], [be], [iso], theta1_range_deg=t1_range)
        t2 = R.raven_theta2_interval(math.radians(al), math.radians(be), iso, math.radians(20), math.radians(140))
        if t2 is None:
            assert got[0, 2] == 0
            continue
        inside = [_ik_membership(v, ports, axes, x0, left, math.radians(al), math.radians(be), t2, t1_range,
                                 plane.d4_max_mm) for v in nodes]
        assert got[0, 2] == sum(inside)
        checked += sum(inside) > 0
        # the figure's common margin: positive exactly where the IK says inside (random nodes of its grid)
        fx, fy, _, _, common = W.design_fields(layout, plane, (20.0, 140.0), geometry, al, be, iso,
                                               theta1_range_deg=t1_range)
        for i, j in zip(rng.integers(0, fx.size, 300), rng.integers(0, fy.size, 300)):
            v = np.array([fx[i], fy[j], -plane.depth_mm])
            assert (common[i, j] > 0) == _ik_membership(v, ports, axes, x0, left, math.radians(al),
                                                        math.radians(be), t2, t1_range, plane.d4_max_mm)
    assert checked >= 1  # not only empty workspaces


def test_theta1_range_cuts_the_workspace_and_its_contour():
    """A limited theta1 leaves a subset of the unlimited workspace; a range of 360 deg is no limit; the
    contour's area stays within a cell row of the node count, and the perimeter grows where theta1 cuts."""
    layout, plane = _layout(), P.PlaneGrid(150.0, 2.0, 250.0)
    g = [(20.0, 10.0, -20.0, 100.0, 50.0)]
    free = W.evaluate_many(layout, plane, (20.0, 140.0), g, [65.0], [45.0], [0.3])
    full = W.evaluate_many(layout, plane, (20.0, 140.0), g, [65.0], [45.0], [0.3], theta1_range_deg=(-180.0, 180.0))
    assert np.array_equal(free, full)
    cuts = []
    for lo in range(-180, 180, 30):
        cut = W.evaluate_many(layout, plane, (20.0, 140.0), g, [65.0], [45.0], [0.3], theta1_range_deg=(lo, lo + 120))
        assert cut[0, 2] <= free[0, 2]
        if cut[0, 2] > 0:
            assert abs(cut[0, 0] - cut[0, 2] * 4.0) < cut[0, 1] * 2.0 + 1e-9  # area ~ nodes x cell
        cuts.append(cut[0, 2])
    assert min(cuts) < free[0, 2] and max(cuts) > 0  # some ranges cut, some leave a workspace


def test_phi_x_and_the_zero_direction_matter_once_theta1_is_limited():
    """Under the default geometry phi_x turns each shoulder axis about itself: no effect while theta1 is
    unlimited, an effect once it is limited (it turns theta1's zero); so does theta1_zero_toward."""
    plane = P.PlaneGrid(150.0, 4.0, 250.0)
    geos = [(0.0, 10.0, -20.0, 100.0, 50.0), (20.0, 10.0, -20.0, 100.0, 50.0)]
    args = ([85.0], [65.0], [0.5])
    free = W.evaluate_many(_layout(), plane, (20.0, 140.0), geos, *args)
    assert np.array_equal(free[0], free[1])
    lim = W.evaluate_many(_layout(), plane, (20.0, 140.0), geos, *args, theta1_range_deg=(0.0, 90.0))
    assert abs(lim[0, 2] - lim[1, 2]) > 10
    other = W.evaluate_many(_layout(theta1_zero_toward="y"), plane, (20.0, 140.0), geos[:1], *args,
                            theta1_range_deg=(0.0, 90.0))
    assert abs(other[0, 2] - lim[0, 2]) > 10
    same = W.evaluate_many(_layout(theta1_zero_toward="y"), plane, (20.0, 140.0), geos[:1], *args)
    assert np.array_equal(same[0], free[0])


def test_turning_the_zero_by_90_deg_is_shifting_the_range():
    """Under horizontal shoulder axes along x, theta1's zero 'y' is the zero 'x' (the downward vertical)
    turned by 90 deg about each shoulder axis, on both sides: the range [lo, hi] about 'x' and
    [lo + 90, hi + 90] about 'y' give the same rows (docs/raven_geometry_fit_theta1.csv pairs them up)."""
    plane = P.PlaneGrid(150.0, 4.0, 250.0)
    geos = [(20.0, 10.0, -20.0, 100.0, 50.0), (-10.0, 0.0, 20.0, 150.0, 50.0)]
    args = ([65.0, 85.0], [45.0, 65.0], [0.1, 0.5])
    for lo, hi in ((0.0, 90.0), (-45.0, 135.0)):
        a = W.evaluate_many(_layout(theta1_zero_toward="x"), plane, (20.0, 140.0), geos, *args,
                            theta1_range_deg=(lo, hi))
        b = W.evaluate_many(_layout(theta1_zero_toward="y"), plane, (20.0, 140.0), geos, *args,
                            theta1_range_deg=(lo + 90.0, hi + 90.0))
        assert a[:, 2].sum() > 0 and np.allclose(a, b, rtol=1e-9, atol=1e-9)
