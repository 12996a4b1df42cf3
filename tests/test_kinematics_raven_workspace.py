"""Raven common workspace driver (surgopt/kinematics/raven_workspace.py) against the brute-force
reference of tests/reference.py, plane grids, the memo and the figure fields."""
import math

import numpy as np
import pytest

from surgopt.kinematics import raven_plane as P
from surgopt.kinematics import raven_workspace as W
from surgopt.studies.raven_sweep import study as S

import reference as R

PLANE = P.PlaneGrid(150.0, 4.0, 250.0)
THETA2 = (20.0, 140.0)


def _layout(**kw):
    return S.arm_layout(S.Geometry(**kw))


@pytest.mark.parametrize("geometry", [(0, 10, -20, 100, 50), (10, -20, 0, 150, 100), (0, 0, 0, 50, 50)])
def test_designs_of_a_geometry_equal_a_brute_force_evaluation(geometry):
    """The level-sharing kernel against per-design, per-arm membership, SVD isotropy, bisected theta2
    intervals and per-cell contour polygons, with ports and axes laid out independently."""
    al, be, iso = [25.0, 65.0, 85.0], [45.0, 85.0], [0.1, 0.5, 0.3, 0.9]
    got = W.evaluate_many(_layout(), PLANE, THETA2, [geometry], al, be, iso)
    ports, axes = R.raven_four_arm_frames(geometry[3], geometry[4], *geometry[:3])
    ref = R.raven_designs_brute_force(ports, axes, PLANE.depth_mm, PLANE.step_mm, PLANE.d4_max_mm,
                                      np.radians(al), np.radians(be), iso, THETA2)
    assert np.array_equal(got[:, 2], ref[:, 2])
    assert (ref[:, 2] > 0).sum() >= 6  # non-trivial
    assert np.allclose(got[:, 3], ref[:, 3], rtol=1e-11, atol=1e-12)
    nonempty = ref[:, 2] > 0
    assert np.allclose(got[nonempty, 4], ref[nonempty, 4], rtol=1e-11)
    assert np.allclose(got[:, 0], ref[:, 0], rtol=1e-11, atol=1e-9)
    assert np.allclose(got[:, 1], ref[:, 1], rtol=1e-11, atol=1e-9)


def test_a_node_at_exactly_the_insertion_limit_is_inside():
    """Table I's insertion range is closed, [0, 250] mm: with ports 40 mm apart each way, 16 nodes of the 4 mm grid
    are exactly 250 mm from their farthest port (a 150-200-250 triangle), and they count in n and the Iso sum.
    Premise: some designs hold such nodes (their n is above the count with the limit a hair shorter)."""
    al, be, iso = [25.0, 65.0, 85.0], [45.0, 85.0], [0.1, 0.5, 0.3, 0.9]
    geometry = (0, 0, 0, 40, 40)
    got = W.evaluate_many(_layout(), PLANE, THETA2, [geometry], al, be, iso)
    ports, axes = R.raven_four_arm_frames(geometry[3], geometry[4], *geometry[:3])
    xs, ys = R.raven_plane_nodes(ports, PLANE.depth_mm, PLANE.d4_max_mm, PLANE.step_mm)
    assert (R.raven_cone_fields(xs, ys, PLANE.depth_mm, ports, axes)[1].max(axis=0) == PLANE.d4_max_mm).sum() == 16
    args = (ports, axes, PLANE.depth_mm, PLANE.step_mm)
    closed = R.raven_designs_brute_force(*args, PLANE.d4_max_mm, np.radians(al), np.radians(be), iso, THETA2)
    open_ = R.raven_designs_brute_force(*args, math.nextafter(PLANE.d4_max_mm, 0.0), np.radians(al),
                                        np.radians(be), iso, THETA2)
    assert (closed[:, 2] > open_[:, 2]).sum() >= 3
    assert np.array_equal(got[:, 2], closed[:, 2])
    assert np.allclose(got[:, 3], closed[:, 3], rtol=1e-11, atol=1e-12)
    assert np.allclose(got[:, 0], closed[:, 0], rtol=1e-11, atol=1e-9)  # the area does not jump at its edge


def test_arm_frames_equal_the_written_out_layout():
    for g in [(0, 0, 0, 100, 50), (20, 10, -20, 100, 50), (-15, 35, 80, 60, 170)]:
        ports, axes = W.arms(_layout(), *g)
        rp, ra = R.raven_four_arm_frames(g[3], g[4], *g[:3])
        assert np.allclose(ports, rp, atol=1e-12) and np.allclose(axes, ra, atol=1e-12)
        assert np.allclose(np.linalg.norm(axes, axis=1), 1.0)


def test_arm_frames_are_the_same_from_the_cache_and_for_unhashable_layouts():
    """The shoulder frames are cached per (layout, phi, port rows); a repeated call, a layout holding lists
    (not hashable, computed directly) and a tilt along y (the rows matter) give the uncached numbers."""
    for toward in ("x", "y"):
        layout = W.ArmLayout(4, None, None, -30.0, toward, True, "zyx", "yz", "x")
        listed = layout._replace(left_arms=[True, False, True, False])
        for g in [(10.0, -5.0, 20.0, 80.0, 60.0), (10.0, -5.0, 20.0, 120.0, 0.0), (-20.0, 0.0, 0.0, 50.0, 50.0)]:
            direct = W._shoulder_frames.__wrapped__(layout, *g[:3], tuple(bool(y >= 0) for y in
                                                                           W.arm_frames(layout, *g)[0][:, 1]))
            for frames in (W.arm_frames(layout, *g), W.arm_frames(layout, *g), W.arm_frames(listed, *g)):
                assert np.array_equal(frames[1], direct[0]) and np.array_equal(frames[2], direct[1])
                frames[1][:] = 0.0  # callers get copies: the cache is not changed through them


