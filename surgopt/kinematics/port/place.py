"""Port placement for RCM arms (dVRK PSMs + ECM) on a patient: per-port, per-pair and per-design kernels.

Numba kernels only; arrays and named tuples in, arrays out. Lengths in m, angles in rad. Each arm's base
frame sits at its port (the RCM) with its neutral shaft (q1 = q2 = 0) pointing at the target's centre
(``docking_frames``); a target point p, in that frame, is reached by the yaw/pitch/insertion mechanism in
closed form (``rcm_inverse``, the inverse of ``rcm_point``; ``surgopt/robots/dvrk/__init__.py`` derives it from the
modified-DH rows and tests/reference.py multiplies them out independently).

The design space factors: what one arm does at one port depends on the port alone (``port_tables``: reach
and dexterity at every target point, the camera's coverage), what two arms do together on the pair of
ports (``pair_tables``: common reach, manipulation angle, shaft clearance inside, arm clearance outside),
and a design (two or three instrument ports and a camera port) combines them (``designs``) at a few
operations per design, so every assignment of >= 10^6 designs is affordable.

One module of ~510 lines: the per-port and per-pair kernels (with the orthogonal and the spherical RCM closed
forms) share the frames, the named tuples and the
bit mask of reasons, and are tested together.
"""
from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from surgopt.jit import EXACT, njit
from surgopt.kinematics.port.reasons import (  # noqa: F401 - the bits the kernels set (and REASONS, for callers)
    ANGLE, CAMERA, CAMERA_SIDE, DOCKING, OUTSIDE, REACH, REASONS, SHAFTS, SPACING,
)


class ArmLimits(NamedTuple):
    """An RCM arm's joint ranges and the reaching point's shaft offset (``dvrk.RcmArm``). ``spherical``: the
    yaw axis (fixed) and the pitch axis (at q1 = 0), unit, in the base frame, are not the orthogonal -y and -x
    of ``shaft_direction`` but any two axes through the RCM (a spherical mechanism, the Raven's kind; the shaft
    at q = 0 is still -z): ``spherical_inverse`` and ``spherical_isotropy`` solve it."""

    yaw_lo: float
    yaw_hi: float
    pitch_lo: float
    pitch_hi: float
    insertion_lo: float
    insertion_hi: float
    along_shaft_m: float
    spherical: bool = False
    yaw_x: float = 0.0
    yaw_y: float = -1.0
    yaw_z: float = 0.0
    pitch_x: float = -1.0
    pitch_y: float = 0.0
    pitch_z: float = 0.0


class Approach(NamedTuple):
    """The directions the jaws must point along at the target (a unit direction in the patient frame) and the
    least cosine between it and the shaft's direction (port to point) for the wrist to give them all:
    cos(wrist bend - cone half-angle); below -1 when any direction will do."""

    dx: float
    dy: float
    dz: float
    cos_min: float


class Camera(NamedTuple):
    """The endoscope: its arm, its field of view (full cone angle), how far before the target's centre its
    tip stops, the depth range it images sharply (from the tip), and its scope angle: the view axis turned that
    far off the shaft (0: a straight scope; 30 deg scopes are common), toward the patient's back when
    ``scope_down`` (the shaft then passes above the target), toward the front otherwise."""

    arm: ArmLimits
    half_fov_rad: float
    standoff_m: float
    near_m: float
    far_m: float
    scope_angle_rad: float = 0.0
    scope_down: bool = True


class Criteria(NamedTuple):
    """What makes a design feasible and how it is scored (``place`` study's [constraints], [objective])."""

    dexterity_length_m: float  # characteristic length L of the isotropy (angular columns scaled by rho / L)
    angle_lo_rad: float  # manipulation angle range (Hanna et al. 1997: 45-75 deg)
    angle_hi_rad: float
    angle_best_rad: float  # 60 deg
    tip_zone_m: float  # the shafts' last stretch before the target centre, left out of their clearance
    min_shaft_gap_m: float  # axis-to-axis distance the shafts need inside (diameter + clearance)
    min_external_m: float  # axis-to-axis distance the arms need outside (along OUTSIDE_LENGTH_M)
    outside_length_m: float
    min_spacing_m: float
    w_reach: float
    w_angle: float
    w_azimuth: float
    w_camera: float
    w_dexterity: float


