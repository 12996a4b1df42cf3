"""port-place's kernels (surgopt/kinematics/port/place.py, designs.py) against references that share no code
with them: the dVRK arms' RCM kinematics (P1, P2) against the modified-DH tables multiplied out in
tests/reference.py, the isotropy (P5) against a finite-difference Jacobian, reach against joint-space sampling,
the pair tables (P6, P7, P9) against closed forms and per-pair numpy loops, the design kernel (P11) against a
brute force over the reach sets. The equations are those of docs/port_placement.md, "The model"."""
import itertools
import math

import numpy as np
import pytest

from surgopt.kinematics.port import columns as F
from surgopt.kinematics.port import designs as D
from surgopt.kinematics.port import place as K
from surgopt.robots.models import get_model
from surgopt.studies.port_place import config as C
from surgopt.studies.port_place import study as S
from surgopt.studies.port_place import tables as T

from reference import (ECM_CLASSIC_MDH, PSM_CLASSIC_MDH, brute_force_reach, finite_difference_jacobian, mdh_chain,
                       segment_distance_sampled)

ANY_APPROACH = K.Approach(0.0, 0.0, -1.0, -2.0)  # no approach cone
RNG = np.random.default_rng(31)


def _limits(arm):
    return T.arm_limits(arm)


@pytest.mark.parametrize("arm, rows", [(get_model("dvrk_psm_classic"), PSM_CLASSIC_MDH),
                                       (get_model("dvrk_ecm_classic"), ECM_CLASSIC_MDH)])
def test_closed_form_rcm_point_is_the_dh_product_and_inverts(arm, rows):
    lim = _limits(arm)
    for _ in range(200):
        q = [RNG.uniform(lim.yaw_lo, lim.yaw_hi), RNG.uniform(lim.pitch_lo, lim.pitch_hi),
             RNG.uniform(lim.insertion_lo, lim.insertion_hi)]
        ref = mdh_chain(rows, q)
        p = K.rcm_point(*q, lim.along_shaft_m)
        assert np.allclose(p, ref[:3, 3], atol=1e-12)
        assert np.allclose(K.shaft_direction(q[0], q[1]), ref[:3, 2], atol=1e-12)  # the shaft is the last z axis
        back = K.rcm_inverse(p, lim.along_shaft_m)
        if q[2] + lim.along_shaft_m > 1e-3:  # away from the RCM itself, where the direction is undefined
            assert np.allclose(back, q, atol=1e-10), (q, back)


def test_the_rcm_stays_at_the_port_for_every_joint_value():
    """The shaft line through the wrist at two insertions passes through the base origin (the port)."""
    for _ in range(100):
        q1, q2 = RNG.uniform(-1.5, 1.5), RNG.uniform(-0.9, 0.9)
        a, b = mdh_chain(PSM_CLASSIC_MDH, [q1, q2, 0.05])[:3, 3], mdh_chain(PSM_CLASSIC_MDH, [q1, q2, 0.2])[:3, 3]
        assert np.linalg.norm(np.cross(a, b)) < 1e-12  # collinear with the origin
        assert np.linalg.norm(b - a) == pytest.approx(0.15, abs=1e-12)


def test_isotropy_is_the_scaled_jacobian_condition_from_finite_differences():
    lim, length = _limits(get_model("dvrk_psm_classic")), 0.1
    for _ in range(50):
        q = np.array([RNG.uniform(-1.5, 1.5), RNG.uniform(-0.9, 0.9), RNG.uniform(0.02, 0.24)])
        J = finite_difference_jacobian(lambda v: mdh_chain(PSM_CLASSIC_MDH, v)[:3, 3], q, h=1e-6)
        J[:, :2] /= length  # angular columns in units of the characteristic length
        s = np.linalg.svd(J, compute_uv=False)
        assert K.isotropy(q[1], q[2] + lim.along_shaft_m, length) == pytest.approx(s[-1] / s[0], rel=1e-6)


