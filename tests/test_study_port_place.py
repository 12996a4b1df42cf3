"""port-place (surgopt/studies/port_place/study.py, surgopt/kinematics/port/place.py): the dVRK arms' RCM kinematics
against the modified-DH tables multiplied out in tests/reference.py, reach against joint-space sampling,
angles and clearances against closed forms, a mirror-symmetric patient's optimum, bad input, the CLI."""
import math
import os

import numpy as np
import pytest

from surgopt.kinematics.port import place as K
from surgopt.robots import dvrk
from surgopt.robots.models import get_model
from surgopt.studies.port_place import config as C
from surgopt.studies.port_place import geometry as G
from surgopt.studies.port_place import tables as T
from surgopt.studies.port_place import model as M
from surgopt.studies.port_place import study as S

from conftest import cli, fault_lines, invoke
from reference import finite_difference_jacobian

ANY_APPROACH = K.Approach(0.0, 0.0, -1.0, -2.0)  # no approach cone

RNG = np.random.default_rng(29)
SMALL = {"patient": {"port_region": {"site_spacing_mm": 36.0}}, "target": {"spacing_mm": 15.0}, "cart": {"model": "none"}}


def _limits(arm):
    return T.arm_limits(arm)


def test_a_mirror_symmetric_patient_gives_a_mirror_symmetric_optimum():
    cfg = C.PortPlaceConfig.model_validate(SMALL)
    sites = G.sites_mm(cfg)
    mirror = {i: int(np.flatnonzero(np.all(np.isclose(sites, sites[i] * [-1, 1, 1]), axis=1))[0])
              for i in range(len(sites))}  # the premise: the sites are symmetric about x = 0
    cols = S.compute_task(cfg, S.n_total(cfg), 0)
    ok = np.flatnonzero(cols["feasible"])
    assert len(ok) > 0
    best = ok[np.argmin(cols["cost"][ok])]
    i, j, k = (cols[c][best] for c in ("psm1_site", "psm2_site", "ecm_site"))
    mi, mj, mk = sorted((mirror[i], mirror[j]))[0], sorted((mirror[i], mirror[j]))[1], mirror[k]
    twin = np.flatnonzero((cols["psm1_site"] == mi) & (cols["psm2_site"] == mj) & (cols["ecm_site"] == mk))[0]
    assert cols["feasible"][twin]
    assert cols["cost"][twin] == pytest.approx(cols["cost"][best], rel=1e-9, abs=1e-12)


THREE = {"patient": {"port_region": {"site_spacing_mm": 50.0}}, "target": {"spacing_mm": 15.0},
         "robot": {"instrument_count": 3}, "cart": {"model": "none"}}


def test_three_psms_on_a_mirror_symmetric_patient_give_every_design_its_mirror_twin():
    """3 PSMs + ECM, every design of a reduced case (18 sites): the mirror image of each design (each port
    mirrored about x = 0, the working pair reordered) has the same cost and feasibility; so the optimum is
    mirror-symmetric or comes with its twin. The common reach of all three against the reach matrix."""
    cfg = C.PortPlaceConfig.model_validate(THREE)
    sites = G.sites_mm(cfg)
    mirror = np.array([int(np.flatnonzero(np.all(np.isclose(sites, sites[i] * [-1, 1, 1]), axis=1))[0])
                       for i in range(len(sites))])
    cols = S.compute_task(cfg, S.n_total(cfg), 0)
    arms = [cols[c] for c in ("psm1_site", "psm2_site", "psm3_site", "ecm_site")]
    index = {d: r for r, d in enumerate(zip(*(a.tolist() for a in arms)))}
    assert len(index) == len(cols["cost"]) == S.n_total(cfg) == 18 * 17 // 2 * 16 * 15
    i, j, l, k = (mirror[a] for a in arms)
    twin = np.array([index[(min(a, b), max(a, b), c, d)] for a, b, c, d in zip(i, j, l, k)])
    np.testing.assert_allclose(cols["cost"][twin], cols["cost"], rtol=1e-9, atol=1e-12)
    assert np.array_equal(cols["infeasible"][twin], cols["infeasible"])
    assert 0 < cols["feasible"].sum() < len(twin)
    reach = M.model_of(cfg).grid.reach
    common = (reach[arms[0]] & reach[arms[1]] & reach[arms[2]]).mean(axis=1)
    np.testing.assert_array_equal(cols["common_reach"], common)


def test_three_psms_from_the_cli_store_only_feasible_rows_and_say_so(tmp_path):
    """rows_stored=feasible: the summary counts every design enumerated and says the infeasible rows were not
    kept, read back from the store too; PSM3 is in the layout; the full 3-PSM default is refused for memory
    with the way out named (an estimate, nothing run)."""
    import json

    overrides = ["patient.port_region.site_spacing_mm=50", "target.spacing_mm=15", "robot.instrument_count=3",
                 "rows_stored=feasible", "cart.model=none"]  # three PSMs on the cart: tests/test_runner.py
    code, out = invoke("port-place", *overrides, "--store", tmp_path / "s")  # in this process: no start-up
    assert code == 0 and "feasible only" in out and "psm3" in out and "all three instruments" in out
    rec = json.loads(cli("summarize", "--store", tmp_path / "s", "--format", "json").stdout)
    assert rec["headline"]["designs"] == 36_720 and rec["rows"] == rec["headline"]["feasible"] > 0
    assert rec["top"][0]["psm3_reach"] == 1.0 and rec["top"][0]["common_reach"] == 1.0
    code, out = invoke("plot", "--store", tmp_path / "s", "--out", tmp_path / "fig")
    assert code == 0 and "port_place_layout_3d.png" in out and "port_place_reasons.png" not in out
    # none feasible: the run kept no reasons, and says how to see them (not "the reasons below")
    import os

    none = cli("port-place", *overrides, "constraints.min_port_spacing_mm=220", "--store", tmp_path / "n",
               env=dict(os.environ, COLUMNS="400"))
    assert "none: no design is feasible (this run stored feasible rows only, so it kept no reasons" in none.stdout
    big = cli("port-place", "robot.instrument_count=3", "--store", tmp_path / "t", "--max-memory-gb", "4",
              check=False)
    assert big.returncode == 2 and "348,612,012 port designs" in big.stderr and "rows_stored=feasible" in big.stderr
    assert not (tmp_path / "t").exists() or not any((tmp_path / "t").rglob("*.parquet"))


def test_a_target_from_a_points_file_gives_the_rows_of_the_same_points_sampled(tmp_path):
    """target.shape = 'points': the small config's own ellipsoid points written to a CSV (with a header comment)
    and to a .npy file (in m) give every row of the sampled target; without centre_mm the centre is the points'
    centroid."""
    from surgopt.config import validate

    cfg = validate(SMALL, C.Config, "x")
    pts = G.target_points_mm(cfg.target)
    np.savetxt(tmp_path / "t.csv", pts, delimiter=",", header="x_mm, y_mm, z_mm")
    np.save(tmp_path / "t.npy", pts / 1000)
    grid = S.compute_task(cfg, 10 ** 7, 0)
    for target in ({"points_file": str(tmp_path / "t.csv")}, {"points_file": str(tmp_path / "t.npy"), "points_units": "m"}):
        f = validate({**SMALL, "target": {"shape": "points", "centre_mm": cfg.target.centre_mm, **target}}, C.Config, "x")
        assert len(G.target_points_mm(f.target)) == len(pts) == 59
        rows = S.compute_task(f, 10 ** 7, 0)
        for c, v in grid.items():
            np.testing.assert_allclose(rows[c], v, rtol=0, atol=1e-9, err_msg=c)
    auto = validate({"target": {"shape": "points", "points_file": str(tmp_path / "t.csv")}}, C.Config, "x")
    np.testing.assert_allclose(auto.target.centre_mm, pts.mean(axis=0), atol=1e-6)
    assert len(auto.target.points_sha256) == 64


POINT_FILE_ERRORS = {
    "not finite": ("1 2 3\n4 nan 6\n", "row 2 is not finite"),
    "two columns": ("1 2\n3 4\n", "not rows of x y z"),
    "words": ("x y z\n1 2 3\n", "not x y z rows of numbers"),
    "outside the body": ("0 -100 40\n0 -100 400\n", "is outside the body"),
}


