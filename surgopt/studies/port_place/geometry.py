"""The geometry a ``port-place`` config implies (numpy; mm): the target's points (a shape on a grid, a points file,
the grid points inside a mesh), the body (the half-ellipsoid or superquadric dome, or a closed mesh read by
trimesh): what lies inside it, its wall's height over the table, the distance to it, its painted region, and
the candidate port sites. Functions of the config's sections (``config.Patient`` as ``patient``, ``config.Target``
as ``t``, the whole ``config.PortPlaceConfig`` as ``cfg``), which they read and never
import; the config's validators call them to check what a config implies before anything runs.

The dome's and the mesh's versions of each quantity (inside, wall height, distance,
extent) sit side by side, so that a new body shape is added in one place: one module of ~540 lines for that reason
(the landmarks' words and the distances along the skin read the same wall).
"""
from __future__ import annotations

import math
import os
from functools import lru_cache
from pathlib import Path

import numpy as np


#: The patient frame, said once (the reports, the figures, the page, the export): where +x, +y, +z point and
#: where the origin is (#42 item 3: the frame said which axis, not which side).
FRAME_TEXT = ("patient frame, mm: +x toward the patient's left, +y toward the head, +z anterior (up from the "
              "table); origin: the centre of the body's base on the table top")
X_LABEL, Y_LABEL, Z_LABEL = "x (mm), + the patient's left", "y (mm), + toward the head", "z anterior (mm)"

#: The dome's landmarks when a config names none (issue 42 item 3): on the midline, at these fractions of the
#: dome's cranio-caudal semi-axis b from its centre. Assumptions, stated: the xiphoid and the pubic symphysis near
#: the ends of an insufflated abdomen (+-0.85 b: +-179 mm on the default 210 mm), the umbilicus over its centre.
DOME_LANDMARKS = (("xiphoid", 0.85), ("umbilicus", 0.0), ("pubis", -0.85))
#: The landmark a layout's ports are measured from when the config names none and it has one of this name.
REFERENCE_LANDMARK = "umbilicus"


def landmarks_mm(patient) -> dict[str, tuple[float, float]]:
    """The patient's named landmarks, top view (x, y mm): the config's ``landmarks_mm``, or the dome's defaults
    (``DOME_LANDMARKS``), or for a mesh without any the frame's origin (the centre of the body's base)."""
    if patient.landmarks_mm:
        return {name: (float(x), float(y)) for name, (x, y) in patient.landmarks_mm.items()}
    if patient.shape == "dome":
        b = patient.semi_axes_mm[1]
        return {name: (0.0, round(f * b, 6)) for name, f in DOME_LANDMARKS}
    return {"origin": (0.0, 0.0)}


def landmark_lines(patient) -> list[tuple[str, str]]:
    """(#57 item 2) The lines between landmarks a team draws on the skin: the config's ``landmark_lines``, else
    the midline's chain (the landmarks within 1 mm of x = 0, head to feet: xiphoid - umbilicus - pubis)."""
    if patient.landmark_lines:
        return [(a, b) for a, b in patient.landmark_lines]
    marks = landmarks_mm(patient)
    midline = sorted((n for n, (x, _) in marks.items() if abs(x) <= 1.0), key=lambda n: -marks[n][1])
    return list(zip(midline, midline[1:]))


def skin_line_mm(patient, a: tuple[float, float], b: tuple[float, float]) -> tuple[np.ndarray, float]:
    """The line between two top-view points drawn on the skin: the straight top-view segment lifted onto the body's
    upper wall (``wall_height_mm``), sampled every SKIN_STEP_MM: (its points (k, 3) mm, its length along the skin
    mm; the top view's length where the wall is missing under it)."""
    n = max(2, int(math.ceil(math.hypot(b[0] - a[0], b[1] - a[1]) / SKIN_STEP_MM)) + 1)
    x, y = np.linspace(a[0], b[0], n), np.linspace(a[1], b[1], n)
    z = wall_height_mm(x, y, patient)
    pts = np.column_stack([x, y, np.nan_to_num(z, nan=0.0)])
    if not np.all(np.isfinite(z)):
        return pts, math.hypot(b[0] - a[0], b[1] - a[1])
    return pts, float(np.linalg.norm(np.diff(pts, axis=0), axis=1).sum())


