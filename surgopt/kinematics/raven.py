"""Raven IV kernels of one arm: DH kinematics, analytic IK, isotropy and the theta2 range it allows.

The common workspace of several arms on a plane is in ``surgopt.kinematics.raven_plane``.

Kernels only (numba); lengths mm, angles rad. Paper: Li, Glozman,
Milutinovic, Rosen, ICRA 2011 (eqs. refer to it). Arm side: left = True for
arms 1 and 3, False for 2 and 4 (``surgopt/robots/raven_iv.py``).
"""
from __future__ import annotations

import math

import numpy as np

from surgopt.jit import EXACT, VECTOR, njit
from surgopt.kinematics.small_linalg import mat_mul, rigid_inverse
from surgopt.robots import raven_iv

# joint ranges of Table I (surgopt/robots/raven_iv.py), as compile-time constants
THETA2_MIN_RAD, THETA2_MAX_RAD = (math.radians(v) for v in raven_iv.THETA2_RANGE_DEG)
THETA3_MAX_RAD = math.radians(raven_iv.THETA3_RANGE_DEG[1])
THETA6_MAX_RAD = math.radians(raven_iv.THETA6_RANGE_DEG[1])
D4_MIN_MM, D4_MAX_MM = raven_iv.D4_RANGE_MM
# DH theta of rows 1-3 as sign * q + offset (surgopt/robots/raven_iv.py)
(_L1S, _L1O), (_L2S, _L2O), (_L3S, _L3O) = raven_iv.DH_THETA_ROWS["left"]
(_R1S, _R1O), (_R2S, _R2O), (_R3S, _R3O) = raven_iv.DH_THETA_ROWS["right"]


# ---------------------------------------------------------------------------
# kinematics of one arm (Sec. II)
# ---------------------------------------------------------------------------


@njit(**EXACT)
def dh_transform(theta, d, a, alpha):
    """Standard DH: Rz(theta) Tz(d) Tx(a) Rx(alpha)."""
    ct, st, ca, sa = math.cos(theta), math.sin(theta), math.cos(alpha), math.sin(alpha)
    T = np.zeros((4, 4))
    T[0, 0], T[0, 1], T[0, 2], T[0, 3] = ct, -st * ca, st * sa, a * ct
    T[1, 0], T[1, 1], T[1, 2], T[1, 3] = st, ct * ca, -ct * sa, a * st
    T[2, 1], T[2, 2], T[2, 3] = sa, ca, d
    T[3, 3] = 1.0
    return T


@njit(**EXACT)
def dh_angles(q, left):
    """DH theta of rows 1-3 from the joint variables (Table I; ``raven_iv.DH_THETA_ROWS``)."""
    if left:
        return _dh_theta(q[0], _L1S, _L1O), _dh_theta(q[1], _L2S, _L2O), _dh_theta(q[2], _L3S, _L3O)
    return _dh_theta(q[0], _R1S, _R1O), _dh_theta(q[1], _R2S, _R2O), _dh_theta(q[2], _R3S, _R3O)


@njit(inline="always", **EXACT)
def _dh_theta(q, sign, offset):
    """sign * q + offset, with q's own zero sign kept when there is no offset."""
    if offset == 0.0:
        return q if sign > 0 else -q
    return offset + q if sign > 0 else offset - q


@njit(**EXACT)
def wrist_transform(d4, theta5, theta6, a5):
    """3T6 = T4 T5 T6 (Table I rows 4-6)."""
    T = dh_transform(0.0, d4, 0.0, -math.pi / 2)
    T = mat_mul(T, dh_transform(math.pi / 2 - theta5, 0.0, a5, math.pi / 2))
    return mat_mul(T, dh_transform(math.pi / 2 + theta6, 0.0, 0.0, -math.pi / 2))


@njit(**EXACT)
def forward_kinematics(q, alpha, beta, a5, left):
    """0T6 for q = [theta1, theta2, theta3, d4, theta5, theta6] (eq. 1)."""
    t1, t2, t3 = dh_angles(q, left)
    T = dh_transform(t1, 0.0, 0.0, math.pi - alpha)
    T = mat_mul(T, dh_transform(t2, 0.0, 0.0, -beta))
    T = mat_mul(T, dh_transform(t3, 0.0, 0.0, 0.0))
    return mat_mul(T, wrist_transform(q[3], q[4], q[5], a5))


@njit(**EXACT)
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
    T03 = mat_mul(T06, rigid_inverse(wrist_transform(d4, th5, th6, a5)))
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
    M = mat_mul(mat_mul(dh_transform(0.0, 0.0, 0.0, math.pi - alpha), dh_transform(t2, 0.0, 0.0, -beta)),
            dh_transform(t3, 0.0, 0.0, 0.0))
    R01 = mat_mul(T03[:3, :3], M[:3, :3].T.copy())
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


@njit(**EXACT)
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


@njit(inline="always", **VECTOR)
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


@njit(**EXACT)
def isotropy_at(theta2, alpha, beta):
    return isotropy(math.cos(theta2), math.sin(theta2), math.sin(alpha), math.cos(alpha),
                    math.sin(beta), math.cos(beta))


#: theta2 resolution of the scan that brackets the isotropy maximum (rad);
#: the interval ends are then refined by bisection to THETA2_TOL_RAD.
THETA2_SCAN_RAD = math.radians(0.25)
THETA2_TOL_RAD = 1e-12


@njit(**EXACT)
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


@njit(**EXACT)
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


@njit(**EXACT)
def cone_angle(theta2, alpha, beta):
    """Angle psi between shoulder axis z0 and the tool axis z3: cos psi = sa sb c2 - ca cb (eq. 22)."""
    c = math.sin(alpha) * math.sin(beta) * math.cos(theta2) - math.cos(alpha) * math.cos(beta)
    return math.acos(min(1.0, max(-1.0, c)))
