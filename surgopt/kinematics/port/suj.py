"""The patient cart's setup joints (SUJ, ``robots/dvrk/suj.py``): forward kinematics from the DH data, and
inverse kinematics: the joint values that put an arm's base (its RCM frame) at a given pose in the cart's
world frame, every solution, or the reason there is none.

Every SUJ is a vertical column (prismatic), then revolute joints about vertical axes (a planar chain: they
set the x, y and the yaw psi of their last frame), then either two more joints (the Classic's: they tilt the
arm) or fixed links (the Si's: the arm's tilt is built in). So

    T_world_rcm = W  H(column, planar joints)  G(wrist joints)  T_tip,                         (S1)

with W = world_origin_to_SUJ, H = Trans(x, y, z) Rz(psi) and G the rest (constant on the Si).

Classic PSM (S2, closed form): with M = R(W^-1 T) R_tip^T, the wrist's two axes are z and n = Rx(alpha_4) z
(alpha_4 = 1.5708 as the file writes it: n is 2e-6 off a right angle to z), so M = Rz(psi) Rot(n, q4)
Rz(q5 + offset_5), a Davenport decomposition: z.M z = c^2 + (1 - c^2) cos q4 with c = n.z gives q4 (two
signs), then psi and q5 from M's other columns; the planar chain's end point gives the two elbows of its first
two joints (the law of cosines) and the third closes the yaw; the column closes z. Up to 4 solutions.

Si PSM1, PSM2, ECM (S3): G is constant, so the base's orientation can only turn about the vertical: the
reachable docking orientations are R = Rz(psi) R_0, a one-parameter family (``si_orientation``); a pose off
the family is refused with the angle it is off by; on it, two elbow solutions. The Si PSM3 (S7) has four planar
joints for the same three degrees of freedom: its first is free, taken on a grid, the rest solved as above.

All in metres and radians. Plain numpy, pose by pose; ``kinematics.port.suj_batch`` jits S2 and S4 over every
(site, cart pose) for the dock tables and is held to these.
"""
from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np


def mdh(alpha: float, a: float, theta: float, d: float) -> np.ndarray:
    """Modified (Craig) DH link transform Rx(alpha) Tx(a) Rz(theta) Tz(d)."""
    ca, sa, ct, st = math.cos(alpha), math.sin(alpha), math.cos(theta), math.sin(theta)
    return np.array([[ct, -st, 0.0, a], [st * ca, ct * ca, -sa, -sa * d], [st * sa, ct * sa, ca, ca * d],
                     [0.0, 0.0, 0.0, 1.0]])


def link(row, q: float) -> np.ndarray:
    """One ``chain.DhRow`` (modified) at joint value q: theta + q for a revolute joint, d + q for the column."""
    if row.prismatic:
        return mdh(row.alpha_rad, row.a_m, row.theta_offset_rad, row.d_m + q)
    return mdh(row.alpha_rad, row.a_m, row.theta_offset_rad + q, row.d_m)


def forward(suj, q) -> np.ndarray:
    """(S1) The arm's base (RCM) frame in the cart's world frame at SUJ joints ``q`` (m, rad)."""
    t = np.asarray(suj.world_to_suj, float)
    for row, v in zip(suj.links, q, strict=True):
        t = t @ link(row, v)
    for row in suj.fixed:
        t = t @ link(row, 0.0)
    return t @ np.asarray(suj.tip_to_tool, float)


def frames(suj, q) -> np.ndarray:
    """(k, 4, 4) The SUJ's frames from its base to the arm's base (RCM), in the cart's world frame: the SUJ's
    base, after each link, and the tool origin (what a figure draws and a collision check reads)."""
    t = np.asarray(suj.world_to_suj, float)
    out = [t]
    for row, v in zip(suj.links, q, strict=True):
        t = t @ link(row, v)
        out.append(t)
    for row in suj.fixed:
        t = t @ link(row, 0.0)
        out.append(t)
    out.append(t @ np.asarray(suj.tip_to_tool, float))
    return np.array(out)