@njit(**EXACT)
def shaft_direction(q1, q2):
    """u(q1, q2) = (sin q1 cos q2, -sin q2, -cos q1 cos q2): the shaft's unit direction in the base frame.
    (docs/port_placement.md, eq. P1.)"""
    c2 = math.cos(q2)
    return np.array([math.sin(q1) * c2, -math.sin(q2), -math.cos(q1) * c2])


@njit(**EXACT)
def rcm_point(q1, q2, q3, along_shaft_m):
    """The reaching point (wrist or scope tip) in the base frame: (q3 + along_shaft_m) u(q1, q2).
    (docs/port_placement.md, eq. P1.)"""
    return (q3 + along_shaft_m) * shaft_direction(q1, q2)


@njit(**EXACT)
def rcm_inverse(p, along_shaft_m):
    """(q1, q2, q3) with rcm_point(q1, q2, q3) = p for a point below the RCM's equator (u_z < 0 branch,
    |q1| < pi/2, |q2| < pi/2): rho = |p|, q2 = -asin(p_y / rho), q1 = atan2(p_x, -p_z), q3 = rho - offset.
    (docs/port_placement.md, eq. P2.)"""
    rho = math.sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2])
    if rho == 0.0:
        return 0.0, 0.0, -along_shaft_m
    q2 = -math.asin(min(1.0, max(-1.0, p[1] / rho)))
    q1 = math.atan2(p[0], -p[2])
    return q1, q2, rho - along_shaft_m


@njit(**EXACT)
def isotropy(q2, rho, length_m):
    """sigma_min / sigma_max of the position Jacobian [rho du/dq1, rho du/dq2, u] with its angular columns
    divided by the characteristic length L: the columns are orthogonal, of norms rho cos q2 / L, rho / L, 1.
    (docs/port_placement.md, eq. P5.)"""
    a = rho * math.cos(q2) / length_m
    b = rho / length_m
    lo = min(a, min(b, 1.0))
    hi = max(a, max(b, 1.0))
    return lo / hi if hi > 0 else 0.0


@njit(**EXACT)
def turn_angle(w, a, b):
    """The angle about the unit axis w that turns a onto b (both taken orthogonal to w): atan2 of w . (a' x b')
    and a' . b'."""
    wa = w[0] * a[0] + w[1] * a[1] + w[2] * a[2]
    wb = w[0] * b[0] + w[1] * b[1] + w[2] * b[2]
    ax, ay, az = a[0] - wa * w[0], a[1] - wa * w[1], a[2] - wa * w[2]
    bx, by, bz = b[0] - wb * w[0], b[1] - wb * w[1], b[2] - wb * w[2]
    cx, cy, cz = ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx
    return math.atan2(w[0] * cx + w[1] * cy + w[2] * cz, ax * bx + ay * by + az * bz)


@njit(**EXACT)
def rotate(w, angle, v):
    """v turned by ``angle`` about the unit axis w (Rodrigues)."""
    c, s = math.cos(angle), math.sin(angle)
    wv = w[0] * v[0] + w[1] * v[1] + w[2] * v[2]
    cx, cy, cz = w[1] * v[2] - w[2] * v[1], w[2] * v[0] - w[0] * v[2], w[0] * v[1] - w[1] * v[0]
    return np.array([v[0] * c + cx * s + w[0] * wv * (1 - c), v[1] * c + cy * s + w[1] * wv * (1 - c),
                     v[2] * c + cz * s + w[2] * wv * (1 - c)])