def reference_landmark(patient) -> tuple[str, tuple[float, float]]:
    """(name, (x, y) mm) of the landmark ports are measured from: ``reference_landmark``, or the umbilicus, or the
    first landmark."""
    marks = landmarks_mm(patient)
    name = patient.reference_landmark or (REFERENCE_LANDMARK if REFERENCE_LANDMARK in marks else next(iter(marks)))
    return name, marks[name]


def from_landmark(x_mm: float, y_mm: float, mark: tuple[float, float]) -> str:
    """A port's top-view position from a landmark along named directions: "72 left, 18 caudal" (mm; the
    patient's left or right, toward the head (cranial) or the feet (caudal); "midline" or "level" within half a
    millimetre)."""
    dx, dy = x_mm - mark[0], y_mm - mark[1]
    across = "midline" if abs(dx) < 0.5 else f"{abs(dx):.0f} {'left' if dx > 0 else 'right'}"
    along = "level" if abs(dy) < 0.5 else f"{abs(dy):.0f} {'cranial' if dy > 0 else 'caudal'}"
    return f"{across}, {along}"


#: The step (mm) at which a path along the skin is sampled.
SKIN_STEP_MM = 1.0


def along_skin_mm(patient, mark: tuple[float, float], x_mm: float, y_mm: float) -> tuple[float, float]:
    """(#57 item 2) How far a port lies from a landmark along the skin, as a surgeon measures it with a tape: first
    across (at the landmark's level, to the port's x), then along the body (at the port's x, to its y); each leg's
    length over the body's upper wall (``wall_height_mm``), sampled every SKIN_STEP_MM: (across, along) mm, signed
    as the top view's (left +, cranial +). Where the wall is missing under a leg (a mesh's ray misses), that leg's
    top-view length (each leg a ``skin_line_mm``)."""
    across = skin_line_mm(patient, (mark[0], mark[1]), (x_mm, mark[1]))[1]
    along = skin_line_mm(patient, (x_mm, mark[1]), (x_mm, y_mm))[1]
    return math.copysign(across, x_mm - mark[0]), math.copysign(along, y_mm - mark[1])


def skin_words(patient, mark: tuple[float, float], x_mm: float, y_mm: float) -> str:
    """``along_skin_mm`` in words, cm: "8.1 cm left, 9.4 cm caudal" ("midline" or "level" within 0.5 mm)."""
    across, along = along_skin_mm(patient, mark, x_mm, y_mm)
    a = "midline" if abs(across) < 0.5 else f"{abs(across) / 10:.1f} cm {'left' if across > 0 else 'right'}"
    b = "level" if abs(along) < 0.5 else f"{abs(along) / 10:.1f} cm {'cranial' if along > 0 else 'caudal'}"
    return f"{a}, {b}"


def polygon_area_mm2(poly: np.ndarray) -> float:
    """|Shoelace area| of a polygon's vertices (N, 2), in order."""
    x, y = poly[:, 0], poly[:, 1]
    return abs(float(np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y))) / 2


def even_odd_area_mm2(poly: np.ndarray, samples: int = 128) -> float:
    """Area (mm^2) inside the polygon under the even-odd rule (what ``inside_polygon`` tests), from the centres of
    samples x samples cells of its bounding box: each lobe of a self-intersecting outline counts (the shoelace
    formula cancels a figure eight's two lobes to 0). Exact to a cell along the outline."""
    lo, hi = poly.min(axis=0), poly.max(axis=0)
    size = hi - lo
    if size[0] <= 0 or size[1] <= 0:
        return 0.0
    u = (np.arange(samples) + 0.5) / samples
    x, y = np.meshgrid(lo[0] + u * size[0], lo[1] + u * size[1])
    return float(inside_polygon(x.ravel(), y.ravel(), poly).mean() * size[0] * size[1])


def inside_polygon(x: np.ndarray, y: np.ndarray, poly: np.ndarray) -> np.ndarray:
    """Whether each point (x, y) is inside the polygon (even-odd rule: a ray towards +x crosses its edges an odd
    number of times)."""
    inside = np.zeros(x.shape, dtype=bool)
    x0, y0 = poly[:, 0], poly[:, 1]
    x1, y1 = np.roll(x0, -1), np.roll(y0, -1)
    for ax, ay, bx, by in zip(x0, y0, x1, y1):
        crosses = (ay > y) != (by > y)
        with np.errstate(divide="ignore", invalid="ignore"):
            at = ax + (y - ay) * (bx - ax) / (by - ay)
        inside ^= crosses & (x < at)
    return inside


