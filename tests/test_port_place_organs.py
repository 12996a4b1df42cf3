"""#57 item 1: organs as obstacles the instruments' shafts must not cross on their way to the target
(``studies/port_place/organs.py``), held to a sphere's analytic distance apart from the voxel code: a shaft passing
clearly through the sphere is blocked, one passing clearly outside it (beyond the voxels' stated reach) is not;
the instruments' reach tables lose exactly the blocked (site, point) pairs; a target in an organ is refused by name;
the organ's content is in the run's key; OpenHELP's organs read from ../shared."""
from pathlib import Path

import numpy as np
import pytest
import trimesh

from surgopt.studies.port_place import config as C
from surgopt.studies.port_place import organs as O

OPENHELP = Path(__file__).resolve().parents[2] / "shared" / "patients" / "openhelp"
CENTRE, RADIUS = np.array([0.0, 0.0, 95.0]), 18.0  # a sphere between the dome's top and a target below it (mm)
#: the dome's default with a small target under the sphere, coarse grids (no cart: the reach tables are what count)
SMALL = {"patient": {"port_region": {"site_spacing_mm": 30.0}},
         "target": {"centre_mm": [0.0, 0.0, 45.0], "radii_mm": [15.0, 15.0, 12.0], "spacing_mm": 8.0},
         "cart": {"model": "none"}}


def _sphere(tmp_path, centre=CENTRE, radius=RADIUS, name="organ.stl") -> Path:
    s = trimesh.creation.icosphere(subdivisions=4, radius=radius)  # its faces lie inside the true sphere (< 0.3 mm)
    s.apply_translation(centre)
    path = tmp_path / name
    s.export(path)
    return path


def _with_organ(tmp_path, **extra) -> C.PortPlaceConfig:
    patient = {**SMALL["patient"], "organs": {"bowel": {"mesh_file": str(_sphere(tmp_path))}}}
    return C.PortPlaceConfig.model_validate({**SMALL, "patient": patient, **extra})