@njit(**EXACT)
def spherical_inverse(d, arm):
    """(q1, q2, found) with R(w1, q1) R(w2, q2) s = d for a unit direction d, the shaft s = -z at q = 0, the yaw
    axis w1 and the pitch axis w2 (at q1 = 0) of a spherical ``arm`` (Paden-Kahan subproblem 2: c = R(w2, q2) s
    = R(w1, -q1) d lies on both cones, c = alpha w1 + beta w2 + gamma w1 x w2); of the two solutions the first
    within the yaw and pitch ranges, ``found`` False when neither is (or d is off both cones).
    (docs/port_placement.md, eq. P2.)"""
    w1 = np.array([arm.yaw_x, arm.yaw_y, arm.yaw_z])
    w2 = np.array([arm.pitch_x, arm.pitch_y, arm.pitch_z])
    s = np.array([0.0, 0.0, -1.0])
    w12 = w1[0] * w2[0] + w1[1] * w2[1] + w1[2] * w2[2]
    e1 = w1[0] * d[0] + w1[1] * d[1] + w1[2] * d[2]
    e2 = -w2[2]  # w2 . s
    det = w12 * w12 - 1.0
    alpha = (w12 * e2 - e1) / det
    beta = (w12 * e1 - e2) / det
    x = np.array([w1[1] * w2[2] - w1[2] * w2[1], w1[2] * w2[0] - w1[0] * w2[2], w1[0] * w2[1] - w1[1] * w2[0]])
    g2 = (1.0 - alpha * alpha - beta * beta - 2.0 * alpha * beta * w12) / (x[0] ** 2 + x[1] ** 2 + x[2] ** 2)
    if g2 < 0.0:
        return 0.0, 0.0, False
    for sign in (1.0, -1.0):
        c = alpha * w1 + beta * w2 + sign * math.sqrt(g2) * x
        q2 = turn_angle(w2, s, c)
        q1 = turn_angle(w1, c, d)
        if arm.yaw_lo <= q1 <= arm.yaw_hi and arm.pitch_lo <= q2 <= arm.pitch_hi:
            return q1, q2, True
    return 0.0, 0.0, False


@njit(**EXACT)
def spherical_isotropy(q1, u, rho, arm, length_m):
    """sigma_min / sigma_max of the position Jacobian [rho w1 x u, rho w2(q1) x u, u] of a spherical ``arm``, its
    angular columns divided by L: u is orthogonal to both angular columns, so the Gram matrix is a 2 x 2 block
    [[A, C], [C, B]] and 1, whose eigenvalues are (A + B) / 2 +- sqrt(((A - B) / 2)^2 + C^2).
    (docs/port_placement.md, eq. P5.)"""
    w1 = np.array([arm.yaw_x, arm.yaw_y, arm.yaw_z])
    w2 = rotate(w1, q1, np.array([arm.pitch_x, arm.pitch_y, arm.pitch_z]))
    k = rho / length_m
    a = k * np.array([w1[1] * u[2] - w1[2] * u[1], w1[2] * u[0] - w1[0] * u[2], w1[0] * u[1] - w1[1] * u[0]])
    b = k * np.array([w2[1] * u[2] - w2[2] * u[1], w2[2] * u[0] - w2[0] * u[2], w2[0] * u[1] - w2[1] * u[0]])
    aa = a[0] * a[0] + a[1] * a[1] + a[2] * a[2]
    bb = b[0] * b[0] + b[1] * b[1] + b[2] * b[2]
    ab = a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
    mid, half = 0.5 * (aa + bb), math.sqrt(0.25 * (aa - bb) ** 2 + ab * ab)
    lo = math.sqrt(max(0.0, mid - half))
    hi = math.sqrt(mid + half)
    return min(lo, 1.0) / max(hi, 1.0)


@njit(**EXACT)
def within(q1, q2, q3, arm):
    return (arm.yaw_lo <= q1 <= arm.yaw_hi and arm.pitch_lo <= q2 <= arm.pitch_hi
            and arm.insertion_lo <= q3 <= arm.insertion_hi)


@njit(**EXACT)
def docking_frames(sites, centre, lateral):
    """Each port's base rotation (columns x, y, z): z = (site - centre)/|.| so the neutral shaft -z points at
    the target's centre, x = the patient's ``lateral`` axis made orthogonal to z (yaw swings the shaft
    across the patient), y = z x x. (docs/port_placement.md, eq. P3.)"""
    n = sites.shape[0]
    rot = np.zeros((n, 3, 3))
    for i in range(n):
        z = sites[i] - centre
        z = z / math.sqrt(z[0] ** 2 + z[1] ** 2 + z[2] ** 2)
        x = lateral - (lateral[0] * z[0] + lateral[1] * z[1] + lateral[2] * z[2]) * z
        nx = math.sqrt(x[0] ** 2 + x[1] ** 2 + x[2] ** 2)
        if nx < 1e-9:
            x = np.array([0.0, 1.0, 0.0]) - z[1] * z
            nx = math.sqrt(x[0] ** 2 + x[1] ** 2 + x[2] ** 2)
        x = x / nx
        y = np.array([z[1] * x[2] - z[2] * x[1], z[2] * x[0] - z[0] * x[2], z[0] * x[1] - z[1] * x[0]])
        for r in range(3):
            rot[i, r, 0] = x[r]
            rot[i, r, 1] = y[r]
            rot[i, r, 2] = z[r]
    return rot


