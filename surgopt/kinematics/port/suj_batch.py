"""The Classic PSM setup joints' closed-form inverse (``reference.classic_psm_ik`` (tests), eq. S2) as one jitted loop over many
poses: for each pose, the largest least range margin of its solutions (-inf: none), which is all a dock table
needs (``studies/port_place/tables.dock_tables``: every arm at every site and cart pose).

The same steps as ``reference.classic_psm_ik`` (tests) written out in scalars (no array per pose): the pose taken into the SUJ's
base frame with the tip transform off, the wrist's two angles from the Davenport decomposition (q4 from
z.M z = c^2 + (1 - c^2) cos q4, two signs; psi and q5 from M's columns), then the planar chain's two elbows (law of
cosines) and the column. ``tests/test_kinematics_suj.py`` holds it to ``classic_psm_ik``'s margins.
"""
from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from surgopt.jit import EXACT, njit
from surgopt.kinematics.port.suj import MARGIN_TIE


class SujArrays(NamedTuple):
    """A Classic PSM SUJ as the kernel reads it: the inverse of world_to_suj and of tip_to_tool (4, 4), the six
    jointed links' alpha, A, D and theta offset (6,) each (modified DH; the column first), their ranges (6, 2)."""

    world_inv: np.ndarray
    tip_inv: np.ndarray
    alpha: np.ndarray
    a: np.ndarray
    d: np.ndarray
    offset: np.ndarray
    ranges: np.ndarray


def suj_arrays(suj) -> SujArrays:
    """A ``robots.dvrk.suj.Suj`` (a Classic PSM's: six jointed links, none fixed) as ``SujArrays``."""
    if len(suj.links) != 6 or suj.fixed:
        raise ValueError(f"{suj.cart} {suj.arm}: the batch solver is the Classic PSM SUJ's (six jointed links)")
    rows = suj.links
    return SujArrays(np.linalg.inv(np.asarray(suj.world_to_suj, float)),
                     np.linalg.inv(np.asarray(suj.tip_to_tool, float)),
                     np.array([r.alpha_rad for r in rows]), np.array([r.a_m for r in rows]),
                     np.array([r.d_m for r in rows]), np.array([r.theta_offset_rad for r in rows]),
                     np.asarray(suj.ranges, float))


@njit(**EXACT)
def wrap(angle):
    """An angle in (-pi, pi] (``suj.wrap``; math.remainder, which numba lacks, as angle - n 2 pi with n the
    nearest integer, ties to even: equal to it within an ulp of the result)."""
    a = angle - np.rint(angle / (2.0 * math.pi)) * (2.0 * math.pi)
    return math.pi if a <= -math.pi else a


@njit(**EXACT)
def rx(alpha):
    c, s = math.cos(alpha), math.sin(alpha)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


@njit(**EXACT)
def rz(theta):
    c, s = math.cos(theta), math.sin(theta)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


@njit(**EXACT)
def mdh(alpha, a, theta, d):
    """Modified (Craig) DH link transform Rx(alpha) Tx(a) Rz(theta) Tz(d) (``suj.mdh``)."""
    ca, sa, ct, st = math.cos(alpha), math.sin(alpha), math.cos(theta), math.sin(theta)
    return np.array([[ct, -st, 0.0, a], [st * ca, ct * ca, -sa, -sa * d], [st * sa, ct * sa, ca, ca * d],
                     [0.0, 0.0, 0.0, 1.0]])


@njit(**EXACT)
def least_margin(q, ranges):
    """The least distance of the joints inside their ranges (negative: outside by that much)."""
    worst = math.inf
    for j in range(6):
        worst = min(worst, min(q[j] - ranges[j, 0], ranges[j, 1] - q[j]))
    return worst


