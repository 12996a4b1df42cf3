"""What the page's 3-D scene draws beside the layouts (``html.py`` draws the layouts and the checks): the patient's
body, its organs (#57: the obstacles and the target's organ, decimated for display), the landmarks, the marked
region, the sides and the bedside (#56 item 4), and the cart with its arms as each listed layout's row docks them.

A mesh is drawn decimated by vertex clustering (``decimated``: the vertices of each cubic cell merged into their
mean, the triangles that collapse dropped; the cell grown until the triangles fit a budget), so that a page of a
CT-derived patient stays a few MB: the drawing only, never what the rows were computed on.
"""
from __future__ import annotations

import numpy as np

#: The most triangles the body's mesh and each organ's are drawn with (a page of OpenHELP: the wall and ten organs).
BODY_FACES = 8000
ORGAN_FACES = 2500
#: The cells (mm) a mesh's vertices are clustered in, tried in turn until its triangles fit the budget.
CELLS_MM = (0.0, 2.0, 3.0, 4.0, 6.0, 8.0, 12.0, 16.0, 24.0)


def decimated(vertices: np.ndarray, faces: np.ndarray, max_faces: int) -> tuple[np.ndarray, np.ndarray, float]:
    """(vertices, faces, cell mm) of a mesh for display: as it is when it fits ``max_faces`` (cell 0), else its
    vertices clustered in the smallest cell of CELLS_MM that makes it fit (each cell's vertices merged into their
    mean, which lies in the cell: within a cell's diagonal of the surface), degenerate and repeated triangles
    dropped."""
    vertices, faces = np.asarray(vertices, float), np.asarray(faces, np.int64)
    for cell in CELLS_MM:
        if cell == 0.0:
            if len(faces) <= max_faces:
                return vertices, faces, 0.0
            continue
        keys = np.floor(vertices / cell).astype(np.int64)
        _, cluster, counts = np.unique(keys, axis=0, return_inverse=True, return_counts=True)
        cluster = cluster.ravel()
        merged = np.zeros((len(counts), 3))
        np.add.at(merged, cluster, vertices)
        merged /= counts[:, None]
        f = cluster[faces]
        f = f[(f[:, 0] != f[:, 1]) & (f[:, 1] != f[:, 2]) & (f[:, 0] != f[:, 2])]
        f = np.unique(np.sort(f, axis=1), axis=0) if len(f) else f  # one of each triangle (its winding dropped)
        if len(f) <= max_faces or cell == CELLS_MM[-1]:
            return merged, f, cell
    raise AssertionError("unreachable")


def body_trace(cfg) -> dict:
    """The patient's surface as a Plotly trace: the dome's, or its mesh decimated for display (``decimated``: at
    most BODY_FACES triangles, each vertex within one cell of the surface)."""
    from surgopt.studies.port_place.geometry import body_extent_mm, dome_surface_mm, patient_mesh

    if cfg.patient.shape == "dome":
        u, v = np.meshgrid(np.linspace(0, 2 * np.pi, 61), np.linspace(0, np.pi / 2, 17))
        x, y, z = dome_surface_mm(body_extent_mm(cfg.patient), cfg.patient.dome_exponent, u, v)
        return {"type": "surface", "x": x, "y": y, "z": z, "opacity": 0.18, "showscale": False,
                "colorscale": [[0, "#c9b8a6"], [1, "#c9b8a6"]], "hoverinfo": "skip", "name": "abdomen"}
    mesh = patient_mesh(cfg.patient)
    v, faces, cell = decimated(np.asarray(mesh.vertices), np.asarray(mesh.faces), BODY_FACES)
    return {"type": "mesh3d", "x": v[:, 0].round(1), "y": v[:, 1].round(1), "z": v[:, 2].round(1), "i": faces[:, 0],
            "j": faces[:, 1], "k": faces[:, 2], "opacity": 0.18, "color": "#c9b8a6", "hoverinfo": "skip",
            "name": "body mesh" + (f" (drawn decimated: {cell:g} mm cells)" if cell else "")}