class SujSolution(NamedTuple):
    """The SUJ's joints (m, rad) and the least margin to their ranges (m for the column, rad otherwise; negative:
    outside, by that much) with the joint it belongs to."""

    joints: tuple
    margin: float
    tightest: str


class SujAnswer(NamedTuple):
    """Every solution within the ranges (``within``), the ones outside them (``outside``, nearest first), and why
    there is none within (empty when there is)."""

    within: tuple
    outside: tuple
    reason: str


def wrap(angle: float) -> float:
    """An angle in (-pi, pi]."""
    a = math.remainder(angle, 2 * math.pi)
    return math.pi if a == -math.pi else a


def _margin(suj, q) -> tuple[float, str]:
    """The least distance of the joints inside their ranges, and the joint's name (a revolute joint's value
    wrapped into its range's turn when it fits there)."""
    worst, name = math.inf, ""
    for row, v, (lo, hi) in zip(suj.links, q, suj.ranges):
        m = min(v - lo, hi - v)
        if m < worst:
            worst, name = m, row.name
    return worst, name


def _solution(suj, q) -> SujSolution:
    q = tuple(float(v) for v in q)
    return SujSolution(q, *_margin(suj, q))


#: Solutions whose least margins differ by less than this (rad or m) are equally good: the first of them in the
#: solver's order (q4 ascending, then the elbow of positive sine) is the best, here and in the batch solver
#: (``suj_batch``), so both dock an arm with the same joints where margins tie (the column's margin, shared by
#: both elbows, often decides under the assumed full-turn ranges).
MARGIN_TIE = 1e-9


def best_first(sols: list) -> list:
    """Solutions best first: the head the first that no later one beats by MARGIN_TIE, the rest by margin."""
    if not sols:
        return []
    head = sols[0]
    for s in sols[1:]:
        if s.margin > head.margin + MARGIN_TIE:
            head = s
    return [head] + sorted((s for s in sols if s is not head), key=lambda s: -s.margin)


def _answer(suj, candidates) -> SujAnswer:
    sols = best_first([_solution(suj, q) for q in candidates])
    within = tuple(s for s in sols if s.margin >= 0)
    outside = tuple(s for s in sols if s.margin < 0)
    if within:
        return SujAnswer(within, outside, "")
    if not outside:
        return SujAnswer((), (), "out of reach: no joint values put the base there")
    best = outside[0]
    lo, hi = suj.ranges[[r.name for r in suj.links].index(best.tightest)]
    value = best.joints[[r.name for r in suj.links].index(best.tightest)]
    unit = "m" if best.tightest == "column" else "deg"
    k = 1.0 if unit == "m" else 180 / math.pi
    return SujAnswer((), outside, f"{suj.cart} {suj.arm} SUJ {best.tightest} = {value * k:.4g} {unit}, outside "
                                  f"its range [{lo * k:.4g}, {hi * k:.4g}] {unit} (the nearest of "
                                  f"{len(outside)} solution(s))")


def _planar(suj, n_planar: int):
    """(the column's x offset A_c, its D, the planar joints' A (from the second on) and D, their offsets)."""
    col = suj.links[0]
    rows = suj.links[1:1 + n_planar]
    return col.a_m, col.d_m, [r.a_m for r in rows], [r.d_m for r in rows], [r.theta_offset_rad for r in rows]


def _elbows(x: float, y: float, l1: float, l2: float) -> list[tuple[float, float]]:
    """Both solutions (theta1, theta2) of a planar two-link chain from the origin to (x, y): l1 u(t1) +
    l2 u(t1 + t2) = (x, y); none when the point is out of the links' reach."""
    r2 = x * x + y * y
    c = (r2 - l1 * l1 - l2 * l2) / (2 * l1 * l2)
    if c > 1 + 1e-12 or c < -1 - 1e-12:
        return []
    c = min(1.0, max(-1.0, c))
    out = []
    for s in (math.sqrt(1 - c * c), -math.sqrt(1 - c * c)):
        t2 = math.atan2(s, c)
        t1 = math.atan2(y, x) - math.atan2(l2 * s, l1 + l2 * c)
        out.append((wrap(t1), wrap(t2)))
    return out if out[0] != out[1] else out[:1]


