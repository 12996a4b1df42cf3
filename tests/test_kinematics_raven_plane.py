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
