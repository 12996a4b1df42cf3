"""Clearance between capsules (a segment swept by a ball): the arms' links outside the body (issue 40).

A capsule's clearance to another is the distance between their segments less both radii (C1); to a convex
solid (the table) the least over the segment of a point's distance to the box less the radius, a convex function
along the segment found by golden-section search (C2); to the patient the least over points along the segment
(spacing given) of the body distance less the radius (C3, in the study: the body is not convex). An arm's
capsules at joint values q come from its skeleton (``robots/dvrk/links.py``): each frame's transform from its
parent, origin, roll-pitch-yaw and joint (C4).

The segment distance is ``kinematics.port.place.segment_distance`` (Ericson, Real-Time Collision Detection,
5.1.9, with its degenerate cases; ``segments_distance`` takes the segments as (2, 3) arrays). The least clearance between two arms over
every pair of their poses (each arm at each of its own target points: the instruments move independently) is one
jitted loop (``least_over_poses``), and pruned by bounding capsules for the rows' tables (``least_between``,
``pair_clearances``; ``studies/port_place/link_tables.py``), with their batch forms of C2-C4.

One module of ~430 lines: the exhaustive and the pruned least, the capsules' placement and their batch forms are
one geometry (the pruned kernels are held to the exhaustive one), and every caller reads them together.
"""
from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from surgopt.jit import EXACT, njit
from surgopt.kinematics.port.place import segment_distance, segment_distance_xyz
from surgopt.robots.chain import rot_x, rot_y, rot_z, trans

GOLDEN = (math.sqrt(5.0) - 1.0) / 2.0
#: How a link clearance's two links are coded in one integer (the tables' and rows' ``external_link_pair``):
#: LINK_CODE * (the first's link) + (the second's link, or what it meets), and LINK_CODE ** 2 * (the arm pair, or
#: 6 + the arm against its surroundings) + that: at most LINK_CODE links an arm (the Classic PSM's meshes' capsules
#: and its setup joints are 23). The largest code, LINK_CODE ** 2 * 10, must fit the tables' int16.
LINK_CODE = 32
PAIR_CODE = LINK_CODE * LINK_CODE


class Capsules(NamedTuple):
    """An arm's links at one pose: segments (n, 2, 3) m, radii (n,) m, and each link's name."""

    segments: np.ndarray
    radii: np.ndarray
    names: tuple


def joint_motion(axis, v: np.ndarray, prismatic: bool) -> np.ndarray:
    """(..., 4, 4) A joint's motion by each of ``v``: a slide along the unit ``axis`` (prismatic), or a turn about
    it, Rodrigues' R = I + sin v K + (1 - cos v) K^2 (K the axis's cross-product matrix)."""
    v = np.asarray(v, float)
    a = np.asarray(axis, float) / np.linalg.norm(axis)
    out = np.broadcast_to(np.eye(4), v.shape + (4, 4)).copy()
    if prismatic:
        out[..., :3, 3] = v[..., None] * a
        return out
    k = np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])
    out[..., :3, :3] = np.eye(3) + np.sin(v)[..., None, None] * k + (1.0 - np.cos(v))[..., None, None] * (k @ k)
    return out


def frame_transform(frame, q) -> np.ndarray:
    """(C4) T_parent_frame = Trans(xyz) Rz(yaw) Ry(pitch) Rx(roll) (URDF's origin) then the joint's motion by
    v = m (q_j + offset) about or along its axis (z unless given; ``joint_motion``)."""
    roll, pitch, yaw = frame.rpy_rad
    t = trans(*frame.xyz_m) @ rot_z(yaw) @ rot_y(pitch) @ rot_x(roll)
    if frame.joint >= 0:
        v = frame.multiplier * (q[frame.joint] + frame.offset_rad)
        t = t @ joint_motion(frame.axis, np.float64(v), frame.prismatic)
    return t


def skeleton(frames, q, base: np.ndarray, mount: np.ndarray | None = None) -> dict:
    """(C4) Every frame of an arm's skeleton in the world at joints q = (yaw, pitch, insertion), the arm's base
    frame (its RCM) at ``base`` (4, 4); ``mount``: the SUJ's tip (4, 4, world), as frame "mount". One arm of
    ``skeleton_batch`` (the one placement, issue 53)."""
    many = skeleton_batch(frames, np.asarray(q, float)[None], np.asarray(base, float)[None],
                          None if mount is None else np.asarray(mount, float)[None])
    return {name: t[0] for name, t in many.items()}