def scene_marks(cfg) -> dict:
    """What the scene marks on the patient (issue 56 item 4): the landmarks on the wall (name, x, y, z mm; the
    dome's own said to be assumed), the marked region's outline lifted onto the wall, the sides (the patient's
    left and right, head and feet) just past the body, and the bedside's boxes the links clear (#54)."""
    from surgopt.studies.port_place.geometry import body_extent_mm, landmarks_mm, wall_height_mm

    marks = landmarks_mm(cfg.patient)
    names = list(marks)
    xy = np.array([marks[n] for n in names], float).reshape(-1, 2)
    z = wall_height_mm(xy[:, 0], xy[:, 1], cfg.patient) if len(xy) else np.zeros(0)
    landmarks = [[n, float(x), float(y), float(np.nan_to_num(h, nan=0.0))] for n, (x, y), h in zip(names, xy, z)]
    region = None
    if cfg.patient.port_region.polygon_mm is not None:
        poly = np.asarray(cfg.patient.port_region.polygon_mm, float)
        edge = np.concatenate([np.linspace(p, q, 12, endpoint=False) for p, q in zip(poly, np.roll(poly, -1, 0))])
        edge = np.vstack([edge, edge[:1]])
        h = np.nan_to_num(wall_height_mm(edge[:, 0], edge[:, 1], cfg.patient), nan=0.0)
        region = np.column_stack([edge, h + 2.0]).round(1)  # 2 mm above the wall, drawn over it
    a, b, _ = body_extent_mm(cfg.patient)
    sides = [["patient's left", 1.15 * a, 0.0, 0.0], ["patient's right", -1.15 * a, 0.0, 0.0],
             ["head", 0.0, 1.1 * b, 0.0], ["feet", 0.0, -1.1 * b, 0.0]]
    from surgopt.studies.port_place.bedside import bedside_lines_mm
    from surgopt.studies.port_place.columns import links_of

    bedside = bedside_lines_mm(cfg, (2.0 * a, 2.0 * b)) if links_of(cfg) else []  # what the links are checked against
    from surgopt.studies.port_place.geometry import landmark_lines, skin_line_mm

    lines = []  # the lines between landmarks on the skin (#57 item 2), 1 mm over it, None between them
    for a, b in landmark_lines(cfg.patient):
        pts, along = skin_line_mm(cfg.patient, marks[a], marks[b])
        if lines:
            lines.append(None)
        drawn = np.vstack([pts[:: max(1, len(pts) // 60)], pts[-1:]]) + [0.0, 0.0, 1.0]
        lines += drawn.round(1).tolist()
    return {"landmarks": landmarks, "landmarks_assumed": not cfg.patient.landmarks_mm, "region": region,
            "sides": sides, "bedside": bedside, "landmark_lines": lines}


def docked_scene(cfg, rows: list[dict]) -> list | None:
    """Each listed layout's cart and arms as its row docks them (``layout.docked_lines_mm``, patient frame, mm),
    drawn in the scene when the layout is clicked (#56 item 4); None without a cart. Rows are taken in design order,
    so that a run of several docking rolls builds each roll's model once (``rolls.model_for``)."""
    from surgopt.studies.port_place.carts import has_cart
    from surgopt.studies.port_place.layout import docked_lines_mm
    from surgopt.studies.port_place.rolls import model_for

    if not has_cart(cfg):
        return None
    out = [None] * len(rows)
    for i in sorted(range(len(rows)), key=lambda i: rows[i]["design_id"]):
        out[i] = docked_lines_mm(model_for(cfg, rows[i]), rows[i])
    return out


#: The organs' colours: obstacles a muted red, the target's organ green.
OBSTACLE_COLOUR, TARGET_ORGAN_COLOUR = "#b5564e", "#4e9a5a"


def organ_traces(cfg) -> list[dict]:
    """Each organ of ``patient.organs`` as a Plotly mesh (its mesh in the patient's frame, decimated for display to
    ORGAN_FACES), named with its role: an obstacle the shafts must not cross, or the target's organ."""
    from surgopt.studies.port_place.geometry import body_mesh

    p = cfg.patient
    out = []
    for name, organ in (p.organs or {}).items():
        if not organ.mesh_sha256:
            continue  # a stored config read as stored (its files not read again)
        mesh = body_mesh(organ.mesh_file, organ.mesh_sha256, p.mesh_units, tuple(p.mesh_offset_mm))
        v, f, cell = decimated(np.asarray(mesh.vertices), np.asarray(mesh.faces), ORGAN_FACES)
        role = "an obstacle" if organ.obstacle else "the target's organ, not an obstacle"
        out.append({"type": "mesh3d", "x": v[:, 0].round(1), "y": v[:, 1].round(1), "z": v[:, 2].round(1),
                    "i": f[:, 0], "j": f[:, 1], "k": f[:, 2], "opacity": 0.35 if organ.obstacle else 0.25,
                    "color": OBSTACLE_COLOUR if organ.obstacle else TARGET_ORGAN_COLOUR, "hoverinfo": "text",
                    "text": f"{name} ({role}" + (f"; drawn decimated, {cell:g} mm cells)" if cell else ")"),
                    "legendgroup": "organs", "showlegend": not out, "name": ORGANS_LEGEND})
    return out


#: The organs' one legend entry (a click hides or shows them all); each organ's own name is its hover text.
ORGANS_LEGEND = "the organs (red: obstacles to the shafts; green: the target's organ): click to hide or show"