@pytest.mark.parametrize("case", sorted(POINT_FILE_ERRORS))
def test_a_bad_points_file_is_one_line_naming_the_field(tmp_path, case):
    text, what = POINT_FILE_ERRORS[case]
    (tmp_path / "t.txt").write_text(text)
    (tmp_path / "p.toml").write_text('[target]\nshape = "points"\npoints_file = "t.txt"\n')
    r = cli("port-place", "p.toml", "--store", tmp_path / "s", check=False, cwd=tmp_path)
    lines = fault_lines(r.stderr)
    assert r.returncode == 2 and len(lines) == 1 and "p.toml" in lines[0] and "target" in lines[0], r.stderr
    assert what in lines[0], lines[0]
    assert not (tmp_path / "s").exists()


BAD = {
    "target outside the body": ("[target]\ncentre_mm = [0.0, -100.0, 130.0]\n", "target", "outside the body"),
    "reversed range": ("[constraints]\nport_to_target_mm = [180.0, 80.0]\n", "port_to_target_mm", "low < high"),
    "no sites": ("[constraints]\nport_to_target_mm = [5.0, 10.0]\n", "port_region", "candidate site"),
    "unknown arm": ('[robot]\ninstrument_arm = "kuka"\n', "robot.instrument_arm", "dvrk_psm_classic"),
    "ports closer than the spacing": ("[constraints]\nmin_port_spacing_mm = 900.0\n", "min_port_spacing_mm",
                                      "no two candidate sites are that far apart"),
    "unreachable target": ("[target]\napproach_direction = [0.0, 0.0, 1.0]\n", "target",  # jaws up: past the wrist
                           "reaches the whole target: 0 of its"),
}


def refused_in_one_line(tmp_path, text: str, where: str, what: str) -> None:
    """`surgopt port-place` on a config of ``text`` exits 2 with one line naming the file (or the run) and
    ``where``, saying ``what``, and writes nothing."""
    (tmp_path / "p.toml").write_text(text)
    r = cli("port-place", tmp_path / "p.toml", "--store", tmp_path / "store", check=False)
    assert r.returncode == 2, r.stderr
    lines = fault_lines(r.stderr)  # a check that needs the kernels may first say they compile
    line = lines[0] if lines else ""
    named = "p.toml" in line or line.startswith("surgopt: error: p: ")  # the file, or the run it names
    assert len(lines) == 1 and named and where in line and what in line, line
    assert not (tmp_path / "store").exists()


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_input_is_one_line_naming_the_field(tmp_path, case):
    refused_in_one_line(tmp_path, *BAD[case])


def test_the_elevation_is_each_shafts_angle_above_the_horizontal():
    """Hanna et al.'s elevation angle of each instrument against atan2 of the rise over the horizontal run
    from its port to the target centre, from the rows' own port positions (three instruments, every row)."""
    cfg = C.PortPlaceConfig.model_validate(THREE)
    cols = S.compute_task(cfg, S.n_total(cfg), 0)
    cx, cy, cz = cfg.target.centre_mm
    for arm in ("psm1", "psm2", "psm3"):
        run = np.hypot(cols[f"{arm}_x_mm"] - cx, cols[f"{arm}_y_mm"] - cy)
        np.testing.assert_allclose(cols[f"{arm}_elevation_deg"], np.degrees(np.arctan2(cols[f"{arm}_z_mm"] - cz, run)),
                                   rtol=0, atol=1e-9)
    assert np.ptp(cols["psm1_elevation_deg"]) > 10  # the premise: the elevation varies over the sites


def test_the_cli_runs_stores_and_reports_the_clinical_checks(tmp_path):
    import json

    overrides = ["patient.port_region.site_spacing_mm=36", "target.spacing_mm=15", "cart.model=none"]  # the
    # cart's report: tests/test_port_place_cart.py
    r = cli("port-place", *overrides, "--store", tmp_path / "s", "--quiet")
    assert "clinical checks" in r.stdout and "manipulation angle at the centre" in r.stdout
    cfg = C.PortPlaceConfig.model_validate(SMALL)
    rec = json.loads(cli("summarize", "--store", tmp_path / "s", "--format", "json").stdout)
    assert rec["rows"] == S.n_total(cfg) and rec["headline"]["feasible"] > 0
    best = rec["top"][0]
    assert best["feasible"] and 45 <= best["manipulation_angle_centre_deg"] <= 75
    assert best["min_port_spacing_mm"] >= 80 and best["common_reach"] == 1.0
    out = cli("plot", "--store", tmp_path / "s", "--out", tmp_path / "fig").stdout
    assert "port_place_layout_3d.png" in out and "port_place_sites_top.png" in out
    assert "port_place_reach_top.png" in out and (tmp_path / "fig" / "port_place_reach_top.png").stat().st_size > 10_000
    wide = {**os.environ, "COLUMNS": "400"}
    text = cli("summarize", "--store", tmp_path / "s", env=wide).stdout  # the top table: the study's selection
    assert "more columns: --columns or --format json" in text and "manipulation_angle_centre_deg" in text
    assert "psm1_x_mm" not in text
    chosen = cli("summarize", "--store", tmp_path / "s", "--columns", "design_id,psm1_x_mm", env=wide).stdout
    assert "psm1_x_mm" in chosen and "more columns" not in chosen


# --- a patient given as a triangle mesh (trimesh) ------------------------------------------------------------

def _dome_mesh(path, subdivisions=4, open_base=False):
    """The default dome (170 x 210 x 140 mm) as a closed triangle mesh: an ellipsoid cut at z = 0 and capped."""
    import trimesh

    sphere = trimesh.creation.icosphere(subdivisions=subdivisions)
    sphere.apply_scale([170.0, 210.0, 140.0])
    half = trimesh.intersections.slice_mesh_plane(sphere, plane_normal=[0, 0, 1], plane_origin=[0, 0, 0],
                                                  cap=not open_base)
    half.export(path)
    return path


def test_a_mesh_of_the_dome_gives_the_domes_sites_and_best_layout(tmp_path):
    """Independent check of the mesh path (vertical rays on trimesh's mesh, its containment test) against the
    closed-form dome: the same candidate sites within the faceting error, the same best layout, its cost within
    0.1 %. The mesh is in metres with an offset, to exercise units and placement."""
    import trimesh

    from surgopt.config import validate

    mesh = trimesh.load(_dome_mesh(tmp_path / "dome.stl", subdivisions=5))
    mesh.apply_scale(0.001)
    mesh.apply_translation([0.0, 0.0, -0.02])  # 20 mm below the table: the offset puts it back
    mesh.export(tmp_path / "dome_m.ply")
    small = {"patient": {"port_region": {"site_spacing_mm": 72.0}}, "target": {"spacing_mm": 20.0}, "cart": {"model": "none"}}
    dome = validate(small, C.Config, "dome")
    as_mesh = validate({**small, "patient": {**small["patient"], "shape": "mesh", "mesh_file": "dome_m.ply",
                                             "mesh_units": "m", "mesh_offset_mm": [0.0, 0.0, 20.0]}},
                       C.Config, "mesh", {"config_dir": str(tmp_path)})
    a, b = G.sites_mm(dome), G.sites_mm(as_mesh)
    assert a.shape == b.shape and np.abs(a[:, :2] - b[:, :2]).max() < 1e-6
    assert np.abs(a[:, 2] - b[:, 2]).max() < 1.0  # mm: the icosphere's faceting
    assert len(as_mesh.patient.mesh_sha256) == 64
    rows_d, rows_m = S.compute_task(dome, 10 ** 6, 0), S.compute_task(as_mesh, 10 ** 6, 0)
    assert rows_d["feasible"].sum() > 0
    assert np.array_equal(rows_d["feasible"], rows_m["feasible"])
    cost_d = np.where(rows_d["feasible"], rows_d["cost"], np.inf)
    cost_m = np.where(rows_m["feasible"], rows_m["cost"], np.inf)
    tied_best = np.flatnonzero(cost_d <= cost_d.min() + 1e-12)  # mirror-image layouts tie on the dome
    assert len(tied_best) == 2 and np.argmin(cost_m) in tied_best  # the faceting breaks the tie, either way
    assert cost_m.min() == pytest.approx(cost_d.min(), rel=1e-3)


