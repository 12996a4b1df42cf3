"""Port placement with instruments held by serial arms that keep the RCM in software (issue #29: "the RCM
inverse kinematics (closed form for yaw/pitch/insertion mechanisms, the generic serial solver otherwise)").

Kernels only; arrays and named tuples in, arrays out; lengths in m. An arm (any serial chain reduced to five
active joints, ``surgopt/robots/chain.py``, with the tool along its tip frame's z) keeps the remote centre of
motion at a fixed point ``rcm`` of its base frame (where rcm-grid puts it), and its base stands so that this
point is the port: base origin o = site - R rcm, R the base's turn about the vertical (``serial_base_frames``).
A target point p is then, in the base frame, R^T (p - site) + rcm, and the arm reaches it when the five
RCM-constrained equations of ``serial_chain`` (tip on p, tool line through the RCM) have a solution within the
joint limits with the RCM on the tool, between the tip and the flange (0 < (p - rcm) . k <= the tool's
length past the flange, k the tool's axis toward the tip).

Which solution: the five equations in five joints have isolated solutions (the elbow up or down, the wrist
flipped); the arm stays on the branch its ``seed`` (then the seed's fixed restarts) reaches at the target
point nearest the target's centre, the *docked pose*. From there every other point is reached by
continuation (``serial_chain.continue_walk``: tangent predictor, Newton corrector, steps of at most 5 mm)
from the nearest point already visited (Prim's order over the target points, ``prim_order``, the same for
every port since the base frames are rigid turns), and failing that straight from the docked pose. A point
neither reaches is unreachable (the seeded branch's reach, as in rcm-grid).

Dexterity at a reached point: sigma_min / sigma_max of the RCM metric's constrained Jacobian B (Locke & Patel
2007 eqs. 5-8, columns scaled by the rated joint speeds, ``rcm_metric.constrained_extremes``): 1 when the tip
moves equally easily in every direction, dimensionless, no characteristic length.

Outside the body the arms are their links' centre lines at the docked pose: base, each active joint's origin,
the flange, the port (``link_polylines``); two arms' clearance is the least distance between their polylines
(``link_clearances``), an arm's and an RCM camera arm's the least distance between its polyline and the
camera's shaft line behind its port (``link_camera_clearances``).
"""
from __future__ import annotations

import math

import numpy as np

from surgopt.jit import CONTRACT, EXACT, njit
from surgopt.kinematics.port.place import segment_distance
from surgopt.kinematics.serial_chain import (
    N_ACTIVE, chain_frames, constraint_reference, continue_walk, newton_rcm, pose_extremes_from_jacobian,
    scalar_buffers, seed_solve, within_limits,
)


def serial_base_frames(sites, centre, rcm, yaw_offset_rad):
    """(rotations (n, 3, 3), origins (n, 3)) of each arm's base, its z up: turned about the vertical so that the
    RCM's horizontal direction from the base points from the port toward the target's vertical axis (the arm
    stands outside the port, radially), then by ``yaw_offset_rad`` (one angle, or one per site); placed so that the RCM ``rcm`` (base frame)
    is the port. A port within 1 mm of the target's axis is reached along +x (the arm on the patient's right)."""
    sites = np.asarray(sites, float)
    inward = np.asarray(centre, float)[None, :2] - sites[:, :2]
    norm = np.hypot(inward[:, 0], inward[:, 1])
    heading = np.where(norm > 1e-3, np.arctan2(inward[:, 1], inward[:, 0]), 0.0)
    yaw = heading - math.atan2(rcm[1], rcm[0]) + yaw_offset_rad
    c, s = np.cos(yaw), np.sin(yaw)
    rot = np.zeros((len(sites), 3, 3))
    rot[:, 0, 0], rot[:, 0, 1], rot[:, 1, 0], rot[:, 1, 1], rot[:, 2, 2] = c, -s, s, c, 1.0
    origins = sites - rot @ np.asarray(rcm, float)
    return rot, origins