@njit(**EXACT)
def planar_best(s, x, y, z, psi, q4, q5, head, q_best):
    """The (up to two) elbow solutions that put the planar chain's last frame at (x, y, z) with yaw psi, the wrist
    at (q4, q5) (``suj._planar_ik``, ``suj._elbows``), after the best so far (its least margin ``head``, -inf:
    none; its joints in ``q_best``): one replaces it only when better by ``suj.MARGIN_TIE`` (``suj.best_first``'s
    rule, in the same order). Returns the best's margin."""
    column = z - s.d[0] - (s.d[1] + s.d[2] + s.d[3])
    px, py, l1, l2 = x - s.a[0], y, s.a[2], s.a[3]
    c = (px * px + py * py - l1 * l1 - l2 * l2) / (2.0 * l1 * l2)
    if c > 1.0 + 1e-12 or c < -1.0 - 1e-12:
        return head
    c = min(1.0, max(-1.0, c))
    q = np.empty(6)
    root = math.sqrt(1.0 - c * c)
    for k in range(2 if root != 0.0 else 1):  # one elbow when both coincide (``suj._elbows``)
        sn = root if k == 0 else -root
        t2 = math.atan2(sn, c)
        t1 = wrap(math.atan2(py, px) - math.atan2(l2 * sn, l1 + l2 * c))
        t2 = wrap(t2)
        q[0], q[1], q[2] = column, t1 - s.offset[1], t2 - s.offset[2]
        q[3] = wrap(psi - t1 - t2 - s.offset[3])
        q[4], q[5] = q4, q5
        m = least_margin(q, s.ranges)
        if m > head + MARGIN_TIE:
            head = m
            q_best[:] = q
    return head


@njit(**EXACT)
def classic_psm_margin(s, pose, q_best):
    """(S2) The largest least range margin of the Classic PSM SUJ's solutions that put the arm's base frame at
    ``pose`` (4x4, cart world); -inf when no joint values reach it (``reference.classic_psm_ik`` (tests)). That solution's
    joints (m, rad) are written to ``q_best`` (6,; untouched when none)."""
    t = s.world_inv @ pose @ s.tip_inv
    m = np.ascontiguousarray(t[:3, :3])
    rx4, rx5 = rx(s.alpha[4]), rx(s.alpha[5])
    u0, u1, u2 = rx4[2, 0], rx4[2, 1], rx4[2, 2]  # rx4^T z
    v0, v1, v2 = rx5[0, 2], rx5[1, 2], rx5[2, 2]  # rx5 z
    ca, sa, k = u0 * v0 + u1 * v1, u1 * v0 - u0 * v1, u2 * v2
    target = m[2, 2] - k
    amp = math.hypot(ca, sa)
    if amp < 1e-12 or abs(target) > amp * (1.0 + 1e-12):
        return -math.inf
    phase = math.atan2(sa, ca)
    spread = math.acos(max(-1.0, min(1.0, target / amp)))
    first, second = wrap(phase + spread), wrap(phase - spread)
    first, second = min(first, second), max(first, second)  # ascending, as ``reference.classic_psm_ik`` (tests) takes them
    best = -math.inf
    for n in range(2 if second != first else 1):
        th4 = first if n == 0 else second
        r4 = rx4 @ rz(th4) @ rx5
        psi = math.atan2(m[1, 2], m[0, 2]) - math.atan2(r4[1, 2], r4[0, 2])
        rest = np.ascontiguousarray(r4.T) @ rz(-psi) @ m
        th5 = math.atan2(rest[1, 0], rest[0, 0])
        q4, q5 = wrap(th4 - s.offset[4]), wrap(th5 - s.offset[5])
        g = mdh(s.alpha[4], s.a[4], th4, s.d[4]) @ mdh(s.alpha[5], s.a[5], th5, s.d[5])
        rg_t, pg = np.ascontiguousarray(g[:3, :3].T), np.ascontiguousarray(g[:3, 3])
        rh = m @ rg_t  # h = t g^-1 = [m rg^T, p - m rg^T pg]
        ph = np.ascontiguousarray(t[:3, 3]) - rh @ pg
        best = planar_best(s, ph[0], ph[1], ph[2], math.atan2(rh[1, 0], rh[0, 0]), q4, q5, best, q_best)
    return best