def test_a_superquadric_dome_lifts_the_sites_onto_its_own_surface_and_agrees_with_its_mesh(tmp_path):
    """patient.dome_exponent = 4: every candidate site lies on |x/a|^4 + |y/b|^4 + |z/c|^4 = 1 (to 1e-9), the
    containment test is that inequality, the flatter top gives more sites above the height fraction than the
    half-ellipsoid, and a closed mesh of the same surface (the convex hull of its points, through trimesh's
    rays) gives the same sites within its faceting."""
    import trimesh

    from surgopt.config import validate
    from surgopt.studies.port_place.geometry import dome_surface_mm

    small = {"patient": {"port_region": {"site_spacing_mm": 36.0}, "dome_exponent": 4.0}}
    quad = validate(small, C.Config, "quad")
    sites = G.sites_mm(quad)
    a, b, c = quad.patient.semi_axes_mm
    np.testing.assert_allclose((np.abs(sites / [a, b, c]) ** 4).sum(axis=1), 1.0, rtol=0, atol=1e-9)
    pts = RNG.uniform([-a, -b, -10.0], [a, b, c], (2000, 3))
    want = (pts[:, 2] >= 0) & ((np.abs(pts / [a, b, c]) ** 4).sum(axis=1) < 1)
    assert np.array_equal(G.inside_body(pts, quad.patient), want) and 0 < want.sum() < len(want)
    assert len(sites) > len(G.sites_mm(validate({"patient": {"port_region": {"site_spacing_mm": 36.0}}}, C.Config,
                                                 "ellipsoid")))
    u, v = np.meshgrid(np.linspace(0, 2 * np.pi, 360, endpoint=False), np.linspace(0, np.pi / 2, 90, endpoint=False))
    surface = np.vstack([np.stack([w.ravel() for w in dome_surface_mm((a, b, c), 4.0, u, v)], axis=1), [[0, 0, c]]])
    trimesh.convex.convex_hull(surface).export(tmp_path / "quad.stl")  # closed: the surface and its base
    as_mesh = validate({"patient": {"port_region": {"site_spacing_mm": 36.0}, "shape": "mesh",
                                    "mesh_file": "quad.stl"}}, C.Config, "mesh", {"config_dir": str(tmp_path)})
    m = G.sites_mm(as_mesh)
    assert m.shape == sites.shape and np.abs(m[:, :2] - sites[:, :2]).max() < 1e-6
    assert np.abs(m[:, 2] - sites[:, 2]).max() < 1.0  # mm: the hull's faceting
    cols = S.compute_task(quad, 10 ** 6, 0)
    assert cols["feasible"].any()


MESH_ERRORS = {
    "not closed": ({"mesh_file": "open.stl"}, "is not closed (watertight)"),
    "missing": ({"mesh_file": "nosuch.stl"}, "mesh_file: file not found"),
    "no file": ({}, "shape = 'mesh' needs mesh_file"),
    "not a mesh format": ({"mesh_file": "dome.txt"}, "not an STL, OBJ or PLY file"),
    "garbage": ({"mesh_file": "garbage.stl"}, "garbage.stl: no triangles"),
    "in metres read as mm": ({"mesh_file": "dome_m.stl"}, "not an abdomen's (20 to 1000 mm); read as m it would fit"),
}


@pytest.mark.parametrize("case", sorted(MESH_ERRORS))
def test_a_bad_mesh_is_refused_with_the_field_named(tmp_path, case):
    import trimesh

    from surgopt.config import validate
    from surgopt.errors import ConfigError

    _dome_mesh(tmp_path / "open.stl", subdivisions=2, open_base=True)
    (tmp_path / "dome.txt").write_text("solid x")
    (tmp_path / "garbage.stl").write_bytes(b"\x00\x01 not a mesh" * 7)
    trimesh.load(_dome_mesh(tmp_path / "dome.stl", subdivisions=2)).apply_scale(0.001).export(tmp_path / "dome_m.stl")
    fields, words = MESH_ERRORS[case]
    with pytest.raises(ConfigError, match="patient") as e:
        validate({"patient": {"shape": "mesh", **fields}}, C.Config, "c.toml", {"config_dir": str(tmp_path)})
    assert words in str(e.value), str(e.value)
    with pytest.raises(ConfigError, match="set shape = 'mesh'"):
        validate({"patient": {"mesh_file": "open.stl"}}, C.Config, "c.toml", {"config_dir": str(tmp_path)})


def _target_mesh(path, subdivisions=4, open_base=False):
    """The default target (an ellipsoid of 35 x 45 x 30 mm semi-axes at (0, -100, 40) mm) as a closed mesh in
    metres (or with a hole), written to ``path``."""
    import trimesh

    mesh = trimesh.creation.icosphere(subdivisions=subdivisions)
    mesh.apply_scale([0.035, 0.045, 0.030])
    mesh.apply_translation([0.0, -0.100, 0.040])
    if open_base:
        mesh.update_faces(np.arange(len(mesh.faces)) > 0)
    mesh.export(path)
    return path


def test_a_target_mesh_of_the_ellipsoid_gives_the_ellipsoids_points_and_rows(tmp_path):
    """A target given as a closed mesh (the default ellipsoid tessellated, in metres) is sampled on the same grid
    as the ellipsoid: every mesh point is an ellipsoid point, every ellipsoid point deeper than the faceting
    (ellipsoid value <= 0.99) is a mesh point (here every one: the sets are equal), and the layouts' rows are the
    ellipsoid's to 1e-6 (the STL's float32 vertices move the grid by ~2e-6 mm)."""
    from surgopt.config import validate

    _target_mesh(tmp_path / "target.stl")
    small = {"patient": {"port_region": {"site_spacing_mm": 36.0}}}
    ell = validate({**small, "target": {"spacing_mm": 10.0}}, C.Config, "ellipsoid")
    mesh = validate({**small, "target": {"shape": "mesh", "mesh_file": "target.stl", "mesh_units": "m",
                                         "spacing_mm": 10.0}}, C.Config, "mesh", {"config_dir": str(tmp_path)})
    a, b = G.target_points_mm(ell.target), G.target_points_mm(mesh.target)
    assert len(mesh.target.mesh_sha256) == 64 and np.allclose(mesh.target.centre_mm, [0.0, -100.0, 40.0], atol=1e-6)
    key = lambda p: {tuple(np.round(x, 3)) for x in p}  # noqa: E731 - to the um (an STL stores float32)
    assert key(b) <= key(a)
    value = (((a - [0.0, -100.0, 40.0]) / [35.0, 45.0, 30.0]) ** 2).sum(axis=1)
    assert key(a[value <= 0.99]) <= key(b) and len(b) > 20
    assert key(a) == key(b)  # at this spacing no grid point lies between the facets and the ellipsoid
    rows_e, rows_m = S.compute_task(ell, 10 ** 6, 0), S.compute_task(mesh, 10 ** 6, 0)
    assert rows_e["feasible"].any()
    for name in ("feasible", "cost", "common_reach"):
        np.testing.assert_allclose(rows_m[name], rows_e[name], rtol=0, atol=1e-6)


TARGET_MESH_ERRORS = {
    "not closed": ({"mesh_file": "open.stl"}, "is not closed (watertight)"),
    "no file": ({}, "shape = 'mesh' needs mesh_file"),
    "in metres read as mm": ({"mesh_file": "target.stl"}, "not a target region's (1 to 300 mm); read as m it would fit"),
    "between its parts": ({"mesh_file": "pair.stl", "spacing_mm": 100.0}, "no point of a 100 mm grid"),
    "not a mesh target": ({"shape": "ellipsoid", "mesh_file": "target.stl"}, "set shape = 'mesh'"),
}


@pytest.mark.parametrize("case", sorted(TARGET_MESH_ERRORS))
def test_a_bad_target_mesh_is_refused_with_the_field_named(tmp_path, case):
    import trimesh

    from surgopt.config import validate
    from surgopt.errors import ConfigError

    _target_mesh(tmp_path / "target.stl")
    _target_mesh(tmp_path / "open.stl", open_base=True)
    pair = trimesh.util.concatenate([trimesh.creation.icosphere(radius=10.0).apply_translation(c)
                                     for c in ([-30.0, -100.0, 40.0], [30.0, -100.0, 40.0])])
    pair.export(tmp_path / "pair.stl")  # two closed balls: the grid's one point, between them, is in neither
    fields, words = TARGET_MESH_ERRORS[case]
    with pytest.raises(ConfigError, match="target") as e:
        validate({"target": {"shape": "mesh", **fields}}, C.Config, "c.toml", {"config_dir": str(tmp_path)})
    assert words in str(e.value), str(e.value)


# --- searches over the ports and the docking (plans) ----------------------------------------------------------

COARSE = {"patient": {"port_region": {"site_spacing_mm": 72.0}}, "target": {"spacing_mm": 20.0}, "cart": {"model": "none"}}