def grid_1d(half: float, spacing: float) -> np.ndarray:
    """Points -half .. half at ``spacing``, symmetric about 0 (0 included when they fit)."""
    k = int(math.floor(half / spacing + 1e-9))
    return np.arange(-k, k + 1) * spacing


#: Target sample points a run takes at most (every port's reach and dexterity is checked at each).
MAX_TARGET_POINTS = 20_000
#: The largest target points file read (bytes): MAX_TARGET_POINTS points of text with room to spare.
MAX_POINTS_BYTES = 20 * 2 ** 20


@lru_cache(maxsize=4)
def file_points_mm(path: str, sha256: str, units: str) -> np.ndarray:
    """The target points of a file (mm): x y z rows of text (commas or spaces, '#' comments) or a .npy array;
    a ValueError naming points_file when it is not n x 3 finite numbers. Cached per file content."""
    import io

    from surgopt.files import read_config_file

    data = read_config_file("points_file", Path(path), MAX_POINTS_BYTES)
    try:
        if path.lower().endswith(".npy"):
            pts = np.load(io.BytesIO(data), allow_pickle=False)
        else:
            text = data.decode("utf-8").replace(",", " ")
            pts = np.loadtxt(io.StringIO(text), comments="#", ndmin=2)
    except (ValueError, UnicodeDecodeError, OSError) as exc:
        raise ValueError(f"points_file: {path}: not x y z rows of numbers ({str(exc).splitlines()[0][:100]})") from None
    pts = np.asarray(pts, dtype=float)
    if pts.ndim != 2 or pts.shape[1] != 3 or len(pts) == 0:
        raise ValueError(f"points_file: {path}: {pts.shape} values, not rows of x y z")
    bad = ~np.isfinite(pts).all(axis=1)
    if bad.any():
        raise ValueError(f"points_file: {path}: row {int(np.argmax(bad)) + 1} is not finite")
    return pts * (1000.0 if units == "m" else 1.0)


@lru_cache(maxsize=4)
def mesh_points_mm(path: str, sha256: str, units: str, offset_mm: tuple, spacing_mm: float) -> np.ndarray:
    """The grid points of ``spacing_mm`` inside a closed target mesh (mm; trimesh's containment test), the grid
    centred on the mesh's bounding box as the shapes' grids are on their centres. A ValueError naming mesh_file
    when no point falls inside (a spacing larger than the region)."""
    mesh = body_mesh(path, sha256, units, offset_mm)
    lo, hi = mesh.bounds
    centre, half = (lo + hi) / 2, (hi - lo) / 2
    if np.prod(2 * half / spacing_mm + 1) > 2_000_000:
        raise ValueError(f"mesh_file: {path}: a {spacing_mm:g} mm grid over its {2 * half.round(0)} mm bounds is "
                         f"more than 2,000,000 points to test (a larger spacing_mm)")
    gx, gy, gz = (grid_1d(h, spacing_mm) + c for h, c in zip(half, centre))
    x, y, z = np.meshgrid(gx, gy, gz, indexing="ij")
    pts = np.stack([x.ravel(), y.ravel(), z.ravel()], axis=1)
    pts = pts[np.asarray(mesh.contains(pts), bool)]
    if len(pts) == 0:
        raise ValueError(f"mesh_file: {path}: no point of a {spacing_mm:g} mm grid lies inside the mesh (a smaller "
                         f"spacing_mm)")
    return pts


def shape_grid_count(t) -> int:
    """Grid points a sphere, ellipsoid or box target's bounding box holds at ``spacing_mm`` (what
    ``target_points_mm`` builds before keeping those inside), by arithmetic."""
    return math.prod(2 * int(math.floor(r / t.spacing_mm + 1e-9)) + 1 for r in t.radii_mm)


def target_points_mm(t) -> np.ndarray:
    """The target's points (mm): the file's, the grid points inside its mesh, or the shape sampled on a grid of
    ``spacing_mm`` centred on it (points inside the shape)."""
    if t.shape == "points":
        return file_points_mm(t.points_file, t.points_sha256, t.points_units)
    if t.shape == "mesh":
        pts = mesh_points_mm(t.mesh_file, t.mesh_sha256, t.mesh_units, tuple(t.mesh_offset_mm), t.spacing_mm)
        if t.region_box_mm is not None:  # a region of the organ (#57 item 1): its points within the box
            lo, hi = np.asarray(t.region_box_mm, float)
            pts = pts[np.all((pts >= lo) & (pts <= hi), axis=1)]
        return pts
    gx, gy, gz = (grid_1d(r, t.spacing_mm) for r in t.radii_mm)
    x, y, z = np.meshgrid(gx, gy, gz, indexing="ij")
    pts = np.stack([x.ravel(), y.ravel(), z.ravel()], axis=1)
    if t.shape != "box":
        r = np.asarray(t.radii_mm, float)
        pts = pts[((pts / r) ** 2).sum(axis=1) <= 1.0 + 1e-12]
    return pts + np.asarray(t.centre_mm, float)