def _segment_distance(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """The least distance from point c to each segment a[i] -> b[i] (written out: the clamped projection)."""
    d = b - a
    t = np.clip(((c - a) * d).sum(axis=1) / (d * d).sum(axis=1), 0.0, 1.0)
    return np.linalg.norm(a + t[:, None] * d - c, axis=1)


def test_a_shaft_through_the_organ_is_blocked_and_one_clear_of_its_voxels_is_not(tmp_path):
    """Random segments from above the sphere to below it: through it by more than the sampling step (1 mm), each is
    blocked; farther from it than the voxels reach (a diagonal, 3.5 mm), each is clear. Both kinds occur."""
    grid = O.organ_grid("bowel", str(_sphere(tmp_path)), "x", "mm", (0.0, 0.0, 0.0))
    rng = np.random.default_rng(7)
    starts = CENTRE + np.column_stack([rng.uniform(-60, 60, 400), rng.uniform(-60, 60, 400), np.full(400, 45.0)])
    ends = CENTRE + np.column_stack([rng.uniform(-40, 40, 400), rng.uniform(-40, 40, 400), np.full(400, -45.0)])
    crossed = np.array([O.shafts_crossing(s[None] / 1000, e[None] / 1000, [grid])[0, 0] for s, e in zip(starts, ends)])
    dist = _segment_distance(starts, ends, CENTRE)
    through = dist < RADIUS - 0.3 - 1.0  # inside the mesh's own faces by more than the step
    outside = dist > RADIUS + np.sqrt(3) * O.ORGAN_PITCH_MM
    assert through.sum() > 20 and outside.sum() > 20  # the premise: both kinds drawn
    assert np.all(crossed[through] == 0) and np.all(crossed[outside] == -1)


def test_an_organ_touching_the_target_point_is_not_crossed_but_one_passed_through_on_the_way_is(tmp_path):
    """The shaft's last ORGAN_REACH_MM before its tip is not checked: a target point 1 mm off the organ (the stomach
    on the pancreas), reached from outside, is clear; the same point reached through the organ is not."""
    grid = O.organ_grid("bowel", str(_sphere(tmp_path)), "x", "mm", (0.0, 0.0, 0.0))
    tip = CENTRE + [RADIUS + 1.0, 0.0, 0.0]
    assert O.organ_at(tip[None], [grid])[0] == 0  # the premise: the tip lies in the organ's voxels
    outside = CENTRE + [RADIUS + 80.0, 0.0, 10.0]  # from the tip's side
    through = CENTRE - [RADIUS + 80.0, 0.0, 0.0]  # from the far side, through the organ
    assert O.shafts_crossing(outside[None] / 1000, tip[None] / 1000, [grid])[0, 0] == -1
    assert O.shafts_crossing(through[None] / 1000, tip[None] / 1000, [grid])[0, 0] == 0


def test_the_reach_tables_lose_exactly_the_shafts_through_an_organ(tmp_path):
    """The instruments' reach at every candidate site and target point with the organ equals the reach without it
    and with every blocked pair taken out, the blocked pairs being the voxel rule's; and some reached pairs are
    blocked (the premise). The isotropy of a blocked pair is 0, as for any point not reached."""
    from surgopt.studies.port_place.model import prepare

    plain = prepare(C.PortPlaceConfig.model_validate(SMALL))
    organ = prepare(_with_organ(tmp_path))
    reach0, dex0 = plain.site_reach
    reach1, dex1 = organ.site_reach
    crossing = O.shafts_crossing(organ.sites_m, organ.targets_m, O.organ_grids(organ.cfg.patient))
    dist = np.array([_segment_distance(np.repeat(s[None] * 1000, len(organ.targets_m), 0), organ.targets_m * 1000,
                                       CENTRE) for s in organ.sites_m])
    assert np.all(crossing[dist < RADIUS - 1.3] == 0) and np.all(crossing[dist > RADIUS + 3.5] == -1)
    blocked = crossing >= 0
    assert (reach0 & blocked).sum() > 50 and (reach0 & ~blocked).sum() > 50  # the premise: both kinds reached
    np.testing.assert_array_equal(reach1, reach0 & ~blocked)
    np.testing.assert_array_equal(dex1, np.where(reach1, dex0, 0.0))


def test_a_target_in_an_organ_is_refused_by_name_and_the_organs_content_is_in_the_key(tmp_path):
    from surgopt.config import study_key

    with pytest.raises(ValueError, match=r"patient.organs.bowel: \d+ of the target.s \d+ points lie in it, .*obstacle = false"):
        _with_organ(tmp_path, target={"centre_mm": CENTRE.tolist(), "radii_mm": [10.0, 10.0, 10.0],
                                      "spacing_mm": 8.0})
    inside = {"centre_mm": CENTRE.tolist(), "radii_mm": [10.0, 10.0, 10.0], "spacing_mm": 8.0}
    target_organ = C.PortPlaceConfig.model_validate({**SMALL, "target": inside, "patient": {
        **SMALL["patient"], "organs": {"bowel": {"mesh_file": str(_sphere(tmp_path)), "obstacle": False}}}})
    assert O.organ_grids(target_organ.patient) == []  # the target's own organ is no obstacle
    path = _sphere(tmp_path, name="mine.stl")
    patient = {**SMALL["patient"], "organs": {"bowel": {"mesh_file": str(path)}}}
    first = C.PortPlaceConfig.model_validate({**SMALL, "patient": patient})
    _sphere(tmp_path, radius=RADIUS + 1.0, name="mine.stl")  # the same file, another organ
    second = C.PortPlaceConfig.model_validate({**SMALL, "patient": patient})
    assert first.patient.organs["bowel"].mesh_sha256 != second.patient.organs["bowel"].mesh_sha256
    assert study_key("port-place", first, 1) != study_key("port-place", second, 1)


@pytest.mark.skipif(not (OPENHELP / "Stomach.stl").exists(), reason="../shared/patients/openhelp is not beside the checkout")
def test_openhelps_stomach_blocks_shafts_to_the_pancreas_behind_it():
    """OpenHELP's stomach lies cranial to and in front of the pancreas's body: some ports' shafts to a target in the
    pancreas cross it, others reach it clear, and those that cross it lie more cranial (over the stomach); the
    pancreas, the target's organ, is not an obstacle."""
    wall = {"shape": "mesh", "mesh_file": str(OPENHELP / "Abdominal_wall.stl"), "mesh_is": "wall",
            "mesh_offset_mm": [0.0, 0.0, -23.0], "port_region": {"site_spacing_mm": 30.0},
            "organs": {"stomach": {"mesh_file": str(OPENHELP / "Stomach.stl")}}}
    cfg = C.PortPlaceConfig.model_validate({"patient": wall, "cart": {"model": "none"},
                                            "target": {"centre_mm": [40.0, 60.0, 105.0], "radii_mm": [12.0, 10.0, 8.0],
                                                       "spacing_mm": 6.0}})
    from surgopt.studies.port_place.model import prepare

    model = prepare(cfg)
    crossing = O.shafts_crossing(model.sites_m, model.targets_m, O.organ_grids(cfg.patient))
    blocked = (crossing == 0).any(axis=1)  # ports some of whose shafts cross the stomach
    assert 0 < blocked.sum() < len(blocked)  # some do, others reach the pancreas clear of it
    assert np.median(model.sites_m[blocked, 1]) > np.median(model.sites_m[~blocked, 1])  # from above it (cranial)


def test_a_target_is_a_region_of_an_organs_mesh(tmp_path):
    """#57 item 1: the target as a region of an organ (``target.region_box_mm`` over ``shape = "mesh"``): its points
    are the grid points inside the organ (a sphere, analytic: away from its facets by 0.5 mm) and inside the box,
    every one of them; its centre and extent are the region's. A box holding no point is refused by field."""
    path = _sphere(tmp_path, centre=np.array([0.0, 0.0, 60.0]), radius=30.0)
    box = [[0.0, -40.0, 20.0], [40.0, 40.0, 100.0]]  # the sphere's left half
    t = C.Target.model_validate({"shape": "mesh", "mesh_file": str(path), "region_box_mm": box, "spacing_mm": 4.0})
    from surgopt.studies.port_place.geometry import target_points_mm

    pts = target_points_mm(t)
    r = np.linalg.norm(pts - [0.0, 0.0, 60.0], axis=1)
    assert len(pts) > 100 and np.all(r <= 30.0) and np.all(pts[:, 0] >= 0.0)
    whole = target_points_mm(C.Target.model_validate({"shape": "mesh", "mesh_file": str(path), "spacing_mm": 4.0}))
    clear = whole[np.linalg.norm(whole - [0.0, 0.0, 60.0], axis=1) < 29.5]
    want = clear[np.all((clear >= box[0]) & (clear <= box[1]), axis=1)]
    assert {tuple(p) for p in want} <= {tuple(p) for p in pts}  # every point of the region, none outside it
    np.testing.assert_allclose(t.centre_mm, pts.mean(axis=0), atol=1e-6)
    assert len(whole) > 1.8 * len(pts)  # the premise: the box cut the organ
    with pytest.raises(ValueError, match="region_box_mm: no point of"):
        C.Target.model_validate({"shape": "mesh", "mesh_file": str(path), "region_box_mm": [[50, 50, 50], [60, 60, 60]]})


def test_a_mesh_is_drawn_decimated_within_a_cell_of_its_surface(tmp_path):
    """The page draws a mesh (the body, each organ) decimated by vertex clustering: within its budget of triangles,
    every drawn vertex within a cell's diagonal of the true sphere, and every point of the sphere's mesh within
    two cells of a drawn vertex (nothing cut away); a mesh within its budget is drawn as it is."""
    from surgopt.studies.port_place.scene import decimated

    sphere = trimesh.creation.icosphere(subdivisions=5, radius=50.0)  # 20,480 triangles
    v, f, cell = decimated(sphere.vertices, sphere.faces, 2000)
    assert 0 < len(f) <= 2000 and cell > 0  # the premise: it had to be decimated
    assert np.all(np.abs(np.linalg.norm(v, axis=1) - 50.0) <= np.sqrt(3) * cell + 0.2)
    from scipy.spatial import cKDTree

    assert cKDTree(v).query(sphere.vertices)[0].max() <= 2 * cell
    assert f.min() >= 0 and f.max() < len(v) and np.all((f[:, 0] != f[:, 1]) & (f[:, 1] != f[:, 2]))
    same_v, same_f, none = decimated(sphere.vertices, sphere.faces, 30_000)
    assert none == 0.0 and len(same_f) == len(sphere.faces)


def test_the_scene_draws_each_organ_with_its_role(tmp_path):
    """The page's scene draws the organs: an obstacle and the target's organ, each named with its role, within the
    drawing's budget of triangles."""
    from surgopt.studies.port_place.scene import ORGAN_FACES, organ_traces

    big = _sphere(tmp_path, name="big.stl")
    patient = {**SMALL["patient"], "organs": {"bowel": {"mesh_file": str(big)},
                                              "spleen": {"mesh_file": str(_sphere(tmp_path, centre=np.array(
                                                  [120.0, 0.0, 60.0]), radius=10.0, name="s.stl")),
                                                         "obstacle": False}}}
    traces = organ_traces(C.PortPlaceConfig.model_validate({**SMALL, "patient": patient}))
    assert [t["text"].split(" (")[0] for t in traces] == ["bowel", "spleen"]  # each organ's hover text
    assert "an obstacle" in traces[0]["text"] and "the target's organ" in traces[1]["text"]
    assert [t["showlegend"] for t in traces] == [True, False]  # one legend entry for them all
    assert all(len(t["i"]) <= ORGAN_FACES for t in traces)