@pytest.mark.parametrize("instruments", [2, 3])
def test_a_design_evaluated_alone_equals_its_row_of_the_enumeration(instruments):
    """The search's evaluator (each design from the tables of its own ports) against the enumeration's
    combined tables: every column equal (floats to 1e-9) for every design of the small config (with three
    instruments, every 50th design)."""
    from surgopt.config import validate

    cfg = validate({**COARSE, "robot": {"instrument_count": instruments}}, C.Config, "x")
    grid = S.compute_task(cfg, 10 ** 6, 0)
    if instruments == 3:
        grid = {c: v[::50] for c, v in grid.items()}
    x = np.column_stack([grid[f"{arm}_site"] for arm in S.arms_of(cfg)]).astype(float)
    alone = S.evaluate_designs(cfg, x, grid["design_id"], "grid")
    assert set(alone) == set(grid)
    for c, v in grid.items():
        if np.asarray(v).dtype.kind == "f":
            np.testing.assert_allclose(alone[c], v, rtol=0, atol=1e-9, err_msg=c)
        else:
            assert np.array_equal(alone[c], v), c


def test_free_docking_turns_the_base_and_a_search_explores_ports_and_docking(tmp_path):
    """Docking offsets turn the arm's base: 0 is the default docking; a large pitch moves target points out of
    the pitch range (reach falls) and moves the arms' outside clearance. A CMA-ES search over the three ports
    (categorical, with margin) and the four docking angles runs, deterministic, within the bounds, and its
    coinciding-port designs are infeasible."""
    from surgopt.config import validate
    from surgopt.runner import run_study
    from surgopt.store import Store

    cfg = validate({**COARSE, "robot": {"docking_range_deg": 60.0},
                    "search": {"method": "cmaes", "trials": 120, "batch": 40, "seed": 3}}, C.Config, "x")
    base = [0.0, 1.0, 2.0]
    rows = S.evaluate_designs(cfg, np.array([base + [0, 0, 0, 0], base + [0, 60, 0, 0]]), np.arange(2), "t")
    # PSM1 pitched 60 deg off the centre, past its +-53 deg pitch range: most points out of reach, and its arm
    # swung toward the others outside the body
    assert rows["psm1_reach"][1] < 0.5 * rows["psm1_reach"][0] and rows["psm2_reach"][1] == rows["psm2_reach"][0]
    assert rows["external_clearance_mm"][1] < rows["external_clearance_mm"][0]
    same = S.evaluate_designs(cfg, np.array([[0.0, 0.0, 2.0, 0, 0, 0, 0]]), np.arange(1), "t")
    assert not same["feasible"][0] and same["min_port_spacing_mm"][0] == 0.0
    plan = S.search_plan(cfg)
    assert list(plan.space) == ["psm1_site", "psm2_site", "ecm_site", *S.DOCKING_COLUMNS]
    a = run_study(S.STUDY, cfg, config_name="a", store=Store(tmp_path / "a"), jobs=2, quiet=True).table
    b = run_study(S.STUDY, cfg, config_name="b", store=Store(tmp_path / "b"), jobs=1, quiet=True).table
    assert a.equals(b) and a.num_rows == 120
    n = len(G.sites_mm(cfg))
    for c in S.SITE_COLUMNS:
        assert set(a[c].to_pylist()) <= set(range(n))
    for c in S.DOCKING_COLUMNS:
        v = a[c].to_numpy()
        assert v.min() >= -60 and v.max() <= 60 and len(set(v.tolist())) > 10


def test_a_surface_search_places_each_port_at_the_site_nearest_its_point(tmp_path):
    """search_ports = "surface": the space is each port's top-view point within the sites' box; a design whose
    points are the sites themselves is the enumeration's row (every column, the aims added); random points go
    to the nearest site (brute force over every site); a CMA-ES search is deterministic on one worker or two,
    its aims within the box and its sites the nearest to them."""
    from surgopt.config import validate
    from surgopt.runner import run_study
    from surgopt.store import Store

    cfg = validate({**COARSE, "search_ports": "surface", "search": {"method": "cmaes", "trials": 60, "seed": 2}},
                   C.Config, "x")
    sites = G.sites_mm(cfg)
    plan = S.search_plan(cfg)
    assert list(plan.space) == list(S.aim_columns(cfg)) == ["psm1_aim_x_mm", "psm1_aim_y_mm", "psm2_aim_x_mm",
                                                           "psm2_aim_y_mm", "ecm_aim_x_mm", "ecm_aim_y_mm"]
    assert plan.space["psm1_aim_x_mm"] == (sites[:, 0].min(), sites[:, 0].max())
    grid = S.compute_task(cfg, 10 ** 6, 0)
    pick = np.arange(0, len(grid["design_id"]), 97)
    ids = np.column_stack([grid[f"{a}_site"][pick] for a in S.arms_of(cfg)])
    x = sites[ids][:, :, :2].reshape(len(pick), -1)
    alone = S.evaluate_designs(cfg, x, grid["design_id"][pick], "t")
    for c, v in grid.items():
        np.testing.assert_allclose(np.asarray(alone[c], float), np.asarray(v, float)[pick], rtol=0, atol=1e-9,
                                   err_msg=c)
    aims = RNG.uniform(sites[:, :2].min(axis=0), sites[:, :2].max(axis=0), (200, 2))
    d = np.linalg.norm(aims[:, None, :] - sites[None, :, :2], axis=2)
    assert np.array_equal(d[np.arange(200), S.nearest_sites(sites[:, :2], aims)], d.min(axis=1))
    a = run_study(S.STUDY, cfg, config_name="a", store=Store(tmp_path / "a"), jobs=2, quiet=True).table
    b = run_study(S.STUDY, cfg, config_name="b", store=Store(tmp_path / "b"), jobs=1, quiet=True).table
    assert a.equals(b) and a.num_rows == 60
    for arm in S.arms_of(cfg):
        aim = np.column_stack([a[f"{arm}_aim_x_mm"].to_numpy(), a[f"{arm}_aim_y_mm"].to_numpy()])
        assert np.all(aim >= sites[:, :2].min(axis=0)) and np.all(aim <= sites[:, :2].max(axis=0))
        assert np.array_equal(a[f"{arm}_site"].to_numpy(), S.nearest_sites(sites[:, :2], aim))


def test_a_pareto_front_is_of_the_feasible_layouts_only(tmp_path):
    """An NSGA-II search on (cost, common reach): the summary's front is the non-dominated set of the feasible
    trials alone (brute-force dominance here), and it says how many were feasible; an infeasible layout of lower
    cost (the premise) is not on it."""
    from surgopt.config import validate
    from surgopt.report import search_front
    from surgopt.runner import run_study
    from surgopt.store import Store

    cfg = validate({**COARSE, "search": {"method": "nsga2", "trials": 80, "seed": 1,
                                         "objectives": ["-cost", "common_reach"]}}, C.Config, "x")
    res = run_study(S.STUDY, cfg, config_name="n", store=Store(tmp_path), jobs=1, quiet=True)
    t = res.table
    cost, reach, ok = (t[c].to_numpy() for c in ("cost", "common_reach", "feasible"))
    assert 0 < ok.sum() < len(ok) and cost[~ok].min() < cost[ok].min()
    want = {int(t["design_id"][i].as_py()) for i in np.flatnonzero(ok)
            if not any(cost[j] <= cost[i] and reach[j] >= reach[i] and (cost[j] < cost[i] or reach[j] > reach[i])
                       for j in np.flatnonzero(ok))}
    from conftest import single_run

    run = single_run(tmp_path)
    title, names, rows = search_front(S.STUDY, run, run.parts(S.schema(cfg)))
    assert {int(r[0]) for r in rows} == want and f"of the {ok.sum()} feasible of {len(ok)} trials" in title