def inside_dome(p: np.ndarray, semi_axes_mm, exponent: float = 2.0) -> np.ndarray:
    """Which points (mm) lie inside the dome |x/a|^n + |y/b|^n + |z/c|^n < 1, z >= 0 (n = 2: the half-ellipsoid)."""
    a = np.asarray(semi_axes_mm, float)
    if exponent == 2.0:
        return (p[:, 2] >= 0) & (((p / a) ** 2).sum(axis=1) < 1.0)
    return (p[:, 2] >= 0) & ((np.abs(p / a) ** exponent).sum(axis=1) < 1.0)


def dome_height_mm(x, y, semi_axes_mm, exponent: float = 2.0):
    """The dome's height (mm) over top-view points: c (1 - |x/a|^n - |y/b|^n)^(1/n), 0 outside its base."""
    a, b, c = semi_axes_mm
    if exponent == 2.0:
        s = 1.0 - (np.asarray(x) / a) ** 2 - (np.asarray(y) / b) ** 2
        return c * np.sqrt(np.clip(s, 0.0, None))
    s = 1.0 - np.abs(np.asarray(x) / a) ** exponent - np.abs(np.asarray(y) / b) ** exponent
    return c * np.clip(s, 0.0, None) ** (1.0 / exponent)


@lru_cache(maxsize=4)
def dome_samples_mm(semi_axes_mm: tuple, exponent: float) -> tuple[np.ndarray, float]:
    """(points (32,401, 3), gap) on the dome's surface, its base rim included: the directions of a 360 x 90 grid
    of longitude and latitude, each scaled out to the surface (radial projection: cells of nearly even size on a
    superquadric too), and the apex. Every point of the surface lies within ``gap`` (mm: half the longest
    diagonal of a grid cell) of a sample, so a nearest-sample distance over-reads the distance to the surface by
    at most ``gap`` (2.6 mm on the default dome, 3.9 mm at exponent 10)."""
    a = np.asarray(semi_axes_mm, float)
    u, v = np.meshgrid(np.linspace(0.0, 2 * np.pi, 361), np.linspace(0.0, np.pi / 2, 91))
    d = np.stack([np.cos(v) * np.cos(u), np.cos(v) * np.sin(u), np.sin(v)], axis=2)
    grid = d * ((np.abs(d / a) ** exponent).sum(axis=2) ** (-1.0 / exponent))[..., None]
    diagonal = np.maximum(np.linalg.norm(grid[1:, 1:] - grid[:-1, :-1], axis=2),
                          np.linalg.norm(grid[1:, :-1] - grid[:-1, 1:], axis=2))
    points = np.vstack([grid[:-1, :-1].reshape(-1, 3), grid[-1:, 0]])
    return points, float(diagonal.max()) / 2


def body_box_mm(patient) -> tuple[np.ndarray, np.ndarray]:
    """(lo, hi) mm: a box holding the body (the dome's semi-axes over its base; the mesh's bounds)."""
    if patient.shape == "dome":
        a = np.asarray(patient.semi_axes_mm, float)
        return np.array([-a[0], -a[1], 0.0]), a.copy()
    lo, hi = patient_mesh(patient).bounds
    return np.asarray(lo, float), np.asarray(hi, float)


@lru_cache(maxsize=4)
def _dome_tree(semi_axes_mm: tuple, exponent: float):
    """A k-d tree over ``dome_samples_mm`` (scipy's cKDTree) and the samples' gap."""
    from scipy.spatial import cKDTree

    samples, gap = dome_samples_mm(semi_axes_mm, exponent)
    return cKDTree(samples), gap


#: Threads the per-port tables' work runs on (a k-d tree's query here, the link tables' kernels): the machine's
#: cores, at most 4; the same answer on any number.
TABLE_THREADS = min(4, len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1)