def tilted_frames(rot, yaw_rad, pitch_rad):
    """Docking offsets (free docking): each base frame turned by ``yaw_rad`` about its y axis, then by
    ``pitch_rad`` about the turned x axis, rot R_y(yaw) R_x(pitch); (0, 0) is the default docking. The arm's
    neutral shaft (-z) then points that far off the target's centre. (docs/port_placement.md, eq. P3.)"""
    out = np.array(rot, dtype=np.float64, copy=True)
    for i in range(out.shape[0]):
        cy, sy, cp, sp = math.cos(yaw_rad[i]), math.sin(yaw_rad[i]), math.cos(pitch_rad[i]), math.sin(pitch_rad[i])
        ry = np.array([[cy, 0.0, sy], [0.0, 1.0, 0.0], [-sy, 0.0, cy]])
        rx = np.array([[1.0, 0.0, 0.0], [0.0, cp, -sp], [0.0, sp, cp]])
        out[i] = out[i] @ ry @ rx
    return out


@njit(**EXACT)
def external_clearances(sites, axes, length_m):
    """Per pair of ports: the distance between the arms' neutral shaft lines outside the body, each the
    segment from its port ``length_m`` back along its base's outward ``axes[i]`` (unit z of the base frame).
    (docs/port_placement.md, eq. P7.)"""
    n = sites.shape[0]
    out = np.zeros((n, n))
    for i in range(n):
        for j in range(i + 1, n):
            out[i, j] = segment_distance(sites[i] + length_m * axes[i], sites[i], sites[j] + length_m * axes[j],
                                         sites[j])
    return out


@njit(**EXACT)
def to_base(rot, site, p):
    """A world point in the base frame of the arm at ``site`` (rotation ``rot``): rot^T (p - site)."""
    d = p - site
    return np.array([rot[0, 0] * d[0] + rot[1, 0] * d[1] + rot[2, 0] * d[2],
                     rot[0, 1] * d[0] + rot[1, 1] * d[1] + rot[2, 1] * d[2],
                     rot[0, 2] * d[0] + rot[1, 2] * d[1] + rot[2, 2] * d[2]])


@njit(**EXACT)
def instrument_tables(sites, rot, targets, arm, length_m, approach):
    """(reach[site, point], dexterity[site, point]): the RCM inverse kinematics of every target point at every
    port within the joint limits and, when the target asks for one, with the shaft within the wrist's bend of
    the approach cone (``Approach``), and the isotropy there (0 where unreachable). Scalar arithmetic in the
    loop (``rcm_inverse`` and ``isotropy`` written out: no array per point).
    (docs/port_placement.md, eq. P1, P2, P4, P5.)"""
    n, m = sites.shape[0], targets.shape[0]
    reach = np.zeros((n, m), dtype=np.bool_)
    dex = np.zeros((n, m))
    for i in range(n):
        r = rot[i]
        for k in range(m):
            dx, dy, dz = targets[k, 0] - sites[i, 0], targets[k, 1] - sites[i, 1], targets[k, 2] - sites[i, 2]
            px = r[0, 0] * dx + r[1, 0] * dy + r[2, 0] * dz
            py = r[0, 1] * dx + r[1, 1] * dy + r[2, 1] * dz
            pz = r[0, 2] * dx + r[1, 2] * dy + r[2, 2] * dz
            rho = math.sqrt(px * px + py * py + pz * pz)
            if rho == 0.0 or (dx * approach.dx + dy * approach.dy + dz * approach.dz) < approach.cos_min * rho:
                continue
            q3 = rho - arm.along_shaft_m
            if not arm.insertion_lo <= q3 <= arm.insertion_hi:
                continue
            if arm.spherical:
                u = np.array([px / rho, py / rho, pz / rho])
                q1, q2, found = spherical_inverse(u, arm)
                if found:
                    reach[i, k] = True
                    dex[i, k] = spherical_isotropy(q1, u, rho, arm, length_m)
                continue
            q2 = -math.asin(min(1.0, max(-1.0, py / rho)))
            q1 = math.atan2(px, -pz)
            if arm.yaw_lo <= q1 <= arm.yaw_hi and arm.pitch_lo <= q2 <= arm.pitch_hi:
                reach[i, k] = True
                dex[i, k] = isotropy(q2, rho, length_m)
    return reach, dex