def test_an_approach_cone_keeps_the_points_whose_shaft_the_wrist_can_turn_into_it():
    """[target] approach_direction / approach_half_angle_deg: a point is reached only where the angle between the
    shaft (port to point) and the approach direction is at most the wrist's bend (80 deg, the LND's wrist rows)
    less the cone's half-angle; computed here apart, with numpy arccos, on the default config's ports and
    points. A cone wider than the wrist can give, a zero direction, or a half-angle alone is refused."""
    from surgopt.config import validate
    from surgopt.errors import ConfigError

    base = {"target": {"spacing_mm": 15.0}, "patient": {"port_region": {"site_spacing_mm": 40.0}}}
    cone = {**base, "target": {**base["target"], "approach_direction": [0.0, 0.3, -1.0],
                               "approach_half_angle_deg": 30.0}}
    free, coned = (validate(c, C.PortPlaceConfig, "t") for c in (base, cone))
    sites = G.sites_mm(free) / 1000
    rot = K.docking_frames(sites, np.asarray(free.target.centre_mm) / 1000, T.LATERAL)
    _, reach_free, _ = T.port_tables(M.prepare(free), sites, rot)
    _, reach_cone, dex_cone = T.port_tables(M.prepare(coned), sites, rot)
    pts = G.target_points_mm(free.target) / 1000
    v = pts[None, :, :] - sites[:, None, :]
    d = np.array([0.0, 0.3, -1.0]) / np.linalg.norm([0.0, 0.3, -1.0])
    angle = np.degrees(np.arccos(np.clip(v @ d / np.linalg.norm(v, axis=2), -1, 1)))
    assert np.array_equal(reach_cone, reach_free & (angle <= 80.0 - 30.0 + 1e-9))
    assert 0 < reach_cone.sum() < reach_free.sum()  # the premise: the cone removes some reached points, not all
    assert np.all(dex_cone[~reach_cone] == 0)
    with pytest.raises(ConfigError, match="more than the instrument's wrist can bend"):
        validate({"target": {"approach_direction": [0, 0, -1], "approach_half_angle_deg": 85.0}},
                 C.PortPlaceConfig, "t")
    with pytest.raises(ConfigError, match="must be a direction"):
        validate({"target": {"approach_direction": [0, 0, 0]}}, C.PortPlaceConfig, "t")
    with pytest.raises(ConfigError, match="goes with approach_direction"):
        validate({"target": {"approach_half_angle_deg": 10.0}}, C.PortPlaceConfig, "t")


def test_the_wrist_margin_is_what_the_cone_leaves_of_the_bend_at_the_worst_point():
    """psmN_wrist_margin_deg: the wrist's bend less the cone's half-angle less the worst point's angle between
    shaft and approach direction, against a per-point loop with atan2 (not the study's arccos); >= 0 exactly at
    the ports whose instrument keeps every point the joints allow; the whole bend (80 deg) without a cone."""
    from surgopt.config import validate

    base = {"target": {"spacing_mm": 15.0}, "patient": {"port_region": {"site_spacing_mm": 40.0}}}
    coned = validate({**base, "target": {**base["target"], "approach_direction": [0.0, 0.3, -1.0],
                                         "approach_half_angle_deg": 10.0}}, C.PortPlaceConfig, "t")
    sites = G.sites_mm(coned) / 1000
    margin = T.wrist_margin_deg(M.prepare(coned), sites)
    d = np.array([0.0, 0.3, -1.0]) / np.linalg.norm([0.0, 0.3, -1.0])
    for i, site in enumerate(sites):
        worst = max(math.degrees(math.atan2(np.linalg.norm(np.cross(p - site, d)), (p - site) @ d))
                    for p in G.target_points_mm(coned.target) / 1000)
        assert margin[i] == pytest.approx(math.degrees(dvrk.LND_WRIST_BEND_RAD) - 10.0 - worst, abs=1e-9)
    rot = K.docking_frames(sites, np.asarray(coned.target.centre_mm) / 1000, T.LATERAL)
    _, reach_cone, _ = T.port_tables(M.prepare(coned), sites, rot)
    free = validate(base, C.PortPlaceConfig, "t")
    _, reach_free, _ = T.port_tables(M.prepare(free), sites, rot)
    keeps = (reach_cone == reach_free).all(axis=1)
    assert 0 < (margin >= 0).sum() < len(sites)  # the premise: the cone binds at some ports, not all
    assert np.array_equal(margin >= -1e-9, keeps)
    assert np.all(T.wrist_margin_deg(M.prepare(free), sites) == math.degrees(dvrk.LND_WRIST_BEND_RAD))


def test_a_port_region_outline_keeps_the_sites_inside_it():
    """[patient.port_region] polygon_mm (a top-view outline a surgeon marks): the sites are the default's inside
    the outline (checked with matplotlib's Path, apart from the study's even-odd test), a concave outline keeps
    its notch empty, and an outline enclosing nothing is refused; a layout is still found inside a plausible one."""
    from matplotlib.path import Path as MplPath

    from surgopt.config import validate
    from surgopt.errors import ConfigError

    outline = [[-100, -160], [100, -160], [100, 40], [20, 40], [20, -60], [-20, -60], [-20, 40], [-100, 40]]
    free = G.sites_mm(C.PortPlaceConfig())
    cfg = validate({"patient": {"port_region": {"polygon_mm": outline}}}, C.PortPlaceConfig, "t")
    sites = G.sites_mm(cfg)
    inside = MplPath(np.asarray(outline, float)).contains_points(free[:, :2])
    assert 0 < len(sites) < len(free) and np.array_equal(sites, free[inside])
    notch = (np.abs(sites[:, 0]) < 20) & (sites[:, 1] > -60)
    assert not notch.any() and ((np.abs(free[:, 0]) < 20) & (free[:, 1] > -60) & (free[:, 1] < 40)).any()
    with pytest.raises(ConfigError, match="polygon_mm: its vertices enclose no area"):
        validate({"patient": {"port_region": {"polygon_mm": [[0, 0], [10, 10], [20, 20]]}}}, C.PortPlaceConfig, "t")


def _painted_dome(path, fmt="ply"):
    """The default dome as a closed mesh with the faces whose centre lies caudal (y < -20 mm) and high (z > 30 mm)
    painted red, the rest grey."""
    import trimesh

    mesh = trimesh.load(_dome_mesh(path.with_suffix(".stl")))
    c = mesh.triangles_center
    colours = np.tile([200, 200, 200, 255], (len(mesh.faces), 1)).astype(np.uint8)
    painted = (c[:, 1] < -20.0) & (c[:, 2] > 30.0)
    colours[painted] = [255, 0, 0, 255]
    mesh.visual.face_colors = colours
    mesh.export(path.with_suffix("." + fmt))
    return mesh, painted


def test_a_region_painted_on_the_mesh_keeps_the_sites_on_its_faces(tmp_path):
    """patient.port_region.face_color_rgb: the sites of the painted mesh are those of the unpainted one whose wall
    point lies on a painted face, the face found apart from the study's rays (trimesh's closest point on the
    mesh as exported, and the painting rule applied to that face's centre); some sites are dropped and some
    kept (the premise), and the painted run still finds feasible layouts."""
    import trimesh

    from surgopt.config import validate

    mesh, painted = _painted_dome(tmp_path / "painted")
    base = {"patient": {"shape": "mesh", "mesh_file": "painted.ply", "port_region": {"site_spacing_mm": 36.0}},
            "target": {"spacing_mm": 20.0}, "cart": {"model": "none"}}
    plain = validate(base, C.Config, "plain", {"config_dir": str(tmp_path)})
    region = {**base["patient"]["port_region"], "face_color_rgb": [255, 0, 0]}
    cfg = validate({**base, "patient": {**base["patient"], "port_region": region}}, C.Config, "painted",
                   {"config_dir": str(tmp_path)})
    every, kept = G.sites_mm(plain), G.sites_mm(cfg)
    _, _, tri = trimesh.proximity.closest_point(mesh, every)
    centre = mesh.triangles_center[tri]
    expect = (centre[:, 1] < -20.0) & (centre[:, 2] > 30.0)
    assert 0 < expect.sum() < len(every)
    assert np.array_equal(kept, every[expect])
    rows = S.compute_task(cfg, 10 ** 6, 0)
    assert rows["feasible"].any()


@pytest.mark.parametrize("case", ["dome", "stl", "colour absent"])
def test_a_painted_region_that_cannot_be_read_is_refused_with_the_field_named(tmp_path, case):
    from surgopt.config import validate
    from surgopt.errors import ConfigError

    _painted_dome(tmp_path / "painted")
    _painted_dome(tmp_path / "painted", fmt="stl")
    region = {"face_color_rgb": [0, 0, 255] if case == "colour absent" else [255, 0, 0]}
    patient = {"port_region": region} if case == "dome" else {
        "shape": "mesh", "mesh_file": "painted.stl" if case == "stl" else "painted.ply", "port_region": region}
    with pytest.raises(ConfigError, match="face_color_rgb") as e:
        validate({"patient": patient}, C.Config, "bad.toml", {"config_dir": str(tmp_path)})
    assert {"dome": "needs shape = 'mesh'", "stl": "no per-face colours",
            "colour absent": "no face of"}[case] in str(e.value)