def body_distance_mm(p: np.ndarray, patient, cap_mm: float, many: bool = False) -> np.ndarray:
    """Per point (mm) outside the body: its distance to the body wall, capped at ``cap_mm`` (the mesh's by
    trimesh's closest point, exact, in chunks; the dome's to the nearest of ``dome_samples_mm``, less their gap: a
    lower bound within that gap of the true distance). ``many``: the dome's nearest sample found by a k-d tree (the
    same sample; for millions of points, where the brute-force loop takes ~30 us a point near the body); the
    mesh's nearest vertex of it subdivided, less its gap (``_mesh_tree``: a lower bound within 1.7 mm)."""
    if patient.shape == "dome" and many:
        tree, gap = _dome_tree(tuple(patient.semi_axes_mm), patient.dome_exponent)
        d, _ = tree.query(np.asarray(p, float), distance_upper_bound=cap_mm + gap, workers=TABLE_THREADS)
        return np.clip(np.where(np.isinf(d), cap_mm + gap, d) - gap, 0.0, cap_mm)
    if patient.shape == "dome":
        from surgopt.kinematics.port.serial import nearest_distances

        samples, gap = dome_samples_mm(tuple(patient.semi_axes_mm), patient.dome_exponent)
        return np.clip(nearest_distances(np.ascontiguousarray(p, float), samples, cap_mm + gap) - gap, 0.0, cap_mm)
    import trimesh

    mesh = patient_mesh(patient)
    out = np.full(len(p), cap_mm)
    lo, hi = mesh.bounds
    near = np.all((p >= lo - cap_mm) & (p <= hi + cap_mm), axis=1)
    if near.any() and many:  # the nearest vertex of the mesh subdivided to MESH_GAP_EDGE_MM, less its gap
        tree, gap = _mesh_tree(patient.mesh_file, patient.mesh_sha256, patient.mesh_units,
                               tuple(patient.mesh_offset_mm))
        d, _ = tree.query(np.asarray(p[near], float), distance_upper_bound=cap_mm + gap, workers=TABLE_THREADS)
        out[near] = np.clip(np.where(np.isinf(d), cap_mm + gap, d) - gap, 0.0, cap_mm)
    elif near.any():
        out[near] = np.minimum(in_chunks(lambda q: trimesh.proximity.closest_point(mesh, q)[1], p[near]), cap_mm)
    return out


#: How many points one call of trimesh's closest point or containment test takes (a mesh patient's link tables
#: ask millions at once: one call of 2 M points asked 9.4 GB; issue 57 item 0).
MESH_QUERY_CHUNK = 5_000
#: The edge a mesh patient is subdivided to for its distance lower bound (mm): every point of a triangle whose
#: edges are at most this lies within MESH_GAP_EDGE_MM / sqrt(3) of one of its vertices.
MESH_GAP_EDGE_MM = 3.0


def in_chunks(f, p: np.ndarray, size: int = MESH_QUERY_CHUNK) -> np.ndarray:
    """``f`` of the points ``p`` taken ``size`` at a time, concatenated: bounded memory for trimesh's queries."""
    if len(p) <= size:
        return np.asarray(f(p))
    return np.concatenate([np.asarray(f(p[k:k + size])) for k in range(0, len(p), size)])


@lru_cache(maxsize=2)
def _mesh_tree(path: str, sha256: str, units: str, offset_mm: tuple):
    """A k-d tree over the vertices of the body mesh subdivided until no edge is longer than MESH_GAP_EDGE_MM
    (trimesh's ``subdivide_to_size``), and their gap, MESH_GAP_EDGE_MM / sqrt(3): the distance to the nearest
    vertex, less the gap, is a lower bound within the gap of the distance to the wall (as the dome's samples)."""
    import trimesh
    from scipy.spatial import cKDTree

    mesh = body_mesh(path, sha256, units, offset_mm)
    v, _ = trimesh.remesh.subdivide_to_size(np.asarray(mesh.vertices), np.asarray(mesh.faces),
                                            max_edge=MESH_GAP_EDGE_MM, max_iter=20)
    return cKDTree(v), MESH_GAP_EDGE_MM / math.sqrt(3.0)


def dome_surface_mm(semi_axes_mm, exponent: float, u: np.ndarray, v: np.ndarray):
    """(x, y, z) of the dome's surface at longitude u and latitude v in [0, pi/2] (rad): the superquadric's
    signed-power parametrisation, a ellipsoid's cos/sin when n = 2."""
    a, b, c = semi_axes_mm
    f = lambda w: np.sign(w) * np.abs(w) ** (2.0 / exponent)  # noqa: E731
    return a * f(np.cos(u)) * f(np.cos(v)), b * f(np.sin(u)) * f(np.cos(v)), c * f(np.sin(v))