def test_reach_matches_joint_space_sampling():
    """Target points around one port: the closed-form verdict against the nearest of ~44,000 joint-space
    samples (reference.brute_force_reach), on every point not within a grid gap of the reach boundary."""
    lim = _limits(get_model("dvrk_psm_classic"))
    site, centre = np.array([0.0, 0.0, 0.0]), np.array([0.02, -0.03, -0.15])
    rot = K.docking_frames(site[None], centre, np.array([1.0, 0.0, 0.0]))
    pts = centre + RNG.uniform(-0.12, 0.12, size=(150, 3))
    reach, _ = K.instrument_tables(site[None], rot, pts, lim, 0.1, ANY_APPROACH)
    base = np.array([K.to_base(rot[0], site, p) for p in pts])
    d, gap = brute_force_reach(base, PSM_CLASSIC_MDH, [(lim.yaw_lo, lim.yaw_hi), (lim.pitch_lo, lim.pitch_hi),
                                                        (lim.insertion_lo, lim.insertion_hi)])
    clear_out = d > gap
    assert clear_out.sum() > 20  # the premise: the sample has points the arm cannot reach
    assert reach[0][clear_out].sum() == 0  # far from every sample: never called reachable
    near = d < 0.25 * gap
    # a point near a sample is reachable unless it sits at the boundary (then the sample is a limit value)
    q = np.array([K.rcm_inverse(p, lim.along_shaft_m) for p in base])
    margin = np.minimum.reduce([q[:, 0] - lim.yaw_lo, lim.yaw_hi - q[:, 0], q[:, 1] - lim.pitch_lo,
                                lim.pitch_hi - q[:, 1], q[:, 2] - lim.insertion_lo, lim.insertion_hi - q[:, 2]])
    inside = near & (margin > 0.05)
    assert inside.sum() > 20 and reach[0][inside].all()


def test_manipulation_angle_and_shaft_distance_closed_forms():
    """Two ports at (+-d, 0, h) over a point target at the origin: the angle 2 atan(d / h); two shafts that
    cross at right angles a height g apart: distance g."""
    d, h = 0.05, 0.1
    sites = np.array([[-d, 0.0, h], [d, 0.0, h]])
    target = np.zeros((1, 3))
    crit = T.criteria(C.PortPlaceConfig())
    reach = np.ones((2, 1), dtype=bool)
    out = K.pair_tables(sites, reach, np.ones((2, 1)), target, np.zeros(3), crit)
    assert out[2][0, 1] == pytest.approx(2 * math.atan(d / h), abs=1e-14)
    assert out[6][0, 1] == pytest.approx(2 * math.atan(d / h), abs=1e-14)
    g = 0.013
    a0, a1 = np.array([-1.0, 0.0, 0.0]), np.array([1.0, 0.0, 0.0])
    b0, b1 = np.array([0.0, -1.0, g]), np.array([0.0, 1.0, g])
    assert K.segment_distance(a0, a1, b0, b1) == pytest.approx(g, abs=1e-15)
    # against sampling both segments
    for _ in range(20):
        p0, p1, q0, q1 = RNG.normal(size=(4, 3))
        s = np.linspace(0, 1, 401)
        P, Q = p0 + s[:, None] * (p1 - p0), q0 + s[:, None] * (q1 - q0)
        brute = np.min(np.linalg.norm(P[:, None] - Q[None], axis=2))
        assert brute - 1e-2 <= K.segment_distance(p0, p1, q0, q1) <= brute + 1e-12