def _scope_tip_by_bisection(p, c, theta, r, down):
    """An angled scope's tip found numerically, apart from the kernel's law of sines: the shaft turned by a in
    the plane of the line of sight and the patient's front (+z); the view, the shaft turned by theta the other
    way, is the line through the centre, and the tip is where it meets the shaft's line (least squares); then
    the a where the centre is r from the tip, by bisection."""
    u = (c - p) / np.linalg.norm(c - p)
    w = np.array([0.0, 0.0, 1.0]) - u[2] * u
    w /= np.linalg.norm(w)
    sign = 1.0 if down else -1.0

    def at(a):
        s = np.cos(a) * u + sign * np.sin(a) * w
        v = np.cos(theta - a) * u - sign * np.sin(theta - a) * w
        (l, m), *_ = np.linalg.lstsq(np.column_stack([s, v]), c - p, rcond=None)  # p + l s = c - m v
        return p + l * s, v, m

    lo, hi = 0.0, theta  # the centre's distance from the tip grows from 0 (a = 0) to |c - p| (a = theta)
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if at(mid)[2] < r else (lo, mid)
    return at(lo)[:2]


@pytest.mark.parametrize("view", ["down", "up"])
def test_an_angled_scope_looks_at_the_centre_from_the_standoff(view):
    """camera_views for a 30 deg scope against the tip found by bisection on the constraints (the view through
    the centre, the tip standoff_m from it), on every default site the ECM can use; the view is 30 deg off the
    shaft; the coverage counts the points in the cone about that view; a straight scope is unchanged."""
    from surgopt.kinematics.port import place as K

    cfg = C.PortPlaceConfig.model_validate({"robot": {"camera_scope_angle_deg": 30.0, "camera_scope_view": view}})
    sites, centre = G.sites_mm(cfg) / 1000, np.asarray(cfg.target.centre_mm) / 1000
    cam = T.camera_of(cfg)
    rot = K.docking_frames(sites, centre, T.LATERAL)
    tips, axes, ok = K.camera_views(sites, rot, centre, cam)
    assert ok.sum() > len(sites) // 2
    placed = ok & np.isclose(np.linalg.norm(centre - tips, axis=1), cam.standoff_m, rtol=0, atol=1e-12)
    # the rest: too close to stop at the standoff without inserting less than the least insertion (the ECM's
    # 50 mm): inserted to it, the tip on the same shaft nearer the centre
    clamped = ok & ~placed
    assert placed.sum() > 10 and clamped.sum() > 10
    np.testing.assert_allclose(np.linalg.norm(tips[clamped] - sites[clamped], axis=1),
                               cam.arm.insertion_lo + cam.arm.along_shaft_m, atol=1e-12)
    assert cam.arm.insertion_lo == 0.050 and (np.linalg.norm(centre - tips[clamped], axis=1) < cam.standoff_m).all()
    for i in np.flatnonzero(placed)[::7]:
        tip, v = _scope_tip_by_bisection(sites[i], centre, math.radians(30.0), cam.standoff_m, view == "down")
        assert np.allclose(tips[i], tip, atol=1e-9) and np.allclose(axes[i], v, atol=1e-9)
        shaft = (tips[i] - sites[i]) / np.linalg.norm(tips[i] - sites[i])
        assert math.degrees(math.acos(np.clip(shaft @ axes[i], -1, 1))) == pytest.approx(30.0, abs=1e-9)
        assert (shaft[2] > (centre - sites[i])[2] / np.linalg.norm(centre - sites[i])) == (view == "down")
    targets = G.target_points_mm(cfg.target) / 1000
    cover = K.camera_coverage(sites, rot, targets, centre, cam)
    for i in np.flatnonzero(ok)[::11]:
        d = targets - tips[i]
        r = np.linalg.norm(d, axis=1)
        seen = (r >= cam.near_m) & (r <= cam.far_m) & (d @ axes[i] >= r * math.cos(cam.half_fov_rad))
        assert cover[i] == seen.mean()
    straight = T.camera_of(C.PortPlaceConfig())
    assert np.array_equal(K.camera_views(sites, rot, centre, straight)[1][ok],
                          ((centre - sites[ok]).T / np.linalg.norm(centre - sites[ok], axis=1)).T)


def test_an_angled_scope_keeps_a_symmetric_layout_balanced_and_moves_the_best():
    """With a 30 deg scope the azimuths are taken about its view axis: the mirror-symmetric best layouts stay
    balanced (imbalance 0); the study still finds feasible layouts, and the angle changes what the camera sees."""
    small = {"patient": {"port_region": {"site_spacing_mm": 36.0}}, "target": {"spacing_mm": 20.0},
             "bedside": {"arms": "none"}}  # out on their boards the arms leave none of this grid's layouts
    straight = C.PortPlaceConfig.model_validate(small)
    angled = C.PortPlaceConfig.model_validate({**small, "robot": {"camera_scope_angle_deg": 30.0}})
    a, b = S.compute_task(straight, 10 ** 6, 0), S.compute_task(angled, 10 ** 6, 0)
    assert b["feasible"].any() and not np.array_equal(a["camera_coverage"], b["camera_coverage"])
    sym = (b["psm1_x_mm"] == -b["psm2_x_mm"]) & (b["psm1_y_mm"] == b["psm2_y_mm"]) & (b["ecm_x_mm"] == 0)
    assert sym.sum() > 10 and np.abs(b["azimuth_imbalance_deg"][sym]).max() < 1e-9


# --- any RCM arm from a DH table or a URDF file (robots/rcm_arm.py) ----------------------------------------------

PSM_DH = [  # the Classic PSM with the Large Needle Driver's roll and wrist, modified DH (dvrk-kinematics.md)
    {"alpha_deg": 90, "a_m": 0, "d_m": 0, "theta_offset_deg": 90, "lower_deg": math.degrees(-1.588),
     "upper_deg": math.degrees(1.588)},
    {"alpha_deg": -90, "a_m": 0, "d_m": 0, "theta_offset_deg": -90, "lower_deg": math.degrees(-0.925025),
     "upper_deg": math.degrees(0.925025)},
    {"joint": "prismatic", "alpha_deg": 90, "a_m": 0, "d_m": -0.4318, "lower_m": 0.0, "upper_m": 0.24},
    {"alpha_deg": 0, "a_m": 0, "d_m": 0.4162, "lower_deg": -260, "upper_deg": 260},
    {"alpha_deg": -90, "a_m": 0, "d_m": 0, "theta_offset_deg": -90, "lower_deg": math.degrees(-1.39626),
     "upper_deg": math.degrees(1.39626)},
    {"alpha_deg": -90, "a_m": 0.0091, "d_m": 0, "theta_offset_deg": -90, "lower_deg": math.degrees(-1.39626),
     "upper_deg": math.degrees(1.39626)},
]


def ecm_urdf(rpy=(0.3, -0.7, 1.1), rcm=(0.12, -0.05, 0.4), pitch_gap_m=0.0, pitch_rpy="0 0 0"):
    """The Classic ECM written as a URDF by its geometry, not from DH rows: the mechanism turned by ``rpy`` and its
    RCM at ``rcm`` in the base link; yaw about the joint frame's -y, pitch about +x (so the closed form's pitch is
    minus the joint's, its limits negated), insertion along -z, a roll about the shaft, the scope's tip 0.7 mm
    past the RCM at zero insertion. ``pitch_gap_m`` moves the pitch axis off the yaw axis, ``pitch_rpy`` turns
    the pitch joint's frame."""
    (lo, hi), (plo, phi), (ilo, ihi) = (get_model("dvrk_ecm_classic").yaw_limits_rad, get_model("dvrk_ecm_classic").pitch_limits_rad,
                                        get_model("dvrk_ecm_classic").insertion_limits_m)
    joints = [("yaw", "revolute", f"{rcm[0]} {rcm[1]} {rcm[2]}", " ".join(map(str, rpy)), "0 -1 0", lo, hi),
              ("pitch", "revolute", f"0 0 {pitch_gap_m}", pitch_rpy, "1 0 0", -phi, -plo),
              ("insertion", "prismatic", "0 0 0", "0 0 0", "0 0 -1", ilo, ihi),
              ("roll", "revolute", "0 0 -0.3", "0 0 0", "0 0 1", -1.5, 1.5)]
    out, parent = ['<?xml version="1.0"?>', '<robot name="ecm_geometry">', '  <link name="base"/>'], "base"
    for i, (name, kind, xyz, rpy_, axis, a, b) in enumerate(joints):
        out += [f'  <joint name="{name}" type="{kind}"><parent link="{parent}"/><child link="l{i}"/><origin '
                f'xyz="{xyz}" rpy="{rpy_}"/><axis xyz="{axis}"/><limit lower="{a}" upper="{b}" velocity="1" '
                f'effort="1"/></joint>', f'  <link name="l{i}"/>']
        parent = f"l{i}"
    out += [f'  <joint name="tip" type="fixed"><parent link="{parent}"/><child link="scope_tip"/>'
            f'<origin xyz="0 0 {0.3 - 0.0007}" rpy="0 0 0"/></joint>', '  <link name="scope_tip"/>', '</robot>']
    return "\n".join(out)


