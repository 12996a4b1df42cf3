"""Answers a surgeon can mark on the patient (issue 42 item 3): landmarks on the patient (the dome's defaults or the
config's), every listed layout's ports as distances from the reference landmark along named directions (the closing
report, the ports CSV), the figures' sides, and a search's repeated layouts listed once."""
from __future__ import annotations

import csv
import io

import numpy as np
import pydantic
import pytest

from surgopt.studies.port_place import config as C
from surgopt.studies.port_place import geometry as G
from surgopt.studies.port_place import report as R
from surgopt.studies.port_place import study as S

COARSE = {"patient": {"port_region": {"site_spacing_mm": 72.0}}, "target": {"spacing_mm": 20.0}, "cart": {"model": "none"}}


@pytest.mark.parametrize("x, y, words", [(72.0, -18.0, "72 left, 18 caudal"), (-72.0, 18.0, "72 right, 18 cranial"),
                                         (0.2, 40.0, "midline, 40 cranial"), (-54.0, -0.3, "54 right, level")])
def test_a_port_is_said_from_the_landmark_along_the_patients_directions(x, y, words):
    """+x is the patient's left and +y the head (the frame, geometry.FRAME_TEXT); from a landmark at (0, 0)."""
    assert G.from_landmark(x, y, (0.0, 0.0)) == words
    assert G.from_landmark(x + 10.0, y - 25.0, (10.0, -25.0)) == words  # measured from the landmark, not the origin


def test_the_domes_landmarks_are_on_its_midline_and_a_config_names_its_own():
    dome = C.PortPlaceConfig().patient
    assert G.landmarks_mm(dome) == {"xiphoid": (0.0, 178.5), "umbilicus": (0.0, 0.0), "pubis": (0.0, -178.5)}
    assert G.reference_landmark(dome) == ("umbilicus", (0.0, 0.0))
    own = C.PortPlaceConfig.model_validate({"patient": {"landmarks_mm": {"pubis": [0.0, -150.0], "ASIS left":
                                                                         [120.0, -120.0]},
                                                        "reference_landmark": "pubis"}}).patient
    assert G.landmarks_mm(own) == {"pubis": (0.0, -150.0), "ASIS left": (120.0, -120.0)}
    assert G.reference_landmark(own) == ("pubis", (0.0, -150.0))
    with pytest.raises(pydantic.ValidationError, match="reference_landmark: 'navel' is not a landmark of this "
                                                       "patient \\(xiphoid, umbilicus, pubis"):
        C.PortPlaceConfig.model_validate({"patient": {"reference_landmark": "navel"}})
    with pytest.raises(pydantic.ValidationError, match="landmarks_mm"):
        C.PortPlaceConfig.model_validate({"patient": {"landmarks_mm": {"pubis": [0.0, float("nan")]}}})


def test_the_ports_csv_measures_the_layout_and_the_landmarks_from_the_reference(tmp_path):
    """``export --format ports``: each port's row as stored, each landmark with the dome's height over it (the
    half-ellipsoid's closed form), and every offset = position - the reference landmark's, in words too."""
    cfg = C.PortPlaceConfig.model_validate({**COARSE, "patient": {**COARSE["patient"],
                                                                  "reference_landmark": "pubis"}})
    cols = S.compute_task(cfg, S.n_total(cfg), 0)
    i = int(np.argmax(cols["feasible"]))
    row = {k: (v[i].item() if hasattr(v[i], "item") else v[i]) for k, v in cols.items()}
    lines = list(csv.DictReader(io.StringIO(S.ports_export(cfg, row))))
    assert [r["name"] for r in lines] == ["PSM1", "PSM2", "ECM", "xiphoid", "umbilicus", "pubis"]
    a, b, c = cfg.patient.semi_axes_mm
    for r in lines:
        x, y = float(r["x_mm"]), float(r["y_mm"])
        assert float(r["left_of_pubis_mm"]) == pytest.approx(x - 0.0, abs=0.051)
        assert float(r["cranial_of_pubis_mm"]) == pytest.approx(y + 178.5, abs=0.051)
        assert r["from_pubis"] == G.from_landmark(x, y, (0.0, -178.5))
        if r["what"] == "port":
            arm = r["name"].lower()
            assert (x, y, float(r["z_mm"])) == pytest.approx((row[f"{arm}_x_mm"], row[f"{arm}_y_mm"],
                                                              row[f"{arm}_z_mm"]), abs=0.051)
        else:
            assert float(r["z_mm"]) == pytest.approx(c * np.sqrt(1 - (x / a) ** 2 - (y / b) ** 2), abs=0.051)