def _planar_ik(suj, x: float, y: float, z: float, psi: float) -> list[tuple]:
    """The column and the three planar joints that put the planar chain's last frame at (x, y, z) with yaw psi
    (its x axis's heading): the two elbows."""
    a_c, d_c, a, d, off = _planar(suj, 3)
    column = z - d_c - sum(d)
    out = []
    for t1, t2 in _elbows(x - a_c, y, a[1], a[2]):
        t3 = wrap(psi - t1 - t2 - off[2])  # t1, t2: the first two links' headings, offsets included
        out.append((column, t1 - off[0], t2 - off[1], t3))
    return out


def _to_suj(suj, pose: np.ndarray) -> np.ndarray:
    """The pose (the base's frame in the cart's world) in the SUJ's base frame, the tip transform taken off."""
    return np.linalg.inv(np.asarray(suj.world_to_suj, float)) @ pose @ np.linalg.inv(np.asarray(suj.tip_to_tool, float))


def classic_psm_ik(suj, pose: np.ndarray) -> SujAnswer:
    """(S2) Every Classic PSM SUJ solution that puts the arm's base frame at ``pose`` (4x4, cart world)."""
    t = _to_suj(suj, pose)
    j4, j5 = suj.links[4], suj.links[5]
    # t = H Rx(a4) Rz(q4) Tz(d4) Rx(a5) Rz(q5 + o5) Tz(d5) with H = Trans(p) Rz(psi)
    a4, a5 = j4.alpha_rad, j5.alpha_rad
    rx4, rx5 = mdh(a4, 0, 0, 0)[:3, :3], mdh(a5, 0, 0, 0)[:3, :3]
    m = t[:3, :3]  # = Rz(psi) rx4 Rz(q4) rx5 Rz(q5 + o5)
    z = np.array([0.0, 0.0, 1.0])
    # z.m z = z.rx4 Rz(q4) rx5 z: Rz(psi) and Rz(q5) leave z alone
    u, v = rx4.T @ z, rx5 @ z  # z.(rx4 Rz(q4) rx5 z) = u.(Rz(q4) v)
    # u.Rz(q)v = (ux vx + uy vy) cos q + (ux vy - uy vx) sin q + uz vz
    ca, sa, k = u[0] * v[0] + u[1] * v[1], u[1] * v[0] - u[0] * v[1], u[2] * v[2]
    target = m[2, 2] - k
    amp = math.hypot(ca, sa)
    if amp < 1e-12 or abs(target) > amp * (1 + 1e-12):
        return SujAnswer((), (), f"{suj.cart} {suj.arm} SUJ: no wrist angle tilts the arm's base so "
                                 f"(its z is {math.degrees(math.acos(max(-1, min(1, m[2, 2])))):.1f} deg off vertical)")
    phase = math.atan2(sa, ca)
    spread = math.acos(max(-1.0, min(1.0, target / amp)))
    candidates = []
    for th4 in sorted({wrap(phase + spread), wrap(phase - spread)}):
        r4 = rx4 @ mdh(0, 0, th4, 0)[:3, :3] @ rx5  # m = Rz(psi) r4 Rz(th5), th = q + offset
        # m z = Rz(psi) r4 z: psi from the horizontal parts of m z and r4 z
        w, g = m @ z, r4 @ z
        psi = math.atan2(w[1], w[0]) - math.atan2(g[1], g[0])
        rest = r4.T @ mdh(0, 0, -psi, 0)[:3, :3] @ m  # = Rz(q5 + o5)
        th5 = math.atan2(rest[1, 0], rest[0, 0])
        q4, q5 = wrap(th4 - j4.theta_offset_rad), wrap(th5 - j5.theta_offset_rad)
        g4 = mdh(a4, j4.a_m, th4, j4.d_m) @ mdh(a5, j5.a_m, th5, j5.d_m)
        h = t @ np.linalg.inv(g4)  # = Trans(x, y, z) Rz(psi)
        for q in _planar_ik(suj, h[0, 3], h[1, 3], h[2, 3], math.atan2(h[1, 0], h[0, 0])):
            candidates.append((*q, q4, q5))
    return _answer(suj, candidates)