@njit(**EXACT)
def scope_tilt_direction(u):
    """The unit vector, orthogonal to the line of sight ``u`` (port to target centre), toward which an angled
    scope's shaft is raised: the patient's front (+z) made orthogonal to ``u``, or, when ``u`` is vertical,
    the cranial axis (+y)."""
    w = np.array([0.0, 0.0, 1.0]) - u[2] * u
    nw = math.sqrt(w[0] ** 2 + w[1] ** 2 + w[2] ** 2)
    if nw < 1e-9:
        w = np.array([0.0, 1.0, 0.0]) - u[1] * u
        nw = math.sqrt(w[0] ** 2 + w[1] ** 2 + w[2] ** 2)
    return w / nw


@njit(**EXACT)
def camera_views(sites, rot, centre, camera):
    """Per port: the endoscope's tip, the unit view axis and whether it can be placed. A straight scope: the
    shaft on the line to the centre, inserted to stop ``standoff_m`` before it. A scope angled by theta whose
    view is to pass through the centre at distance r from the tip, from a port at distance d: in the triangle
    port, tip, centre the angle at the port is alpha, at the tip pi - theta, so sin(alpha) = r sin(theta) / d and
    the shaft reaches l = d sin(theta - alpha) / sin(theta); the shaft is turned by alpha off the line of sight,
    in the plane of ``scope_tilt_direction``, away from the side the view turns to. Where that would insert the
    scope less than its insertion's lower limit (``arm.insertion_lo``: the least insertion, the scope out of its
    cannula and inside the body), it is inserted to that limit: the tip nearer the centre than the standoff, on
    the same shaft (an angled scope's view then passes beside the centre). Beyond its range, with the tip then
    nearer the centre than the scope's sharp range begins (``near_m``), with r sin(theta) > d, or with the shaft
    outside the arm's yaw and pitch in its docking frame ``rot`` (``rcm_inverse``), the port cannot be used.
    (docs/port_placement.md, eq. P10.)"""
    n = sites.shape[0]
    tips = np.zeros((n, 3))
    axes = np.zeros((n, 3))
    ok = np.zeros(n, dtype=np.bool_)
    arm = camera.arm
    theta = camera.scope_angle_rad
    for i in range(n):
        d = centre - sites[i]
        dist = math.sqrt(d[0] ** 2 + d[1] ** 2 + d[2] ** 2)
        u = d / dist
        if theta == 0.0:
            shaft, view, reach = u, u, dist - camera.standoff_m
        else:
            sin_a = camera.standoff_m * math.sin(theta) / dist
            if sin_a > 1.0:
                continue
            alpha = math.asin(sin_a)
            w = scope_tilt_direction(u)
            sign = 1.0 if camera.scope_down else -1.0
            shaft = math.cos(alpha) * u + sign * math.sin(alpha) * w
            view = math.cos(theta - alpha) * u - sign * math.sin(theta - alpha) * w
            reach = dist * math.sin(theta - alpha) / math.sin(theta)
            local = rot[i].T @ shaft  # the shaft in the docking frame: within the arm's yaw and pitch?
            if arm.spherical:
                if not spherical_inverse(local, arm)[2]:
                    continue
            else:
                q1, q2, _ = rcm_inverse(local, 0.0)
                if not (arm.yaw_lo <= q1 <= arm.yaw_hi and arm.pitch_lo <= q2 <= arm.pitch_hi):
                    continue
        q3 = max(reach - arm.along_shaft_m, arm.insertion_lo)
        if q3 > arm.insertion_hi:
            continue
        tip = sites[i] + (q3 + arm.along_shaft_m) * shaft
        left = centre - tip
        if left[0] ** 2 + left[1] ** 2 + left[2] ** 2 < camera.near_m ** 2:  # the tip at (or past) the target
            continue
        tips[i] = tip
        axes[i] = view
        ok[i] = True
    return tips, axes, ok