@njit(**EXACT)
def prim_order(points, root):
    """(order, parent) of Prim's minimum spanning tree over ``points`` from ``root``: each point in the order
    after the first is attached to its nearest point earlier in the order (``parent``; -1 for the root), so a
    continuation from the parent's solution is the shortest step the visited points allow. O(m^2)."""
    m = points.shape[0]
    best = np.full(m, np.inf)
    parent = np.full(m, -1, np.int64)
    done = np.zeros(m, np.bool_)
    order = np.empty(m, np.int64)
    best[root] = 0.0
    for step in range(m):
        k = -1
        for j in range(m):
            if not done[j] and (k < 0 or best[j] < best[k]):
                k = j
        order[step] = k
        done[k] = True
        for j in range(m):
            if not done[j]:
                d = ((points[j, 0] - points[k, 0]) ** 2 + (points[j, 1] - points[k, 1]) ** 2
                     + (points[j, 2] - points[k, 2]) ** 2)
                if d < best[j]:
                    best[j], parent[j] = d, k
    return order, parent


@njit(**CONTRACT)
def tool_holds_rcm(rot, pos, prismatic, q, c, tool_m, bufs):
    """Whether the RCM lies on the tool at joints ``q``: 0 < (tip - c) . k <= tool_m (k the tool axis toward
    the tip), i.e. behind the tip and ahead of the flange, not on the tool's line beyond either end."""
    axes, origins, jac, res, step, work, trig = bufs
    r = chain_frames(rot, pos, prismatic, q, axes, origins, trig)
    s = (r[9] - c[0]) * r[2] + (r[10] - c[1]) * r[5] + (r[11] - c[2]) * r[8]
    return 0.0 < s <= tool_m


@njit(**CONTRACT)
def _reach_from(chain_arrays, q, q_from, at, c, ref, end, tool_m, bufs):
    """Continue from the solution ``q_from`` at base point ``at`` to c + ``end``; True with ``q`` the solution
    when it converges within the limits with the RCM on the tool (``bufs``' Jacobian then the one there)."""
    rot, pos, prismatic, lower, upper, qdot_max = chain_arrays
    axes, origins, jac, res, step, work, trig = bufs
    target = at.copy()
    for i in range(N_ACTIVE):
        q[i] = q_from[i]
    newton_rcm(rot, pos, prismatic, q, target, c, ref, 0, bufs)
    if continue_walk(rot, pos, prismatic, q, target, c, ref, end, bufs) < 0:
        return False
    if not within_limits(q, prismatic, lower, upper):
        return False
    return tool_holds_rcm(rot, pos, prismatic, q, c, tool_m, bufs)  # (it leaves the Jacobian as it is)


#: Target points tried for the seed solve, spread over Prim's order from the centre (the first that solves
#: anchors the branch).
ANCHOR_TRIES = 32


