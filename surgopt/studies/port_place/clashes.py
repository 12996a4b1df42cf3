"""A docked layout's clearances outside the body (issue 40): each arm's setup-joint links and its own links
(``robots/dvrk_links.py``) as capsules in the cart's world frame, docked and at the joint values that reach each
target point, checked between arms, against the patient and against the table (``kinematics.capsules``).

Between two arms the least is over every pair of their poses (each instrument at any of its target points, the
other at any of its own: they move independently), the ECM held where it docks. Against the patient and the
table, every link but those that pass through the port (the shafts) at every pose, at points along the link at
most ``SPACING_M`` apart (the least over-reads by at most half that, and on a dome by the surface samples' gap);
the table as a slab under the patient frame's z = 0 of ``TABLE_THICKNESS_M`` (an assumption), tilted with it.
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np

SPACING_M = 0.01
TABLE_THICKNESS_M = 0.10
#: Against the patient, clearances are resolved up to this (mm); a link farther off reads as this much.
PATIENT_CAP_MM = 150.0
#: The arms' poses: docked, and reaching each of at most this many target points, spread by farthest-point
#: sampling from the centre (the target's extremes come first; ``spread_points`` gives the covering radius).
POSE_POINTS = 64


def spread_points(points: np.ndarray, k: int, start: int = 0) -> tuple[np.ndarray, float]:
    """Farthest-point sampling: k indices (all when fewer), each next the point farthest from those chosen, and
    the covering radius (m): every point lies within it of a chosen one."""
    if len(points) <= k:
        return np.arange(len(points)), 0.0
    chosen = [start]
    d = np.linalg.norm(points - points[start], axis=1)
    for _ in range(k - 1):
        i = int(np.argmax(d))
        chosen.append(i)
        d = np.minimum(d, np.linalg.norm(points - points[i], axis=1))
    return np.array(chosen), float(d.max())


class Clearance(NamedTuple):
    """One least clearance: what against what, the value (mm, negative: they overlap), which links, and where
    (the pose of each arm: "docked" or the target point it reaches, mm in the patient frame)."""

    check: str
    clearance_mm: float
    link_a: str
    link_b: str
    where: str


class ArmPoses(NamedTuple):
    """One docked arm: its name, capsules at each pose (p, n, 2, 3), radii, link names, which links pass the
    port, and each pose's label."""

    arm: str
    segments: np.ndarray
    radii: np.ndarray
    names: tuple
    through_port: np.ndarray
    poses: tuple


def _point_label(p_mm: np.ndarray) -> str:
    return f"target point ({p_mm[0]:.0f}, {p_mm[1]:.0f}, {p_mm[2]:.0f}) mm"


def arm_poses(cfg, arm, patient: np.ndarray, targets_m: np.ndarray, along_shaft_m: float) -> ArmPoses:
    """A docked arm's capsules (its setup joints', fixed, and its own, moving) docked and at each target point
    (a PSM; the ECM held at its docked aim)."""
    from surgopt.kinematics import capsules as C
    from surgopt.kinematics import suj as S
    from surgopt.kinematics.port_place import rcm_inverse
    from surgopt.robots import dvrk_links as L
    from surgopt.robots.dvrk_suj import CARTS

    frames = S.frames(CARTS[cfg.cart.model][arm.arm], arm.joints)
    suj = C.polyline_capsules(frames[:-1, :3, 3], L.SUJ_RADIUS_M, f"{arm.arm} setup joint", L.SUJ_ON_COLUMN)
    mount = frames[-2]
    base = arm.base
    if arm.arm == "ECM":
        skeleton, capsules = L.ECM_CLASSIC_FRAMES, L.ECM_CLASSIC_CAPSULES
        qs = [(arm.ecm[0], arm.ecm[1], 0.0)]
        labels = ("docked",)
    else:
        skeleton, capsules = L.PSM_CLASSIC_FRAMES, L.PSM_CLASSIC_CAPSULES
        world = targets_m @ patient[:3, :3].T + patient[:3, 3]
        local = (world - base[:3, 3]) @ base[:3, :3]
        centre = np.asarray(cfg.target.centre_mm, float) / 1000 @ patient[:3, :3].T + patient[:3, 3]
        rho = float(np.linalg.norm(centre - base[:3, 3]))
        qs = [(0.0, 0.0, rho - along_shaft_m)] + [rcm_inverse(p, along_shaft_m) for p in local]
        labels = ("docked",) + tuple(_point_label(p * 1000) for p in targets_m)
    segs = []
    for q in qs:
        own = C.capsules_at(capsules, C.skeleton(skeleton, np.asarray(q, float), base, mount))
        segs.append(C.join(suj, own._replace(names=tuple(f"{arm.arm} {n}" for n in own.names))))
    through = np.array([False] * len(suj.names) + ["base" in (c.frame_a, c.frame_b) for c in capsules])
    return ArmPoses(arm.arm, np.stack([s.segments for s in segs]), segs[0].radii, segs[0].names, through,
                    labels)