def capsules_at(capsules, frames: dict) -> Capsules:
    """The capsules' segments in the world from one arm's skeleton's frames (``capsules_batch`` of one)."""
    seg = capsules_batch(capsules, {name: t[None] for name, t in frames.items()})[0]
    return Capsules(seg, np.array([c.radius_m for c in capsules]), tuple(c.name for c in capsules))


@njit(**EXACT)
def least_pair_clearance(a, ra, b, rb):
    """(C1) min over i, j of |seg a_i, seg b_j| - ra_i - rb_j, and (i, j)."""
    best, bi, bj = np.inf, -1, -1
    for i in range(a.shape[0]):
        for j in range(b.shape[0]):
            c = segment_distance(a[i, 0], a[i, 1], b[j, 0], b[j, 1]) - ra[i] - rb[j]
            if c < best:
                best, bi, bj = c, i, j
    return best, bi, bj


@njit(**EXACT)
def least_over_poses(a, ra, b, rb):
    """(C1) The least clearance between arm A at each of its poses a (pa, n, 2, 3) and arm B at each of its
    poses b (pb, k, 2, 3): (clearance, pose of A, pose of B, link of A, link of B)."""
    best = np.inf
    out = (-1, -1, -1, -1)
    for p in range(a.shape[0]):
        for s in range(b.shape[0]):
            c, i, j = least_pair_clearance(a[p], ra, b[s], rb)
            if c < best:
                best = c
                out = (p, s, i, j)
    return best, out[0], out[1], out[2], out[3]