@njit(**CONTRACT)
def _anchor(chain_arrays, seed, restarts, c, tool_m, pts, order, ref, q, bufs):
    """The first of ``ANCHOR_TRIES`` target points (base frame ``pts``), taken evenly along ``order`` from the
    point nearest the centre, that the seed (or a restart) solves within the limits with the RCM on the tool:
    its index, ``q`` its solution; -1 when none does."""
    rot, pos, prismatic, lower, upper, qdot_max = chain_arrays
    m = order.shape[0]
    stride = max(1, m // ANCHOR_TRIES)
    for idx in range(0, m, stride):
        target = pts[order[idx]].copy()
        if seed_solve(rot, pos, prismatic, lower, upper, seed, restarts, target, c, ref, q, bufs) and \
                tool_holds_rcm(rot, pos, prismatic, q, c, tool_m, bufs):
            return order[idx]
    return -1


@njit(**CONTRACT)
def serial_instrument_tables(chain_arrays, seed, restarts, rcm, tool_m, base_rot, base_pos, targets, order, parent,
                             usable, q_out):
    """(reach[site, point], dexterity[site, point]) of a serial arm whose base stands at each port (``base_rot``,
    ``base_pos``: ``serial_base_frames``), on the seeded branch (module docstring); ``q_out`` (n, m, 5) gets the
    joints (NaN where unreached). ``order``/``parent``: ``prim_order`` of the target points from the docked
    pose's point ``order[0]``. A site not ``usable`` (its base inside the body) reaches nothing."""
    rot, pos, prismatic, lower, upper, qdot_max = chain_arrays
    n, m = base_pos.shape[0], targets.shape[0]
    reach = np.zeros((n, m), np.bool_)
    dex = np.zeros((n, m))
    q_out[:] = np.nan
    bufs = scalar_buffers()
    q = np.empty(N_ACTIVE)
    pts = np.empty((m, 3))
    for i in range(n):
        if not usable[i]:
            continue
        r, o = base_rot[i], base_pos[i]
        for k in range(m):
            d0, d1, d2 = targets[k, 0] - o[0], targets[k, 1] - o[1], targets[k, 2] - o[2]
            pts[k, 0] = r[0, 0] * d0 + r[1, 0] * d1 + r[2, 0] * d2
            pts[k, 1] = r[0, 1] * d0 + r[1, 1] * d1 + r[2, 1] * d2
            pts[k, 2] = r[0, 2] * d0 + r[1, 2] * d1 + r[2, 2] * d2
        ref = constraint_reference(pts[order[0]] - rcm)
        anchor = _anchor(chain_arrays, seed, restarts, rcm, tool_m, pts, order, ref, q, bufs)
        if anchor < 0:
            continue
        q0 = q.copy()
        for idx in range(m):
            k = order[idx]
            par = parent[k]
            ok = False
            if par >= 0 and reach[i, par]:
                ok = _reach_from(chain_arrays, q, q_out[i, par], pts[par], rcm, ref, pts[k] - rcm, tool_m, bufs)
            if not ok:
                ok = _reach_from(chain_arrays, q, q0, pts[anchor], rcm, ref, pts[k] - rcm, tool_m, bufs)
            if not ok:
                continue
            reach[i, k] = True
            for j in range(N_ACTIVE):
                q_out[i, k, j] = q[j]
            smin2, smax2, singular = pose_extremes_from_jacobian(bufs.jac, qdot_max)
            dex[i, k] = 0.0 if singular or smax2 <= 0.0 else math.sqrt(smin2 / smax2)
    return reach, dex


#: Points of an arm's centre line: the base, the five active joints' origins, the flange, the port.
LINE_POINTS = N_ACTIVE + 3


@njit(**CONTRACT)
def link_polylines(chain_arrays, q_dock, tool_m, rcm, base_rot, base_pos):
    """(n, LINE_POINTS, 3) centre lines of the arms at their docked joints ``q_dock`` (n, 5), in the patient frame:
    the base's origin, the five active joints' origins, the flange (``tool_m`` back from the tip along the tool),
    the port (the RCM, where the tool enters). An arm without a docked pose (NaN joints) gets NaN."""
    rot, pos, prismatic, lower, upper, qdot_max = chain_arrays
    n = q_dock.shape[0]
    out = np.full((n, LINE_POINTS, 3), np.nan)
    axes = np.empty((N_ACTIVE, 3))
    origins = np.empty((N_ACTIVE, 3))
    trig = np.zeros((4, N_ACTIVE))
    trig[2, :] = np.nan
    local = np.empty((LINE_POINTS, 3))
    for i in range(n):
        if not np.isfinite(q_dock[i, 0]):
            continue
        r = chain_frames(rot, pos, prismatic, q_dock[i], axes, origins, trig)
        local[0] = 0.0
        local[1:N_ACTIVE + 1] = origins
        local[N_ACTIVE + 1, 0] = r[9] - tool_m * r[2]
        local[N_ACTIVE + 1, 1] = r[10] - tool_m * r[5]
        local[N_ACTIVE + 1, 2] = r[11] - tool_m * r[8]
        local[N_ACTIVE + 2] = rcm
        for k in range(LINE_POINTS):
            for a in range(3):
                out[i, k, a] = (base_rot[i, a, 0] * local[k, 0] + base_rot[i, a, 1] * local[k, 1]
                                + base_rot[i, a, 2] * local[k, 2] + base_pos[i, a])
    return out


@njit(**EXACT)
def _real_segments(lines):
    """[arm, segment]: whether the segment has a length (a joint origin on the one before is a point, already
    an end of a neighbouring segment)."""
    n, p = lines.shape[0], lines.shape[1]
    real = np.zeros((n, p - 1), np.bool_)
    for i in range(n):
        for a in range(p - 1):
            d = lines[i, a + 1] - lines[i, a]
            real[i, a] = d[0] ** 2 + d[1] ** 2 + d[2] ** 2 > 1e-18
    return real


@njit(**EXACT)
def link_clearances(lines):
    """(n, n) least distance between two arms' centre lines (``link_polylines``), entries i < j filled (as
    ``place.pair_tables``' outside); 0 where either arm has no docked pose."""
    n, p = lines.shape[0], lines.shape[1]
    out = np.zeros((n, n))
    real = _real_segments(lines)
    for i in range(n):
        for j in range(i + 1, n):
            if not (np.isfinite(lines[i, 0, 0]) and np.isfinite(lines[j, 0, 0])):
                continue
            best = np.inf
            for a in range(p - 1):
                for b in range(p - 1):
                    if real[i, a] and real[j, b]:
                        best = min(best, segment_distance(lines[i, a], lines[i, a + 1], lines[j, b], lines[j, b + 1]))
            out[i, j] = best
    return out


@njit(**EXACT)
def polyline_clearances(a, b):
    """[i, k]: least distance between arm centre line ``a[i]`` and ``b[k]`` (two sets of ``link_polylines``, e.g.
    the instrument arms' and the camera arm's), i != k; 0 where either has no docked pose or i == k."""
    n = a.shape[0]
    out = np.zeros((n, n))
    real_a, real_b = _real_segments(a), _real_segments(b)
    for i in range(n):
        if not np.isfinite(a[i, 0, 0]):
            continue
        for k in range(n):
            if k == i or not np.isfinite(b[k, 0, 0]):
                continue
            best = np.inf
            for s in range(a.shape[1] - 1):
                for t in range(b.shape[1] - 1):
                    if real_a[i, s] and real_b[k, t]:
                        best = min(best, segment_distance(a[i, s], a[i, s + 1], b[k, t], b[k, t + 1]))
            out[i, k] = best
    return out


@njit(**EXACT)
def link_camera_clearances(lines, sites, axes, length_m):
    """[instrument site, camera site]: least distance between the serial arm's centre line at the first and the
    camera arm's shaft line continued ``length_m`` behind its port along ``axes`` (unit, outward) at the second
    (``place.external_clearances``' segment); 0 where the arm has no docked pose, or the two share a site."""
    n, p = lines.shape[0], lines.shape[1]
    out = np.zeros((n, n))
    real = _real_segments(lines)
    for i in range(n):
        if not np.isfinite(lines[i, 0, 0]):
            continue
        for k in range(n):
            if k == i:
                continue
            far = sites[k] + length_m * axes[k]
            best = np.inf
            for a in range(p - 1):
                if real[i, a]:
                    best = min(best, segment_distance(lines[i, a], lines[i, a + 1], far, sites[k]))
            out[i, k] = best
    return out


@njit(**EXACT)
def nearest_distances(points, surface, cap):
    """Per point (n, 3): the distance to the nearest of the ``surface`` samples (m, 3), or ``cap`` when the
    point lies farther than ``cap`` outside the samples' bounding box (no sample can be nearer than that).
    Brute force over the samples for the rest."""
    lo = np.empty(3)
    hi = np.empty(3)
    for a in range(3):
        lo[a] = surface[:, a].min() - cap
        hi[a] = surface[:, a].max() + cap
    out = np.full(points.shape[0], cap)
    for i in range(points.shape[0]):
        x, y, z = points[i, 0], points[i, 1], points[i, 2]
        if not (lo[0] <= x <= hi[0] and lo[1] <= y <= hi[1] and lo[2] <= z <= hi[2]):
            continue
        best = cap * cap
        for k in range(surface.shape[0]):
            d = (surface[k, 0] - x) ** 2 + (surface[k, 1] - y) ** 2 + (surface[k, 2] - z) ** 2
            if d < best:
                best = d
        out[i] = math.sqrt(best)
    return out