def _tables(n, m, rng):
    """Random per-port and per-pair tables of n sites over m target points (pair entries filled i < j), with
    some sites reaching every point and some only part of them."""
    reach = rng.random((n, m)) < 0.9
    reach[: n // 2] = True
    dex = rng.random((n, m)) * reach
    upper = np.triu(np.ones((n, n), bool), 1)
    pair = [np.where(upper, rng.random((n, n)), 0.0) for _ in range(8)]
    count = np.where(upper, (reach[:, None, :] & reach[None, :, :]).sum(axis=2), 0)
    spacing = rng.random((n, n)) * 0.2
    spacing = spacing + spacing.T
    return D.PortTables(reach.sum(axis=1), rng.random(n), count, *pair, spacing, rng.random((n, n)),
                        rng.random((n, n)) - 0.5, m, D.reach_bits(reach), D.site_dexterity(reach, dex),
                        np.zeros(n), rng.random((n, n)), *T.no_cart(n)), reach, dex


@pytest.mark.parametrize("instruments", [2, 3])
def test_design_enumeration_covers_every_assignment_once(instruments):
    n = 7
    t, _, _ = _tables(n, 5, np.random.default_rng(1))
    crit = T.criteria(C.PortPlaceConfig())
    total = S.n_designs(n, instruments)
    ids = np.concatenate([D.design_columns(t, crit, s, min(total, s + 13), instruments)[0]
                          for s in range(0, total, 13)])
    designs = {tuple(r) for r in ids.tolist()}
    assert len(ids) == len(designs) == total
    assert total == n * (n - 1) // 2 * (n - 2) * ((n - 3) if instruments == 3 else 1)
    assert all(r[0] < r[1] and len(set(r)) == len(r) for r in designs)


def test_three_instruments_combine_as_a_brute_force_over_the_reach_sets():
    """Every 3-PSM design's columns against numpy over the reach matrix and the pair tables, written
    per design: the common reach of all three (the premise: some designs need the bit count, neither the
    pair nor the third reaching every point), the least clearances over the pairs, the spacing over the
    four ports, the third's isotropy in the cost; the pair's columns are the 2-PSM design's."""
    from surgopt.kinematics.port.place import REACH, SHAFTS, SPACING

    n, m = 8, 131  # 131 points: three words, the last one partial
    t, reach, dex = _tables(n, m, np.random.default_rng(2))
    crit = T.criteria(C.PortPlaceConfig())._replace(min_shaft_gap_m=0.3, min_spacing_m=0.02)
    ids, f, bad, cost, design, dock = D.design_columns(t, crit, 0, S.n_designs(n, 3), 3)
    ids2, f2, bad2, cost2, _, _ = D.design_columns(t, crit, 0, S.n_designs(n, 2), 2)
    assert np.all(dock == [0, 0, -1])  # no cart: every layout docks at the one pose, as enumerated, no links
    assert np.array_equal(design, np.arange(S.n_designs(n, 3)))
    loose = crit._replace(min_shaft_gap_m=0.0, min_external_m=0.0, angle_lo_rad=0.0, angle_hi_rad=math.pi)
    seen = t._replace(coverage=np.ones(n))  # the camera sees everything: feasibility is the reach and spacing
    every = D.design_columns(seen, loose, 0, S.n_designs(n, 3), 3)
    kept = D.design_columns(seen, loose, 0, S.n_designs(n, 3), 3, True)  # only the feasible rows, written alone
    ok = every[2] == 0
    assert 0 < ok.sum() < len(ok)
    for got, full in zip(kept, every):
        assert np.array_equal(got, full[ok])
    two = {tuple(r): q for q, r in enumerate(ids2.tolist())}
    pair = lambda a, x, y: a[min(x, y), max(x, y)]  # noqa: E731
    bit_counted = 0
    for r, (i, j, l, k) in enumerate(ids.tolist()):
        common = np.count_nonzero(reach[i] & reach[j] & reach[l])
        if not reach[l].all() and not (reach[i] & reach[j]).all():
            bit_counted += 1
        assert f[r, F.COMMON_REACH] == common / m
        assert f[r, F.REACH_3] == reach[l].sum() / m
        assert f[r, F.DEXTERITY_3] == pytest.approx(dex[l][reach[l]].mean(), abs=1e-12)
        assert f[r, F.SHAFT_CLEARANCE] == min(t.inside[i, j], pair(t.inside, i, l), pair(t.inside, j, l))
        # the instruments' pairs from their table, each instrument and the camera from theirs ([instrument, camera])
        assert f[r, F.EXTERNAL_CLEARANCE] == min(*(pair(t.outside, x, y) for x, y in itertools.combinations((i, j, l), 2)),
                               *(t.outside_camera[x, k] for x in (i, j, l)))
        spacing = min(t.spacing[x, y] for x, y in itertools.combinations((i, j, l, k), 2))
        assert f[r, F.PORT_SPACING] == spacing  # the kernel's own least spacing, stored as min_port_spacing_mm
        assert bool(bad[r] & SPACING) == (spacing < crit.min_spacing_m)
        assert bool(bad[r] & REACH) == (common < m)
        assert bool(bad[r] & SHAFTS) == (f[r, F.SHAFT_CLEARANCE] < crit.min_shaft_gap_m)
        q = two[(i, j, k)]
        for c in (F.REACH_1, F.REACH_2, F.DEXTERITY_MEAN, F.ANGLE_MEAN, F.ANGLE_MIN, F.ANGLE_MAX, F.ANGLE_SHARE,
                  F.ANGLE_CENTRE, F.AZIMUTH_IMBALANCE, F.CAMERA_COVERAGE, F.CAMERA_OFF_ARC):
            assert f[r, c] == f2[q, c]
        expected = cost2[q] + crit.w_reach * (f2[q, F.COMMON_REACH] - f[r, F.COMMON_REACH]) + crit.w_dexterity * (1 - dex[l][reach[l]].mean())
        assert cost[r] == pytest.approx(expected, abs=1e-12)
    assert bit_counted > 0  # the premise: the popcount branch was taken


def test_the_arms_clearance_outside_is_the_least_distance_of_the_shaft_lines_behind_the_ports():
    """P7 against sampling both segments (reference.segment_distance_sampled): each pair's clearance is at most
    the sampled least distance and within a sampling step of it; the table is filled above its diagonal only."""
    sites = RNG.uniform([-0.1, -0.1, 0.05], [0.1, 0.1, 0.12], (7, 3))
    axes = RNG.normal(size=(7, 3))
    axes /= np.linalg.norm(axes, axis=1)[:, None]
    length = 0.4318
    out = K.external_clearances(sites, axes, length)
    step = length / 400
    for i, j in itertools.combinations(range(7), 2):
        brute = segment_distance_sampled(sites[i] + length * axes[i], sites[i], sites[j] + length * axes[j], sites[j])
        assert brute - step <= out[i, j] <= brute + 1e-12
    assert not np.tril(out).any()


def test_the_azimuths_and_sides_are_the_angles_at_the_centre_and_the_lateral_offsets():
    """P9 against a numpy loop written from the definitions: the azimuth of instrument port i seen from camera
    port k is the angle at the centre between the centre->port i and centre->port k directions (arccos of the
    normalised dot product); the side is port i's offset from port k along the lateral axis made orthogonal to
    the optical axis. Premise: instruments on both sides of camera ports."""
    sites = RNG.uniform([-0.12, -0.12, 0.06], [0.12, 0.12, 0.14], (9, 3))
    centre, lateral = np.array([0.01, -0.02, 0.0]), np.array([1.0, 0.0, 0.0])
    azimuth, side = K.camera_pair_tables(sites, centre, lateral)
    for k in range(9):
        axis = (centre - sites[k]) / np.linalg.norm(centre - sites[k])
        lat = lateral - (lateral @ axis) * axis
        lat /= np.linalg.norm(lat)
        for i in range(9):
            if i == k:  # the camera's own port: 0 (arccos reads it as 1.5e-8)
                assert azimuth[i, k] == 0.0
                continue
            a, b = sites[i] - centre, sites[k] - centre
            want = math.acos(np.clip(a @ b / np.linalg.norm(a) / np.linalg.norm(b), -1.0, 1.0))
            assert azimuth[i, k] == pytest.approx(want, abs=1e-12)
            assert side[i, k] == pytest.approx((sites[i] - sites[k]) @ lat, abs=1e-15)
    assert (side > 0).sum() > 9 and (side < 0).sum() > 9


def test_every_kernel_column_is_named_once_and_stored_in_the_unit_its_name_says():
    """Issue 53: the design kernel's columns by named index (``kinematics/port/columns.py``): every position named
    once, every stored name in the rows' schema exactly once, and its unit what the name says (rad -> _deg,
    m -> _mm); a two-instrument design's array stops before the third's columns."""
    names = [c.stored for c in F.COLUMNS]
    assert len(set(names)) == len(names)
    for cfg in (C.PortPlaceConfig(), C.PortPlaceConfig.model_validate({"robot": {"instrument_count": 3}})):
        schema = S.schema(cfg).names
        stored = [n for n in names if n in schema]
        assert len(stored) == F.width(cfg.robot.instrument_count) and all(schema.count(n) == 1 for n in stored)
    for c in F.COLUMNS:
        unit = {"rad": "_deg", "m": "_mm"}.get(c.kernel_unit)
        assert (c.stored.endswith(unit) if unit else not c.stored.endswith(("_deg", "_mm"))), c
    assert F.width(2) == F.REACH_3 < F.DEXTERITY_3 == F.width(3) - 1
