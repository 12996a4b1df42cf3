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

Where the SUJ's planar chain does not reach the port at psi* (its end's position turns with psi), other yaws are
tried on a grid; each docking kept is one where the SUJ solves within its ranges (S3) and q1, q2 are within the
arm's. All in the cart's world frame, metres and radians.
"""
from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from surgopt.kinematics.port import suj as S

#: The yaws tried besides psi*: a grid of this step over a whole turn (rad).
YAW_STEP_RAD = math.radians(1.0)


class SiDocking(NamedTuple):
    """One way the Si docks an arm on a port: the planar chain's yaw ``yaw_rad`` (S5), the base frame there
    (4x4, cart world, its origin the port), the SUJ's best solution (``suj.SujSolution``), the arm's own yaw
    and pitch that point its shaft along the aim (rad), and the angle they absorb (rad)."""

    yaw_rad: float
    base: np.ndarray
    suj: S.SujSolution
    q1: float
    q2: float
    absorbed_rad: float


class SiAnswer(NamedTuple):
    """Every docking found (least absorbed angle first, then the SUJ's margin), and why there is none."""

    dockings: tuple
    reason: str


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


def si_docking(suj, port: np.ndarray, aim: np.ndarray, limits) -> SiAnswer:
    """Every Si docking of an arm on ``port`` (m, cart world) whose own yaw and pitch (``limits``: ``yaw_lo``,
    ``yaw_hi``, ``pitch_lo``, ``pitch_hi``, rad) point its shaft along ``aim``: psi* (S6) and a whole turn of
    yaws at ``YAW_STEP_RAD``, each where the SUJ solves within its ranges (S3). None: the reason (the SUJ
    reaches the port at no yaw; or where it does, the arm's yaw or pitch would leave its range, by how much)."""
    port = np.asarray(port, float)
    best_psi, _ = least_absorbed(suj, aim)
    yaws = [best_psi] + [S.wrap(best_psi + k * YAW_STEP_RAD) for k in range(1, round(2 * math.pi / YAW_STEP_RAD))]
    found, reached, nearest = [], 0, (math.inf, "")
    for psi in yaws:
        base = np.eye(4)
        base[:3, :3], base[:3, 3] = S.si_orientation(suj, psi), port
        answer = S.si_ik(suj, base)
        if not answer.within:
            continue
        reached += 1
        q1, q2, absorbed = own_joints(base[:3, :3], aim)
        over = max(limits.yaw_lo - q1, q1 - limits.yaw_hi, limits.pitch_lo - q2, q2 - limits.pitch_hi)
        if over > 0:
            if over < nearest[0]:
                nearest = (over, f"yaw {math.degrees(q1):.1f} deg" if max(limits.yaw_lo - q1, q1 - limits.yaw_hi) == over
                           else f"pitch {math.degrees(q2):.1f} deg")
            continue
        found.append(SiDocking(psi, base, answer.within[0], q1, q2, absorbed))
    found.sort(key=lambda d: (round(d.absorbed_rad, 12), -d.suj.margin))
    if found:
        return SiAnswer(tuple(found), "")
    if not reached:
        return SiAnswer((), f"{suj.cart} {suj.arm} SUJ: reaches the port at no yaw of its planar chain (within its "
                            f"ranges)")
    return SiAnswer((), f"{suj.cart} {suj.arm}: at every yaw where its SUJ reaches the port ({reached} of "
                        f"{len(yaws)} tried) the arm's own joints cannot point the shaft along the aim (nearest: "
                        f"{nearest[1]}, {math.degrees(nearest[0]):.1f} deg past its range)")


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
    """(S3, S7) ``suj.si_ik`` over many poses (N, 4, 4, the base in the cart's world) at once, as a dock table needs
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