def box_distance(p: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Distance (m) of points (..., 3) to the axis-aligned box [lo, hi] (0 inside)."""
    d = np.maximum(np.maximum(lo - p, p - hi), 0.0)
    return np.sqrt((d * d).sum(axis=-1))


def segment_box_distance(p0: np.ndarray, p1: np.ndarray, lo: np.ndarray, hi: np.ndarray,
                         iterations: int = 60) -> tuple[float, float]:
    """(C2) The least distance from the segment [p0, p1] to the box and where (t in [0, 1]): the distance to a
    convex set is convex along a line, so golden-section search finds it (to GOLDEN^iterations of the length)."""
    f = lambda t: float(box_distance(p0 + t * (p1 - p0), lo, hi))
    a, b = 0.0, 1.0
    c, d = b - GOLDEN * (b - a), a + GOLDEN * (b - a)
    fc, fd = f(c), f(d)
    for _ in range(iterations):
        if fc <= fd:
            b, d, fd = d, c, fc
            c = b - GOLDEN * (b - a)
            fc = f(c)
        else:
            a, c, fc = c, d, fd
            d = a + GOLDEN * (b - a)
            fd = f(d)
    best = min((f(0.0), 0.0), (f(1.0), 1.0), (f((a + b) / 2), (a + b) / 2))
    return best


def along(segments: np.ndarray, spacing_m: float) -> tuple[np.ndarray, np.ndarray]:
    """Points along each segment at most ``spacing_m`` apart (both ends included) and each point's segment:
    a least distance over them over-reads the segment's by at most spacing_m / 2 (C3)."""
    pts, owner = [], []
    for i, (p0, p1) in enumerate(segments):
        n = max(2, math.ceil(np.linalg.norm(p1 - p0) / spacing_m) + 1)
        t = np.linspace(0.0, 1.0, n)[:, None]
        pts.append(p0 + t * (p1 - p0))
        owner.append(np.full(n, i))
    return np.concatenate(pts), np.concatenate(owner)


# ---- the least clearance between two arms, pruned (issue 40: the links' clearance in every row)
#
# An arm at many poses is bounded link by link by a capsule holding that link at every pose of a group of poses
# (``swept_capsules``: the group's mean segment, its radius the link's plus the farthest any endpoint strays from
# the mean's; a point at parameter t of a posed segment lies within that of the mean's point at t, the distance
# being convex in t). A long link that turns a little is held far tighter so than by a ball about it (#54 item 3:
# the whole target's 915 points, ~1 s a layout with balls, ~20 ms with capsules). The least clearance between two
# arms (``least_between``) visits link pairs in the order of their bound and stops when a bound is no better than
# the least found, and within a link pair skips each group of one arm whose capsule's distance to the other's
# already bounds it out. The answer is the exact least (the bounds are lower bounds, never estimates): held to
# ``least_over_poses`` by tests/test_link_tables.py.

#: A swept capsule's layout: the two endpoints (6), then the radius.
SWEPT = 7


@njit(**EXACT)
def swept_capsules(segs, radii, groups):
    """(L, G, 7) Per link of an arm at poses ``segs`` (P, L, 2, 3) and per group of poses (``groups`` (G + 1,):
    group g is poses groups[g] .. groups[g + 1] - 1): a capsule (two endpoints, radius) holding the link's capsule
    at every pose of the group: the group's mean segment, its radius the link's plus the farthest an endpoint lies
    from the mean's."""
    n_link, n_group = segs.shape[1], groups.shape[0] - 1
    out = np.empty((n_link, n_group, SWEPT))
    for k in range(n_link):
        for g in range(n_group):
            mean = np.zeros((2, 3))
            for p in range(groups[g], groups[g + 1]):
                mean += segs[p, k]
            mean /= max(groups[g + 1] - groups[g], 1)
            far = 0.0
            for p in range(groups[g], groups[g + 1]):
                for e in range(2):
                    far = max(far, math.sqrt(((segs[p, k, e] - mean[e]) ** 2).sum()))
            out[k, g, :3], out[k, g, 3:6] = mean[0], mean[1]
            out[k, g, 6] = far + radii[k]
    return out


@njit(**EXACT)
def whole_capsules(caps):
    """(L, 7) One capsule per link holding its groups' capsules (``swept_capsules``): their mean segment, its
    radius the farthest a group's endpoint lies from it plus that group's radius."""
    n_link, n_group = caps.shape[0], caps.shape[1]
    out = np.empty((n_link, SWEPT))
    for k in range(n_link):
        mean = np.zeros(6)
        for g in range(n_group):
            mean += caps[k, g, :6]
        mean /= max(n_group, 1)
        far = 0.0
        for g in range(n_group):
            stray = max(math.sqrt(((caps[k, g, :3] - mean[:3]) ** 2).sum()),
                        math.sqrt(((caps[k, g, 3:6] - mean[3:6]) ** 2).sum()))
            far = max(far, stray + caps[k, g, 6])
        out[k, :6] = mean
        out[k, 6] = far
    return out


@njit(**EXACT)
def point_segment_distance(x, p0, p1):
    """The distance from point x to the segment [p0, p1]."""
    d = p1 - p0
    dd = (d * d).sum()
    t = 0.0 if dd == 0.0 else min(1.0, max(0.0, ((x - p0) * d).sum() / dd))
    return math.sqrt(((p0 + t * d - x) ** 2).sum())


@njit(**EXACT)
def segments_distance(p, q):
    """The shortest distance between segments p (2, 3) and q (2, 3), either possibly of zero length
    (``place.segment_distance_xyz``)."""
    return segment_distance_xyz(p[0, 0], p[0, 1], p[0, 2], p[1, 0], p[1, 1], p[1, 2],
                                q[0, 0], q[0, 1], q[0, 2], q[1, 0], q[1, 1], q[1, 2])


@njit(**EXACT)
def _gap(x, y):
    """The least clearance two swept capsules (endpoints, radius) allow: a lower bound of their contents'."""
    return segment_distance_xyz(x[0], x[1], x[2], x[3], x[4], x[5], y[0], y[1], y[2], y[3], y[4], y[5]) - x[6] - y[6]


@njit(**EXACT)
def least_between(a, ra, balls_a, groups_a, b, rb, balls_b, groups_b, best, floor=-np.inf):
    """(C1, pruned) The least clearance between arm A at each of its poses ``a`` (Pa, La, 2, 3) and arm B at each
    of ``b`` (Pb, Lb, 2, 3), radii ``ra``, ``rb``, their ``swept_capsules`` over the pose groups ``groups_*``
    (``balls_*``), if less than ``best``: (clearance, link of A, link of B, pose of A, pose of B), or (best, -1, -1,
    -1, -1) when no pair is closer than ``best``. Link pairs are visited in the order of their whole capsules'
    bound, and a group of poses, then a pair of groups, is skipped when its capsules' bound is no better than the
    least found (each bound a lower bound, so the answer is exact). With a ``floor``, the search stops at the first
    clearance below it (then an upper bound of the least)."""
    la, lb = a.shape[1], b.shape[1]
    wa, wb = whole_capsules(balls_a), whole_capsules(balls_b)
    bound = np.empty(la * lb)
    for i in range(la):
        for j in range(lb):
            bound[i * lb + j] = _gap(wa[i], wb[j])
    order = np.argsort(bound)
    out = (-1, -1, -1, -1)
    for o in order:
        if bound[o] >= best:
            break
        i, j = o // lb, o % lb
        for ga in range(groups_a.shape[0] - 1):
            if _gap(balls_a[i, ga], wb[j]) >= best:
                continue
            for gb in range(groups_b.shape[0] - 1):
                if _gap(balls_a[i, ga], balls_b[j, gb]) >= best:
                    continue
                for p in range(groups_a[ga], groups_a[ga + 1]):
                    for s in range(groups_b[gb], groups_b[gb + 1]):
                        c = segments_distance(a[p, i], b[s, j]) - ra[i] - rb[j]
                        if c < best:
                            best = c
                            out = (i, j, p, s)
                            if best < floor:
                                return best, out[0], out[1], out[2], out[3]
    return best, out[0], out[1], out[2], out[3]


@njit(**EXACT)
def pair_clearances(tasks, static_x, moving_x, r_sx, r_mx, balls_mx, static_y, moving_y, r_sy, r_my, balls_my,
                    groups, start, start_code, floor):
    """The least clearance between arm X at site i and arm Y at site j, cart pose p, for each task (i, j, p) of
    ``tasks`` (T, 3): each arm is its links fixed at that pose (``static_*`` (sites, poses, Ls, 2, 3): the setup
    joints' links, or all of an arm held docked) and its links that move over the target (``moving_*`` (sites,
    P, Lm, 2, 3), ``balls_m*`` their ``swept_capsules`` over the pose ``groups`` per site; Lm may be 0), the least of fixed to fixed, fixed
    to moving and moving to fixed, below ``start`` (T,: moving to moving, which does not depend on the cart's
    pose, given by the caller; the cap when none) with its ``start_code``, stopping at the first below ``floor``
    (``least_between``). Returns the clearance (m) and the link pair, LINK_CODE * (X's link) + (Y's link), each arm's
    links numbered fixed first, then moving (-1: none below the start).""" 
    n_task = tasks.shape[0]
    value = np.empty(n_task)
    code = np.empty(n_task, dtype=np.int64)
    fx, fy = static_x.shape[2], static_y.shape[2]
    one = np.array([0, 1])
    for t in range(n_task):
        i, j, p = tasks[t, 0], tasks[t, 1], tasks[t, 2]
        sx, sy = static_x[i, p:p + 1], static_y[j, p:p + 1]
        bx, by = swept_capsules(sx, r_sx, one), swept_capsules(sy, r_sy, one)
        best, c = start[t], start_code[t]
        v, a, b, _, _ = least_between(sx, r_sx, bx, one, sy, r_sy, by, one, best, floor)
        if a >= 0:
            best, c = v, LINK_CODE * a + b
        if moving_y.shape[2] > 0 and best >= floor:
            v, a, b, _, _ = least_between(sx, r_sx, bx, one, moving_y[j], r_my, balls_my[j], groups, best, floor)
            if a >= 0:
                best, c = v, LINK_CODE * a + fy + b
        if moving_x.shape[2] > 0 and best >= floor:
            v, a, b, _, _ = least_between(moving_x[i], r_mx, balls_mx[i], groups, sy, r_sy, by, one, best, floor)
            if a >= 0:
                best, c = v, LINK_CODE * (fx + a) + b
        value[t], code[t] = best, c
    return value, code


@njit(**EXACT)
def moving_pairs(pairs, moving_a, balls_a, moving_b, balls_b, radii, groups, cap, floor):
    """The least clearance between one arm's moving links at site i (``moving_a``, its ``balls_a``) and another's
    at site j (``moving_b``: the same arrays when both arms dock in the same frames) over every pair of their
    poses (``least_between`` below ``cap``, stopping below ``floor``), for each (i, j) of ``pairs`` (U, 2):
    (clearance m, link of i, link of j; -1 when none is below the cap)."""
    n = pairs.shape[0]
    value = np.empty(n)
    links = np.empty((n, 2), dtype=np.int64)
    for u in range(n):
        i, j = pairs[u, 0], pairs[u, 1]
        v, a, b, _, _ = least_between(moving_a[i], radii, balls_a[i], groups, moving_b[j], radii, balls_b[j], groups,
                                      cap, floor)
        value[u], links[u, 0], links[u, 1] = v, a, b
    return value, links


def skeleton_batch(frames, q: np.ndarray, base: np.ndarray, mount: np.ndarray | None = None) -> dict:
    """(C4) ``skeleton`` for N arms at once: q (N, 3), base and mount (N, 4, 4); each frame (N, 4, 4)."""
    out = {"base": np.asarray(base, float)}
    if mount is not None:
        out["mount"] = np.asarray(mount, float)
    for f in frames:
        t = out[f.parent] @ frame_transform(f._replace(joint=-1), None)  # the origin; the joint per arm below
        if f.joint >= 0:
            t = t @ joint_motion(f.axis, f.multiplier * (q[:, f.joint] + f.offset_rad), f.prismatic)
        out[f.name] = t
    return out


def capsules_batch(capsules, frames: dict) -> np.ndarray:
    """(N, L, 2, 3) The capsules' segments from ``skeleton_batch``'s frames."""
    n = len(next(iter(frames.values())))
    seg = np.empty((n, len(capsules), 2, 3))
    for i, c in enumerate(capsules):
        for e, (name, point) in enumerate(((c.frame_a, c.point_a_m), (c.frame_b, c.point_b_m))):
            t = frames[name]
            seg[:, i, e] = t[:, :3, :3] @ np.asarray(point, float) + t[:, :3, 3]
    return seg


@njit(**EXACT)
def along_many(segs, spacing_m):
    """``along`` jitted: points along each of ``segs`` (k, 2, 3) at most ``spacing_m`` apart (both ends) and
    each point's segment."""
    k = segs.shape[0]
    counts = np.empty(k, dtype=np.int64)
    for i in range(k):
        length = math.sqrt(((segs[i, 1] - segs[i, 0]) ** 2).sum())
        counts[i] = max(2, int(math.ceil(length / spacing_m)) + 1)
    pts = np.empty((counts.sum(), 3))
    owner = np.empty(counts.sum(), dtype=np.int64)
    o = 0
    for i in range(k):
        n = counts[i]
        for s in range(n):
            t = s / (n - 1)
            pts[o] = segs[i, 0] + t * (segs[i, 1] - segs[i, 0])
            owner[o] = i
            o += 1
    return pts, owner


@njit(**EXACT)
def _box_gap(x, lo, hi):
    s = 0.0
    for c in range(3):
        d = max(max(lo[c] - x[c], x[c] - hi[c]), 0.0)
        s += d * d
    return math.sqrt(s)


@njit(**EXACT)
def segments_box_distance(segs, lo, hi):
    """(C2) ``segment_box_distance`` of each of ``segs`` (k, 2, 3), jitted: golden-section search along the
    segment (60 steps), the ends and the bracket's middle kept."""
    out = np.empty(segs.shape[0])
    for k in range(segs.shape[0]):
        p0, d = segs[k, 0], segs[k, 1] - segs[k, 0]
        a, b = 0.0, 1.0
        c, e = b - GOLDEN * (b - a), a + GOLDEN * (b - a)
        fc, fe = _box_gap(p0 + c * d, lo, hi), _box_gap(p0 + e * d, lo, hi)
        for _ in range(60):
            if fc <= fe:
                b, e, fe = e, c, fc
                c = b - GOLDEN * (b - a)
                fc = _box_gap(p0 + c * d, lo, hi)
            else:
                a, c, fc = c, e, fe
                e = a + GOLDEN * (b - a)
                fe = _box_gap(p0 + e * d, lo, hi)
        out[k] = min(_box_gap(p0, lo, hi), min(_box_gap(p0 + d, lo, hi), _box_gap(p0 + 0.5 * (a + b) * d, lo, hi)))
    return out
