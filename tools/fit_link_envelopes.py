"""Fit a bounding capsule to each dVRK link mesh, in the frame of surgopt's skeleton that carries it (issue 54:
link envelopes from the arms' own geometry, in place of assumed radii).

    python tools/fit_link_envelopes.py /work/.mirror/jhu-dvrk+dvrk_model/repo

reads the meshes from that git directory at ``COMMIT`` (jhu-dvrk/dvrk_model, the last commit whose meshes are plain
files: the next one turned them into Git LFS pointers), places each by its visual origin in the URDF
(``urdf/Classic/PSM_base.urdf.xacro``, ``urdf/Si/PSM_base.urdf.xacro``,
``urdf/common/instruments/housing/housing_Classic.urdf.xacro``; transcribed in ``LINKS`` below), and writes

- ``surgopt/robots/dvrk/link_envelopes.py``: per link, the capsule's two end points and radius (m) in the link's
  frame, the mesh's path and sha256, its convex hull's volume and the capsule's, and the largest distance from a
  hull vertex to the capsule's surface (the fit's slack: how far the capsule reaches past the mesh at its worst);
- ``tests/data/dvrk_link_hulls.npz``: each mesh's convex-hull vertices in the same frame (mm, float64), for the test
  that each capsule contains its mesh (a capsule is convex, so containing the hull's vertices is containing the mesh).

A link whose mesh two capsules fit in at least 30 % less volume than one (``SPLIT_GAIN``) gets two: the mesh is cut
by the plane through its vertices' median across one of its principal axes (the axis giving the least total), each
part's convex hull (its vertices and the cut's: the hull of the uncapped part holds the solid's part) fitted alone.

The fit: the capsule of least volume containing every hull vertex. For an axis (a unit direction and a point) and a
radius r, the shortest segment that covers each vertex p at axial coordinate t and distance rho from the axis runs
from max(t - sqrt(r^2 - rho^2)) back to min(t + sqrt(r^2 - rho^2)); the volume pi r^2 L + 4/3 pi r^3 is minimised over
the axis (4 numbers) and r by Nelder-Mead from the hull's principal axis (scipy: a tool run by hand, not a
dependency of the package), with restarts from its three principal axes. The ends are then rounded to 1 um and the radius, from the rounded ends, up to 0.1 mm.
"""
from __future__ import annotations

import hashlib
import io
import math
import subprocess
import sys
from pathlib import Path

import numpy as np

COMMIT = "138663f"  # "Track large mesh files with Git LFS": its meshes are still the files themselves
REPO = "jhu-dvrk/dvrk_model"
HERE = Path(__file__).resolve().parents[1]
PI_2 = 1.5708

#: (skeleton, frame of surgopt's skeleton, link name, mesh path, visual origin xyz (m), rpy (rad), URDF file)
CLASSIC = "urdf/Classic/PSM_base.urdf.xacro"
SI = "urdf/Si/PSM_base.urdf.xacro"
LINKS = (
    ("PSM_CLASSIC", "base", "base housing", "meshes/arms/Classic/PSM/PSM_base.dae",
     (0.039, -0.40788, -0.07879), (1.5708, 0.0, 3.1416), CLASSIC),
    ("PSM_CLASSIC", "yaw", "yaw link", "meshes/arms/Classic/PSM/PSM_yaw.dae", (0.0125, 0.0, 0.5265),
     (3.1416, 0.0, 1.5708), CLASSIC),
    ("PSM_CLASSIC", "back", "parallelogram back link", "meshes/arms/Classic/PSM/PSM_pitch_2.dae", (0.0, 0.0, 0.0),
     (0.0, 0.0, -0.27129), CLASSIC),
    ("PSM_CLASSIC", "front", "parallelogram front link", "meshes/arms/Classic/PSM/PSM_pitch_3.dae", (0.0, 0.0, 0.0),
     (0.0, 0.0, -0.27129), CLASSIC),
    ("PSM_CLASSIC", "bottom", "parallelogram lower link", "meshes/arms/Classic/PSM/PSM_pitch_4.dae",
     (0.009, 0.0, 0.0), (0.0, -1.5708, 0.0), CLASSIC),
    ("PSM_CLASSIC", "top", "parallelogram top link", "meshes/arms/Classic/PSM/PSM_pitch_5.dae", (0.009, 0.0, 0.0),
     (0.0, -1.5708, 0.0), CLASSIC),
    ("PSM_CLASSIC", "insertion", "insertion stage", "meshes/arms/Classic/PSM/PSM_insertion.dae",
     (0.02528, 0.429, 0.0), (0.0, -1.5708, 1.5708), CLASSIC),
    ("PSM_CLASSIC", "carriage", "instrument housing", "meshes/instruments/housing/Classic/housing_Classic_body.dae",
     (0.0, 0.0, 0.0904), (0.0, 0.0, PI_2), "urdf/common/instruments/housing/housing_Classic.urdf.xacro"),
    ("PSM_SI", "arm base", "arm base housing", "meshes/arms/Si/USM/USM_base.stl",
     (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), SI),
    ("PSM_SI", "yaw", "yaw link", "meshes/arms/Si/USM/USM_yaw.stl", (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), SI),
    ("PSM_SI", "pitch", "pitch link", "meshes/arms/Si/USM/USM_pitch.stl", (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), SI),
    ("PSM_SI", "pitch 2", "parallelogram link", "meshes/arms/Si/USM/USM_pitch_3.stl", (0.0, 0.0, 0.0),
     (0.0, 0.0, 0.0), SI),
    ("PSM_SI", "pitch 3", "insertion stage", "meshes/arms/Si/USM/USM_pitch_4.stl", (0.0, 0.0, 0.0),
     (0.0, 0.0, 0.0), SI),
)


