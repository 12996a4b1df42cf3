"""Raven IV kernels: DH kinematics, analytic IK, isotropy, common workspace on a plane.

Kernels only (numba); lengths mm, angles rad. Paper: Li, Glozman,
Milutinovic, Rosen, ICRA 2011 (eqs. refer to it). Arm side: left = True for
arms 1 and 3, False for 2 and 4 (``surgopt/robots/raven_iv.py``).
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from surgopt.kinematics.small_linalg import _mm, rigid_inverse
from surgopt.robots import raven_iv

_JIT = dict(cache=True, nogil=True, fastmath=False)
_VJIT = dict(cache=True, nogil=True, fastmath=False, error_model="numpy")

# joint ranges of Table I (surgopt/robots/raven_iv.py), as compile-time constants
THETA2_MIN_RAD, THETA2_MAX_RAD = (math.radians(v) for v in raven_iv.THETA2_RANGE_DEG)
THETA3_MAX_RAD = math.radians(raven_iv.THETA3_RANGE_DEG[1])
THETA6_MAX_RAD = math.radians(raven_iv.THETA6_RANGE_DEG[1])
D4_MIN_MM, D4_MAX_MM = raven_iv.D4_RANGE_MM


# ---------------------------------------------------------------------------
# kinematics of one arm (Sec. II)
# ---------------------------------------------------------------------------


@njit(**_JIT)
def dh_transform(theta, d, a, alpha):
    """Standard DH: Rz(theta) Tz(d) Tx(a) Rx(alpha)."""
    ct, st, ca, sa = math.cos(theta), math.sin(theta), math.cos(alpha), math.sin(alpha)
    T = np.zeros((4, 4))
    T[0, 0], T[0, 1], T[0, 2], T[0, 3] = ct, -st * ca, st * sa, a * ct
    T[1, 0], T[1, 1], T[1, 2], T[1, 3] = st, ct * ca, -ct * sa, a * st
    T[2, 1], T[2, 2], T[2, 3] = sa, ca, d
    T[3, 3] = 1.0
    return T


@njit(**_JIT)
def dh_angles(q, left):
    """DH theta of rows 1-3 from the joint variables (Table I)."""
    if left:
        return q[0], -q[1], math.pi / 2 - q[2]
    return math.pi - q[0], q[1], 1.5 * math.pi + q[2]


@njit(**_JIT)
def wrist_transform(d4, theta5, theta6, a5):
    """3T6 = T4 T5 T6 (Table I rows 4-6)."""
    T = dh_transform(0.0, d4, 0.0, -math.pi / 2)
    T = _mm(T, dh_transform(math.pi / 2 - theta5, 0.0, a5, math.pi / 2))
    return _mm(T, dh_transform(math.pi / 2 + theta6, 0.0, 0.0, -math.pi / 2))


@njit(**_JIT)
def forward_kinematics(q, alpha, beta, a5, left):
    """0T6 for q = [theta1, theta2, theta3, d4, theta5, theta6] (eq. 1)."""
    t1, t2, t3 = dh_angles(q, left)
    T = dh_transform(t1, 0.0, 0.0, math.pi - alpha)
    T = _mm(T, dh_transform(t2, 0.0, 0.0, -beta))
    T = _mm(T, dh_transform(t3, 0.0, 0.0, 0.0))
    return _mm(T, wrist_transform(q[3], q[4], q[5], a5))


@njit(**_JIT)
def inverse_kinematics(T06, alpha, beta, a5, left):
    """Analytic IK following Sec. II-B; returns q (6,) and whether it is within the joint ranges.

    1. P_inv = position of the base origin in frame 6 (eq. 2). With Table I's
       DH it is ((a5 - d4 c5) s6, d4 s5, (a5 - d4 c5) c6) for both arms (the
       printed eqs. 3-4 swap x and z). |P_inv|^2 = a5^2 + d4^2 - 2 a5 d4 c5
       (eq. 5) gives d4 by eqs. 9-12; we take the root with d4 > 0 and
       c5 >= 0 (eq. 18), d4^2 = a5^2 + P^2 + 2 a5 sqrt(P^2 - P_y^2), which is
       the valid one whenever d4 c5 > a5 (tool longer than the wrist offset).
    2. theta6 = Atan2 (eqs. 13-16), theta5 = Atan2(s5, c5) (eqs. 17-19).
    3. 0T3 = 0T6 (3T6)^-1 (eq. 20); theta2 from a33 (eqs. 22-25, s2 >= 0);
       theta3: the two solutions of a32 = a c3 + b s3 (eq. 28), chosen by the
       branch check on the other theta1-free element a31 (the role of the
       paper's a13 check, eqs. 29-30); theta1 from 0T1 (eqs. 31-32).
    """
    P = rigid_inverse(T06)[:3, 3]
    P2 = P[0] * P[0] + P[1] * P[1] + P[2] * P[2]
    rho = math.sqrt(max(0.0, P2 - P[1] * P[1]))
    d4 = math.sqrt(a5 * a5 + P2 + 2.0 * a5 * rho)
    s5 = P[1] / d4
    c5 = math.sqrt(max(0.0, 1.0 - s5 * s5))
    k = a5 - d4 * c5
    th6 = math.atan2(P[0] / k, P[2] / k)
    th5 = math.atan2(s5, c5)
    T03 = _mm(T06, rigid_inverse(wrist_transform(d4, th5, th6, a5)))
    sa, ca, sb, cb = math.sin(alpha), math.cos(alpha), math.sin(beta), math.cos(beta)
    c2 = min(1.0, max(-1.0, (T03[2, 2] + ca * cb) / (sa * sb)))
    t2abs = math.acos(c2)
    t2 = -t2abs if left else t2abs  # theta2 in [0, pi] for both arms
    st2 = math.sin(t2)
    # row 2 of Rx(pi - alpha) Rz(t2) Rx(-beta) before Rz(t3): (w0, w1, w2)
    w0 = sa * st2
    w1 = sa * c2 * cb + ca * sb
    a31, a32 = T03[2, 0], T03[2, 1]
    # eq. 28 on a32 = -w0 s3 + w1 c3 = r cos(t3 + phi): two candidates
    r = math.sqrt(w0 * w0 + w1 * w1)
    phi = math.atan2(w0, w1)
    base = math.acos(min(1.0, max(-1.0, a32 / r)))
    best_t3 = 0.0
    best_err = 1e300
    for sgn in (1.0, -1.0):
        t3c = sgn * base - phi
        err = abs(w0 * math.cos(t3c) + w1 * math.sin(t3c) - a31)  # a31 check
        if err < best_err:
            best_err = err
            best_t3 = t3c
    t3 = best_t3
    M = _mm(_mm(dh_transform(0.0, 0.0, 0.0, math.pi - alpha), dh_transform(t2, 0.0, 0.0, -beta)),
            dh_transform(t3, 0.0, 0.0, 0.0))
    R01 = _mm(T03[:3, :3], M[:3, :3].T.copy())
    t1 = math.atan2(R01[1, 0], R01[0, 0])
    q = np.empty(6)
    if left:
        q[0], q[1], q[2] = t1, -t2, math.pi / 2 - t3
    else:
        q[0], q[1], q[2] = math.pi - t1, t2, t3 - 1.5 * math.pi
    q[2] = (q[2] + math.pi) % (2 * math.pi) - math.pi
    q[0] = (q[0] + math.pi) % (2 * math.pi) - math.pi
    q[3], q[4], q[5] = d4, th5, th6
    ok = (THETA2_MIN_RAD <= q[1] <= THETA2_MAX_RAD and abs(q[2]) <= THETA3_MAX_RAD
          and abs(q[5]) <= THETA6_MAX_RAD and D4_MIN_MM <= d4 <= D4_MAX_MM)
    return q, ok


# ---------------------------------------------------------------------------
# isotropy of the spherical mechanism (Sec. III-C)
# ---------------------------------------------------------------------------


@njit(**_JIT)
def spherical_jacobian(theta2, alpha, beta, left):
    """3J of eqs. 41 (left) / 42 (right): columns theta1, theta2, d4 in frame 3."""
    s2, c2 = math.sin(theta2), math.cos(theta2)
    sa, ca, sb, cb = math.sin(alpha), math.cos(alpha), math.sin(beta), math.cos(beta)
    sign = 1.0 if left else -1.0
    J = np.zeros((3, 3))
    J[0, 0] = sign * (c2 * cb * sa + sb * ca)
    J[0, 1] = -sign * sb
    J[1, 0] = s2 * sa
    J[2, 0] = c2 * sb * sa - cb * ca
    J[2, 1] = cb
    J[2, 2] = 1.0
    return J


@njit(inline="always", **_VJIT)
def isotropy(c2, s2, sa, ca, sb, cb):
    """Iso = 1/cond(J_s) of the 2x2 top-left block of eq. 41 (eq. 35), closed form.

    For a 2x2 matrix with squared Frobenius norm S and |det| D, the singular
    values satisfy s1^2 + s2^2 = S, s1 s2 = D, so 1/cond = 2D / (S + sqrt(S^2 - 4D^2)).
    Depends on theta2 only (Fig. 6b); the same for left and right arms.
    """
    a = c2 * cb * sa + sb * ca
    c = s2 * sa
    S = a * a + sb * sb + c * c
    D = abs(sb * c)
    return 2.0 * D / (S + math.sqrt(max(0.0, S * S - 4.0 * D * D)) + 1e-300)


@njit(**_JIT)
def isotropy_at(theta2, alpha, beta):
    return isotropy(math.cos(theta2), math.sin(theta2), math.sin(alpha), math.cos(alpha),
                    math.sin(beta), math.cos(beta))


#: theta2 resolution of the scan that brackets the isotropy maximum (rad);
#: the interval ends are then refined by bisection to THETA2_TOL_RAD.
THETA2_SCAN_RAD = math.radians(0.25)
THETA2_TOL_RAD = 1e-12


@njit(**_JIT)
def _iso_crossing(end, inside, alpha, beta, iso_min):
    """Between an interval end and a point where Iso >= iso_min: the end itself if it qualifies,
    else the crossing Iso = iso_min found by bisection (to THETA2_TOL_RAD)."""
    if isotropy_at(end, alpha, beta) >= iso_min:
        return end
    out, good = end, inside
    while abs(good - out) > THETA2_TOL_RAD:
        m = 0.5 * (out + good)
        if isotropy_at(m, alpha, beta) >= iso_min:
            good = m
        else:
            out = m
    return good


@njit(**_JIT)
def theta2_interval(alpha, beta, iso_min, lo, hi):
    """The theta2 interval within [lo, hi] where Iso >= iso_min (Fig. 6a).

    Iso(theta2) has a single interior maximum for every alpha, beta in
    (0, 90] deg (checked on a 5 deg grid in tests), so the set is one
    interval: bracket the maximum by a scan, then bisect each side.
    Returns (t_lo, t_hi, ok); ok is False when no theta2 qualifies.
    """
    n = max(2, int((hi - lo) / THETA2_SCAN_RAD) + 1)
    best_t = lo
    best = -1.0
    for k in range(n + 1):
        t = lo + (hi - lo) * k / n
        v = isotropy_at(t, alpha, beta)
        if v > best:
            best, best_t = v, t
    if best < iso_min:
        return lo, lo, False
    t_lo = _iso_crossing(lo, best_t, alpha, beta, iso_min)
    t_hi = _iso_crossing(hi, best_t, alpha, beta, iso_min)
    return t_lo, t_hi, True


@njit(**_JIT)
def cone_angle(theta2, alpha, beta):
    """Angle psi between shoulder axis z0 and the tool axis z3: cos psi = sa sb c2 - ca cb (eq. 22)."""
    c = math.sin(alpha) * math.sin(beta) * math.cos(theta2) - math.cos(alpha) * math.cos(beta)
    return math.acos(min(1.0, max(-1.0, c)))


# ---------------------------------------------------------------------------
# common workspace on the reference plane (Sec. III, IV)
# ---------------------------------------------------------------------------


@njit(**_VJIT)
def arm_cone_geometry(xs, ys, depth, port, axis, cos_psi, dist):
    """Per grid node: cos of the angle psi between the shoulder axis and the direction to the node, and distance.

    Node (xs[i], ys[j], -depth); fills cos_psi[i*ny + j], dist[i*ny + j]. These
    are independent of alpha, beta and Iso_min, so one geometry serves 125
    designs. (cos psi, not psi: no acos, and cos is what eq. 22 and the
    isotropy need.)
    """
    ny = ys.shape[0]
    for i in range(xs.shape[0]):
        for j in range(ny):
            vx, vy, vz = xs[i] - port[0], ys[j] - port[1], -depth - port[2]
            r = math.sqrt(vx * vx + vy * vy + vz * vz)
            c = (vx * axis[0] + vy * axis[1] + vz * axis[2]) / r
            cos_psi[i * ny + j] = min(1.0, max(-1.0, c))
            dist[i * ny + j] = r


@njit(**_VJIT)
def arm_isotropy(cos_psi, alpha, beta, out):
    """Isotropy at each node for one arm: theta2 from cos psi (eq. 22), then eq. 35."""
    sa, ca, sb, cb = math.sin(alpha), math.cos(alpha), math.sin(beta), math.cos(beta)
    k = 1.0 / (sa * sb)
    for j in range(cos_psi.shape[0]):
        c2 = min(1.0, max(-1.0, (cos_psi[j] + ca * cb) * k))
        s2 = math.sqrt(1.0 - c2 * c2)
        out[j] = isotropy(c2, s2, sa, ca, sb, cb)


@njit(**_JIT)
def marching_squares(m, nx, ny, step, i0=0, i1=-1, j0=0, j1=-1):
    """Length and enclosed area of the zero contour of a node field m (nx*ny, row i = x).

    Crossings on cell edges are interpolated linearly; a saddle cell is
    resolved by the mean of its corners. Only cells with lower corner in
    [i0, i1) x [j0, j1) are visited (all when i1, j1 < 0): pass a box that
    holds every node with m > 0 plus one cell of margin. Area is the area of {m > 0} with the
    same interpolated boundary (per-cell polygon clipping).
    """
    length = 0.0
    area = 0.0
    cx = np.empty(8)  # scratch, allocated once: the inside polygon of a cell
    cy = np.empty(8)
    ex = np.empty(4)  # and its edge crossings
    ey = np.empty(4)
    i1 = nx - 1 if i1 < 0 else min(i1, nx - 1)
    j1 = ny - 1 if j1 < 0 else min(j1, ny - 1)
    for i in range(max(0, i0), i1):
        for j in range(max(0, j0), j1):
            v0 = m[i * ny + j]            # (0, 0)
            v1 = m[(i + 1) * ny + j]      # (1, 0)
            v2 = m[(i + 1) * ny + j + 1]  # (1, 1)
            v3 = m[i * ny + j + 1]        # (0, 1)
            in0, in1, in2, in3 = v0 > 0, v1 > 0, v2 > 0, v3 > 0
            n_in = in0 + in1 + in2 + in3
            if n_in == 0:
                continue
            if n_in == 4:
                area += 1.0
                continue
            # polygon of the inside part, walking the square 0 -> 1 -> 2 -> 3
            npts = 0
            vs = (v0, v1, v2, v3)
            px = (0.0, 1.0, 1.0, 0.0)
            py = (0.0, 0.0, 1.0, 1.0)
            ne = 0
            for k in range(4):
                a, b = vs[k], vs[(k + 1) % 4]
                if a > 0:
                    cx[npts], cy[npts] = px[k], py[k]
                    npts += 1
                if (a > 0) != (b > 0):
                    t = a / (a - b)
                    x = px[k] + t * (px[(k + 1) % 4] - px[k])
                    y = py[k] + t * (py[(k + 1) % 4] - py[k])
                    cx[npts], cy[npts] = x, y
                    npts += 1
                    ex[ne], ey[ne] = x, y
                    ne += 1
            # shoelace (a saddle's polygon is self-consistent for area purposes)
            s = 0.0
            for k in range(npts):
                k2 = (k + 1) % npts
                s += cx[k] * cy[k2] - cx[k2] * cy[k]
            area += abs(s) * 0.5
            if ne == 2:
                length += math.hypot(ex[1] - ex[0], ey[1] - ey[0])
            elif ne == 4:
                centre = 0.25 * (v0 + v1 + v2 + v3)
                # crossings are ordered around the square starting on edge 0-1
                if (centre > 0) == in0:
                    length += math.hypot(ex[1] - ex[0], ey[1] - ey[0]) + math.hypot(ex[3] - ex[2], ey[3] - ey[2])
                else:
                    length += math.hypot(ex[3] - ex[0], ey[3] - ey[0]) + math.hypot(ex[2] - ex[1], ey[2] - ey[1])
    return length * step, area * step * step


@njit(**_VJIT)
def _margin_update(margin, cos_psi, dist, c_lo, c_hi):
    """margin = min(margin, (cos psi - c_lo) dist, (c_hi - cos psi) dist), a vectorisable loop.

    psi in [psi_lo, psi_hi] <=> cos psi in [cos psi_hi, cos psi_lo] = [c_lo, c_hi];
    the margin is smooth and zero on the cone boundary, which is all marching
    squares needs (about dist * sin(psi) * angle: mm-like near the boundary).
    """
    for j in range(margin.shape[0]):
        r = dist[j]
        c = cos_psi[j]
        margin[j] = min(margin[j], min((c - c_lo) * r, (c_hi - c) * r))


@njit(**_JIT)
def _box_margin(margin, reach, cos_psi, dist, c_lo, c_hi, ny, i0, i1, j0, j1):
    """Margin of one design on the node box [i0, i1] x [j0, j1] (inclusive), row by row."""
    for i in range(i0, i1 + 1):
        s, e = i * ny + j0, i * ny + j1 + 1
        margin[s:e] = reach[s:e]
        for a in range(cos_psi.shape[0]):
            _margin_update(margin[s:e], cos_psi[a, s:e], dist[a, s:e], c_lo, c_hi)


@njit(**_JIT)
def _box_members(margin, iso_node, ny, i0, i1, j0, j1):
    """Count, isotropy sum and minimum, and bounding box of the nodes with margin > 0."""
    count = 0
    total = 0.0
    mn = 1.0
    b0, b1, c0, c1 = i1 + 1, i0 - 1, j1 + 1, j0 - 1
    for i in range(i0, i1 + 1):
        for j in range(j0, j1 + 1):
            if margin[i * ny + j] > 0.0:
                v = iso_node[i * ny + j]
                count += 1
                total += v
                mn = min(mn, v)
                b0, b1 = min(b0, i), max(b1, i)
                c0, c1 = min(c0, j), max(c1, j)
    return count, total, mn, b0, b1, c0, c1


@njit(**_JIT)
def evaluate_designs(cos_psi, dist, nx, ny, step, d4_max, alphas, betas, iso_mins, psi_lo, psi_hi, has, out):
    """All (alpha, beta, Iso_min) designs of one geometry (ports and shoulder axes fixed).

    ``cos_psi``, ``dist``: (arms, nx*ny) from ``arm_cone_geometry``. ``psi_lo``,
    ``psi_hi``, ``has``: (A, B, I) cone-angle interval allowed by the theta2
    range narrowed by Iso_min (``has`` False: no theta2 qualifies). A node is in
    the common workspace when for every arm psi_lo <= psi <= psi_hi and
    dist <= d4_max (theta1 unlimited); its margin, the smallest of
    (cos psi - cos psi_hi) dist, (cos psi_lo - cos psi) dist and d4_max - dist
    over arms (zero on the boundary), feeds marching squares. A node's
    isotropy is the minimum over the arms. ``out`` (A*B*I, 6): area_mm2,
    perimeter_mm, n_points, iso_sum, iso_min_actual, 1 if any point.

    Work sharing: a higher Iso_min only narrows the interval, so for each
    (alpha, beta) the loosest Iso_min is evaluated on the whole grid first;
    the stricter ones (and the isotropy) only inside the box around its
    workspace, and not at all when it is empty.
    """
    n_arms, n = cos_psi.shape
    reach = np.empty(n)
    for j in range(n):
        reach[j] = d4_max - dist[0, j]
    for a in range(1, n_arms):
        for j in range(n):
            reach[j] = min(reach[j], d4_max - dist[a, j])
    # range of cos psi over the nodes every arm can reach: a design whose cone interval misses it
    # for some arm has no common workspace, whatever the grid says (checked before any grid pass)
    c_min = np.full(n_arms, 2.0)
    c_max = np.full(n_arms, -2.0)
    for a in range(n_arms):
        for j in range(n):
            if reach[j] > 0.0:
                c_min[a] = min(c_min[a], cos_psi[a, j])
                c_max[a] = max(c_max[a], cos_psi[a, j])
    iso_arm = np.empty(ny)
    iso_node = np.empty(n)
    margin = np.empty(n)
    order = np.argsort(iso_mins)
    n_iso = iso_mins.shape[0]
    for ia in range(alphas.shape[0]):
        for ib in range(betas.shape[0]):
            base = (ia * betas.shape[0] + ib) * n_iso
            box = (0, -1, 0, -1)
            first = True
            for k in order:
                row = base + k
                out[row, :] = 0.0
                if not has[ia, ib, k]:
                    continue
                c_lo, c_hi = math.cos(psi_hi[ia, ib, k]), math.cos(psi_lo[ia, ib, k])
                if first:  # loosest Iso_min: the whole grid
                    first = False
                    missed = False
                    for a in range(n_arms):
                        missed = missed or c_hi < c_min[a] or c_lo > c_max[a]
                    if missed:
                        break  # this and every stricter Iso_min are empty
                    _box_margin(margin, reach, cos_psi, dist, c_lo, c_hi, ny, 0, nx - 1, 0, ny - 1)
                    iso_node[:] = 1.0  # not used for counting; bounding box only
                    c, _, _, b0, b1, c0, c1 = _box_members(margin, iso_node, ny, 0, nx - 1, 0, ny - 1)
                    if c == 0:
                        break  # every stricter Iso_min is empty too
                    box = (max(0, b0 - 1), min(nx - 1, b1 + 1), max(0, c0 - 1), min(ny - 1, c1 + 1))
                    for i in range(box[0], box[1] + 1):
                        s, e = i * ny + box[2], i * ny + box[3] + 1
                        iso_node[s:e] = 1.0
                        for a in range(n_arms):
                            arm_isotropy(cos_psi[a, s:e], alphas[ia], betas[ib], iso_arm[:e - s])
                            for j in range(e - s):
                                iso_node[s + j] = min(iso_node[s + j], iso_arm[j])
                else:
                    _box_margin(margin, reach, cos_psi, dist, c_lo, c_hi, ny, box[0], box[1], box[2], box[3])
                count, total, mn, b0, b1, c0, c1 = _box_members(margin, iso_node, ny, box[0], box[1], box[2], box[3])
                if count == 0:
                    continue
                length, area = marching_squares(margin, nx, ny, step, b0 - 1, b1 + 1, c0 - 1, c1 + 1)
                out[row, 0] = area
                out[row, 1] = length
                out[row, 2] = count
                out[row, 3] = total
                out[row, 4] = mn
                out[row, 5] = 1.0