@njit(**EXACT)
def camera_coverage(sites, rot, targets, centre, camera):
    """The share of target points each port's endoscope images (``camera_views``: its tip and view axis), a
    point counting when it lies inside the view cone and between ``near_m`` and ``far_m`` from the tip. A port
    whose scope cannot be placed (too close, too far, beyond the arm's joints) covers nothing.
    (docs/port_placement.md, eq. P8.)"""
    n, m = sites.shape[0], targets.shape[0]
    out = np.zeros(n)
    tips, axes, ok = camera_views(sites, rot, centre, camera)
    for i in range(n):
        if not ok[i]:
            continue
        tip, u = tips[i], axes[i]
        seen = 0
        for k in range(m):
            v = targets[k] - tip
            r = math.sqrt(v[0] ** 2 + v[1] ** 2 + v[2] ** 2)
            if r < camera.near_m or r > camera.far_m:
                continue
            if (v[0] * u[0] + v[1] * u[1] + v[2] * u[2]) >= r * math.cos(camera.half_fov_rad):
                seen += 1
        out[i] = seen / m
    return out


@njit(**EXACT)
def segment_distance(p0, p1, q0, q1):
    """The shortest distance between segments [p0, p1] and [q0, q1] (``segment_distance_xyz``)."""
    return segment_distance_xyz(p0[0], p0[1], p0[2], p1[0], p1[1], p1[2], q0[0], q0[1], q0[2], q1[0], q1[1], q1[2])


@njit(**EXACT)
def segment_distance_xyz(p0x, p0y, p0z, p1x, p1y, p1z, q0x, q0y, q0z, q1x, q1y, q1z):
    """The shortest distance between segments [p0, p1] and [q0, q1] given by their coordinates, either possibly
    of zero length (Ericson, Real-Time Collision Detection, Sec. 5.1.9: the closest points of the lines, clamped
    to the segments, with its degenerate cases). Scalars only: it runs in the capsules' innermost loops, where an
    array view per call costs a third of the link tables' time."""
    d1x, d1y, d1z = p1x - p0x, p1y - p0y, p1z - p0z
    d2x, d2y, d2z = q1x - q0x, q1y - q0y, q1z - q0z
    rx, ry, rz = p0x - q0x, p0y - q0y, p0z - q0z
    a = d1x * d1x + d1y * d1y + d1z * d1z
    e = d2x * d2x + d2y * d2y + d2z * d2z
    f = d2x * rx + d2y * ry + d2z * rz
    eps = 1e-18
    if a <= eps and e <= eps:
        s = t = 0.0
    elif a <= eps:
        s, t = 0.0, min(1.0, max(0.0, f / e))
    else:
        c = d1x * rx + d1y * ry + d1z * rz
        if e <= eps:
            t, s = 0.0, min(1.0, max(0.0, -c / a))
        else:
            b = d1x * d2x + d1y * d2y + d1z * d2z
            denom = a * e - b * b
            s = min(1.0, max(0.0, (b * f - c * e) / denom)) if denom > eps else 0.0
            t = (b * s + f) / e
            if t < 0.0:
                t, s = 0.0, min(1.0, max(0.0, -c / a))
            elif t > 1.0:
                t, s = 1.0, min(1.0, max(0.0, (b - c) / a))
    wx = rx + s * d1x - t * d2x
    wy = ry + s * d1y - t * d2y
    wz = rz + s * d1z - t * d2z
    return math.sqrt(wx * wx + wy * wy + wz * wz)


@njit(**EXACT)
def angle_between(a, b):
    """The angle between two vectors (rad), by atan2 of |a x b| and a.b (accurate near 0 and pi)."""
    cx = a[1] * b[2] - a[2] * b[1]
    cy = a[2] * b[0] - a[0] * b[2]
    cz = a[0] * b[1] - a[1] * b[0]
    return math.atan2(math.sqrt(cx * cx + cy * cy + cz * cz), a[0] * b[0] + a[1] * b[1] + a[2] * b[2])


