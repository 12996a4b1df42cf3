"""Docking an arm on the Si cart (issue 40: "where the SUJ cannot give every orientation (Si), the reachable docking
orientations follow from the SUJ and the PSM's own joints must absorb the rest").

The Si's setup joints set only the yaw psi of the arm's base about the vertical (S3, ``suj.si_orientation``):

    R(psi) = R_W Rz(psi) R_G R_tip,                                                             (S5)

so with the RCM on the port, the arm's neutral shaft -z_base points along R(psi) (0, 0, -1) and cannot be aimed
at the target's centre in general. The arm's own yaw q1 and pitch q2 absorb the rest: in the base frame the
aim a (a unit vector from the port toward the centre) is a_b = R(psi)^T a, and (P2, ``place.rcm_inverse``)
q2 = -asin(a_b,y), q1 = atan2(a_b,x, -a_b,z). The angle they absorb, between the neutral shaft and the aim, is
least at the yaw that brings the neutral shaft's horizontal part onto the aim's (S6):

    v = R_G R_tip (0, 0, -1),  e = R_W^T a,  psi* = atan2(e_y, e_x) - atan2(v_y, v_x),
    least absorbed angle = |asin(v_z) - asin(e_z)|  (the two directions' elevations).

The study docks each arm at psi* (or psi* turned by a stated yaw, ``si_frame``) and solves the setup joints there
for many poses at once (``si_solutions``, S3, S7). A search over every yaw of a whole turn, each kept where the SUJ
solves within its ranges and q1, q2 within the arm's, is the plain twin in ``tests/reference.py`` (``si_docking``).
All in the cart's world frame, metres and radians.
"""
from __future__ import annotations

import math

import numpy as np

from surgopt.kinematics.port import suj as S


def neutral_shaft(suj) -> np.ndarray:
    """v = R_G R_tip (0, 0, -1): the arm's neutral shaft in the frame after the planar chain's yaw (S6)."""
    g = np.eye(4)
    for row in suj.fixed:
        g = g @ S.link(row, 0.0)
    return g[:3, :3] @ np.asarray(suj.tip_to_tool, float)[:3, :3] @ np.array([0.0, 0.0, -1.0])


def least_absorbed(suj, aim: np.ndarray) -> tuple[float, float]:
    """(psi*, the least angle the arm's own joints absorb) for a unit ``aim`` in the cart's world (S6)."""
    v = neutral_shaft(suj)
    e = np.asarray(suj.world_to_suj, float)[:3, :3].T @ (aim / np.linalg.norm(aim))
    psi = math.atan2(e[1], e[0]) - math.atan2(v[1], v[0])
    return S.wrap(psi), abs(math.asin(max(-1.0, min(1.0, v[2]))) - math.asin(max(-1.0, min(1.0, e[2]))))


def own_joints(base_rot: np.ndarray, aim: np.ndarray) -> tuple[float, float, float]:
    """(q1, q2, the absorbed angle) that point the shaft along ``aim`` from a base of rotation ``base_rot`` (P2)."""
    a = base_rot.T @ (aim / np.linalg.norm(aim))
    q2 = -math.asin(max(-1.0, min(1.0, a[1])))
    q1 = math.atan2(a[0], -a[2])
    return q1, q2, math.acos(max(-1.0, min(1.0, -a[2])))


def si_frame(suj, aim: np.ndarray, turn_rad: float = 0.0) -> np.ndarray:
    """(3, 3) The base's rotation (cart world) at psi* (S6) for a unit ``aim`` in the cart's world: the Si docking
    that leaves the arm's own joints the least to absorb; ``turn_rad``: yawed that much off psi* (the arm's own
    joints absorbing more). Turning the cart about the vertical turns psi* with it, so in the patient's frame this
    frame depends on the table's tilt, not on the cart's pose on the floor."""
    return S.si_orientation(suj, least_absorbed(suj, aim)[0] + turn_rad)


