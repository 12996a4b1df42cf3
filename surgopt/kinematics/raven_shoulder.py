"""Raven IV kernels: the shoulder joint theta1 of each arm at each node of the reference plane, and its range.

Kernels only (numba); lengths mm, angles rad. The common-workspace kernel
(``surgopt.kinematics.raven_plane.evaluate_designs``) calls these when the shoulder range is limited.

Where theta1 comes from (Table I's DH, ``surgopt.robots.raven_iv``). In an arm's frame 0 (origin at
the port, z0 the shoulder axis, x0 its zero direction) the tool axis is
z3 = Rz(t1) Rx(pi - alpha) Rz(t2) Rx(-beta) e_z, whose components are
Rz(t1) (-st2 sb, -(ca c2 sb + sa cb), sa sb c2 - ca cb). The z component is eq. 22 (it fixes theta2 from
the angle psi between z0 and the direction to the node); the x, y components make the node's azimuth
az about z0 equal to t1 + off, off = atan2(-(ca c2 sb + sa cb), -st2 sb). With t1 = theta1, t2 = -theta2
(left arms) and t1 = pi - theta1, t2 = theta2 (right arms), both arms give

    theta1 = sigma * az - atan2(-(ca c2 sb + sa cb), s2 sb),    sigma = +1 left, -1 right,

(theta2 in [0, pi], so s2 >= 0): the same joint range means mirror-image motions of the two sides, as on the
Raven II (its ``defines.h``: "joint ranges are identical on each arm"). Worked example (a test checks it):
alpha = beta = 90 deg, theta2 = 90 deg: off = atan2(0, 1) = 0, so theta1 = az for a left arm.

No arctangent is evaluated: theta1's unit vector is (cos az, sigma sin az) turned back by off, and
whether it lies in [lo, hi] is two cross products with the range ends' unit vectors.
"""
from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from surgopt.jit import EXACT, VECTOR, njit


class ShoulderRange(NamedTuple):
    """theta1 range [lo, hi] as the range ends' unit vectors; ``wide`` when hi - lo > 180 deg.

    ``limited`` False: theta1 unlimited (the paper's Table I lists no range); then nothing is checked.
    """

    limited: bool
    cos_lo: float
    sin_lo: float
    cos_hi: float
    sin_hi: float
    wide: bool


class ShoulderFields(NamedTuple):
    """Per arm (rows) and plane node (columns): cos psi, and the node's direction v from the port projected on
    the plane of the shoulder's zero direction x0 and y0 = z0 x x0 as (v . x0, sigma v . y0) mm (``sigma``
    +1 left, -1 right arms): rho (cos az, sigma sin az), rho the node's distance from the shoulder axis.
    Zero columns when theta1 is unlimited."""

    cos_psi: np.ndarray
    u_mm: np.ndarray
    w_mm: np.ndarray


def shoulder_range(range_deg) -> ShoulderRange:
    """The kernels' ``ShoulderRange`` of [lo, hi] deg, or of None (unlimited). A range of 360 deg or more
    is no limit."""
    if range_deg is None or range_deg[1] - range_deg[0] >= 360.0:
        return ShoulderRange(False, 1.0, 0.0, 1.0, 0.0, False)
    lo, hi = (math.radians(v) for v in range_deg)
    return ShoulderRange(True, math.cos(lo), math.sin(lo), math.cos(hi), math.sin(hi), hi - lo > math.pi)


@njit(**VECTOR)
def _fields_row(x, ys, depth, px, py, pz, zx, zy, zz, ex, ey, ez, fx, fy, fz, cp, u, w):
    """One grid row (x, ys[j], -depth) of ``shoulder_fields`` for one arm at port p with axis z and
    in-plane directions e = x0 and f = sigma y0 (scalars, so the loop vectorises)."""
    for j in range(ys.shape[0]):
        vx, vy, vz = x - px, ys[j] - py, -depth - pz
        r = math.sqrt(vx * vx + vy * vy + vz * vz)
        cp[j] = min(1.0, max(-1.0, (vx * zx + vy * zy + vz * zz) / r))
        u[j] = vx * ex + vy * ey + vz * ez
        w[j] = vx * fx + vy * fy + vz * fz


