"""port-place with instruments on serial arms that keep the RCM in software (``[robot.instrument_serial]``,
surgopt/kinematics/port/serial.py): reach and dexterity against the PA10-7C's closed-form IK and a
finite-difference constrained Jacobian in tests/reference.py, every solution through the chain's textbook DH
product in the patient frame, the clearances against sampled segments, the study's rows, bad input."""
import math

import numpy as np
import pytest

from surgopt.kinematics.port import serial as P
from surgopt.robots.models import get_model
from surgopt.studies.port_place import config as C
from surgopt.studies.port_place import geometry as G
from surgopt.studies.port_place import tables as T
from surgopt.studies.port_place import model as M
from surgopt.studies.port_place import study as S
from surgopt.studies.port_place.arms import walk_order
from surgopt.studies.port_place.serial_arms import BASE_INSIDE, serial_tables

from conftest import cli
from reference import (dh_chain_transform, pa10_ik, rcm_constrained_isotropy, scaled_singular_values,
                       segment_distance_sampled)

#: Sites 36 mm apart, a 20 mm sphere at 10 mm: 33 points; the PA10 where it reaches most ports.
SMALL = {"patient": {"port_region": {"site_spacing_mm": 36.0}},
         "target": {"shape": "sphere", "centre_mm": [0.0, -100.0, 40.0], "radii_mm": [20.0, 20.0, 20.0],
                    "spacing_mm": 10.0},
         "constraints": {"min_external_clearance_mm": 150.0}}
PA10_LINKS = (0.317, 0.45, 0.48, 0.07)


def _config(model, rcm, **extra):
    d = {**SMALL, "robot": {"instrument_serial": {"model": model, "rcm_in_base_m": rcm, **extra}}}
    return C.PortPlaceConfig.model_validate(d)


def _in_base(st, i, p):
    return st.base_rot[i].T @ (p - st.base_pos[i])


def _within(q, lo, hi):
    """Within [lo, hi] as the arm may take it, a turn either way."""
    return any(lo <= v <= hi for v in (q, q - 2 * math.pi, q + 2 * math.pi))