def si_orientation(suj, yaw_rad: float) -> np.ndarray:
    """(S3) The one orientation an Si SUJ gives its arm's base at yaw ``yaw_rad`` of its planar chain, in the
    cart's world frame: R(W) Rz(yaw) R(fixed links) R_tip. Every reachable docking orientation is one of these."""
    g = np.eye(4)
    for row in suj.fixed:
        g = g @ link(row, 0.0)
    r = np.asarray(suj.world_to_suj, float)[:3, :3] @ mdh(0, 0, yaw_rad, 0)[:3, :3] @ g[:3, :3]
    return r @ np.asarray(suj.tip_to_tool, float)[:3, :3]


#: The Si PSM3's first planar joint, free (S7): its inverse takes it on a grid of this many values over a turn.
SI_REDUNDANT_STEPS = 360


def _redundant_planar_ik(suj, x: float, y: float, z: float, psi: float, steps: int) -> list[tuple]:
    """(S7) The Si PSM3's column and four planar joints that put the chain's last frame at (x, y, z) with yaw psi:
    four revolute joints for three planar degrees of freedom, so the first, theta1, is free; at each of ``steps``
    values of it over a turn the rest is the three-joint chain's inverse (two elbows) from the end of the first
    link, A_2 u(theta1)."""
    a_c, d_c, a, d, off = _planar(suj, 4)
    column = z - d_c - sum(d)
    out = []
    for k in range(steps):
        t1 = -math.pi + 2 * math.pi * k / steps  # the first link's heading, its offset included
        px, py = x - a_c - a[1] * math.cos(t1), y - a[1] * math.sin(t1)
        c, s = math.cos(t1), math.sin(t1)
        for h2, t3 in _elbows(c * px + s * py, -s * px + c * py, a[2], a[3]):  # in the first link's frame
            t4 = wrap(psi - t1 - h2 - t3 - off[3])
            out.append((column, wrap(t1 - off[0]), wrap(h2 - off[1]), wrap(t3 - off[2]), t4))
    return out


def si_ik(suj, pose: np.ndarray, tolerance_rad: float = 1e-9, steps: int = SI_REDUNDANT_STEPS) -> SujAnswer:
    """(S3) Every Si SUJ solution (PSM1, PSM2, ECM: a column and three planar joints) that puts the base at
    ``pose``; refused when its orientation is off the reachable family by more than ``tolerance_rad``. The Si
    PSM3 (four planar joints, redundant: S7): its solutions on a grid of ``steps`` values of its first planar
    joint, the best (the largest least range margin) first."""
    if len(suj.links) not in (4, 5):
        raise ValueError(f"{suj.cart} {suj.arm}: {len(suj.links) - 1} planar joints; si_ik solves three or four")
    t = _to_suj(suj, pose)
    g = np.eye(4)
    for row in suj.fixed:
        g = g @ link(row, 0.0)
    h = t @ np.linalg.inv(g)  # must be Trans(x, y, z) Rz(psi)
    off = math.degrees(math.atan2(math.hypot(h[0, 2], h[1, 2]), h[2, 2]))  # not acos: exact near 0 (1e-16, not 1e-8)
    if off > math.degrees(tolerance_rad):
        return SujAnswer((), (), f"{suj.cart} {suj.arm} SUJ: the Si sets only the base's yaw; this docking is "
                                 f"tilted {off:.2f} deg off the orientations it can give")
    psi = math.atan2(h[1, 0], h[0, 0])
    if len(suj.links) == 5:
        return _answer(suj, _redundant_planar_ik(suj, h[0, 3], h[1, 3], h[2, 3], psi, steps))
    return _answer(suj, _planar_ik(suj, h[0, 3], h[1, 3], h[2, 3], psi))


def _rz(a: np.ndarray) -> np.ndarray:
    """Rotations about z by each angle of ``a`` (..., 3, 3)."""
    c, s = np.cos(a), np.sin(a)
    z, o = np.zeros_like(a), np.ones_like(a)
    return np.stack([np.stack([c, -s, z], -1), np.stack([s, c, z], -1), np.stack([z, z, o], -1)], -2)