#: The largest mesh file read (bytes) and the most triangles accepted.
MAX_MESH_BYTES = 200 * 2 ** 20
MAX_MESH_FACES = 2_000_000


def _read_mesh_bytes(path) -> bytes:
    from surgopt.files import read_config_file

    return read_config_file("mesh_file", path, MAX_MESH_BYTES)


#: The largest |coordinate| a body mesh may have, in its own units (a body is metres across, not kilometres).
MAX_MESH_COORDINATE = 1e6


@lru_cache(maxsize=4)
def body_mesh(path: str, sha256: str, units: str, offset_mm: tuple):
    """The patient's mesh (trimesh) in mm, offset; a ValueError naming the problem if it cannot be read, is not
    closed (inside and outside would be undefined) or is too large. Cached per file content."""
    import io
    import warnings

    import trimesh

    data = _read_mesh_bytes(path)
    kind = Path(path).suffix.lower().lstrip(".")
    if kind not in ("stl", "obj", "ply"):
        raise ValueError(f"mesh_file: {path}: not an STL, OBJ or PLY file")
    try:  # as written (processing merges vertices and drops NaN and degenerate triangles: checked first, below);
        # quietly: a loader's arithmetic on a vertex at 1e300 warns before the checks below can name it
        with warnings.catch_warnings(), np.errstate(all="ignore"):
            warnings.simplefilter("ignore")
            mesh = trimesh.load(io.BytesIO(data), file_type=kind, force="mesh", process=False)
    except Exception as exc:  # noqa: BLE001 - whatever trimesh raises on a malformed file
        raise ValueError(f"mesh_file: {path}: cannot be read as {kind.upper()} ({type(exc).__name__}: "
                         f"{str(exc)[:120]})") from None
    if len(mesh.faces) == 0:
        raise ValueError(f"mesh_file: {path}: no triangles")
    if len(mesh.faces) > MAX_MESH_FACES:
        raise ValueError(f"mesh_file: {path}: {len(mesh.faces):,} triangles (at most {MAX_MESH_FACES:,})")
    vertices = np.asarray(mesh.vertices)
    if not np.all(np.isfinite(vertices)):
        bad = int(np.count_nonzero(~np.isfinite(vertices).all(axis=1)))
        raise ValueError(f"mesh_file: {path}: {bad:,} vertex(es) not finite (NaN or infinite coordinates)")
    far = float(np.abs(vertices).max())
    if far > MAX_MESH_COORDINATE:  # before any arithmetic on them (1e300 squared overflows, with a warning)
        raise ValueError(f"mesh_file: {path}: a vertex lies {far:.3g} {units} from the origin (at most "
                         f"{MAX_MESH_COORDINATE:g}): not a patient's body")
    with np.errstate(all="ignore"):
        degenerate = int(np.count_nonzero(~(np.asarray(mesh.area_faces) > 0)))
    if degenerate:
        raise ValueError(f"mesh_file: {path}: {degenerate:,} triangle(s) have zero area (degenerate: repeated or "
                         f"collinear corners); remove them, e.g. with trimesh's or MeshLab's repair, and keep the "
                         f"body closed")
    mesh.process()
    if not mesh.is_watertight:
        raise ValueError(f"mesh_file: {path}: the mesh is not closed (watertight), so inside and outside the body "
                         f"are undefined; close it (e.g. cap the base plane)")
    mesh.apply_scale(1000.0 if units == "m" else 1.0)
    mesh.apply_translation(np.asarray(offset_mm, float))
    if mesh.bounds[1][2] <= 0:
        raise ValueError(f"mesh_file: {path}: the mesh lies below z = 0 (mesh_offset_mm puts its base on z = 0)")
    return mesh