def test_plane_grid_covers_every_reachable_node():
    geo = S.Config().geometry
    for g in [(0, 0, 0, 50, 50), (20, -10, 10, 200, 150), (0, 0, 0, 200, 200)]:
        ports, _ = W.arms(S.arm_layout(geo), *g)
        xs, ys = P.plane_grid(ports, geo.depth_mm, geo.d4_max_mm, geo.step_mm)
        reach = math.sqrt(geo.d4_max_mm ** 2 - geo.depth_mm ** 2)
        X, Y = np.meshgrid(np.arange(-400, 400.1, 2.0), np.arange(-400, 400.1, 2.0), indexing="ij")
        ok = np.all([(X - p[0]) ** 2 + (Y - p[1]) ** 2 <= reach ** 2 for p in ports], axis=0)
        if ok.any():
            assert xs.min() < X[ok].min() and xs.max() > X[ok].max()
            assert ys.min() < Y[ok].min() and ys.max() > Y[ok].max()
            assert np.allclose(np.diff(xs), geo.step_mm) and np.allclose(np.diff(ys), geo.step_mm)
            rx, ry = R.raven_plane_nodes(ports, geo.depth_mm, geo.d4_max_mm, geo.step_mm)
            assert np.array_equal(xs, rx) and np.array_equal(ys, ry)


def test_identical_geometries_share_one_evaluation():
    """Horizontal shoulder axes along x: phi_x turns them about themselves, so its rows coincide;
    the memo hands them over, and memo hits equal fresh evaluations."""
    geos = [(-20, 10, -20, 100, 50), (0, 10, -20, 100, 50), (20, 10, -20, 100, 50)]
    args = ([45, 85], [65], [0.3, 0.7])
    W.clear_memo()
    a = W.evaluate_many(_layout(), PLANE, THETA2, geos, *args)
    per = 4
    v = a.reshape(3, per, 6)
    assert np.array_equal(v[0], v[1]) and np.array_equal(v[0], v[2])
    b = W.evaluate_many(_layout(), PLANE, THETA2, geos, *args)  # all from the memo now
    W.clear_memo()
    c = W.evaluate_many(_layout(), PLANE, THETA2, geos[2:], *args)  # the last geometry alone, afresh
    assert np.array_equal(a, b)
    assert np.array_equal(a[2 * per:], c)


def test_design_fields_agree_with_the_sweep():
    """The figure's fields come from the sweep's kernels: the common margin is positive exactly on the
    nodes the sweep counts, and each arm's margin contains the common one."""
    g = (20.0, 10.0, -20.0, 100.0, 50.0)
    xs, ys, ports, per_arm, common = W.design_fields(_layout(), PLANE, THETA2, g, 65.0, 45.0, 0.5)
    metrics = W.evaluate_many(_layout(), PLANE, THETA2, [g], [65.0], [45.0], [0.5])
    assert int((common > 0).sum()) == int(metrics[0, 2]) > 0
    assert per_arm.shape == (4, xs.size, ys.size)
    assert np.all(per_arm.min(axis=0)[common > 0] > 0)
    # no interval (Iso_min above the mechanism's best): nothing inside
    assert np.all(W.design_fields(_layout(), PLANE, THETA2, g, 65.0, 45.0, 0.999)[4] < 0)


def test_every_geometry_field_changes_what_it_should():
    """phi_order and mirror_plane change the shoulder axes exactly where the rotations do not commute or
    the mirror differs; phi_x, which turns a horizontal x axis about itself under the default, moves the
    axes (and the sweep's rows) under an axis along y."""
    g = (20.0, 10.0, -20.0, 100.0, 50.0)
    _, a0 = W.arms(_layout(), *g)
    _, a1 = W.arms(_layout(phi_order="xyz"), *g)
    assert np.abs(a0 - a1).max() > 0.05
    _, b0 = W.arms(_layout(), 0.0, 0.0, 30.0, 100.0, 50.0)  # one rotation: the order does not matter
    _, b1 = W.arms(_layout(phi_order="xyz"), 0.0, 0.0, 30.0, 100.0, 50.0)
    assert np.allclose(b0, b1)
    # mirror planes: the right arms (2, 4) unchanged, the left ones (1, 3) not
    _, m0 = W.arms(_layout(), *g)
    _, m1 = W.arms(_layout(mirror_plane="xz"), *g)
    assert np.allclose(m0[[1, 3]], m1[[1, 3]]) and np.abs(m0[[0, 2]] - m1[[0, 2]]).max() > 0.05
    # a mirror image: the left arm's axis is the right arm's reflected in the chosen plane
    _, sym = W.arms(_layout(mirror_plane="yz"), *g)
    assert np.allclose(sym[0] * [-1, 1, 1], sym[1])
    # phi_x under the default geometry (axes along x): no effect; along y: an effect
    for toward, moves in (("x", False), ("y", True)):
        _, ax0 = W.arms(_layout(shoulder_tilt_toward=toward), 0.0, 0.0, 0.0, 100.0, 50.0)
        _, ax1 = W.arms(_layout(shoulder_tilt_toward=toward), 20.0, 0.0, 0.0, 100.0, 50.0)
        assert (np.abs(ax0 - ax1).max() > 0.1) == moves
    rows = W.evaluate_many(_layout(shoulder_tilt_toward="y"), PLANE, THETA2, [(0, 0, 0, 100, 50), (20, 0, 0, 100, 50)],
                           [85.0], [65.0], [0.5])
    assert abs(rows[0, 2] - rows[1, 2]) > 1.0  # area (cm^2) moves with phi_x