@njit(**EXACT)
def shoulder_fields(xs, ys, depth, ports, axes, zero_axes, left, buffer=None):
    """``ShoulderFields`` of the plane nodes (xs[i], ys[j], -depth), node index i*ny + j.

    ``axes``: the shoulder axes z0 (arms, 3); ``zero_axes``: x0, perpendicular to z0 (arms, 3);
    ``left``: per arm, True for the mirrored (left) arms. y0 = z0 x x0. ``buffer``: at least
    3 * arms * nx * ny floats to fill instead of allocating (fresh megabytes cost page faults, about
    half the time of one geometry); the fields are C-contiguous views of its start.
    """
    n_arms, nx, ny = ports.shape[0], xs.shape[0], ys.shape[0]
    n = nx * ny
    if buffer is None:
        buffer = np.empty(3 * n_arms * n)
    block = buffer[:3 * n_arms * n].reshape((3, n_arms, n))
    cp, u, w = block[0], block[1], block[2]
    for a in range(n_arms):
        z, x = axes[a], zero_axes[a]
        y = (z[1] * x[2] - z[2] * x[1], z[2] * x[0] - z[0] * x[2], z[0] * x[1] - z[1] * x[0])
        sigma = 1.0 if left[a] else -1.0
        for i in range(nx):
            s, e = i * ny, (i + 1) * ny
            _fields_row(xs[i], ys, depth, ports[a, 0], ports[a, 1], ports[a, 2], z[0], z[1], z[2], x[0], x[1], x[2],
                        sigma * y[0], sigma * y[1], sigma * y[2], cp[a, s:e], u[a, s:e], w[a, s:e])
    return ShoulderFields(cp, u, w)


@njit(inline="always", **VECTOR)
def theta1_cross(cos_psi, u, w, sa, ca, sb, cb, k, cos_lo, sin_lo, cos_hi, sin_hi, wide):
    """(m, r): m / r is rho times the signed sine of theta1's angle to the nearer end of its range (> 0 inside).

    theta2 from cos psi by eq. 22 (c2 = (cos psi + ca cb) / (sa sb), k = 1 / (sa sb)); theta1's direction
    is (u, w) = rho (cos az, sigma sin az) (``ShoulderFields``) turned by -off, off the direction of
    (x, y) = (s2 sb, -(ca c2 sb + sa cb)) (module docstring), r = |(x, y)|. With u_lo, u_hi the range
    ends: for a range under 180 deg (``wide`` = 1.0) inside is both r cross(u_lo, u) > 0 and
    r cross(u, u_hi) > 0; for a wider one (``wide`` = -1.0), not both < 0 (the complement is the narrow
    arc): w * min(w a, w b) is min(a, b) or max(a, b). The sign needs neither r nor rho.
    """
    c2 = min(1.0, max(-1.0, (cos_psi + ca * cb) * k))
    x = math.sqrt(max(0.0, 1.0 - c2 * c2)) * sb
    y = -(ca * c2 * sb + sa * cb)
    c1 = u * x + w * y
    s1 = w * x - u * y
    a = cos_lo * s1 - sin_lo * c1
    b = c1 * sin_hi - s1 * cos_hi
    return wide * min(wide * a, wide * b), math.sqrt(x * x + y * y)


class ShoulderDesign(NamedTuple):
    """One (alpha, beta) and the range, as the scalars ``theta1_cross`` takes."""

    sa: float
    ca: float
    sb: float
    cb: float
    k: float
    cos_lo: float
    sin_lo: float
    cos_hi: float
    sin_hi: float
    wide: float


@njit(**EXACT)
def shoulder_design(alpha, beta, rng):
    sa, ca, sb, cb = math.sin(alpha), math.cos(alpha), math.sin(beta), math.cos(beta)
    return ShoulderDesign(sa, ca, sb, cb, 1.0 / (sa * sb), rng.cos_lo, rng.sin_lo, rng.cos_hi, rng.sin_hi,
                          -1.0 if rng.wide else 1.0)