def rpy_matrix(rpy) -> np.ndarray:
    """URDF's fixed-axis roll-pitch-yaw: Rz(yaw) Ry(pitch) Rx(roll)."""
    r, p, y = rpy
    cr, sr, cp, sp, cy, sy = math.cos(r), math.sin(r), math.cos(p), math.sin(p), math.cos(y), math.sin(y)
    rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    return rz @ ry @ rx


def capsule_of(points: np.ndarray, axis_point, direction, radius):
    """The shortest segment on the axis that, with ``radius``, covers every point: (a, b), or None when a point
    lies farther than ``radius`` from the axis."""
    d = direction / np.linalg.norm(direction)
    rel = points - axis_point
    t = rel @ d
    rho2 = np.einsum("ij,ij->i", rel, rel) - t * t
    if np.any(rho2 > radius * radius):
        return None
    half = np.sqrt(radius * radius - rho2)
    lo, hi = np.max(t - half), np.min(t + half)  # the segment must reach past lo and back before hi
    if lo <= hi:  # a sphere at any t in [lo, hi] covers every point
        mid = 0.5 * (lo + hi)
        return axis_point + mid * d, axis_point + mid * d
    return axis_point + hi * d, axis_point + lo * d


def volume(a, b, r) -> float:
    return math.pi * r * r * float(np.linalg.norm(b - a)) + 4.0 / 3.0 * math.pi * r ** 3


def fit_capsule(points: np.ndarray):
    """The least-volume capsule containing ``points`` (see the module's docstring): (a, b, r)."""
    from scipy.optimize import minimize

    centre = points.mean(axis=0)
    _, _, axes = np.linalg.svd(points - centre)
    scale = float(np.max(np.linalg.norm(points - centre, axis=1)))

    def unpack(x, frame):
        u, v, w = frame
        direction = u + x[0] * v + x[1] * w
        point = centre + scale * (x[2] * v + x[3] * w)
        return point, direction / np.linalg.norm(direction)

    def least_radius(point, direction):
        rel = points - point
        t = rel @ direction
        return math.sqrt(max(float(np.max(np.einsum("ij,ij->i", rel, rel) - t * t)), 0.0))

    def cost(x, frame):
        point, direction = unpack(x, frame)
        r = least_radius(point, direction) * (1.0 + abs(x[4]))
        a, b = capsule_of(points, point, direction, r * (1 + 1e-12))
        return volume(a, b, r)

    best = None
    for k in range(3):
        frame = (axes[k], axes[(k + 1) % 3], axes[(k + 2) % 3])
        for x0 in (np.zeros(5), np.array([0, 0, 0, 0, 0.3])):
            res = minimize(cost, x0, args=(frame,), method="Nelder-Mead",
                           options={"xatol": 1e-7, "fatol": 1e-12, "maxiter": 20000, "maxfev": 40000})
            if best is None or res.fun < best[0]:
                best = (res.fun, res.x, frame)
    _, x, frame = best
    point, direction = unpack(x, frame)
    r = least_radius(point, direction) * (1.0 + abs(x[4]))
    a, b = (np.round(p, 6) for p in capsule_of(points, point, direction, r * (1 + 1e-12)))  # to 1 um
    r = math.ceil(float(np.max(segment_distance(points, a, b))) * 1e4) / 1e4  # up to 0.1 mm, on the rounded ends
    return a, b, r


