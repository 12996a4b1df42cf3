"""port-place's model choices of issue 40 item 3, each against something independent of the code under test: the
point that must reach (the jaw tip past the wrist, through the Large Needle Driver's own DH rows), the least wrist
depth (the dVRK controller's 45 mm), the docking roll about the shaft (given or the one of most reach, mirrored)
and the port-to-target bound measured in 3-D or in the top view."""
from __future__ import annotations

import numpy as np
import pydantic
import pytest

from surgopt.kinematics.port import place as K
from surgopt.robots import dvrk
from surgopt.robots.models import get_model
from surgopt.studies.port_place import config as C
from surgopt.studies.port_place import geometry as G
from surgopt.studies.port_place import study as S
from surgopt.studies.port_place import tables as T
from surgopt.studies.port_place import model as M

from reference import PSM_CLASSIC_MDH, mdh_chain

#: The Large Needle Driver's wrist pitch and wrist yaw rows (alpha, A, D, prismatic, offset), typed from
#: ../shared/robots/dvrk-kinematics.md: the yaw row's A, 0.0091 m, carries the jaws' tip past the wrist.
LND_WRIST_MDH = [(-np.pi / 2, 0.0, 0.0, False, -np.pi / 2), (-np.pi / 2, 0.0091, 0.0, False, -np.pi / 2)]
SMALL = {"patient": {"port_region": {"site_spacing_mm": 36.0}}, "target": {"spacing_mm": 15.0}, "cart": {"model": "none"}}
#: A larger target (120 x 150 x 70 mm, issue 40 item 3's) on which the choices move which sites reach it all.
LARGE = {"patient": {"port_region": {"site_spacing_mm": 36.0}},
         "target": {"shape": "box", "radii_mm": [60.0, 75.0, 35.0], "centre_mm": [0.0, -40.0, 50.0],
                    "spacing_mm": 15.0}, "cart": {"model": "none"}}
RNG = np.random.default_rng(40)


def model(base: dict, **robot):
    cfg = C.PortPlaceConfig.model_validate({**base, "robot": {**base.get("robot", {}), **robot}})
    return M.prepare(cfg)


def full_reach_sites(m) -> np.ndarray:
    reach = m.grid.reach
    return reach.all(axis=1)


def test_the_tip_is_the_needle_drivers_last_frame_with_the_wrist_straight():
    """rcm_point with the run's limits (the default: the jaw tip) lands where the PSM's rows and the LND's wrist
    rows, multiplied out in tests/reference.py, put the wrist-yaw frame's origin at q5 = q6 = 0; with
    tip_beyond_wrist_mm = 0, where the roll row puts the wrist."""
    tip = M.prepare(C.PortPlaceConfig()).limits
    wrist = model({}, tip_beyond_wrist_mm=0.0).limits
    assert tip.along_shaft_m - wrist.along_shaft_m == pytest.approx(dvrk.LND_WRIST_LINK_M, abs=1e-15)
    for _ in range(20):
        q = [RNG.uniform(-1.5, 1.5), RNG.uniform(-0.9, 0.9), RNG.uniform(0.0, 0.24), RNG.uniform(-4.0, 4.0)]
        at_tip = mdh_chain(PSM_CLASSIC_MDH + LND_WRIST_MDH, q + [0.0, 0.0])[:3, 3]
        at_wrist = mdh_chain(PSM_CLASSIC_MDH, q)[:3, 3]
        np.testing.assert_allclose(K.rcm_point(*q[:3], tip.along_shaft_m), at_tip, atol=1e-12)
        np.testing.assert_allclose(K.rcm_point(*q[:3], wrist.along_shaft_m), at_wrist, atol=1e-12)


def test_the_wrist_stays_the_least_depth_inside_at_every_reached_point():
    """Every point the default reaches puts the wrist (the tip less 9.1 mm along the shaft) >= 45 mm past the
    RCM, by plain distances; points that only the wrist-at-any-depth model reaches exist (the bound decides)."""
    deep = M.prepare(C.PortPlaceConfig.model_validate(SMALL))
    shallow = model(SMALL, min_wrist_depth_mm=0.0)
    rho = np.linalg.norm(deep.targets_m[None, :, :] - deep.sites_m[:, None, :], axis=2)
    wrist_depth = rho - dvrk.LND_WRIST_LINK_M
    assert (wrist_depth[deep.grid.reach] >= dvrk.PSM_SAFE_DISTANCE_FROM_RCM_M - 1e-12).all()
    lost = shallow.grid.reach & ~deep.grid.reach
    assert lost.any() and (wrist_depth[lost] < dvrk.PSM_SAFE_DISTANCE_FROM_RCM_M).all()
    assert not (deep.grid.reach & ~shallow.grid.reach).any()