def test_the_closing_report_gives_each_listed_layouts_ports_from_the_umbilicus(tmp_path):
    from surgopt.runner import run_study
    from surgopt.store import Store

    from conftest import single_run

    cfg = C.PortPlaceConfig.model_validate(COARSE)
    run_study(S.STUDY, cfg, config_name="c", store=Store(tmp_path), jobs=1, quiet=True)
    run = single_run(tmp_path)
    summary = R.summary(run.parts(S.schema(cfg)))
    tables = {title.split(" (")[0]: (names, rows) for title, names, rows in summary.tables}
    names, rows = tables["best layout: ports"]
    assert names[-1] == "from the umbilicus (mm, top view)"
    for r in rows:
        assert r[-1] == G.from_landmark(float(r[2]), float(r[3]), (0.0, 0.0))
    names, rows = tables["best feasible designs: ports from the umbilicus"]
    best = R.least_cost_layouts(run.parts(S.schema(cfg)), 5).to_pylist()
    assert names == ["design_id", "psm1", "psm2", "ecm"] and len(rows) == len(best) == 5
    for r, b in zip(rows, best):
        assert r == [str(b["design_id"]), *(G.from_landmark(b[f"{a}_x_mm"], b[f"{a}_y_mm"], (0.0, 0.0))
                                            for a in ("psm1", "psm2", "ecm"))]