def check_mesh_scale(mesh, path: str, units: str, lo_mm: float, hi_mm: float, what: str) -> None:
    """Refuse a mesh whose half extents are not all within [lo_mm, hi_mm] (a wrongly scaled file: metres read as
    mm make an abdomen 0.2 mm across), naming the units that would fit."""
    half = (mesh.bounds[1] - mesh.bounds[0]) / 2
    if np.all((half >= lo_mm) & (half <= hi_mm)):
        return
    hint = ""
    for other, factor in (("m", 1000.0), ("mm", 0.001)):
        if other != units and np.all((half * factor >= lo_mm) & (half * factor <= hi_mm)):
            hint = f"; read as {other} it would fit: mesh_units = '{other}'?"
    raise ValueError(f"mesh_file: {path}: its half extents are {', '.join(f'{v:.4g}' for v in half)} mm with "
                     f"mesh_units = '{units}', not {what} ({lo_mm:g} to {hi_mm:g} mm){hint}")


def patient_mesh(patient):
    return body_mesh(patient.mesh_file, patient.mesh_sha256, patient.mesh_units, tuple(patient.mesh_offset_mm))


def inside_body(p: np.ndarray, patient) -> np.ndarray:
    """Which points (mm) lie inside the body: the dome, the closed mesh (trimesh's containment test), or with
    ``mesh_is = "wall"`` (a wall's shell) every point under its outer skin above the table (the highest crossing of
    a vertical ray with the mesh above it: the cavity is the body's)."""
    if patient.shape == "dome":
        return inside_dome(p, patient.semi_axes_mm, patient.dome_exponent)
    p = np.asarray(p, float).reshape(-1, 3)
    if getattr(patient, "mesh_is", "body") == "wall":
        skin = in_chunks(lambda q: _mesh_wall(q[:, 0], q[:, 1], patient_mesh(patient))[0], p)
        return (p[:, 2] >= 0) & (p[:, 2] <= np.nan_to_num(skin, nan=-np.inf))
    return in_chunks(patient_mesh(patient).contains, p).astype(bool) & (p[:, 2] >= 0)


def wall_thickness_mm(ports_mm: np.ndarray, toward_mm: np.ndarray, patient) -> np.ndarray:
    """(n,) With ``mesh_is = "wall"``: the wall's thickness (mm) at each port (n, 3 mm, on the outer skin) along the
    line from it toward ``toward_mm`` (3,: the target's centre, the shaft's docking direction): from the skin's
    crossing to the next one, the inner surface (NaN where the line meets the wall once or not at all). Where the
    dVRK's cannula sets its remote centre in the wall, the RCM lies up to this far below the port's skin point."""
    mesh = patient_mesh(patient)
    ports = np.asarray(ports_mm, float).reshape(-1, 3)
    d = np.asarray(toward_mm, float)[None, :] - ports
    d /= np.linalg.norm(d, axis=1)[:, None]
    origins = ports - 5.0 * d  # from just outside the skin
    locations, index_ray, _ = mesh.ray.intersects_location(origins, d, multiple_hits=True)
    out = np.full(len(ports), np.nan)
    for k in range(len(ports)):
        s = np.sort(((locations[index_ray == k] - origins[k]) @ d[k]))
        s = s[np.concatenate([[True], np.diff(s) > 1e-6])] if len(s) else s  # a hit on a shared edge, once
        if len(s) >= 2:
            out[k] = s[1] - s[0]
    return out


def wall_height_mm(x: np.ndarray, y: np.ndarray, patient) -> np.ndarray:
    """Height (mm) of the body's upper wall over each top-view point: the dome's, or the highest crossing of a
    vertical ray with the mesh (NaN where the ray misses it)."""
    if patient.shape == "dome":
        return dome_height_mm(x, y, patient.semi_axes_mm, patient.dome_exponent)
    return _mesh_wall(x, y, patient_mesh(patient))[0]


def _mesh_wall(x: np.ndarray, y: np.ndarray, mesh) -> tuple[np.ndarray, np.ndarray]:
    """(height mm, face) of the highest crossing of a vertical ray through each top-view point with the mesh
    (NaN and -1 where the ray misses it)."""
    top = mesh.bounds[1][2] + 10.0
    origins = np.stack([x, y, np.full(len(x), top)], axis=1)
    dirs = np.tile([0.0, 0.0, -1.0], (len(x), 1))
    locations, index_ray, index_tri = mesh.ray.intersects_location(origins, dirs, multiple_hits=True)
    z = np.full(len(x), np.nan)
    np.fmax.at(z, index_ray, locations[:, 2])
    face = np.full(len(x), -1, np.int64)
    highest = locations[:, 2] == z[index_ray]
    face[index_ray[highest]] = index_tri[highest]
    return z, face