#: A part is cut in two where the two capsules' volume is at most this fraction of its own; at most MAX_PARTS
#: capsules per mesh.
SPLIT_GAIN = 0.8
MAX_PARTS = 4
#: Where a part may be cut: these quantiles of its vertices along each of its principal axes.
CUTS = (0.25, 0.4, 0.5, 0.6, 0.75)


def fitted(points):
    """(hull vertices, a, b, r): the capsule fitted to the convex hull of ``points``."""
    import trimesh

    hull = np.asarray(trimesh.convex.convex_hull(points).vertices)
    return (hull, *fit_capsule(hull))


def best_cut(mesh, part):
    """The cut of ``mesh`` (a trimesh) in two that least totals its two capsules' volume: (volume, [two meshes,
    two fits]) or None."""
    import trimesh

    best = None
    hull = part[0]
    _, _, axes = np.linalg.svd(hull - hull.mean(axis=0))
    for n in axes:
        for q in CUTS:
            offset = float(np.quantile(mesh.vertices @ n, q))
            pieces = [trimesh.intersections.slice_mesh_plane(mesh, side * n, offset * n, cap=False)
                      for side in (1.0, -1.0)]
            if any(len(p.vertices) < 4 or len(p.faces) == 0 for p in pieces):
                continue
            try:
                fits = [fitted(p.vertices) for p in pieces]
            except Exception:  # a flat piece: no hull
                continue
            v = total(fits)
            if best is None or v < best[0]:
                best = (v, pieces, fits)
    return best


def fitted_parts(mesh):
    """[(hull vertices (m), a, b, r)]: one capsule, cut in two where that saves volume (module docstring) until
    MAX_PARTS."""
    parts = [(mesh, fitted(mesh.vertices))]
    while len(parts) < MAX_PARTS:
        gains = []
        for i, (m, fit) in enumerate(parts):
            cut = best_cut(m, fit)
            if cut is not None and cut[0] <= SPLIT_GAIN * total([fit]):
                gains.append((total([fit]) - cut[0], i, cut))
        if not gains:
            break
        _, i, (_, pieces, fits) = max(gains, key=lambda g: g[0])
        parts[i:i + 1] = list(zip(pieces, fits))
    return covering(mesh.vertices, [fit for _, fit in parts])


def covering(vertices, fits):
    """The fits with any mesh vertex a cut left a hair outside every capsule (the slicer snaps points within its
    tolerance of the plane) taken in by the capsule it is least outside of, its radius rounded up to 0.1 mm."""
    fits = list(fits)
    excess = np.array([segment_distance(vertices, a, b) - r for _, a, b, r in fits])
    for v in np.flatnonzero(excess.min(axis=0) > 0):
        k = int(np.argmin(excess[:, v]))
        hull, a, b, r = fits[k]
        fits[k] = (np.vstack([hull, vertices[v]]), a, b,
                   math.ceil(float(segment_distance(vertices[v:v + 1], a, b)[0]) * 1e4) / 1e4)
        excess[k] = segment_distance(vertices, a, b) - fits[k][3]
    return fits


def total(parts) -> float:
    return sum(volume(a, b, r) for _, a, b, r in parts)


def segment_distance(points, a, b) -> np.ndarray:
    ab = b - a
    denom = float(ab @ ab)
    t = np.zeros(len(points)) if denom == 0 else np.clip((points - a) @ ab / denom, 0.0, 1.0)
    return np.linalg.norm(points - (a + t[:, None] * ab), axis=1)