def test_a_searchs_repeated_layouts_are_listed_once_and_counted():
    """A search evaluates a layout again when its optimiser asks again: rows that repeat a layout under new design
    ids (here the grid's rows, the best ones asked again and again, in two parts as a run stores them). The
    least-cost list is the first row of each layout (pandas' drop_duplicates over the sites, brute force), and the
    repeats among the rows ranked up to the last listed are counted."""
    import pyarrow as pa

    from surgopt.parts import Parts

    cfg = C.PortPlaceConfig.model_validate(COARSE)
    grid = pa.Table.from_pydict(S.compute_task(cfg, S.n_total(cfg), 0), schema=S.schema(cfg))
    ok = np.flatnonzero(grid["feasible"].to_numpy())
    best = ok[np.argsort(grid["cost"].to_numpy()[ok], kind="stable")][:8]
    rng = np.random.default_rng(3)
    again = grid.take(pa.array(rng.choice(best, 30)))
    again = again.set_column(0, "design_id", pa.array(np.arange(30) + 10 ** 6))  # new trials of old layouts
    halves = [pa.concat_tables([grid.slice(0, grid.num_rows // 2), again.slice(0, 15)]),
              pa.concat_tables([grid.slice(grid.num_rows // 2), again.slice(15)])]
    parts = Parts(lambda columns=None: [t if columns is None else t.select(columns) for t in halves],
                  grid.num_rows + 30, grid.schema)
    listed = R.least_cost_layouts(parts, 5)
    df = pa.concat_tables(halves).to_pandas()
    ranked = df[df["feasible"]].sort_values(["cost", "design_id"])
    firsts = ranked.drop_duplicates(["psm1_site", "psm2_site", "ecm_site"])
    assert listed["design_id"].to_pylist() == firsts["design_id"].head(5).tolist()
    last = ranked.index.get_loc(firsts.index[4])
    repeats = int(ranked.iloc[:last + 1].duplicated(["psm1_site", "psm2_site", "ecm_site"]).sum())
    assert repeats > 0 and listed.schema.metadata[b"repeats_collapsed"] == str(repeats).encode()
    plain = R.least_cost_layouts(Parts.of_table(grid), 5)  # the grid alone: no repeats, the five best rows
    assert plain["design_id"].to_pylist() == grid.take(pa.array(best[:5]))["design_id"].to_pylist()
    assert plain.schema.metadata[b"repeats_collapsed"] == b"0"


def test_the_scene_marks_the_landmarks_the_region_and_the_sides_on_the_wall():
    """#56 item 4: the page's scene gets the landmarks on the wall (the dome's said to be assumed; a config's not),
    the marked region's outline closed and lifted 2 mm above the wall, and the four sides past the body."""
    from surgopt.studies.port_place.geometry import wall_height_mm
    from surgopt.studies.port_place.scene import scene_marks

    poly = [[-150.0, -150.0], [150.0, -150.0], [150.0, 100.0], [-150.0, 100.0]]
    cfg = C.PortPlaceConfig.model_validate({**COARSE, "patient": {"port_region": {"site_spacing_mm": 72.0,
                                                                                 "polygon_mm": poly}}})
    m = scene_marks(cfg)
    assert m["landmarks_assumed"] and "umbilicus" in [n for n, *_ in m["landmarks"]]
    for _, x, y, z in m["landmarks"]:
        assert z == pytest.approx(float(wall_height_mm(np.array([x]), np.array([y]), cfg.patient)[0]))
    r = np.asarray(m["region"])
    np.testing.assert_array_equal(r[0], r[-1])  # closed
    np.testing.assert_allclose(r[:, 2], wall_height_mm(r[:, 0], r[:, 1], cfg.patient) + 2.0, atol=0.06)
    assert {tuple(v[:2]) for v in r[::12][:4]} == {tuple(p) for p in poly}  # through every vertex
    assert [s[0] for s in m["sides"]] == ["patient's left", "patient's right", "head", "feet"]
    own = C.PortPlaceConfig.model_validate({**COARSE, "patient": {"landmarks_mm": {"umbilicus": [0.0, 0.0]}}})
    assert not scene_marks(own)["landmarks_assumed"]


def _ellipse_arc_mm(a: float, c: float, x0: float, x1: float) -> float:
    """The length of the ellipse z = c sqrt(1 - (x / a)^2) between x0 and x1, by quadrature of its parametric speed
    (x = a sin t, z = c cos t: sqrt(a^2 cos^2 t + c^2 sin^2 t)), scipy's quad: no sampling shared with the code."""
    from scipy.integrate import quad

    t0, t1 = np.arcsin(np.clip([x0 / a, x1 / a], -1.0, 1.0))
    return abs(quad(lambda t: np.hypot(a * np.cos(t), c * np.sin(t)), t0, t1, epsabs=1e-10)[0])


@pytest.mark.parametrize("mark, x, y", [((0.0, 0.0), 72.0, -90.0), ((0.0, 0.0), -126.0, 36.0),
                                        ((0.0, -178.5), 54.0, -108.0), ((20.0, 30.0), -40.0, 150.0)])
def test_a_ports_distance_along_the_skin_is_the_domes_arc_across_then_along(mark, x, y):
    """#57 item 2: ``geometry.along_skin_mm`` on the default dome (a half-ellipsoid) against the two ellipse arcs a
    tape follows, across at the landmark's level (semi-axes a k, c k, k = sqrt(1 - (y0 / b)^2)) then along at the
    port's x, by quadrature (0.05 mm: the 1 mm polyline's chords); each at least the top view's offset, signed as
    it; in words in cm."""
    cfg = C.PortPlaceConfig()
    a, b, c = cfg.patient.semi_axes_mm
    across, along = G.along_skin_mm(cfg.patient, mark, x, y)
    k1, k2 = np.sqrt(1 - (mark[1] / b) ** 2), np.sqrt(1 - (x / a) ** 2)
    want_across = _ellipse_arc_mm(a * k1, c * k1, mark[0], x)
    want_along = _ellipse_arc_mm(b * k2, c * k2, mark[1], y)
    assert abs(across) == pytest.approx(want_across, abs=0.05) and abs(along) == pytest.approx(want_along, abs=0.05)
    assert np.sign(across) == np.sign(x - mark[0]) and np.sign(along) == np.sign(y - mark[1])
    assert abs(across) >= abs(x - mark[0]) - 1e-9 and abs(along) >= abs(y - mark[1]) - 1e-9
    assert abs(across) + abs(along) > abs(x - mark[0]) + abs(y - mark[1]) + 1.0  # the premise: the skin is curved
    words = G.skin_words(cfg.patient, mark, x, y)
    assert words.split(", ")[0].endswith("left" if x > mark[0] else "right") and " cm " in words


def test_the_ports_csv_and_the_report_give_the_distances_along_the_skin(tmp_path):
    """The ports CSV carries the along-the-skin offsets (``along_skin_mm``) and words beside the top view's; the
    closing report's ports table the words."""
    cfg = C.PortPlaceConfig.model_validate(COARSE)
    cols = S.compute_task(cfg, S.n_total(cfg), 0)
    i = int(np.argmax(cols["feasible"]))
    row = {k: (v[i].item() if hasattr(v[i], "item") else v[i]) for k, v in cols.items()}
    for r in csv.DictReader(io.StringIO(S.ports_export(cfg, row))):
        x, y = float(r["x_mm"]), float(r["y_mm"])
        across, along = G.along_skin_mm(cfg.patient, (0.0, 0.0), x, y)
        assert float(r["left_of_umbilicus_along_skin_mm"]) == pytest.approx(across, abs=0.051)
        assert float(r["cranial_of_umbilicus_along_skin_mm"]) == pytest.approx(along, abs=0.051)
        assert r["from_umbilicus_along_skin"] == G.skin_words(cfg.patient, (0.0, 0.0), x, y)


def test_a_ports_distance_along_a_mesh_patients_skin_against_a_geodesic_computed_apart(tmp_path):
    """#57's check "landmark distances along the skin against a geodesic computed apart": on a mesh patient (the
    default dome as 41,984 triangles), the shortest path over a dense graph of points sampled on its upper surface
    (scipy's Dijkstra over 25,000 points joined within 9 mm: a geodesic's stand-in, no code shared with
    ``along_skin_mm``). A tape across at the landmark's level is the geodesic where that level is a plane of
    symmetry (the umbilicus's, y = 0): equal within 3 %; elsewhere the tape's two legs are never shorter than it."""
    import trimesh
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import dijkstra
    from scipy.spatial import cKDTree

    from surgopt.config import validate

    sphere = trimesh.creation.icosphere(subdivisions=6)
    sphere.apply_scale([170.0, 210.0, 140.0])
    half = trimesh.intersections.slice_mesh_plane(sphere, plane_normal=[0, 0, 1], plane_origin=[0, 0, 0], cap=True)
    half.export(tmp_path / "dome.stl")
    cfg = validate({"patient": {"shape": "mesh", "mesh_file": "dome.stl"}, "cart": {"model": "none"}}, C.Config, "m",
                   {"config_dir": str(tmp_path)})
    rng = np.random.default_rng(5)
    u = rng.uniform(-1, 1, (25_000, 2)) * [170.0, 210.0]
    u = u[((u / [170.0, 210.0]) ** 2).sum(axis=1) < 0.9]
    z = 140.0 * np.sqrt(1 - ((u / [170.0, 210.0]) ** 2).sum(axis=1))  # on the ellipsoid itself
    cloud = np.column_stack([u, z])

    def geodesic(p, q):
        pts = np.vstack([cloud, p, q])
        pairs = cKDTree(pts).query_pairs(9.0, output_type="ndarray")
        w = np.linalg.norm(pts[pairs[:, 0]] - pts[pairs[:, 1]], axis=1)
        graph = coo_matrix((w, (pairs[:, 0], pairs[:, 1])), shape=(len(pts), len(pts)))
        return dijkstra(graph, directed=False, indices=len(pts) - 2)[len(pts) - 1]

    def on_skin(x, y):
        return np.array([x, y, 140.0 * np.sqrt(1 - (x / 170.0) ** 2 - (y / 210.0) ** 2)])

    mark = (0.0, 0.0)
    for x in (-120.0, 90.0):  # across at the umbilicus's level: the section y = 0 is a geodesic of the dome
        across, along = G.along_skin_mm(cfg.patient, mark, x, 0.0)
        assert along == 0.0 and abs(across) == pytest.approx(geodesic(on_skin(*mark), on_skin(x, 0.0)), rel=0.03)
    for x, y in ((72.0, -90.0), (-60.0, 120.0)):  # across, then along: no shorter than the geodesic
        across, along = G.along_skin_mm(cfg.patient, mark, x, y)
        assert abs(across) + abs(along) >= 0.97 * geodesic(on_skin(*mark), on_skin(x, y))


def test_the_lines_between_landmarks_are_measured_along_the_skin():
    """#57 item 2, "the lines between them": by default the midline's chain, head to feet (the dome's xiphoid -
    umbilicus - pubis); each line's length along the skin is the dome's midline ellipse arc between them (the
    y-z section's semi-axes b, c; quadrature, 0.05 mm), longer than the top view's; the closing report's table and
    the scene's polyline (1 mm over the wall) say so; a configured line names landmarks of the patient."""
    cfg = C.PortPlaceConfig()
    a, b, c = cfg.patient.semi_axes_mm
    marks = G.landmarks_mm(cfg.patient)
    lines = G.landmark_lines(cfg.patient)
    assert lines == [("xiphoid", "umbilicus"), ("umbilicus", "pubis")]
    for p, q in lines:
        _, along = G.skin_line_mm(cfg.patient, marks[p], marks[q])
        assert along == pytest.approx(_ellipse_arc_mm(b, c, marks[p][1], marks[q][1]), abs=0.05)
        assert along > abs(marks[p][1] - marks[q][1]) + 1.0  # the premise: the skin is curved
    title, header, rows = R.landmark_lines_table(cfg)
    assert [r[0] for r in rows] == ["xiphoid - umbilicus", "umbilicus - pubis"]
    from surgopt.studies.port_place.scene import scene_marks

    pts = np.array([p for p in scene_marks(cfg)["landmark_lines"] if p is not None])
    wall = G.wall_height_mm(pts[:, 0], pts[:, 1], cfg.patient)
    assert len(pts) > 20 and np.all(np.abs(pts[:, 2] - wall - 1.0) <= 0.12)  # drawn to 0.1 mm, 1 mm over the wall
    with pytest.raises(pydantic.ValidationError, match="landmark_lines: 'asis'"):
        C.PortPlaceConfig.model_validate({"patient": {"landmark_lines": [["umbilicus", "asis"]]}})
    own = C.PortPlaceConfig.model_validate({"patient": {"landmark_lines": [["umbilicus", "xiphoid"]]}})
    assert G.landmark_lines(own.patient) == [("umbilicus", "xiphoid")]