def between(a: ArmPoses, b: ArmPoses) -> tuple[Clearance, Clearance]:
    """The least clearance between two arms docked, and over every pair of their poses."""
    from surgopt.kinematics.capsules import least_over_poses, least_pair_clearance

    c0, i0, j0 = least_pair_clearance(a.segments[0], a.radii, b.segments[0], b.radii)
    docked = Clearance(f"{a.arm} and {b.arm}, docked", c0 * 1000, a.names[i0], b.names[j0], "docked")
    c, pa, pb, i, j = least_over_poses(a.segments, a.radii, b.segments, b.radii)
    moving = Clearance(f"{a.arm} and {b.arm}, over the target", c * 1000, a.names[i], b.names[j],
                       f"{a.arm} {a.poses[pa]}; {b.arm} {b.poses[pb]}")
    return docked, moving


def against_patient(cfg, a: ArmPoses, patient: np.ndarray) -> Clearance:
    """(C3) The least clearance of the arm's links (not the shafts) to the patient's body at any pose."""
    from surgopt.kinematics.capsules import along
    from surgopt.studies.port_place.geometry import body_distance_mm, inside_body

    fixed = np.all(a.segments == a.segments[:1], axis=(0, 2, 3))  # the setup joints' links: once, not per pose
    keep = np.flatnonzero(~a.through_port)
    parts = [(0, i) for i in keep if fixed[i]] + [(p, i) for p in range(len(a.poses)) for i in keep if not fixed[i]]
    pts, owner = along(np.array([a.segments[p, i] for p, i in parts]), SPACING_M)
    local_mm = ((pts - patient[:3, 3]) @ patient[:3, :3]) * 1000
    d = body_distance_mm(local_mm, cfg.patient, PATIENT_CAP_MM)
    d = np.where(inside_body(local_mm, cfg.patient), 0.0, d)
    pose, link = np.array(parts)[owner].T
    c = d - a.radii[link] * 1000
    k = int(np.argmin(c))
    note = " (inside the body)" if d[k] == 0.0 else (f" (at least: nothing within {PATIENT_CAP_MM:.0f} mm)"
                                                       if d[k] >= PATIENT_CAP_MM else "")
    return Clearance(f"{a.arm} and the patient", float(c[k]), a.names[link[k]], "patient's body",
                     f"{a.arm} {a.poses[pose[k]]}{note}")


def against_table(cfg, a: ArmPoses, patient: np.ndarray) -> Clearance:
    """(C2) The least clearance of the arm's links to the table (a slab under the patient, in its frame),
    refined on the closest link by golden-section search."""
    from surgopt.kinematics.capsules import along, box_distance, segment_box_distance

    cart = cfg.cart
    w = cart.table_half_width_mm / 1000
    lo = np.array([-w, cart.table_y_mm[0] / 1000, -TABLE_THICKNESS_M])
    hi = np.array([w, cart.table_y_mm[1] / 1000, 0.0])
    segs = (a.segments - patient[:3, 3]) @ patient[:3, :3]  # into the patient's frame
    flat = segs.reshape(-1, 2, 3)
    pts, owner = along(flat, SPACING_M)
    n = segs.shape[1]
    rough = box_distance(pts, lo, hi) - a.radii[owner % n]
    s = int(owner[np.argmin(rough)])
    d, _ = segment_box_distance(flat[s, 0], flat[s, 1], lo, hi)
    return Clearance(f"{a.arm} and the table", (d - a.radii[s % n]) * 1000, a.names[s % n], "table",
                     f"{a.arm} {a.poses[s // n]}")


def layout_clearances(cfg, row: dict, docked=None) -> list[Clearance]:
    """Every least clearance of a layout's row on the cart (its ports and cart pose): each pair of docked arms
    (docked and over the target), each arm against the patient and the table. Arms that do not dock are left
    out (their setup joints have no solution to place links at)."""
    from surgopt.studies.port_place.tables import docked_arms, model_of, patient_in_cart

    if docked is None:
        docked = docked_arms(cfg, row)
    patient = patient_in_cart(cfg.cart, row["cart_x_mm"], row["cart_y_mm"], row["cart_heading_deg"])
    model = model_of(cfg)
    start = int(np.argmin(np.linalg.norm(model.targets_m - model.centre_m, axis=1)))
    points = model.targets_m[spread_points(model.targets_m, POSE_POINTS, start)[0]]
    arms = [arm_poses(cfg, a, patient, points, model.limits.along_shaft_m) for a in docked if a.joints]
    out = []
    for i in range(len(arms)):
        for j in range(i + 1, len(arms)):
            out += between(arms[i], arms[j])
    out += [against_patient(cfg, a, patient) for a in arms]
    out += [against_table(cfg, a, patient) for a in arms]
    return out


def least(clearances: list[Clearance]) -> Clearance | None:
    return min(clearances, key=lambda c: c.clearance_mm) if clearances else None