@njit(**EXACT)
def classic_psm_margins(s, poses):
    """``classic_psm_margin`` of each of ``poses`` (k, 4, 4)."""
    return classic_psm_solutions(s, poses)[0]


@njit(**EXACT)
def classic_psm_solutions(s, poses):
    """``classic_psm_margin`` of each of ``poses`` (k, 4, 4) and its best solution's joints (k, 6; NaN where
    none reaches)."""
    out = np.empty(poses.shape[0])
    joints = np.full((poses.shape[0], 6), np.nan)
    for i in range(poses.shape[0]):
        out[i] = classic_psm_margin(s, np.ascontiguousarray(poses[i]), joints[i])
    return out, joints


@njit(**EXACT)
def chain_points(world, alpha, a, d, offset, prismatic, jointed, q):
    """(L + 1, 3) The origins of a modified-DH chain's frames (L rows: the ``jointed`` first turned or slid by q,
    the rest fixed links at their offsets, as the Si's two after its joints) (``suj.frames`` without the tool
    transform, ``suj.link``): its base ``world`` (4, 4), then after each row."""
    return chain_frames(world, alpha, a, d, offset, prismatic, jointed, q)[0]


@njit(**EXACT)
def chain_frames(world, alpha, a, d, offset, prismatic, jointed, q):
    """``chain_points`` and the chain's last frame (4, 4)."""
    rows = alpha.shape[0]
    out = np.empty((rows + 1, 3))
    t = world.copy()
    out[0] = t[:3, 3]
    for j in range(rows):
        v = q[j] if j < jointed else 0.0
        if prismatic[j]:
            t = t @ mdh(alpha[j], a[j], offset[j], d[j] + v)
        else:
            t = t @ mdh(alpha[j], a[j], v + offset[j], d[j])
        out[j + 1] = t[:3, 3]
    return out, t


class EcmArrays(NamedTuple):
    """The Classic ECM's SUJ and ranges as ``ecm_margins`` reads them: world_to_suj (4, 4), the tip transform's
    translation (3,) and angle about z, the six links' alpha, A, D and theta offset, the SUJ's ranges (6, 2),
    and the ECM's own yaw and pitch ranges (2,) each."""

    world: np.ndarray
    p_tip: np.ndarray
    tip_angle: float
    alpha: np.ndarray
    a: np.ndarray
    d: np.ndarray
    offset: np.ndarray
    ranges: np.ndarray
    yaw: np.ndarray
    pitch: np.ndarray


def ecm_arrays(suj, yaw_rad: tuple, pitch_rad: tuple) -> EcmArrays:
    """A Classic ECM ``robots.dvrk.suj.Suj`` and the ECM's yaw and pitch ranges as ``EcmArrays``."""
    tip = np.asarray(suj.tip_to_tool, float)
    rows = suj.links
    return EcmArrays(np.asarray(suj.world_to_suj, float), tip[:3, 3].copy(), math.atan2(tip[1, 0], tip[0, 0]),
                     np.array([r.alpha_rad for r in rows]), np.array([r.a_m for r in rows]),
                     np.array([r.d_m for r in rows]), np.array([r.theta_offset_rad for r in rows]),
                     np.asarray(suj.ranges, float), np.asarray(yaw_rad, float), np.asarray(pitch_rad, float))


@njit(**EXACT)
def turn(q):
    """(q + pi) mod 2 pi - pi, the modulus taking the divisor's sign (numpy's remainder): in [-pi, pi)."""
    x = q + math.pi
    return x - (2.0 * math.pi) * math.floor(x / (2.0 * math.pi)) - math.pi