def mesh_bytes(git_dir: str, path: str) -> bytes:
    return subprocess.run(["git", "--git-dir", git_dir, "show", f"{COMMIT}:{path}"], check=True,
                          capture_output=True).stdout


def main(git_dir: str) -> None:
    import trimesh

    rows, hulls = [], {}
    for skeleton, frame, name, path, xyz, rpy, urdf in LINKS:
        data = mesh_bytes(git_dir, path)
        mesh = trimesh.load(io.BytesIO(data), file_type=Path(path).suffix[1:].lower(), force="mesh")
        mesh.vertices = mesh.vertices @ rpy_matrix(rpy).T + np.asarray(xyz)
        hull_l = mesh.convex_hull.volume * 1e3
        parts = fitted_parts(mesh)
        for k, (hull, a, b, r) in enumerate(parts):
            reach = float(np.max(segment_distance(hull, a, b)))
            assert reach <= r + 1e-12, (path, reach, r)
            part = name if len(parts) == 1 else f"{name} ({k + 1} of {len(parts)})"
            rows.append(dict(skeleton=skeleton, frame=frame, name=part, mesh=path, urdf=urdf,
                             sha256=hashlib.sha256(data).hexdigest(), a=tuple(a),
                             b=tuple(b), r=r, hull_l=hull_l, capsule_l=volume(a, b, r) * 1e3))
            hulls[f"{skeleton}/{frame}/{part}"] = hull * 1e3
            print(f"{skeleton:12s} {frame:10s} {part:48s} r={r * 1e3:6.1f} mm L={np.linalg.norm(b - a) * 1e3:6.1f} mm")
        print(f"{'':24s}{name}: hull {hull_l:6.2f} L, capsules {total(parts) * 1e3:6.2f} L "
              f"(x{total(parts) * 1e3 / hull_l:4.1f})")
    write_module(rows)
    out = HERE / "tests" / "data" / "dvrk_link_hulls.npz"
    out.parent.mkdir(exist_ok=True)
    np.savez_compressed(out, **hulls)


def write_module(rows) -> None:
    lines = [
        '"""The dVRK PSMs\' link envelopes fitted to the arms\' own meshes: GENERATED by tools/fit_link_envelopes.py',
        f"from {REPO} at commit {COMMIT} (do not edit by hand; run the tool again). Each capsule is the least-volume",
        "capsule containing its mesh, in the frame of surgopt's skeleton (``dvrk.links``) that carries the link: end",
        "points and radius in m, the mesh's sha256, its convex hull's volume (the whole mesh's) and the capsule's",
        "(litres): the sum of a mesh's capsules over its hull is how loose the fit is. A mesh two capsules fit",
        'much more tightly than one has two, named "(1 of 2)" and "(2 of 2)"."""',
        "from __future__ import annotations",
        "",
        "from typing import NamedTuple",
        "",
        f'REPOSITORY = "{REPO}"',
        f'COMMIT = "{COMMIT}"',
        "",
        "",
        "class MeshEnvelope(NamedTuple):",
        '    """One link\'s mesh and the capsule fitted to it (m, in ``frame``)."""',
        "",
        "    skeleton: str",
        "    frame: str",
        "    name: str",
        "    mesh: str",
        "    mesh_sha256: str",
        "    urdf: str",
        "    point_a_m: tuple",
        "    point_b_m: tuple",
        "    radius_m: float",
        "    hull_volume_l: float",
        "    capsule_volume_l: float",
        "",
        "",
        "ENVELOPES = (",
    ]
    for r in rows:
        lines.append(f"    MeshEnvelope({r['skeleton']!r}, {r['frame']!r}, {r['name']!r},")
        lines.append(f"                 {r['mesh']!r},")
        lines.append(f"                 {r['sha256']!r},")
        lines.append(f"                 {r['urdf']!r},")
        lines.append(f"                 {tuple(float(v) for v in r['a'])!r}, {tuple(float(v) for v in r['b'])!r}, "
                     f"{r['r']!r}, {round(float(r['hull_l']), 4)!r}, {round(float(r['capsule_l']), 4)!r}),")
    lines.append(")")
    (HERE / "surgopt" / "robots" / "dvrk" / "link_envelopes.py").write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "/work/.mirror/jhu-dvrk+dvrk_model/repo")