def painted_faces(patient) -> np.ndarray | None:
    """Which faces of a mesh patient carry ``port_region.face_color_rgb`` (None when no colour is given); a
    ValueError naming the field when the mesh has no per-face colours or none of that colour."""
    rgb = patient.port_region.face_color_rgb
    if rgb is None:
        return None
    if patient.shape != "mesh":
        raise ValueError("patient.port_region.face_color_rgb: a painted region needs shape = 'mesh' (a PLY file "
                         "with per-face colours); on the dome, mark the region with polygon_mm")
    mesh = patient_mesh(patient)
    if getattr(mesh.visual, "kind", None) != "face":
        raise ValueError(f"patient.port_region.face_color_rgb: {patient.mesh_file} has no per-face colours (STL "
                         f"has none, OBJ stores vertex colours): export the painted mesh as PLY with face colours")
    colours = np.asarray(mesh.visual.face_colors)[:, :3]
    painted = np.all(colours == np.asarray(rgb), axis=1)
    if not painted.any():
        present = ", ".join(str(list(c)) for c in np.unique(colours, axis=0)[:6])
        raise ValueError(f"patient.port_region.face_color_rgb: no face of {patient.mesh_file} has the colour {rgb} "
                         f"(its colours: {present})")
    return painted


def body_extent_mm(patient) -> tuple[float, float, float]:
    """Half widths in x and y about 0 and the height of the body (the dome's semi-axes, the mesh's bounds)."""
    if patient.shape == "dome":
        return tuple(patient.semi_axes_mm)
    lo, hi = patient_mesh(patient).bounds
    return max(abs(lo[0]), abs(hi[0])), max(abs(lo[1]), abs(hi[1])), float(hi[2])


def sites_mm(cfg) -> np.ndarray:
    """Candidate ports: a top-view grid at ``site_spacing_mm`` (symmetric about x = 0) lifted onto the body's
    upper wall (the dome, or the mesh by vertical rays), kept where the wall is at least
    ``min_height_fraction`` of the body's height, inside ``polygon_mm`` when given, on a face painted
    ``face_color_rgb`` when given, and where the target centre is within ``port_to_target_mm`` (3-D or top-view,
    ``port_to_target_measure``)."""
    return site_stages(cfg)[0]


def site_stages(cfg) -> tuple[np.ndarray, list[tuple[str, int]]]:
    """``sites_mm`` and how many grid points each of its filters kept, in order: (what kept them, count) for the
    wall high enough (and painted), the marked region, the distance to the target (issue 56 item 10: a region
    wholly outside the body was blamed on port_to_target_mm)."""
    a, b, c = body_extent_mm(cfg.patient)
    s = cfg.patient.port_region.site_spacing_mm
    gx, gy = np.meshgrid(grid_1d(a, s), grid_1d(b, s), indexing="ij")
    x, y = gx.ravel(), gy.ravel()
    painted = painted_faces(cfg.patient)
    if painted is None:
        z = wall_height_mm(x, y, cfg.patient)
    else:  # the face each site lies on must be painted
        z, face = _mesh_wall(x, y, patient_mesh(cfg.patient))
        z = np.where((face >= 0) & painted[np.maximum(face, 0)], z, np.nan)
    keep = np.nan_to_num(z, nan=-1.0) >= cfg.patient.port_region.min_height_fraction * c
    stages = [(f"on the body's wall at least patient.port_region.min_height_fraction "
               f"({cfg.patient.port_region.min_height_fraction:g}) of its height"
               + (", on a painted face" if painted is not None else ""), int(keep.sum()))]
    if cfg.patient.port_region.polygon_mm is not None:
        inside = inside_polygon(x, y, np.asarray(cfg.patient.port_region.polygon_mm, float))
        keep &= inside
        stages.append(("of those, inside patient.port_region.polygon_mm" + (
            " (no grid point over the body lies inside it: the region is outside the body's top view)"
            if not inside.any() else f" ({int(inside.sum())} grid points over the body inside it)"), int(keep.sum())))
    pts = np.stack([x[keep], y[keep], z[keep]], axis=1)
    apart = pts - np.asarray(cfg.target.centre_mm)
    dist = np.linalg.norm(apart[:, :2] if cfg.constraints.port_to_target_measure == "horizontal" else apart, axis=1)
    lo, hi = cfg.constraints.port_to_target_mm
    near = (dist >= lo) & (dist <= hi)
    stages.append((f"of those, within constraints.port_to_target_mm [{lo:g}, {hi:g}] of the target's centre",
                   int(near.sum())))
    return pts[near], stages