def test_a_least_depth_past_the_insertions_travel_is_refused_naming_the_field():
    deepest = (0.240 - 0.0156) * 1000
    with pytest.raises(pydantic.ValidationError, match=r"robot.min_wrist_depth_mm: 230 mm.*224.4 mm"):
        C.PortPlaceConfig.model_validate({"robot": {"min_wrist_depth_mm": 230.0}})
    assert deepest == pytest.approx(224.4)
    serial = {"instrument_serial": {"model": "ur5e", "rcm_in_base_m": [0.4, 0.0, 0.3]}, "tip_beyond_wrist_mm": 5.0}
    with pytest.raises(pydantic.ValidationError, match="tip_beyond_wrist_mm goes with an RCM instrument arm"):
        C.PortPlaceConfig.model_validate({"robot": serial})


def test_a_rolled_frame_keeps_its_shaft_and_turns_its_yaw_axis_by_the_roll_mirrored_across_the_midline():
    m = model(SMALL, docking_roll_deg=30.0)
    rot, turned = m.rot, m.instrument_rot
    np.testing.assert_allclose(turned[:, :, 2], rot[:, :, 2], atol=1e-15)
    np.testing.assert_allclose(np.einsum("nij,nik->njk", turned, turned), np.broadcast_to(np.eye(3), rot.shape),
                               atol=1e-14)
    cos = np.einsum("ni,ni->n", turned[:, :, 0], rot[:, :, 0])
    np.testing.assert_allclose(cos, np.cos(np.radians(30.0)), atol=1e-14)
    toward_y = np.einsum("ni,ni->n", turned[:, :, 0], rot[:, :, 1])  # + on the patient's left, - on the right
    left = m.sites_m[:, 0] >= 0
    assert left.any() and (~left).any()
    np.testing.assert_allclose(toward_y[left], 0.5, atol=1e-14)
    np.testing.assert_allclose(toward_y[~left], -0.5, atol=1e-14)
    cfg = C.PortPlaceConfig.model_validate({**SMALL, "robot": {"docking_roll_deg": 30.0}})
    cols = S.compute_task(cfg, S.n_total(cfg), 0)  # the rows say each port's roll: +30 on the left, -30 on the right
    for arm in ("psm1", "psm2"):
        np.testing.assert_array_equal(cols[f"{arm}_roll_deg"], np.where(cols[f"{arm}_x_mm"] >= 0, 30.0, -30.0))
    back = model(SMALL, docking_roll_deg=-30.0).instrument_rot  # a negative roll: each side the other way
    toward_y = np.einsum("ni,ni->n", back[:, :, 0], rot[:, :, 1])
    np.testing.assert_allclose(toward_y[left], -0.5, atol=1e-14)
    np.testing.assert_allclose(toward_y[~left], 0.5, atol=1e-14)


def mirror_of(sites: np.ndarray) -> np.ndarray:
    return np.array([int(np.flatnonzero(np.all(np.isclose(sites, sites[i] * [-1, 1, 1]), axis=1))[0])
                     for i in range(len(sites))])


@pytest.mark.parametrize("roll", [30.0, 90.0])
def test_a_rolled_docking_on_a_symmetric_patient_reaches_as_much_at_each_site_as_at_its_mirror(roll):
    m = model(LARGE, docking_roll_deg=roll)
    counts = m.grid.reach.sum(axis=1)
    twin = mirror_of(m.sites_m)
    off_midline = np.abs(m.sites_m[:, 0]) > 1e-9  # a midline site's mirror is itself, its roll not mirrored
    np.testing.assert_array_equal(counts[off_midline], counts[twin][off_midline])