@njit(**EXACT)
def ecm_margins(s, origins, aims, psi_steps, aim_steps, q4_steps):
    """(S4) ``reference.ecm_classic_dock`` (tests) as one jitted loop: per origin (n, 3, the RCM in the cart's world) and aim
    (n, 3, unit), the largest least margin over the grid of the planar chain's heading psi, the aim's angle phi
    (the best of the ECM's own yaw/pitch margins and its twin pi - phi) and theta4, with the SUJ joints and the
    ECM's yaw and pitch there (-inf, NaN where no grid point docks). The same grid, the same order and the same
    strict comparisons as the numpy version, so the same grid point wins."""
    n = origins.shape[0]
    best = np.full(n, -np.inf)
    joints = np.full((n, 6), np.nan)
    ecm = np.full((n, 2), np.nan)
    wr, wp = s.world[:3, :3], s.world[:3, 3]
    ca, sa = math.cos(s.alpha[4]), math.sin(s.alpha[4])
    half = aim_steps // 2
    phi = np.empty(aim_steps)
    cos_phi, sin_phi = np.empty(aim_steps), np.empty(aim_steps)
    for f in range(aim_steps):
        phi[f] = (2.0 * math.pi / aim_steps) * (f - half)
        cos_phi[f] = math.cos(abs(phi[f]))
        sin_phi[f] = math.copysign(math.sin(abs(phi[f])), phi[f])
    l2, l3 = s.a[2], s.a[3]
    drop = s.d[0] + s.d[1] + s.d[2] + s.d[3]
    v = np.empty((psi_steps, 3))
    r = np.empty(psi_steps)
    chosen = np.empty((psi_steps, 2), np.int64)
    aim_of = np.empty((psi_steps, 2))
    q = np.empty(6)
    for i in range(n):
        o = np.empty(3)
        dd = np.empty(3)
        for j in range(3):
            o[j] = (origins[i, 0] - wp[0]) * wr[0, j] + (origins[i, 1] - wp[1]) * wr[1, j] \
                + (origins[i, 2] - wp[2]) * wr[2, j]
            dd[j] = aims[i, 0] * wr[0, j] + aims[i, 1] * wr[1, j] + aims[i, 2] * wr[2, j]
        for ip in range(psi_steps):
            psi = -math.pi + (2.0 * math.pi / psi_steps) * ip
            c, sn = math.cos(-psi), math.sin(-psi)
            dz0, dz1, dz2 = c * dd[0] - sn * dd[1], sn * dd[0] + c * dd[1], dd[2]
            v[ip, 0], v[ip, 1], v[ip, 2] = dz0, ca * dz1 + sa * dz2, -sa * dz1 + ca * dz2
            r[ip] = math.sqrt(max(0.0, 1.0 - v[ip, 2] * v[ip, 2]))
            top, first = -math.inf, 0
            for f in range(aim_steps):
                ux, uy = r[ip] * cos_phi[f], r[ip] * sin_phi[f]
                pitch = -math.asin(min(1.0, max(-1.0, uy)))
                yaw = math.atan2(ux, -v[ip, 2])
                m = min(min(yaw - s.yaw[0], s.yaw[1] - yaw), min(pitch - s.pitch[0], s.pitch[1] - pitch))
                if m > top or f == 0:
                    top, first = m, f
            twin = (half - (first - half) + half) % aim_steps
            chosen[ip, 0], chosen[ip, 1] = first, twin
            for b in range(2):
                f = chosen[ip, b]
                ux, uy = r[ip] * cos_phi[f], r[ip] * sin_phi[f]
                pitch = -math.asin(min(1.0, max(-1.0, uy)))
                yaw = math.atan2(ux, -v[ip, 2])
                aim_of[ip, b] = min(min(yaw - s.yaw[0], s.yaw[1] - yaw), min(pitch - s.pitch[0], s.pitch[1] - pitch))
        for b in range(2):
            for sign in (1.0, -1.0):
                local, at_p, at_q = -math.inf, -1, -1
                lq = np.empty(6)
                for ip in range(psi_steps):
                    psi = -math.pi + (2.0 * math.pi / psi_steps) * ip
                    sigma = math.atan2(v[ip, 1], v[ip, 0]) - phi[chosen[ip, b]] - s.tip_angle
                    cs, ss = math.cos(sigma), math.sin(sigma)
                    tx = cs * s.p_tip[0] - ss * s.p_tip[1]
                    ty = ss * s.p_tip[0] + cs * s.p_tip[1]
                    tz = s.p_tip[2]
                    cp, sp = math.cos(psi), math.sin(psi)
                    for iq in range(q4_steps):
                        q4 = -math.pi + (2.0 * math.pi / q4_steps) * iq
                        th4 = q4 + s.offset[4]
                        ix, iy, iz = math.cos(th4) * s.a[5] + tx, math.sin(th4) * s.a[5] + ty, tz
                        jx, jy, jz = ix, ca * iy - sa * iz, sa * iy + ca * iz  # Rx(alpha_4) inner
                        ex = o[0] - (cp * jx - sp * jy)
                        ey = o[1] - (sp * jx + cp * jy)
                        ez = o[2] - jz
                        x, y = ex - s.a[0], ey
                        c2 = (x * x + y * y - l2 * l2 - l3 * l3) / (2.0 * l2 * l3)
                        if abs(c2) > 1.0:
                            continue
                        s2 = sign * math.sqrt(1.0 - c2 * c2)
                        t2 = math.atan2(s2, c2)
                        t1 = math.atan2(y, x) - math.atan2(l3 * s2, l2 + l3 * c2)
                        q[0] = ez - drop
                        q[1] = turn(t1 - s.offset[1])
                        q[2] = turn(t2 - s.offset[2])
                        q[3] = turn(psi - t1 - t2 - s.offset[3])
                        q[4] = turn(q4)
                        q[5] = turn(sigma - th4 - s.offset[5])
                        m = aim_of[ip, b]
                        for j in range(6):
                            m = min(m, min(q[j] - s.ranges[j, 0], s.ranges[j, 1] - q[j]))
                        if m > local:
                            local, at_p, at_q = m, ip, iq
                            lq[:] = q
                if at_p >= 0 and local > best[i]:
                    best[i] = local
                    joints[i] = lq
                    f = chosen[at_p, b]
                    ux, uy, uz = r[at_p] * cos_phi[f], r[at_p] * sin_phi[f], v[at_p, 2]
                    ecm[i, 0] = math.atan2(ux, -uz)
                    ecm[i, 1] = -math.asin(min(1.0, max(-1.0, uy)))
    return best, joints, ecm


