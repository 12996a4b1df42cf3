"""Raven IV plane kernels (surgopt/kinematics/raven_plane.py): marching squares against closed forms
and per-cell polygons, node isotropy against the SVD reference."""
import math

import numpy as np
import pytest

from surgopt.kinematics import raven_plane as P

import reference as R


def _field(f, step, ext):
    xs = np.arange(-ext, ext + step / 2, step)
    X, Y = np.meshgrid(xs, xs, indexing="ij")
    return f(np.hypot(X, Y)).ravel(), xs.size


@pytest.mark.parametrize("radius", [20.0, 57.3, 150.0])
def test_marching_squares_disc(radius):
    m, n = _field(lambda r: radius - r, 2.0, radius + 10)
    length, area = P.marching_squares(m, n, n, 2.0)
    assert length == pytest.approx(2 * math.pi * radius, rel=0.01)
    assert area == pytest.approx(math.pi * radius ** 2, rel=0.01)
    # the 0/1 staircase would overestimate the perimeter by 4/pi
    staircase = 2.0 * np.sum(np.abs(np.diff((m.reshape(n, n) > 0).astype(int), axis=0))) * 2
    assert staircase / (2 * math.pi * radius) > 1.2


def test_marching_squares_annulus():
    r1, r2 = 40.0, 130.0
    m, n = _field(lambda r: np.minimum(r - r1, r2 - r), 2.0, r2 + 10)
    length, area = P.marching_squares(m, n, n, 2.0)
    assert length == pytest.approx(2 * math.pi * (r1 + r2), rel=0.01)
    assert area == pytest.approx(math.pi * (r2 ** 2 - r1 ** 2), rel=0.01)
    assert area / length == pytest.approx(R.annulus_zeta_mm(r1, r2), rel=0.01)


def test_cell_contour_matches_polygon_clipping():
    """The closed-form cell routine against a shoelace on the walked inside polygon (tests/reference.py)."""
    rng = np.random.default_rng(40)
    cases = rng.normal(size=(4000, 4))
    cases[:200] = np.sign(cases[:200]) * rng.uniform(1e-9, 1e-6, (200, 4))  # near-degenerate crossings
    cases[200:300] = [[1, -1, 1, -1], [-1, 1, -1, 1], [2, -1, 3, -0.5], [-2, 1, -3, 0.5]] * 25  # saddles
    for v in cases:
        length, area = P.marching_squares(np.array([v[0], v[3], v[1], v[2]]), 2, 2, 1.0)  # rows are x
        ref_len, ref_area = R.cell_contour(v)
        assert length == pytest.approx(ref_len, rel=1e-12, abs=1e-14)
        assert area == pytest.approx(ref_area, rel=1e-12, abs=1e-14)


def test_node_isotropy_is_the_minimum_over_the_arms():
    """Iso is unimodal in theta2, so the minimum over the arms sits at the lowest or highest cos psi."""
    rng = np.random.default_rng(41)
    for a_deg, b_deg in [(5, 5), (25, 85), (55, 40), (85, 85), (90, 45), (15, 75)]:
        al, be = math.radians(a_deg), math.radians(b_deg)
        lo_c, hi_c = -math.cos(al - be), -math.cos(al + be)  # theta2 = 180 and 0 deg (eq. 22)
        cos_psi = rng.uniform(lo_c, hi_c, (4, 500))  # reachable cone angles of four arms
        out = np.empty(500)
        P.node_isotropy(cos_psi.min(axis=0), cos_psi.max(axis=0), al, be, out)
        ref = R.raven_isotropy_from_cos_psi(cos_psi, al, be).min(axis=0)
        assert np.allclose(out, ref, rtol=1e-12, atol=1e-14)