def _wrap(a: np.ndarray) -> np.ndarray:
    """``suj.wrap`` of each angle: into (-pi, pi] (within an ulp of math.remainder)."""
    out = a - np.rint(a / (2 * math.pi)) * (2 * math.pi)
    return np.where(out <= -math.pi, math.pi, out)


def si_solutions(suj, poses: np.ndarray, tolerance_rad: float = 1e-9,
                 steps: int = S.SI_REDUNDANT_STEPS) -> tuple[np.ndarray, np.ndarray]:
    """(S3, S7) ``reference.si_ik`` (tests) over many poses (N, 4, 4, the base in the cart's world) at once, as a dock table needs
    it: per pose the best solution's least range margin (m for the column, rad otherwise; -inf: no solution, or the
    pose off the orientations the Si gives by more than ``tolerance_rad``) and its joints (N, the SUJ's joints; the
    column first). The best: the first in ``si_ik``'s order (the first planar joint's grid of ``steps`` on the
    redundant PSM3, then the elbow of positive sine) unless a later one beats it by ``suj.MARGIN_TIE``, as
    ``suj.best_first``."""
    planar = len(suj.links) - 1
    if planar not in (3, 4):
        raise ValueError(f"{suj.cart} {suj.arm}: {planar} planar joints; si_solutions solves three or four")
    g = np.eye(4)
    for row in suj.fixed:
        g = g @ S.link(row, 0.0)
    h = (np.linalg.inv(np.asarray(suj.world_to_suj, float)) @ poses
         @ np.linalg.inv(np.asarray(suj.tip_to_tool, float)) @ np.linalg.inv(g))  # Trans(x, y, z) Rz(psi) on the family
    on = np.arctan2(np.hypot(h[:, 0, 2], h[:, 1, 2]), h[:, 2, 2]) <= tolerance_rad  # as si_ik: not acos
    a_c, d_c, a, d, off = S._planar(suj, planar)
    x, y = h[:, 0, 3] - a_c, h[:, 1, 3]
    psi = np.arctan2(h[:, 1, 0], h[:, 0, 0])
    column = h[:, 2, 3] - d_c - sum(d)
    lo, hi = np.asarray(suj.ranges, float).T
    best, joints = np.full(len(poses), -np.inf), np.full((len(poses), planar + 1), np.nan)
    firsts = [None] if planar == 3 else [-math.pi + 2 * math.pi * k / steps for k in range(steps)]
    for t1 in firsts:  # the redundant PSM3's first joint (S7): the rest from its link's end, in its frame
        if t1 is None:
            px, py, l1, l2 = x, y, a[1], a[2]
        else:
            ex, ey = x - a[1] * math.cos(t1), y - a[1] * math.sin(t1)
            px, py = math.cos(t1) * ex + math.sin(t1) * ey, -math.sin(t1) * ex + math.cos(t1) * ey
            l1, l2 = a[2], a[3]
        c = (px * px + py * py - l1 * l1 - l2 * l2) / (2 * l1 * l2)
        ok = on & (np.abs(c) <= 1 + 1e-12)
        c = np.clip(c, -1.0, 1.0)
        for sign in (1.0, -1.0):
            s = sign * np.sqrt(1 - c * c)
            u = _wrap(np.arctan2(py, px) - np.arctan2(l2 * s, l1 + l2 * c))
            v = _wrap(np.arctan2(s, c))
            if t1 is None:
                q = [column, u - off[0], v - off[1], _wrap(psi - u - v - off[2])]
            else:
                q = [column, np.full_like(u, S.wrap(t1 - off[0])), _wrap(u - off[1]), _wrap(v - off[2]),
                     _wrap(psi - t1 - u - v - off[3])]
            q = np.stack(q, axis=1)
            margin = np.where(ok, np.minimum(q - lo, hi - q).min(axis=1), -np.inf)
            take = margin > best + S.MARGIN_TIE  # -inf + tie is -inf: the first candidate is taken where it solves
            best, joints = np.where(take, margin, best), np.where(take[:, None], q, joints)
    return best, joints