def test_an_rcm_arm_from_a_dh_table_or_a_urdf_gives_the_shipped_arms_rows(tmp_path):
    """The Classic PSM as a modified-DH table (instrument_file) and the Classic ECM as a URDF turned and moved off
    the base with its pitch joint reversed (camera_file): the mechanism is recognised (ranges, shaft offset,
    the wrist's bend), and every row of the small study equals the shipped arms' (floats to 1e-9)."""
    from surgopt.config import validate

    (tmp_path / "ecm.urdf").write_text(ecm_urdf())
    shipped = validate(COARSE, C.Config, "x")
    # a file has no controller: the ECM's least insertion (50 mm, the shipped arm's) is the config's
    files = validate({**COARSE, "robot": {"instrument_file": {"dh": PSM_DH},
                                          "camera_file": {"urdf": str(tmp_path / "ecm.urdf")},
                                          "camera_min_insertion_mm": 50.0}}, C.Config, "x")
    psm, ecm = C.instrument_of(files), C.camera_arm_of(files)
    for got, ref in ((psm, get_model("dvrk_psm_classic")), (ecm, get_model("dvrk_ecm_classic"))):
        for f in ("yaw_limits_rad", "pitch_limits_rad", "insertion_limits_m"):
            assert getattr(got, f) == pytest.approx(getattr(ref, f), abs=1e-12), f
        assert got.along_shaft_m == pytest.approx(ref.along_shaft_m, abs=1e-12)
    assert psm.wrist_bend_rad == pytest.approx(dvrk.LND_WRIST_BEND_RAD, abs=1e-12) and ecm.wrist_bend_rad == 0.0
    a, b = S.compute_task(shipped, 10 ** 6, 0), S.compute_task(files, 10 ** 6, 0)
    assert b["feasible"].any()
    for c, v in a.items():
        if np.asarray(v).dtype.kind == "f":
            np.testing.assert_allclose(b[c], v, rtol=0, atol=1e-9, err_msg=c)
        else:
            assert np.array_equal(b[c], v), c


RCM_FILE_ERRORS = {
    "axes apart": ("gap", "do not meet: 5.000 mm apart"),
    "axes parallel": ("tilt", "the yaw and pitch axes are parallel"),
    "not an RCM arm": ("ur5e", "an RCM arm needs revolute (yaw), revolute (pitch), any rolls about the shaft, "
                               "then prismatic (insertion)"),
    "no source": ("none", "give urdf or dh"),
}


@pytest.mark.parametrize("case", sorted(RCM_FILE_ERRORS))
def test_a_file_arm_that_is_not_an_rcm_mechanism_is_refused_naming_the_field(tmp_path, case):
    from surgopt.robots.models import get_model

    kind, message = RCM_FILE_ERRORS[case]
    if kind == "gap":
        (tmp_path / "ecm.urdf").write_text(ecm_urdf(pitch_gap_m=0.005))
        arm = '[robot.camera_file]\nurdf = "ecm.urdf"\n'
    elif kind == "tilt":
        (tmp_path / "ecm.urdf").write_text(ecm_urdf(pitch_rpy=f"0 0 {math.pi / 2}"))
        arm = '[robot.camera_file]\nurdf = "ecm.urdf"\n'
    elif kind == "ur5e":
        arm = '[robot.instrument_file]\ndh_convention = "standard"\n' + "".join(
            f"[[robot.instrument_file.dh]]\na_m = {r.a_m}\nalpha_deg = {math.degrees(r.alpha_rad)}\nd_m = {r.d_m}\n"
            for r in get_model("ur5e").dh)
    else:
        arm = "[robot.instrument_file]\n"
    (tmp_path / "p.toml").write_text(arm)
    r = cli("port-place", "p.toml", "--store", tmp_path / "s", check=False, cwd=tmp_path)
    assert r.returncode == 2 and message in r.stderr, r.stderr
    assert "robot." in r.stderr and len(r.stderr.strip().splitlines()) == 1
    assert not (tmp_path / "s").exists()


RAVEN_DH = [  # the Raven IV right arm (Li et al. 2011, Table I, standard DH), the paper's optimum alpha 85, beta 65 deg;
    # its joint variables as the table's theta = q + offset: q1 = -theta1, q5 = -theta5
    {"alpha_deg": 95, "a_m": 0, "d_m": 0, "theta_offset_deg": 180},
    {"alpha_deg": -65, "a_m": 0, "d_m": 0, "lower_deg": 20, "upper_deg": 140},
    {"alpha_deg": 0, "a_m": 0, "d_m": 0, "theta_offset_deg": 270, "lower_deg": -86, "upper_deg": 86},
    {"joint": "prismatic", "alpha_deg": -90, "a_m": 0, "d_m": 0, "lower_m": 0.0, "upper_m": 0.25},
    {"alpha_deg": 90, "a_m": 0.013, "d_m": 0, "theta_offset_deg": 90, "lower_deg": -86, "upper_deg": 86},
    {"alpha_deg": -90, "a_m": 0, "d_m": 0, "theta_offset_deg": 90, "lower_deg": -86, "upper_deg": 86},
]


def _raven():
    """(config, its RcmLimits, the kernel's ArmLimits, the chain's wrist point at joint values (q1, q2, roll, d4)
    in the closed form's base frame B)."""
    from surgopt.robots import chain
    from surgopt.robots.chain import frames_at

    cfg = C.PortPlaceConfig.model_validate({**COARSE, "robot": {"instrument_file": {"dh": RAVEN_DH,
                                                                                    "dh_convention": "standard"}}})
    arm = C.instrument_of(cfg)
    spec = chain.from_dh([r.row(i) for i, r in enumerate(cfg.robot.instrument_file.dh)], "standard")
    base, rcm = np.array(arm.base_rotation), np.array(arm.rcm_m)

    def wrist(q):  # joint 5's frame origin: the wrist's first axis on the shaft
        return base.T @ (frames_at(spec, q)[4][:3, 3] - rcm)

    return cfg, arm, T.arm_limits(arm), wrist


def test_a_spherical_rcm_arm_the_raven_is_solved_in_closed_form():
    """The Raven IV right arm from its own standard-DH table (a spherical RCM: axes at 85 and 65 deg, a tool roll
    before the insertion, its pitch range 20-140 deg excluding 0, so docked at the middle, 80 deg): the link
    angles come back from the file; the kernel's inverse (Paden-Kahan subproblem 2) of the chain's wrist point
    at random joint values gives joint values within the ranges whose chain forward kinematics is that point
    (1e-10 m), and its isotropy is sigma_min / sigma_max of the chain's finite-difference Jacobian (1e-6)."""
    _, arm, lim, wrist = _raven()
    w1, w2 = np.array(arm.yaw_axis), np.array(arm.pitch_axis)
    assert math.degrees(math.acos(abs(w1 @ w2))) == pytest.approx(85.0, abs=1e-9)
    assert math.degrees(math.acos(abs(w2[2]))) == pytest.approx(65.0, abs=1e-9)
    assert arm.neutral_rad == pytest.approx((0.0, math.radians(80.0))) and arm.along_shaft_m == pytest.approx(0.0)
    assert lim.spherical and arm.wrist_bend_rad == pytest.approx(math.radians(86.0))
    home = np.array([*arm.neutral_rad, 0.0, 0.0])
    for _ in range(60):
        q = np.array([RNG.uniform(-3.0, 3.0), math.radians(RNG.uniform(21, 139)), RNG.uniform(-1.4, 1.4),
                      RNG.uniform(0.02, 0.24)])
        p = wrist(q)
        rho = np.linalg.norm(p)
        q1, q2, found = K.spherical_inverse(p / rho, lim)
        assert found and lim.yaw_lo <= q1 <= lim.yaw_hi and lim.pitch_lo <= q2 <= lim.pitch_hi
        back = wrist(home + [q1, q2, 0.0, rho - arm.along_shaft_m])
        assert np.linalg.norm(back - p) < 1e-10
        J = finite_difference_jacobian(lambda v: wrist([v[0], v[1], q[2], v[2]]), np.array([q[0], q[1], q[3]]),
                                       h=1e-6)
        J[:, :2] /= 0.1
        s = np.linalg.svd(J, compute_uv=False)
        u = p / rho
        assert K.spherical_isotropy(q[0] - home[0], u, rho, lim, 0.1) == pytest.approx(s[-1] / s[0], rel=1e-6)
    # along the yaw axis the shaft cannot point (85 deg to the pitch axis, the shaft 65 deg from it): not found
    assert not K.spherical_inverse(w1, lim)[2]


