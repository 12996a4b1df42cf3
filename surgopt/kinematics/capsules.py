"""Clearance between capsules (a segment swept by a ball): the arms' links outside the body (issue 40).

A capsule's clearance to another is the distance between their segments less both radii (C1); to a convex
solid (the table) the least over the segment of a point's distance to the box less the radius, a convex function
along the segment found by golden-section search (C2); to the patient the least over points along the segment
(spacing given) of the body distance less the radius (C3, in the study: the body is not convex). An arm's
capsules at joint values q come from its skeleton (``robots/dvrk_links.py``): each frame's transform from its
parent, origin, roll-pitch-yaw and joint (C4).

The segment distance is ``kinematics.port_place.segment_distance`` (Ericson, Real-Time Collision Detection,
5.1.9). The least clearance between two arms over every pair of their poses (each arm at each of its own
target points: the instruments move independently) is one jitted loop (``least_over_poses``).
"""
from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from surgopt.jit import EXACT, njit
from surgopt.kinematics.port_place import segment_distance
from surgopt.robots.chain import rot_x, rot_y, rot_z, trans

GOLDEN = (math.sqrt(5.0) - 1.0) / 2.0


class Capsules(NamedTuple):
    """An arm's links at one pose: segments (n, 2, 3) m, radii (n,) m, and each link's name."""

    segments: np.ndarray
    radii: np.ndarray
    names: tuple


def frame_transform(frame, q) -> np.ndarray:
    """(C4) T_parent_frame = Trans(xyz) Rz(yaw) Ry(pitch) Rx(roll) (URDF's origin) then Rz(m q_j) (revolute) or
    Tz(m q_j) (prismatic)."""
    roll, pitch, yaw = frame.rpy_rad
    t = trans(*frame.xyz_m) @ rot_z(yaw) @ rot_y(pitch) @ rot_x(roll)
    if frame.joint >= 0:
        v = frame.multiplier * q[frame.joint]
        t = t @ (trans(0.0, 0.0, v) if frame.prismatic else rot_z(v))
    return t


def skeleton(frames, q, base: np.ndarray, mount: np.ndarray | None = None) -> dict:
    """(C4) Every frame of an arm's skeleton in the world at joints q = (yaw, pitch, insertion), the arm's base
    frame (its RCM) at ``base`` (4, 4); ``mount``: the SUJ's tip (4, 4, world), as frame "mount"."""
    out = {"base": np.asarray(base, float)}
    if mount is not None:
        out["mount"] = np.asarray(mount, float)
    for f in frames:
        out[f.name] = out[f.parent] @ frame_transform(f, q)
    return out


def capsules_at(capsules, frames: dict) -> Capsules:
    """The capsules' segments in the world from the skeleton's frames."""
    seg = np.empty((len(capsules), 2, 3))
    for i, c in enumerate(capsules):
        seg[i, 0] = frames[c.frame_a][:3, :3] @ c.point_a_m + frames[c.frame_a][:3, 3]
        seg[i, 1] = frames[c.frame_b][:3, :3] @ c.point_b_m + frames[c.frame_b][:3, 3]
    return Capsules(seg, np.array([c.radius_m for c in capsules]), tuple(c.name for c in capsules))


def polyline_capsules(points: np.ndarray, radius_m: float, name: str, skip: int = 0) -> Capsules:
    """A chain of points (a setup joint's frame origins) as capsules between successive points, the first
    ``skip`` segments and any of zero length left out."""
    seg = np.stack([points[:-1], points[1:]], axis=1)[skip:]
    keep = np.linalg.norm(seg[:, 1] - seg[:, 0], axis=1) > 1e-9
    idx = np.flatnonzero(keep) + skip
    return Capsules(seg[keep], np.full(int(keep.sum()), radius_m), tuple(f"{name} link {i + 1}" for i in idx))


def join(*parts: Capsules) -> Capsules:
    return Capsules(np.concatenate([p.segments for p in parts]), np.concatenate([p.radii for p in parts]),
                    sum((p.names for p in parts), ()))


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