def test_the_roll_of_most_reach_is_at_each_site_the_best_of_the_given_rolls():
    """'most_reach' against each given roll run on its own: the per-site count is the largest of the seven, and
    the choice is the given roll that attains it nearest docking_roll_deg (0); on the larger target the roll
    decides: more sites reach everything than at 0 deg."""
    best = model(LARGE, docking_roll="most_reach")
    given = np.stack([model(LARGE, docking_roll_deg=r).grid.reach.sum(axis=1) for r in T.ROLL_CHOICES_DEG], axis=1)
    np.testing.assert_array_equal(best.grid.reach.sum(axis=1), given.max(axis=1))
    chosen = np.degrees(np.abs(T.instrument_rolls_rad(best, best.sites_m, best.rot)))
    np.testing.assert_allclose(chosen, np.asarray(T.ROLL_CHOICES_DEG)[given.argmax(axis=1)], atol=1e-9)
    assert (chosen > 0).any() and full_reach_sites(best).sum() > full_reach_sites(model(LARGE)).sum()


def test_the_setup_joints_dock_the_rolled_frame():
    """With a cart, a rolled docking is what the setup joints are solved for: the docked base's x axis is the
    rolled frame's (turned 90 deg from the unrolled one, the shaft kept)."""
    from surgopt.studies.port_place.tables import docked_arms

    cart = {"cart": {"model": "classic", "pose": "given", "x_mm": 0.0, "y_mm": -1100.0}}
    rows = {}
    for roll in (0.0, 90.0):
        cfg = C.PortPlaceConfig.model_validate({**SMALL, **cart, "robot": {"docking_roll_deg": roll}})
        sites = G.sites_mm(cfg)
        i = int(np.argmin(np.abs(sites[:, 0] - 60.0) + np.abs(sites[:, 1] + 40.0)))
        row = {"psm1_site": i, "cart_x_mm": 0.0, "cart_y_mm": -1100.0, "cart_heading_deg": 0.0,
               **{f"psm1_{c}_mm": sites[i, k] for k, c in enumerate("xyz")}}
        rows[roll] = docked_arms(M.model_of(cfg), row)[0].base
    a, b = rows[0.0], rows[90.0]
    np.testing.assert_allclose(a[:3, 3], b[:3, 3], atol=1e-12)
    np.testing.assert_allclose(a[:3, 2], b[:3, 2], atol=1e-12)
    np.testing.assert_allclose(b[:3, 0] @ a[:3, 1], 1.0, atol=1e-12)  # a port on the left: x toward the old y


def test_the_port_to_target_bound_in_the_top_view_keeps_what_its_horizontal_distance_allows():
    flat = C.PortPlaceConfig.model_validate({"constraints": {"port_to_target_measure": "horizontal"}})
    full = C.PortPlaceConfig()
    centre = np.asarray(full.target.centre_mm)
    s_flat, s_full = G.sites_mm(flat), G.sites_mm(full)
    horizontal = np.linalg.norm(s_flat[:, :2] - centre[:2], axis=1)
    assert ((horizontal >= 80.0) & (horizontal <= 180.0)).all()
    every = G.sites_mm(C.PortPlaceConfig.model_validate({"constraints": {"port_to_target_mm": [0.0, 10_000.0]}}))
    h_every = np.linalg.norm(every[:, :2] - centre[:2], axis=1)
    assert len(s_flat) == int(((h_every >= 80.0) & (h_every <= 180.0)).sum())
    in_3d = np.linalg.norm(s_flat - centre, axis=1)
    assert (in_3d > 180.0).any() and len(s_flat) != len(s_full)  # the measure decides


def test_an_arm_from_a_file_keeps_its_own_reaching_point_unless_told():
    """A file arm (RcmLimits) has no tip or controller depth of its own: its reaching point is what its file
    gives, as before; the fields apply when given."""
    arm = get_model("dvrk_psm_classic")
    as_file = T.arm_limits(arm)  # what an RcmLimits of the same rows gives: no tip, no depth
    cfg = C.PortPlaceConfig()
    assert T.reach_offsets_m(cfg, object()) == (0.0, 0.0)
    assert T.reach_offsets_m(cfg, arm) == (dvrk.LND_WRIST_LINK_M, dvrk.PSM_SAFE_DISTANCE_FROM_RCM_M)
    told = C.PortPlaceConfig.model_validate({"robot": {"tip_beyond_wrist_mm": 5.0, "min_wrist_depth_mm": 20.0}})
    assert T.reach_offsets_m(told, object()) == pytest.approx((0.005, 0.020))
    assert as_file.along_shaft_m == pytest.approx(-0.0156)