def test_the_raven_as_a_port_place_instrument_reaches_what_joint_sampling_reaches():
    """Reach of the spherical Raven arm at one port against the nearest of ~30,000 joint-space samples through
    the chain (no closed form), on points clear of the boundary; then the small study runs with it: feasible
    layouts, every row's instrument columns from the Raven."""
    cfg, arm, lim, wrist = _raven()
    site, centre = np.zeros(3), np.array([0.0, 0.0, -0.15])
    rot = K.docking_frames(site[None], centre, np.array([1.0, 0.0, 0.0]))
    # its own stream: the module's RNG depends on which tests ran before in this worker (a premise failed once)
    pts = centre + np.random.default_rng(1).uniform(-0.2, 0.2, size=(200, 3))  # some past the insertion, off cones
    reach, _ = K.instrument_tables(site[None], rot, pts, lim, 0.1, ANY_APPROACH)
    base = np.array([K.to_base(rot[0], site, p) for p in pts])
    home = arm.neutral_rad
    g1, g2, g3 = (np.linspace(lo, hi, k) for lo, hi, k in ((lim.yaw_lo, lim.yaw_hi, 61), (lim.pitch_lo, lim.pitch_hi, 31),
                                                          (lim.insertion_lo, lim.insertion_hi, 16)))
    samples = np.array([wrist([a + home[0], b + home[1], 0.0, c]) for a in g1 for b in g2 for c in g3])
    d = np.array([np.min(np.linalg.norm(samples - p, axis=1)) for p in base])
    gap = 0.25 * max(g1[1] - g1[0], g2[1] - g2[0]) + (g3[1] - g3[0])
    far, near = d > gap, d < 0.2 * gap
    assert far.sum() > 10 and near.sum() > 10  # the premise: both kinds of point are in the sample
    assert not reach[0][far].any() and reach[0][near].mean() > 0.9
    cols = S.compute_task(cfg, S.n_total(cfg), 0)
    assert cols["feasible"].any() and cols["psm1_reach"].max() == 1.0


def test_an_angled_scope_on_a_spherical_arm_is_held_to_that_arms_pointing():
    """The Raven's spherical mechanism as the endoscope arm with a 30 deg scope, its pitch narrowed to 60-100 deg:
    every site camera_views accepts has a shaft the arm can point, checked through the chain (the joints
    spherical_inverse gives put the chain's shaft on it, 1e-9); the sites the full 20-140 deg range accepts and
    the narrow one refuses have shafts the narrow arm cannot point (the premise: there are some)."""
    cfg, arm, lim, wrist = _raven()

    def views(pitch_deg):
        rows = [dict(r) for r in RAVEN_DH]
        rows[1].update(lower_deg=pitch_deg[0], upper_deg=pitch_deg[1])
        scope = C.PortPlaceConfig.model_validate({**COARSE, "robot": {
            "camera_file": {"dh": rows, "dh_convention": "standard"}, "camera_scope_angle_deg": 30.0}})
        cam = T.camera_of(scope)
        sites, centre = G.sites_mm(scope) / 1000, np.asarray(scope.target.centre_mm) / 1000
        rot = K.docking_frames(sites, centre, T.LATERAL)
        return cam, sites, rot, *K.camera_views(sites, rot, centre, cam)

    cam, sites, rot, tips, _, ok = views((60.0, 100.0))
    _, _, _, tips_wide, _, ok_wide = views((20.0, 140.0))
    assert cam.arm.spherical and ok.any()
    home = np.array([*arm.neutral_rad, 0.0])
    for i in range(len(sites)):
        t = tips[i] if ok[i] else tips_wide[i]
        if np.linalg.norm(t - sites[i]) < 1e-6 or not ok_wide[i]:
            continue  # a tip at the port (insertion clamped to 0) shows no shaft direction
        shaft = rot[i].T @ (t - sites[i]) / np.linalg.norm(t - sites[i])
        q1, q2, found = K.spherical_inverse(shaft, cam.arm)
        assert found == bool(ok[i])
        if found:
            p = wrist([home[0] + q1, home[1] + q2, 0.0, 0.1])
            np.testing.assert_allclose(p / np.linalg.norm(p), shaft, atol=1e-9)
    assert (ok_wide & ~ok).any()  # the premise: the narrow pitch refuses sites the full range accepts


def test_a_feasible_rows_run_is_budgeted_at_its_likely_peak_and_shows_the_bound(tmp_path):
    """``rows_stored = "feasible"`` (three PSMs, the README's line): the estimate's peak allows for
    FEASIBLE_SHARE_MEMORY of the designs feasible, and the bound were every design feasible is shown beside it
    (it was the only number: 7.5 GB against 0.69 GB measured, which an 8 GB machine's budget refused); a budget
    between the two lets the run through, one below the likely peak refuses it. Premise: the two differ."""
    cfg = C.PortPlaceConfig.model_validate({"robot": {"instrument_count": 3}, "rows_stored": "feasible"})
    est = S.estimate(cfg)
    assert est.peak_bytes_bound is not None and est.peak_bytes < est.peak_bytes_bound / 3
    between = (est.peak_bytes + est.peak_bytes_bound) / 2 / 2 ** 30
    r = cli("port-place", "robot.instrument_count=3", "rows_stored=feasible", "--dry-run", "--max-memory-gb",
            f"{between:.2f}", "--store", tmp_path / "s", env={**os.environ, "COLUMNS": "300"})
    assert "within budget" in r.stdout and "were every row stored" in r.stdout
    r = cli("port-place", "robot.instrument_count=3", "rows_stored=feasible", "--dry-run", "--max-memory-gb",
            f"{est.peak_bytes / 2 ** 30 / 2:.2f}", "--store", tmp_path / "s", env={**os.environ, "COLUMNS": "300"})
    assert "REFUSED" in r.stdout


def test_too_few_sites_names_the_filter_that_left_too_few():
    """#56 item 10: a marked region wholly outside the body was blamed on constraints.port_to_target_mm. The error
    counts the grid's points kept by each filter up to the one that left too few, so it names that one."""
    from pydantic import ValidationError

    outside = {"patient": {"port_region": {"polygon_mm": [[500, 500], [700, 500], [700, 700], [500, 700]]}}}
    with pytest.raises(ValidationError, match=r"inside patient.port_region.polygon_mm \(no grid point over the body "
                                              r"lies inside it: the region is outside the body's top view\): 0"):
        C.PortPlaceConfig.model_validate(outside)
    with pytest.raises(ValidationError) as near:
        C.PortPlaceConfig.model_validate({"constraints": {"port_to_target_mm": [0, 20]}})
    text = str(near.value)
    assert "within constraints.port_to_target_mm [0, 20] of the target's centre: 0" in text
    assert "polygon_mm" not in text  # no region marked: not named


def test_a_mesh_patients_distance_for_many_points_is_a_bounded_lower_bound(tmp_path):
    """#57 item 0: a closed 10,494-face patient with the cart ran out of memory building its link tables (trimesh's
    closest point asked 9.4 GB for 2 M points at once). Many points go through a k-d tree over the mesh
    subdivided to MESH_GAP_EDGE_MM: a lower bound within its gap of trimesh's exact distance (the reference), in
    bounded memory; fewer points still get the exact distance, in chunks."""
    import tracemalloc

    from surgopt.config import validate
    from surgopt.studies.port_place import geometry as G

    _dome_mesh(tmp_path / "dome.stl", subdivisions=5)
    cfg = validate({"patient": {"shape": "mesh", "mesh_file": "dome.stl"}, "cart": {"model": "none"}}, C.Config, "m",
                   {"config_dir": str(tmp_path)})
    rng = np.random.default_rng(57)
    p = rng.uniform([-220, -260, 0], [220, 260, 200], (3000, 3))
    p = p[~G.inside_body(p, cfg.patient)]
    exact = G.body_distance_mm(p, cfg.patient, 60.0)
    bound = G.body_distance_mm(p, cfg.patient, 60.0, many=True)
    gap = G.MESH_GAP_EDGE_MM / np.sqrt(3)
    assert np.all(bound <= exact + 1e-9) and np.all(bound >= exact - gap - 1e-9)
    assert np.any(exact < 60.0) and np.any(exact == 60.0)  # the premise: points near the wall and past the cap
    many = rng.uniform([-200, -240, 100], [200, 240, 180], (200_000, 3))
    tracemalloc.start()
    G.body_distance_mm(many, cfg.patient, 60.0, many=True)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert peak < 120 * 2 ** 20, peak / 2 ** 20  # 200,000 points (the exact query at once: ~1 GB)