#: The Classic ECM docking's grid (S4): the planar chain's heading, the aim's angle, theta4.
ECM_GRID_STEPS = (36, 36, 12)


def ecm_classic_dock(suj, yaw_rad: tuple, pitch_rad: tuple, origins: np.ndarray, aims: np.ndarray,
                     psi_steps: int = ECM_GRID_STEPS[0], aim_steps: int = ECM_GRID_STEPS[1],
                     q4_steps: int = ECM_GRID_STEPS[2]):
    """(S4) The Classic ECM's setup joints for an endoscope base at each of ``origins`` (n, 3: the RCM, at its
    port, in the cart's world frame) whose own yaw and pitch (within ``yaw_rad``, ``pitch_rad``) aim its shaft
    along ``aims`` (n, 3, unit: port to the target's centre).

    The ECM's SUJ ends in two parallel joints about an axis alpha_4 = -0.7853 rad off the vertical, so its base's
    z axis is always tilted |alpha_4| from the vertical at the planar chain's heading psi, and turned about
    itself by sigma = theta4 + theta5: the base orientation is Rz(psi) Rx(alpha_4) Rz(sigma) R_tip. In the base
    frame the aim u = R^T d has u_z fixed by psi and its horizontal part turned by sigma, so the aim is a choice
    of the angle phi of that part: the shaft's pitch -asin(u_y) and yaw atan2(u_x, -u_z) must lie in their
    ranges. The base's origin adds Rz(psi) Rx(alpha_4) (Rz(theta4) (A_5, 0, 0) + Rz(sigma) p_tip) to the planar
    chain's end, whose two elbows and column follow (S2's planar inverse). Searched on a grid of psi
    (``psi_steps``), phi (``aim_steps``) and theta4 (``q4_steps``); returns per origin (least margin, or -inf where
    no grid point docks; SUJ joints (6,), ECM yaw and pitch (2,)) of the grid point with the largest least margin
    (rad; the column's in m) over the SUJ's ranges and the ECM's yaw and pitch ranges."""
    col, j1, j2, j3, j4, j5 = suj.links
    w = np.asarray(suj.world_to_suj, float)
    tip = np.asarray(suj.tip_to_tool, float)
    p_tip = tip[:3, 3]
    tip_angle = math.atan2(tip[1, 0], tip[0, 0])  # R_tip = Rz(tip_angle)
    a4 = j4.alpha_rad
    n = len(origins)
    o = (origins - w[:3, 3]) @ w[:3, :3]  # in the SUJ's base frame
    d = aims @ w[:3, :3]
    psi = np.linspace(-math.pi, math.pi, psi_steps, endpoint=False)
    # v = Rx(-a4) Rz(-psi) d: (n, P, 3)
    dz = np.einsum("pij,nj->npi", _rz(-psi), d)
    ca, sa = math.cos(a4), math.sin(a4)
    v = np.stack([dz[..., 0], ca * dz[..., 1] + sa * dz[..., 2], -sa * dz[..., 1] + ca * dz[..., 2]], -1)
    uz = v[..., 2]
    r = np.sqrt(np.maximum(0.0, 1.0 - uz * uz))
    # the aim's grid k * step, k = -F/2 .. F/2 - 1 (F even: each aim's twin pi - phi is on it, below)
    if aim_steps % 2:
        raise ValueError(f"aim_steps must be even, not {aim_steps}")
    phi = (2 * math.pi / aim_steps) * np.arange(-(aim_steps // 2), aim_steps - aim_steps // 2)
    cos_phi, sin_phi = np.cos(np.abs(phi)), np.copysign(np.sin(np.abs(phi)), phi)
    ux, uy = r[..., None] * cos_phi, r[..., None] * sin_phi  # (n, P, F)
    pitch = -np.arcsin(np.clip(uy, -1.0, 1.0))
    yaw = np.arctan2(ux, -uz[..., None])
    aim_margin = np.minimum.reduce([yaw - yaw_rad[0], yaw_rad[1] - yaw, pitch - pitch_rad[0], pitch_rad[1] - pitch])
    # the aim with the largest margin, and its twin pi - phi: with the yaw range symmetric the two tie exactly
    # (ux changes sign, uy does not), and which one lets the setup joints dock differs, so both are solved
    # (an argmax alone picked one of them by rounding: which ECM docks changed with the CPU and the batch size)
    first = aim_margin.argmax(axis=2)  # (n, P)
    half = aim_steps // 2
    twin = (half - (first - half) + half) % aim_steps  # pi - phi on the grid (k - half = j  ->  half - j)
    q4 = np.linspace(-math.pi, math.pi, q4_steps, endpoint=False)
    th4 = q4 + j4.theta_offset_rad
    rx = np.array([[1.0, 0.0, 0.0], [0.0, ca, -sa], [0.0, sa, ca]])
    a_c, l2, l3 = col.a_m, j2.a_m, j3.a_m
    best = np.full(n, -np.inf)
    joints = np.full((n, 6), np.nan)
    ecm = np.full((n, 2), np.nan)
    lim = suj.ranges
    for best_phi in (first, twin):
        aim = np.take_along_axis(aim_margin, best_phi[..., None], 2)[..., 0]
        # u_xy = Rz(-sigma - tip_angle) v_xy  ->  phi = angle(v_xy) - sigma - tip_angle
        sigma = np.arctan2(v[..., 1], v[..., 0]) - phi[best_phi] - tip_angle
        # the base's origin less the planar chain's end: Rz(psi) Rx(a4) (Rz(th4) (A5, 0, 0) + Rz(sigma) p_tip)
        inner = (np.stack([np.cos(th4), np.sin(th4), np.zeros_like(th4)], -1)[None, None] * j5.a_m
                 + np.einsum("npij,j->npi", _rz(sigma), p_tip)[:, :, None, :])  # (n, P, Q, 3)
        off = np.einsum("pij,npqj->npqi", _rz(psi), inner @ rx.T)
        end = o[:, None, None, :] - off  # the planar chain's end (n, P, Q, 3)
        x, y = end[..., 0] - a_c, end[..., 1]
        c2 = (x * x + y * y - l2 * l2 - l3 * l3) / (2 * l2 * l3)
        reach = np.abs(c2) <= 1.0
        c2 = np.clip(c2, -1.0, 1.0)
        column = end[..., 2] - col.d_m - j1.d_m - j2.d_m - j3.d_m
        for sign in (1.0, -1.0):
            s2 = sign * np.sqrt(1.0 - c2 * c2)
            t2 = np.arctan2(s2, c2)
            t1 = np.arctan2(y, x) - np.arctan2(l3 * s2, l2 + l3 * c2)
            qs = [column, t1 - j1.theta_offset_rad, t2 - j2.theta_offset_rad,
                  psi[None, :, None] - t1 - t2 - j3.theta_offset_rad, np.broadcast_to(q4, column.shape),
                  sigma[:, :, None] - th4 - j5.theta_offset_rad]
            qs = [qs[0]] + [np.remainder(q + math.pi, 2 * math.pi) - math.pi for q in qs[1:]]
            margin = np.minimum.reduce([np.minimum(q - lo, hi - q) for q, (lo, hi) in zip(qs, lim)])
            margin = np.where(reach, np.minimum(margin, aim[:, :, None]), -np.inf)
            flat = margin.reshape(n, -1)
            k = flat.argmax(axis=1)
            better = flat[np.arange(n), k] > best
            if better.any():
                ip, iq = np.unravel_index(k, margin.shape[1:])
                rows = np.flatnonzero(better)
                best[rows] = flat[rows, k[rows]]
                joints[rows] = np.stack([q[rows, ip[rows], iq[rows]] for q in qs], -1)
                f = best_phi[rows, ip[rows]]
                uxy = r[rows, ip[rows]]
                u = np.stack([uxy * cos_phi[f], uxy * sin_phi[f], uz[rows, ip[rows]]], -1)
                ecm[rows] = np.stack([np.arctan2(u[:, 0], -u[:, 2]), -np.arcsin(np.clip(u[:, 1], -1, 1))], -1)
    return best, joints, ecm