@pytest.mark.parametrize("rcm", [[0.65, 0.0, 0.5], [0.535, 0.0, 0.107]])  # a low stance; the paper's best RCM
def test_the_pa10s_reach_and_dexterity_are_its_closed_form_ik_at_every_port(rcm):
    """Every (port, point): the generic Newton kernel's reach against the PA10's closed-form IK (reference.pa10_ik,
    elbow up, within the joint limits), its isotropy against the reciprocal singular values of Q^-1 J_r there.
    Agreement is exact at every port the seeded branch anchors at (one of the tried points is reachable); a port
    where none of them is reaches nothing. Premises: ports that reach part of the target, and, from the low
    stance, ports that reach all of it; from the paper's RCM (its best for a vertical tool) ports that reach
    none."""
    cfg = _config("pa10_7c", rcm)
    sites = G.sites_mm(cfg) / 1000
    st = serial_tables(M.prepare(cfg), sites)
    targets = G.target_points_mm(cfg.target) / 1000
    arm = cfg.robot.instrument_serial
    lim = np.radians([arm.joint_limit_deg.S1, arm.joint_limit_deg.S2, arm.joint_limit_deg.E1, arm.joint_limit_deg.E2,
                      arm.joint_limit_deg.W1])
    qdot = [arm.max_joint_speed_rad_s.S1, arm.max_joint_speed_rad_s.S2, arm.max_joint_speed_rad_s.E1,
            arm.max_joint_speed_rad_s.E2, arm.max_joint_speed_rad_s.W1]
    rcm = np.asarray(arm.rcm_in_base_m)
    order, _ = walk_order(cfg.target, np.asarray(cfg.target.centre_mm) / 1000)
    tried = order[:: max(1, len(order) // P.ANCHOR_TRIES)]
    ref = np.zeros_like(st.reach)
    iso = np.zeros(st.reach.shape)
    for i in range(len(sites)):
        for k, p in enumerate(targets):
            pb = _in_base(st, i, p)
            k_axis = (pb - rcm) / np.linalg.norm(pb - rcm)
            q = pa10_ik(pb, k_axis, PA10_LINKS, 0.587, elbow_up=True)
            if q is None or not all(_within(v, -lo, lo) for v, lo in zip(q, lim)):
                continue
            ref[i, k] = True
            s = scaled_singular_values(q, PA10_LINKS, 0.587, rcm, qdot)  # of Q^-1 J_r: B's reciprocals
            iso[i, k] = s.min() / s.max()
    anchored = ref[:, tried].any(axis=1)
    assert np.array_equal(st.reach[anchored], ref[anchored])
    assert not st.reach[~anchored].any()
    np.testing.assert_allclose(st.dexterity[st.reach], iso[st.reach], rtol=1e-6)
    counts = st.reach.sum(axis=1)
    assert ((counts > 0) & (counts < len(targets))).any()
    assert (counts == len(targets)).sum() >= 2 if rcm[2] == 0.5 else (counts == 0).any()


def test_every_solution_closes_the_ur5es_chain_in_the_patient_frame():
    """UR5e (wrist_3 locked): at every reached (port, point), the shipped model's DH product (reference,
    textbook 4x4 matrices) with the tool along the flange's z puts the tip on the target point and the port on
    the tool, between the tip and the flange, to 1e-9 m, with the base where the config stands it; the joints
    are within the model's limits; the isotropy matches a finite-difference constrained Jacobian."""
    cfg = _config("ur5e", [0.55, 0.0, 0.1], base_yaw_deg=20.0)
    arm = cfg.robot.instrument_serial
    model = get_model("ur5e")
    assert arm.locked_joints_deg == {"wrist_3": 0.0} and arm.tool_axis == [0.0, 0.0, 1.0] and not any(arm.tool_offset_m)
    sites = G.sites_mm(cfg) / 1000
    st = serial_tables(M.prepare(cfg), sites)
    targets = G.target_points_mm(cfg.target) / 1000
    assert st.reach.mean() > 0.5  # the premise: most (port, point) pairs reached
    limits = [(r.lower, r.upper) for r in model.dh[:5]]
    qdot = [r.max_speed for r in model.dh[:5]]
    checked_iso = 0
    for i in range(len(sites)):
        assert np.allclose(st.base_rot[i] @ arm.rcm_in_base_m + st.base_pos[i], sites[i], atol=1e-12)
        assert st.base_rot[i][2, 2] == 1.0  # the base stands upright
        for k in np.nonzero(st.reach[i])[0]:
            q5 = st.joints[i, k]
            assert all(_within(v, lo, hi) for v, (lo, hi) in zip(q5, limits))
            flange = dh_chain_transform(model, [*q5, 0.0])
            tip_b = flange[:3, 3] + arm.tool_length_m * flange[:3, 2]
            tip = st.base_rot[i] @ tip_b + st.base_pos[i]
            axis = st.base_rot[i] @ flange[:3, 2]
            assert np.linalg.norm(tip - targets[k]) < 1e-9
            along = (tip - sites[i]) @ axis
            off = tip - sites[i] - along * axis
            assert np.linalg.norm(off) < 1e-9 and 0 < along <= arm.tool_length_m
            if (i + k) % 17 == 0:
                def tool(q, i=i):
                    f = dh_chain_transform(model, [*q, 0.0])
                    return f[:3, 3] + arm.tool_length_m * f[:3, 2], f[:3, 2]

                want = rcm_constrained_isotropy(tool, q5, _in_base(st, i, sites[i]), qdot)
                assert st.dexterity[i, k] == pytest.approx(want, rel=1e-5)
                checked_iso += 1
    assert checked_iso > 20


def test_the_bases_stand_radially_outside_their_ports():
    """The RCM's horizontal direction from the base points from the port toward the target's vertical axis, turned
    by base_yaw_deg; a port on that axis is reached along +x."""
    centre = np.array([0.0, -0.1, 0.04])
    sites = np.array([[0.1, -0.1, 0.12], [0.0, 0.05, 0.13], [0.0, -0.1, 0.14]])
    rcm = np.array([0.5, 0.2, 0.1])
    rot, pos = P.serial_base_frames(sites, centre, rcm, 0.0)
    inward = np.array([[-1.0, 0.0], [0.0, -1.0], [1.0, 0.0]])
    for i in range(3):
        assert np.allclose(rot[i] @ rcm + pos[i], sites[i], atol=1e-15)
        run = sites[i, :2] - pos[i, :2]
        assert np.allclose(run / np.linalg.norm(run), inward[i], atol=1e-12)
    turned, pos30 = P.serial_base_frames(sites, centre, rcm, math.radians(30.0))
    for i in range(3):
        run = sites[i, :2] - pos30[i, :2]
        c, s = math.cos(math.radians(30.0)), math.sin(math.radians(30.0))
        assert np.allclose(run / np.linalg.norm(run), [c * inward[i, 0] - s * inward[i, 1],
                                                       s * inward[i, 0] + c * inward[i, 1]], atol=1e-12)


def test_the_arms_clearances_are_the_least_distance_between_their_lines():
    """link_clearances and link_camera_clearances against densely sampled segments (random polylines, one with
    a repeated point: a segment of no length), and 0 for an arm with no docked pose."""
    rng = np.random.default_rng(7)
    lines = rng.normal(0.0, 0.2, (4, P.LINE_POINTS, 3))
    lines[1, 2] = lines[1, 1]
    lines[3] = np.nan
    sites = rng.normal(0.0, 0.1, (4, 3))
    axes = rng.normal(size=(4, 3))
    axes /= np.linalg.norm(axes, axis=1)[:, None]
    got = P.link_clearances(lines)
    cam = P.link_camera_clearances(lines, sites, axes, 0.4)
    for i in range(3):
        for j in range(i + 1, 3):
            want = min(segment_distance_sampled(lines[i, a], lines[i, a + 1], lines[j, b], lines[j, b + 1])
                       for a in range(P.LINE_POINTS - 1) for b in range(P.LINE_POINTS - 1))
            assert want - 2e-3 <= got[i, j] <= want + 1e-12
        for k in range(4):
            if k != i:
                want = min(segment_distance_sampled(lines[i, a], lines[i, a + 1], sites[k] + 0.4 * axes[k], sites[k])
                           for a in range(P.LINE_POINTS - 1))
                assert want - 2e-3 <= cam[i, k] <= want + 1e-12
    assert got[0, 3] == 0.0 and got[2, 3] == 0.0 and not cam[3].any()


def test_a_base_inside_the_body_refuses_the_port():
    """An RCM 0.06 m beside the base: a base under the dome (the ellipsoid's own inequality) refuses its port;
    a refused port reaches nothing and has no centre line."""
    cfg = _config("ur5e", [0.06, 0.0, 0.05])
    st = serial_tables(M.prepare(cfg), G.sites_mm(cfg) / 1000)
    a, b, c = np.asarray(cfg.patient.semi_axes_mm) / 1000
    x, y, z = st.base_pos.T
    under = ((x / a) ** 2 + (y / b) ** 2 + (z / c) ** 2 < 1) & (z >= 0)
    assert 0 < under.sum() < len(under)  # the premise: some bases inside, some outside
    assert np.array_equal(st.refused == BASE_INSIDE, under)
    assert not st.reach[under].any() and np.isnan(st.links[under]).all()


def test_links_through_or_near_the_wall_are_found_and_the_tool_entering_is_not():
    """_links_inside on hand-built centre lines over the default dome (170 x 210 x 140 mm): a link crossing the
    dome between two outside joints is found (its ends are outside: only the samples between them are in); a
    line whose only part inside is its last segment, the tool from the flange into the port, is not, as long
    as its flange, 40 mm above the dome's top, is farther from the wall than the links' radius (refused at 60
    mm, kept at 30 mm and at 0); no line (NaN) is not."""
    from surgopt.studies.port_place.serial_arms import _links_inside

    outside = np.array([0.5, 0.0, 0.3])
    crossing = np.array([outside, outside, [0.3, 0.0, 0.05], [-0.3, 0.0, 0.05], [-0.3, 0.0, 0.4], [-0.2, 0.0, 0.4],
                         [-0.1, 0.0, 0.4], [0.0, 0.0, 0.14]])
    entering = np.array([outside, outside, [0.4, 0.0, 0.4], [0.3, 0.0, 0.45], [0.2, 0.0, 0.45], [0.1, 0.0, 0.45],
                         [0.0, 0.0, 0.18], [0.0, 0.0, 0.10]])  # the flange 40 mm above the top, the port inside
    lines = np.stack([crossing, entering, np.full_like(crossing, np.nan)])
    cfg = _config("ur5e", [0.5, 0.0, 0.1])
    for radius, want in ((60.0, [True, True, False]), (30.0, [True, False, False]), (0.0, [True, False, False])):
        assert not G.inside_body(crossing[:-1] * 1000, cfg.patient).any()  # the premise: every joint is outside
        assert list(_links_inside(lines, cfg, radius)) == want, radius


@pytest.mark.parametrize("exponent", [2.0, 4.0])
def test_the_distance_to_the_dome_is_a_lower_bound_within_its_sampling_gap(exponent):
    """body_distance_mm on the dome: for points outside it (z >= 0), at most the true distance and within the
    samples' gap (< 3 mm) of it. The true distance: Eberly's root for the half-ellipsoid (reference), and for the
    superquadric the least distance to 2 million points of its surface ~0.2 mm apart (an upper bound within
    that)."""
    from reference import ellipsoid_distance

    from surgopt.studies.port_place.geometry import body_distance_mm, dome_samples_mm

    cfg = _config("ur5e", [0.5, 0.0, 0.1])
    cfg = C.PortPlaceConfig.model_validate({**cfg.model_dump(), "patient": {**cfg.patient.model_dump(),
                                                                            "dome_exponent": exponent}})
    axes = cfg.patient.semi_axes_mm
    rng = np.random.default_rng(4)
    p = rng.uniform([-300.0, -350.0, 0.0], [300.0, 350.0, 260.0], (300, 3))
    p = p[~G.inside_body(p, cfg.patient)][:150 if exponent == 2.0 else 40]
    got = body_distance_mm(p, cfg.patient, 1000.0)
    _, gap = dome_samples_mm(tuple(axes), exponent)
    assert gap < 3.0
    if exponent == 2.0:
        want = np.array([ellipsoid_distance(x, axes) for x in p])
        assert np.all(got <= want + 1e-9) and np.all(got >= want - gap - 1e-9)
    else:
        dense = []
        for lon in np.linspace(0, 2 * np.pi, 2880, endpoint=False):  # 2880 x 720 directions, 0.14 mm apart
            lat = np.linspace(0, np.pi / 2, 721)
            d = np.stack([np.cos(lat) * np.cos(lon), np.cos(lat) * np.sin(lon), np.sin(lat)], axis=1)
            dense.append(d / ((np.abs(d / axes) ** 4).sum(axis=1) ** 0.25)[:, None])  # out to the surface
        dense = np.concatenate(dense)
        upper = np.array([np.sqrt(((dense - x) ** 2).sum(axis=1).min()) for x in p])
        assert np.all(got <= upper + 1e-9) and np.all(got >= upper - gap - 0.3)
    assert got.min() < 20.0 < got.max()  # the premise: near and far points


def test_the_search_evaluator_gives_the_enumerations_rows():
    """A design evaluated on its own ports (a search's path: each port's serial IK again) gives the grid's row."""
    cfg = _config("pa10_7c", [0.65, 0.0, 0.5])
    full = S.compute_task(cfg, S.n_total(cfg), 0)
    ok = np.nonzero(full["feasible"])[0]
    assert len(ok) > 0  # the premise: feasible layouts exist
    pick = np.concatenate([ok[:3], [0, len(full["feasible"]) - 1]])
    x = np.stack([full[f"{a}_site"][pick] for a in S.arms_of(cfg)], axis=1)
    got = S.evaluate_designs(cfg, x, full["design_id"][pick], "test")
    for name in ("common_reach", "dexterity_mean", "external_clearance_mm", "cost", "infeasible"):
        np.testing.assert_allclose(got[name], full[name][pick], rtol=0, atol=1e-12)


def test_a_search_turns_each_serial_base_about_its_port():
    """With robot.docking_range_deg a search's space has each instrument's base yaw (no pitch), and a design
    evaluated with both bases turned 20 deg is the grid's row of the config whose base_yaw_deg is 20 (the
    stance set in the config: another path to the same base frames)."""
    cfg = _config("pa10_7c", [0.65, 0.0, 0.5])
    searched = C.PortPlaceConfig.model_validate({**cfg.model_dump(), "robot": {
        **cfg.robot.model_dump(), "docking_range_deg": 30.0}, "search": {"method": "random", "trials": 8}})
    plan = S.search_plan(searched)
    assert list(plan.space)[3:] == ["psm1_docking_yaw_deg", "psm2_docking_yaw_deg"]
    turned = _config("pa10_7c", [0.65, 0.0, 0.5], base_yaw_deg=20.0)
    full = S.compute_task(turned, S.n_total(turned), 0)
    ok = np.nonzero(full["feasible"])[0]
    pick = np.concatenate([ok[:2], np.nonzero(~full["feasible"])[0][:2]])
    assert len(ok) >= 2  # the premise: feasible layouts with the turned bases
    x = np.stack([*(full[f"{a}_site"][pick] for a in S.arms_of(cfg)), np.full(len(pick), 20.0),
                  np.full(len(pick), 20.0)], axis=1)
    got = S.evaluate_designs(searched, x, full["design_id"][pick], "test")
    for name in ("common_reach", "dexterity_mean", "external_clearance_mm", "cost", "infeasible"):
        np.testing.assert_allclose(got[name], full[name][pick], rtol=0, atol=1e-12)
    assert (got["psm1_docking_yaw_deg"] == 20.0).all() and (got["psm2_docking_pitch_deg"] == 0.0).all()


def test_a_search_moves_the_serial_arms_stance_with_the_ports():
    """instrument_serial.stance_range_m: a search's space has the RCM's move out from the base and up within the
    range, and a design moved (+0.1, -0.1) m is the grid's row of the config whose rcm_in_base_m is moved so
    (0.65, 0, 0.5) -> (0.75, 0, 0.4): the same base frames by another path. A CMA-ES search over ports and
    stance runs, its stances within the range and varied."""
    import tempfile

    from surgopt.runner import run_study
    from surgopt.store import Store

    cfg = _config("pa10_7c", [0.65, 0.0, 0.5], stance_range_m=0.2)
    searched = C.PortPlaceConfig.model_validate({**cfg.model_dump(), "search": {"method": "cmaes", "trials": 24,
                                                                                "seed": 1}})
    plan = S.search_plan(searched)
    assert plan.space["instrument_stance_out_m"] == (-0.2, 0.2) and list(plan.space)[-1] == "instrument_stance_up_m"
    moved = _config("pa10_7c", [0.75, 0.0, 0.4], stance_range_m=0.2)
    full = S.compute_task(moved, S.n_total(moved), 0)
    ok = np.nonzero(full["feasible"])[0]
    assert len(ok) >= 2  # the premise: feasible layouts at the moved stance
    pick = np.concatenate([ok[:2], np.nonzero(~full["feasible"])[0][:2]])
    x = np.stack([*(full[f"{a}_site"][pick] for a in S.arms_of(cfg)), np.full(len(pick), 0.1),
                  np.full(len(pick), -0.1)], axis=1)
    got = S.evaluate_designs(searched, x, full["design_id"][pick], "test")
    for name in ("common_reach", "dexterity_mean", "external_clearance_mm", "cost", "infeasible"):
        np.testing.assert_allclose(got[name], full[name][pick], rtol=0, atol=1e-12)
    assert (got["instrument_stance_out_m"] == 0.1).all() and (full["instrument_stance_out_m"] == 0.0).all()
    with tempfile.TemporaryDirectory() as tmp:
        t = run_study(S.STUDY, searched, config_name="s", store=Store(tmp), jobs=2, quiet=True).table
    out = t["instrument_stance_out_m"].to_numpy()
    assert t.num_rows == 24 and np.abs(out).max() <= 0.2 and len(set(out.tolist())) > 10


def test_the_cli_runs_a_pa10_layout_and_draws_the_arms(tmp_path):
    import json

    (tmp_path / "p.toml").write_text(
        '[patient.port_region]\nsite_spacing_mm = 36.0\n[target]\nshape = "sphere"\nradii_mm = [20.0, 20.0, 20.0]\n'
        'spacing_mm = 10.0\n[robot.instrument_serial]\nmodel = "pa10_7c"\nrcm_in_base_m = [0.65, 0.0, 0.5]\n'
        '[constraints]\nmin_external_clearance_mm = 150.0\n')
    r = cli("port-place", tmp_path / "p.toml", "--store", tmp_path / "s", "--quiet")
    assert "clinical checks" in r.stdout
    rec = json.loads(cli("summarize", "--store", tmp_path / "s", "--format", "json").stdout)
    assert rec["headline"]["feasible"] > 0 and rec["top"][0]["external_clearance_mm"] >= 150
    out = cli("plot", "--store", tmp_path / "s", "--out", tmp_path / "fig").stdout
    assert "port_place_layout_3d.png" in out and (tmp_path / "fig" / "port_place_layout_3d.png").stat().st_size > 10_000


BAD = {
    "two instrument arms": ('[robot]\ninstrument_arm = "dvrk_psm_si"\n[robot.instrument_serial]\nmodel = "ur5e"\n'
                            "rcm_in_base_m = [0.5, 0.0, 0.1]\n", "robot", "not both"),
    "rcm under the base": ('[robot.instrument_serial]\nmodel = "ur5e"\nrcm_in_base_m = [0.01, 0.0, 0.1]\n',
                           "rcm_in_base_m", "0.05 m"),
    "no rcm": ('[robot.instrument_serial]\nmodel = "ur5e"\n', "rcm_in_base_m", "Field required"),
    "out of the arm's reach": ('[robot.instrument_serial]\nmodel = "ur5e"\nrcm_in_base_m = [2.5, 0.0, 0.1]\n', "target",
                               "stand the arm elsewhere (robot.instrument_serial.rcm_in_base_m"),
    "unknown model": ('[robot.instrument_serial]\nmodel = "ur5"\nrcm_in_base_m = [0.5, 0.0, 0.1]\n', "model",
                      "ur5e"),
    "two camera arms": ('[robot]\ncamera_arm = "dvrk_ecm_si"\n[robot.camera_serial]\nmodel = "ur5e"\n'
                        'rcm_in_base_m = [0.5, 0.0, 0.1]\n', "robot", "camera_serial (a serial arm) or camera_arm"),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_serial_arm_input_is_one_line_naming_the_field(tmp_path, case):
    from test_study_port_place import refused_in_one_line

    refused_in_one_line(tmp_path, *BAD[case])


def test_the_shipped_pa10_config_loads_and_both_best_ports_reach_the_whole_target():
    """configs/port_place_pa10.toml: a PA10 at each of its worked example's two ports (docs/port_placement.md:
    sites 28 and 144, 180 mm apart) reaches every target point."""
    from pathlib import Path

    from surgopt.config import load_config

    cfg = load_config(Path(__file__).parents[1] / "configs" / "port_place_pa10.toml", C.Config)
    assert cfg.robot.instrument_serial.holder().name == "pa10_7c (software RCM)"
    sites = G.sites_mm(cfg)[[28, 144]] / 1000
    assert np.linalg.norm(sites[0] - sites[1]) == pytest.approx(0.180, abs=1e-9)
    assert serial_tables(M.prepare(cfg), sites).reach.all()


def test_the_distance_to_a_mesh_patient_is_trimeshs_closest_point(tmp_path):
    """body_distance_mm on a mesh patient (the default dome tessellated, 10,494 triangles): within the faceting
    (1 mm) of the exact distance to the half-ellipsoid (Eberly's root, reference), and the cap beyond reach."""
    from reference import ellipsoid_distance
    from test_study_port_place import _dome_mesh

    from surgopt.config import validate
    from surgopt.studies.port_place.geometry import body_distance_mm

    _dome_mesh(tmp_path / "dome.stl", subdivisions=5)
    cfg = validate({"patient": {"shape": "mesh", "mesh_file": "dome.stl"}}, C.Config, "m", {"config_dir": str(tmp_path)})
    rng = np.random.default_rng(5)
    p = rng.uniform([-300.0, -350.0, 5.0], [300.0, 350.0, 260.0], (200, 3))
    p = p[~G.inside_body(p, cfg.patient)][:60]
    got = body_distance_mm(p, cfg.patient, 80.0)
    want = np.minimum([ellipsoid_distance(x, cfg.patient.semi_axes_mm) for x in p], 80.0)
    assert np.abs(got - want).max() < 1.0 and (want < 80.0).any() and (want == 80.0).any()


def _camera_config(rcm, **extra):
    d = {**SMALL, "target": {"spacing_mm": 15.0},
         "robot": {"camera_serial": {"model": "ur5e", "rcm_in_base_m": rcm, **extra}}}
    return C.PortPlaceConfig.model_validate(d)


def test_a_serial_arm_holds_the_endoscope_where_the_scope_must_be():
    """robot.camera_serial (a UR5e holding the scope): at every port it is said to hold it, the shipped model's DH
    product (reference) puts the tip where camera_views puts the scope's tip and the port on the tool, between
    tip and flange, to 1e-9 m; the camera's coverage is the mechanism-free coverage there and 0 at the other
    ports (premise: both kinds); the instruments' outside clearance to it is the least distance from their
    shaft lines to its centre line (sampled segments)."""
    from surgopt.kinematics.port import place as K
    from surgopt.robots import dvrk
    from surgopt.studies.port_place.serial_arms import serial_camera_tables

    cfg = _camera_config([0.45, 0.0, 0.3])
    arm, model = cfg.robot.camera_serial, get_model("ur5e")
    sites = G.sites_mm(cfg) / 1000
    centre = np.asarray(cfg.target.centre_mm) / 1000
    rot = K.docking_frames(sites, centre, T.LATERAL)
    tips, _, ok = K.camera_views(sites, rot, centre, T.camera_of(cfg))
    held = serial_camera_tables(M.prepare(cfg), sites, tips, ok)
    assert 0 < held.placed.sum() < len(sites)
    for i in np.flatnonzero(held.placed):
        flange = dh_chain_transform(model, [*held.joints[i], 0.0])
        tip = held.base_rot[i] @ (flange[:3, 3] + arm.tool_length_m * flange[:3, 2]) + held.base_pos[i]
        axis = held.base_rot[i] @ flange[:3, 2]
        assert np.linalg.norm(tip - tips[i]) < 1e-9
        along = (tip - sites[i]) @ axis
        assert np.linalg.norm(tip - sites[i] - along * axis) < 1e-9 and 0 < along <= arm.tool_length_m
    t, _, _ = T.port_tables(M.prepare(cfg), sites, rot)
    free = K.camera_coverage(sites, rot, G.target_points_mm(cfg.target) / 1000, centre, T.camera_of(cfg))
    np.testing.assert_array_equal(t.coverage, np.where(held.placed, free, 0.0))
    i = 0
    for k in np.flatnonzero(held.placed)[:4]:
        if k == i:
            continue
        shaft = (sites[i] + dvrk.OUTSIDE_LENGTH_M * rot[i, :, 2], sites[i])
        want = min(segment_distance_sampled(*shaft, held.links[k, s], held.links[k, s + 1])
                   for s in range(P.LINE_POINTS - 1))
        assert want - 2e-3 <= t.outside_camera[i, k] <= want + 1e-12


def test_polyline_clearances_are_the_least_distance_between_two_arms_lines():
    rng = np.random.default_rng(8)
    a, b = rng.normal(0.0, 0.2, (3, P.LINE_POINTS, 3)), rng.normal(0.0, 0.2, (3, P.LINE_POINTS, 3))
    b[2] = np.nan
    got = P.polyline_clearances(a, b)
    for i in range(3):
        for k in range(2):
            if i != k:
                want = min(segment_distance_sampled(a[i, s], a[i, s + 1], b[k, t], b[k, t + 1])
                           for s in range(P.LINE_POINTS - 1) for t in range(P.LINE_POINTS - 1))
                assert want - 2e-3 <= got[i, k] <= want + 1e-12
    assert not got[:, 2].any() and not np.diag(got).any()


def test_a_layout_of_serial_arms_only_runs_and_a_camera_arm_that_holds_the_scope_nowhere_is_refused(tmp_path):
    """Two PA10s and a UR5e camera: the study runs with feasible layouts. A camera arm standing where it holds
    the scope at no port is one line naming robot.camera_serial, exit 2, nothing written."""
    from test_study_port_place import refused_in_one_line

    cfg = C.PortPlaceConfig.model_validate({**SMALL, "robot": {
        "instrument_serial": {"model": "pa10_7c", "rcm_in_base_m": [0.65, 0.0, 0.5]},
        "camera_serial": {"model": "ur5e", "rcm_in_base_m": [0.55, 0.0, 0.1]}}})
    rows = S.compute_task(cfg, S.n_total(cfg), 0)
    assert rows["feasible"].any()
    refused_in_one_line(tmp_path, '[robot.camera_serial]\nmodel = "ur5e"\nrcm_in_base_m = [2.5, 0.0, 0.1]\n',
                        "robot.camera_serial", "holds the endoscope where it must be at no candidate port")