def _full_plane(ports, axes, zero_axes, left, plane, designs, rng):
    """Every design of one geometry on the whole plane grid (no mirror halving)."""
    from surgopt.kinematics.raven_shoulder import shoulder_fields

    xs, ys = P.plane_grid(ports, plane.depth_mm, plane.d4_max_mm, plane.step_mm)
    bounds = P.plane_node_bounds(xs, ys, plane.depth_mm, ports, axes, plane.d4_max_mm)
    fields = shoulder_fields(xs, ys, plane.depth_mm, ports, axes, zero_axes, left)
    out = np.zeros((designs.alphas_rad.size * designs.betas_rad.size * designs.iso_mins.size, 6))
    P.evaluate_designs(bounds, xs.size, ys.size, plane.step_mm, designs, fields, rng, out)
    return out


@pytest.mark.parametrize("layout_fields, t1", [
    ({}, (0.0, 90.0)),
    ({"shoulder_tilt_toward": "y", "shoulder_tilt_deg": -30.0, "theta1_zero_toward": "y"}, (90.0, 240.0)),
    ({"n_arms": 2, "phi_order": "xyz"}, None),
])
def test_a_mirror_symmetric_layout_is_evaluated_on_half_the_plane(layout_fields, t1):
    """Arms that are their own mirror image in x = 0 (the left arms mirroring the right ones) are
    detected for random phi; the sweep then evaluates the half x >= 0 and counts the rest twice: the
    same point counts and Iso minima as the whole plane, areas, perimeters and isotropy sums to rounding.
    A layout that is not symmetric is not halved."""
    from surgopt.kinematics import raven_workspace as W
    from surgopt.kinematics.raven_shoulder import shoulder_range

    rng = np.random.default_rng(7)
    base = dict(n_arms=4, ports_mm=None, left_arms=None, shoulder_tilt_deg=90.0, shoulder_tilt_toward="x",
                mirror_left_phi=True, phi_order="zyx", mirror_plane="yz", theta1_zero_toward="x")
    layout = W.ArmLayout(**{**base, **layout_fields})
    plane, shoulder = P.PlaneGrid(150.0, 4.0, 250.0), shoulder_range(t1)
    al, be, iso = np.radians([55.0, 80.0]), np.radians([50.0, 75.0]), np.array([0.1, 0.4])
    designs = W.cone_angle_intervals(al, be, iso, (20.0, 140.0))
    left = W.left_arms(layout)
    for _ in range(3):
        g = (*rng.uniform(-20, 20, 3), *rng.uniform(60, 150, 2))
        ports, axes, x0 = W.arm_frames(layout, *g)
        assert P.mirror_symmetric(ports, axes, x0, left, shoulder.limited)
        half = np.zeros((8, 6))
        P.evaluate_geometries(ports[None], axes[None], x0[None], left, plane, designs, shoulder, half)
        full = _full_plane(ports, axes, x0, left, plane, designs, shoulder)
        assert full[:, 2].sum() > 0
        assert np.array_equal(half[:, [2, 4, 5]], full[:, [2, 4, 5]])
        assert np.allclose(half, full, rtol=1e-12, atol=0)
    # not symmetric: phi not mirrored for the left arms, or ports that are not mirror images
    ports, axes, x0 = W.arm_frames(layout._replace(mirror_left_phi=False), 10.0, 5.0, 8.0, 100.0, 50.0)
    assert not P.mirror_symmetric(ports, axes, x0, left, shoulder.limited)
    shifted = layout._replace(ports_mm=tuple((x + 5.0, y) for x, y in W.arm_frames(layout, 0, 0, 0, 100, 50)[0][:, :2]))
    ports, axes, x0 = W.arm_frames(shifted, 0.0, 0.0, 0.0, 100.0, 50.0)
    assert not P.mirror_symmetric(ports, axes, x0, left, shoulder.limited)
    half = np.zeros((8, 6))
    P.evaluate_geometries(ports[None], axes[None], x0[None], left, plane, designs, shoulder, half)
    assert np.array_equal(half, _full_plane(ports, axes, x0, left, plane, designs, shoulder))