@njit(**EXACT)
def pair_tables(sites, reach, dex, targets, centre, crit):
    """Per ordered pair (i < j) of instrument ports, over the target points both reach: the count, the mean
    of the smaller isotropy, the manipulation angle (the angle at the point between the two shafts, Hanna
    et al. 1997) mean / min / max and share within [lo, hi]; the manipulation angle at the centre; the
    shafts' axis distance inside (ports to the centre, less the tip zone); and the distance outside (each
    shaft continued ``outside_length_m`` behind its port). Arrays n x n (entries i < j filled). The unit
    vectors from every point to every port are computed once (no array per pair and point).
    (docs/port_placement.md, eq. P6.)"""
    n, m = sites.shape[0], targets.shape[0]
    count = np.zeros((n, n), dtype=np.int64)
    dex_mean = np.zeros((n, n))
    ang_mean = np.zeros((n, n))
    ang_min = np.zeros((n, n))
    ang_max = np.zeros((n, n))
    ang_share = np.zeros((n, n))
    ang_centre = np.zeros((n, n))
    inside = np.zeros((n, n))
    outside = np.zeros((n, n))
    ends = np.zeros((n, 3))  # where each shaft's clearance stretch ends, before the tip zone
    backs = np.zeros((n, 3))  # the outside end of each shaft
    unit = np.zeros((n, m, 3))  # from target point k toward port i
    for i in range(n):
        d = centre - sites[i]
        dist = math.sqrt(d[0] ** 2 + d[1] ** 2 + d[2] ** 2)
        ends[i] = sites[i] + max(0.0, dist - crit.tip_zone_m) / dist * d
        backs[i] = sites[i] - crit.outside_length_m / dist * d
        for k in range(m):
            vx, vy, vz = sites[i, 0] - targets[k, 0], sites[i, 1] - targets[k, 1], sites[i, 2] - targets[k, 2]
            s = 1.0 / math.sqrt(vx * vx + vy * vy + vz * vz)
            unit[i, k, 0], unit[i, k, 1], unit[i, k, 2] = vx * s, vy * s, vz * s
    for i in range(n):
        for j in range(i + 1, n):
            c, dsum, asum, amin, amax, ain = 0, 0.0, 0.0, 10.0, 0.0, 0
            for k in range(m):
                if reach[i, k] and reach[j, k]:
                    c += 1
                    dsum += min(dex[i, k], dex[j, k])
                    ax, ay, az = unit[i, k, 0], unit[i, k, 1], unit[i, k, 2]
                    bx, by, bz = unit[j, k, 0], unit[j, k, 1], unit[j, k, 2]
                    cx, cy, cz = ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx
                    a = math.atan2(math.sqrt(cx * cx + cy * cy + cz * cz), ax * bx + ay * by + az * bz)
                    asum += a
                    amin = min(amin, a)
                    amax = max(amax, a)
                    if crit.angle_lo_rad <= a <= crit.angle_hi_rad:
                        ain += 1
            count[i, j] = c
            if c > 0:
                dex_mean[i, j] = dsum / c
                ang_mean[i, j] = asum / c
                ang_min[i, j] = amin
                ang_max[i, j] = amax
                ang_share[i, j] = ain / c
            ang_centre[i, j] = angle_between(sites[i] - centre, sites[j] - centre)
            inside[i, j] = segment_distance(sites[i], ends[i], sites[j], ends[j])
            outside[i, j] = segment_distance(backs[i], sites[i], backs[j], sites[j])
    return count, dex_mean, ang_mean, ang_min, ang_max, ang_share, ang_centre, inside, outside


@njit(**EXACT)
def camera_pair_tables(sites, centre, lateral, view_axes=None):
    """Per (instrument port i, camera port k): the azimuth (the angle at the centre between the shaft and the
    optical axis) and the instrument's side of the optical axis (its offset from the camera port along the
    patient's lateral axis made orthogonal to the optical axis, in m). The optical axis runs from the camera
    port to the centre, or, for an angled scope, along the unit ``view_axes[k]`` (``camera_views``) through the
    centre. (docs/port_placement.md, eq. P9.)"""
    n = sites.shape[0]
    azimuth = np.zeros((n, n))
    side = np.zeros((n, n))
    for k in range(n):
        if view_axes is None:
            axis = centre - sites[k]
            axis = axis / math.sqrt(axis[0] ** 2 + axis[1] ** 2 + axis[2] ** 2)
            behind = sites[k] - centre  # from the centre back along the optical axis
        else:
            axis = view_axes[k]
            behind = -axis
        lat = lateral - (lateral[0] * axis[0] + lateral[1] * axis[1] + lateral[2] * axis[2]) * axis
        lat = lat / math.sqrt(lat[0] ** 2 + lat[1] ** 2 + lat[2] ** 2)
        for i in range(n):
            azimuth[i, k] = angle_between(sites[i] - centre, behind)
            d = sites[i] - sites[k]
            side[i, k] = d[0] * lat[0] + d[1] * lat[1] + d[2] * lat[2]
    return azimuth, side