@njit(**EXACT)
def link_segments(world, alpha, a, d, offset, prismatic, jointed, joints, to_frame, first):
    """(k, L - first, 2, 3) A chain's links (L rows, ``chain_points``) from the ``first``-th on as segments between
    successive frame origins, at each of ``joints`` (k, >= jointed; NaN rows give NaN), taken by ``to_frame``
    (k, 4, 4) into another frame (the patient's): the setup joints' links, for the rows and one layout
    (``link_tables.placed_arm``)."""
    k, rows = joints.shape[0], alpha.shape[0]
    out = np.full((k, rows - first, 2, 3), np.nan)
    for n in range(k):
        if np.isnan(joints[n, 0]):
            continue
        pts = chain_points(world, alpha, a, d, offset, prismatic, jointed, joints[n])
        r, t = np.ascontiguousarray(to_frame[n, :3, :3]), to_frame[n, :3, 3]
        for s in range(rows - first):
            out[n, s, 0] = r @ pts[first + s] + t
            out[n, s, 1] = r @ pts[first + s + 1] + t
    return out


@njit(**EXACT)
def chain_ends(world, alpha, a, d, offset, prismatic, jointed, joints):
    """(k, 4, 4) A chain's last frame (``suj.frames``' before the tool transform) at each of ``joints`` (k,
    >= jointed; NaN rows give NaN)."""
    out = np.full((joints.shape[0], 4, 4), np.nan)
    for n in range(joints.shape[0]):
        if np.isnan(joints[n, 0]):
            continue
        out[n] = chain_frames(world, alpha, a, d, offset, prismatic, jointed, joints[n])[1]
    return out