@njit(**VECTOR)
def _margin_arm_row(cp, u, w, d, out):
    """out[j] = min(out[j], m / r of ``theta1_cross`` at node j) along one row of one arm (vectorisable)."""
    for j in range(out.shape[0]):
        m, r = theta1_cross(cp[j], u[j], w[j], d.sa, d.ca, d.sb, d.cb, d.k, d.cos_lo, d.sin_lo, d.cos_hi,
                            d.sin_hi, d.wide)
        out[j] = min(out[j], m / max(r, 1e-300))


@njit(**EXACT)
def theta1_row(fields, s, e, d, out):
    """out[j] = ``theta1_margin`` at node s + j (j < e - s), ``d`` a ``shoulder_design``: the common
    workspace's theta1 condition along one grid row, one arm at a time (vectorised)."""
    cp, u, w = fields
    out[:e - s] = np.inf
    for a in range(cp.shape[0]):
        _margin_arm_row(cp[a, s:e], u[a, s:e], w[a, s:e], d, out[:e - s])


@njit(inline="always", **VECTOR)
def theta1_sign(cos_psi, u, w, sa, ca, sb, cb, k, cos_lo, sin_lo, cos_hi, sin_hi, wide):
    """m of ``theta1_cross`` alone: its sign is the membership (r > 0), with neither r's square root nor
    the division by it."""
    c2 = min(1.0, max(-1.0, (cos_psi + ca * cb) * k))
    x = math.sqrt(max(0.0, 1.0 - c2 * c2)) * sb
    y = -(ca * c2 * sb + sa * cb)
    c1 = u * x + w * y
    s1 = w * x - u * y
    return wide * min(wide * (cos_lo * s1 - sin_lo * c1), wide * (c1 * sin_hi - s1 * cos_hi))


@njit(**VECTOR)
def _sign_arm_row(cp, u, w, d, out):
    """out[j] = min(out[j], ``theta1_sign`` at node j) along one row of one arm (vectorisable)."""
    for j in range(out.shape[0]):
        out[j] = min(out[j], theta1_sign(cp[j], u[j], w[j], d.sa, d.ca, d.sb, d.cb, d.k, d.cos_lo, d.sin_lo,
                                         d.cos_hi, d.sin_hi, d.wide))


@njit(**EXACT)
def theta1_inside_row(fields, s, e, d, out):
    """out[j] > 0 exactly where ``theta1_margin`` at node s + j is (j < e - s): every arm's theta1 in its
    range along one grid row, as the sign of min over the arms of ``theta1_sign`` (cheaper than
    ``theta1_row``: the margin's size is only needed on boundary cells)."""
    cp, u, w = fields
    out[:e - s] = np.inf
    for a in range(cp.shape[0]):
        _sign_arm_row(cp[a, s:e], u[a, s:e], w[a, s:e], d, out[:e - s])


@njit(inline="always", **EXACT)
def theta1_margin(fields, k, d):
    """The smallest over the arms of m / r (``theta1_cross``) at node k: about the distance (mm) the
    node is inside the range (> 0) or outside it (``theta1_row`` computes it for a row at once)."""
    cp, u, w = fields
    out = np.inf
    for a in range(cp.shape[0]):
        m, r = theta1_cross(cp[a, k], u[a, k], w[a, k], d.sa, d.ca, d.sb, d.cb, d.k, d.cos_lo, d.sin_lo,
                            d.cos_hi, d.sin_hi, d.wide)
        out = min(out, m / max(r, 1e-300))
    return out


@njit(**EXACT)
def theta1_of_node(cos_psi, cos_az, sin_az, alpha, beta):
    """theta1 (rad, in (-pi, pi]) at one node of one arm, by arctangents (tests); (cos az, sin az) may be
    scaled by rho."""
    sa, ca, sb, cb = math.sin(alpha), math.cos(alpha), math.sin(beta), math.cos(beta)
    c2 = min(1.0, max(-1.0, (cos_psi + ca * cb) / (sa * sb)))
    off = math.atan2(-(ca * c2 * sb + sa * cb), math.sqrt(max(0.0, 1.0 - c2 * c2)) * sb)
    t = math.atan2(sin_az, cos_az) - off
    return math.atan2(math.sin(t), math.cos(t))
