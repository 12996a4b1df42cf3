"""PA10-7C under a remote-centre-of-motion constraint (Locke & Patel 2007).

Kernels only. Everything is computed without trigonometric calls so that the
per-point loop has no calls and no branches and LLVM can vectorise it:
joint axes and origins come straight from the closed-form IK geometry (paper
Sec. III-C, eq. 9) instead of from joint angles, and joint limits are checked
as cosine comparisons.

Conventions (see ``surgopt/robots/pa10_7c.py``):
  - world frame at the PA10 base, z up; the shoulder (S2 axis) is at height d1.
  - active joints S1, S2, E1, E2, W1 (DH joints 1, 2, 4, 5, 6); S3 = W2 = 0.
  - the tool tip is ``tool_offset_m`` beyond the wrist centre along the tool
    axis (d7 + 587 mm when the 587 mm is measured from the flange).
  - the skin normal k_rcm is the world z axis; e_x, e_y are the x, y
    components of (tool line ∩ skin plane) − RCM (eq. 8, Fig. 2).

The per-pose quantity returned is the pair of extreme singular values of
B = A_x N, where A = J_a Q is the alternative Jacobian (eq. 8) with columns
scaled by the maximum joint speeds Q (Stocco & Salcudean), A_x its three tip
rows and N an orthonormal basis of the null space of its two constraint rows.
B is the constrained forward map from normalised joint speeds to tip velocity
(m/s); its singular values are the reciprocals of those of Q^-1 J_r (eqs. 5-6),
so GII = min sigma_min(B) / max sigma_max(B) equals eq. 7 on Q^-1 J_r.
"""
from __future__ import annotations

import numpy as np
from numba import njit

#: J_a counts as singular when a pivot falls below this fraction of its size.
SINGULAR_RTOL = 1e-12
#: Guards against 0/0 in branch-free normalisations.
TINY = 1e-300

STATUS_OK = 0
STATUS_UNREACHABLE = 1  # out of reach or outside a joint limit
STATUS_SINGULAR = 2  # J_a rank deficient (eq. 5 text): GII contribution 0

_JIT = dict(cache=True, nogil=True, fastmath=False, error_model="numpy")


@njit(inline="always", **_JIT)
def _cross(ax, ay, az, bx, by, bz):
    return ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx


#: Chebyshev coefficients (in t = 2 s - 1, s = sqrt((1 + x) / 2)) of
#: g(x) = cos(acos(x) / 3), the largest root of 4 g^3 - 3 g = x. g is analytic
#: in s on [0, 1], so degree 16 reaches 4e-15 relative (least squares on 2000
#: Chebyshev nodes against a long-double reference; tests re-check it).
TRISECT_CHEB = (
    0.7580911654351291,
    0.24933602102708852,
    -0.008021174548795217,
    0.000655646818891204,
    -6.892435632794781e-05,
    8.188877173085825e-06,
    -1.0466055459885706e-06,
    1.4043322844539394e-07,
    -1.9510326148143444e-08,
    2.7823203915058586e-09,
    -4.0493900533214715e-10,
    5.990385568903754e-11,
    -8.980916694323932e-12,
    1.361526646093866e-12,
    -2.0836966865110964e-13,
    3.21376588840264e-14,
    -4.917209605306292e-15,
)


@njit(inline="always", **_JIT)
def cos_third_acos(x):
    """cos(acos(x) / 3) for x in [-1, 1] without trigonometric calls (vectorisable)."""
    s = np.sqrt(0.5 * (1.0 + x))
    t = 2.0 * s - 1.0
    # Clenshaw recurrence, written out so that the caller's loop vectorises
    c = TRISECT_CHEB
    t2 = 2.0 * t
    b1 = c[16]
    b2 = 0.0
    b1, b2 = t2 * b1 - b2 + c[15], b1
    b1, b2 = t2 * b1 - b2 + c[14], b1
    b1, b2 = t2 * b1 - b2 + c[13], b1
    b1, b2 = t2 * b1 - b2 + c[12], b1
    b1, b2 = t2 * b1 - b2 + c[11], b1
    b1, b2 = t2 * b1 - b2 + c[10], b1
    b1, b2 = t2 * b1 - b2 + c[9], b1
    b1, b2 = t2 * b1 - b2 + c[8], b1
    b1, b2 = t2 * b1 - b2 + c[7], b1
    b1, b2 = t2 * b1 - b2 + c[6], b1
    b1, b2 = t2 * b1 - b2 + c[5], b1
    b1, b2 = t2 * b1 - b2 + c[4], b1
    b1, b2 = t2 * b1 - b2 + c[3], b1
    b1, b2 = t2 * b1 - b2 + c[2], b1
    b1, b2 = t2 * b1 - b2 + c[1], b1
    return t * b1 - b2 + c[0]


@njit(inline="always", **_JIT)
def sym3_lambda_max(a00, a11, a22, a01, a02, a12):
    """Largest eigenvalue of a symmetric 3x3 matrix, closed form.

    lambda_max = m + 2 sqrt(p) cos(acos(q / p^1.5) / 3) with m = tr / 3,
    p = ||A - m I||_F^2 / 6, q = det(A - m I) / 2 (Smith 1961). Every term is
    non-negative for the largest root, so there is no cancellation: relative
    accuracy ~1e-15 even for repeated eigenvalues.
    """
    m = (a00 + a11 + a22) * (1.0 / 3.0)
    b00, b11, b22 = a00 - m, a11 - m, a22 - m
    p = (b00 * b00 + b11 * b11 + b22 * b22 + 2.0 * (a01 * a01 + a02 * a02 + a12 * a12)) * (1.0 / 6.0)
    q = 0.5 * (b00 * (b11 * b22 - a12 * a12) - a01 * (a01 * b22 - a12 * a02) + a02 * (a01 * a12 - b11 * a02))
    sp = np.sqrt(p)
    x = q / (p * sp + TINY)
    x = min(1.0, max(-1.0, x))
    return m + 2.0 * sp * cos_third_acos(x)


@njit(inline="always", **_JIT)
def gram_lambda_max(b00, b01, b02, b10, b11, b12, b20, b21, b22):
    """Largest eigenvalue of B^T B, i.e. sigma_max(B)^2, for a 3x3 B."""
    return sym3_lambda_max(b00 * b00 + b10 * b10 + b20 * b20,
                           b01 * b01 + b11 * b11 + b21 * b21,
                           b02 * b02 + b12 * b12 + b22 * b22,
                           b00 * b01 + b10 * b11 + b20 * b21,
                           b00 * b02 + b10 * b12 + b20 * b22,
                           b01 * b02 + b11 * b12 + b21 * b22)


@njit(inline="always", **_JIT)
def singular_values_3x3(b00, b01, b02, b10, b11, b12, b20, b21, b22):
    """Extreme singular values (min, max) of a 3x3 matrix B, closed form.

    sigma_max^2 = lambda_max(B^T B). sigma_min = |det B| / sigma_max(cof B),
    since the cofactor matrix has singular values sigma_i sigma_j and its
    largest is sigma_1 sigma_2. Cofactors and the determinant are formed
    from B itself, so sigma_min keeps a relative accuracy ~eps * cond(B)
    (the Gram route B^T B alone would give eps * cond(B)^2). Five square
    roots and two divisions, no iteration (the Jacobi SVD this replaced
    spent 70% of the kernel's time).
    """
    smax2 = gram_lambda_max(b00, b01, b02, b10, b11, b12, b20, b21, b22)
    c00 = b11 * b22 - b12 * b21
    c01 = b12 * b20 - b10 * b22
    c02 = b10 * b21 - b11 * b20
    c10 = b02 * b21 - b01 * b22
    c11 = b00 * b22 - b02 * b20
    c12 = b01 * b20 - b00 * b21
    c20 = b01 * b12 - b02 * b11
    c21 = b02 * b10 - b00 * b12
    c22 = b00 * b11 - b01 * b10
    det = b00 * c00 + b01 * c01 + b02 * c02
    cmax2 = gram_lambda_max(c00, c01, c02, c10, c11, c12, c20, c21, c22)
    smin = abs(det) / (np.sqrt(cmax2) + TINY)
    return smin, np.sqrt(smax2)


@njit(inline="always", **_JIT)
def _dot5(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2] + a[3] * b[3] + a[4] * b[4]


@njit(inline="always", **_JIT)
def _reflect5(row, v, two_over_vv):
    """Householder reflection (I - 2 v v^T / v^T v) applied to a row 5-tuple."""
    f = two_over_vv * _dot5(row, v)
    return (row[0] - f * v[0], row[1] - f * v[1], row[2] - f * v[2],
            row[3] - f * v[3], row[4] - f * v[4])


@njit(inline="always", **_JIT)
def _jacobian_column(zx, zy, zz, ox, oy, oz, px, py, pz, cx, cy, cz, kx, ky, kz, ikz, q):
    """Column of A = J_a Q for a revolute axis z through o (eq. 8).

    Rows 0-2: tip velocity z x (p - o). Rows 3-4: rate of the RCM error
    e_x, e_y, i.e. of the x, y of (tool line ∩ skin plane z = c_z); with the
    body point at c moving at g = z x (c - o) this is g_xy - (g_z / k_z) k_xy.
    """
    tx, ty, tz = _cross(zx, zy, zz, px - ox, py - oy, pz - oz)
    gx, gy, gz = _cross(zx, zy, zz, cx - ox, cy - oy, cz - oz)
    return (q * tx, q * ty, q * tz, q * (gx - gz * ikz * kx), q * (gy - gz * ikz * ky))


@njit(inline="always", **_JIT)
def constrained_extremes(c0, c1, c2, c3, c4):
    """Extreme singular values of B = A_x N from the five columns of A.

    Two Householder reflections, applied from the right, map the constraint
    rows A[3], A[4] onto the first two coordinates; what remains of the tip
    rows in the last three coordinates is B (eqs. 5-6 without forming J_a^-1).
    Returns (0, sigma_max, singular) when J_a is rank deficient.
    """
    r0 = (c0[0], c1[0], c2[0], c3[0], c4[0])
    r1 = (c0[1], c1[1], c2[1], c3[1], c4[1])
    r2 = (c0[2], c1[2], c2[2], c3[2], c4[2])
    r3 = (c0[3], c1[3], c2[3], c3[3], c4[3])
    r4 = (c0[4], c1[4], c2[4], c3[4], c4[4])
    scale = max(max(max(abs(r0[0]), abs(r0[1])), max(abs(r0[2]), abs(r0[3]))), abs(r0[4]))
    for r in (r1, r2, r3, r4):
        scale = max(scale, max(max(max(abs(r[0]), abs(r[1])), max(abs(r[2]), abs(r[3]))), abs(r[4])))
    # reflection 1: row 3 -> (-+|r3|, 0, 0, 0, 0)
    n3 = np.sqrt(_dot5(r3, r3))
    v = (r3[0] + (n3 if r3[0] >= 0.0 else -n3), r3[1], r3[2], r3[3], r3[4])
    vv = 2.0 / (_dot5(v, v) + TINY)
    r0 = _reflect5(r0, v, vv)
    r1 = _reflect5(r1, v, vv)
    r2 = _reflect5(r2, v, vv)
    r4 = _reflect5(r4, v, vv)
    # reflection 2: row 4 (coordinates 1..4) -> (*, -+|.|, 0, 0, 0)
    n4 = np.sqrt(r4[1] * r4[1] + r4[2] * r4[2] + r4[3] * r4[3] + r4[4] * r4[4])
    v = (0.0, r4[1] + (n4 if r4[1] >= 0.0 else -n4), r4[2], r4[3], r4[4])
    vv = 2.0 / (_dot5(v, v) + TINY)
    r0 = _reflect5(r0, v, vv)
    r1 = _reflect5(r1, v, vv)
    r2 = _reflect5(r2, v, vv)
    smin, smax = singular_values_3x3(r0[2], r0[3], r0[4], r1[2], r1[3], r1[4],
                                     r2[2], r2[3], r2[4])
    tol = SINGULAR_RTOL * scale
    singular = (n3 <= tol) or (n4 <= tol) or (smin <= tol)
    return (0.0 if singular else smin), smax, singular


@njit(inline="always", **_JIT)
def rcm_ik(px, py, pz, cx, cy, cz, d1, d3, d5, tool_offset_m, elbow_sign, cl0, cl1, cl2, cl3, cl4):
    """Closed-form IK with the tool axis through the RCM (eq. 9), as geometry.

    Tip p, RCM c (m); ``cl0..cl4`` are cos(min(limit, pi)) of the S1, S2,
    E1, E2, W1 joint limits. Returns the tool axis k, wrist centre w, S2/E1
    axis n, elbow e, forearm direction f (each as 3 scalars) and whether the
    pose is reachable within the joint limits (S3 = W2 = 0, Sec. III-C).
    """
    # tool axis from RCM to tip (eq. 9) and the wrist centre
    kx, ky, kz = px - cx, py - cy, pz - cz
    il = 1.0 / (np.sqrt(kx * kx + ky * ky + kz * kz) + TINY)
    kx, ky, kz = kx * il, ky * il, kz * il
    wx, wy, wz = px - tool_offset_m * kx, py - tool_offset_m * ky, pz - tool_offset_m * kz
    # S1: arm plane through the z axis and the wrist centre
    r = np.sqrt(wx * wx + wy * wy)
    ir = 1.0 / (r + TINY)
    nx, ny, nz = -wy * ir, wx * ir, 0.0  # S2 and E1 axis
    # S2/E1: planar two-link IK in the arm plane, elbow above the s-w line
    sx, sy, sz = wx, wy, wz - d1
    dist = np.sqrt(sx * sx + sy * sy + sz * sz) + TINY
    idist = 1.0 / dist
    ux, uy, uz = sx * idist, sy * idist, sz * idist
    cos_a = (d3 * d3 + dist * dist - d5 * d5) * (0.5 / d3) * idist
    sin_a = elbow_sign * np.sqrt(max(0.0, 1.0 - cos_a * cos_a))
    vx, vy, vz = _cross(ux, uy, uz, nx, ny, nz)  # in-plane normal, "up"
    ax_, ay_, az_ = cos_a * ux + sin_a * vx, cos_a * uy + sin_a * vy, cos_a * uz + sin_a * vz
    ex, ey, ez = d3 * ax_, d3 * ay_, d1 + d3 * az_
    id5 = 1.0 / d5
    fx, fy, fz = (wx - ex) * id5, (wy - ey) * id5, (wz - ez) * id5
    # joint limits as cosine tests: S1 atan2(wy,wx), S2 tilt of a, E1 a.f,
    # E2 atan2(k.n, k.(n x f)), W1 acos(k.f)
    bx, by, bz = _cross(nx, ny, nz, fx, fy, fz)
    k4x = kx * bx + ky * by + kz * bz
    k4y = kx * nx + ky * ny + kz * nz
    k4z = kx * fx + ky * fy + kz * fz
    ok = ((abs(cos_a) <= 1.0) & (wx >= cl0 * r) & (az_ >= cl1)
          & (ax_ * fx + ay_ * fy + az_ * fz >= cl2)
          & (k4x >= cl3 * np.sqrt(k4x * k4x + k4y * k4y)) & (k4z >= cl4))
    return kx, ky, kz, wx, wy, wz, nx, ny, nz, ex, ey, ez, fx, fy, fz, ok


@njit(inline="always", **_JIT)
def rcm_pose_jacobian(
    px, py, pz, cx, cy, cz, d1, d3, d5, tool_offset_m, elbow_sign,
    q0, q1, q2, q3, q4, cl0, cl1, cl2, cl3, cl4,
):
    """Closed-form IK (eq. 9) and the columns of A = J_a Q (eq. 8) at one pose.

    Arguments as ``rcm_ik``; ``q0..q4`` are the maximum speeds (rad/s) of S1,
    S2, E1, E2, W1 (1 for the unscaled J_a). Returns the five columns
    (5-tuples) and whether the pose is reachable within the joint limits.
    """
    kx, ky, kz, wx, wy, wz, nx, ny, nz, ex, ey, ez, fx, fy, fz, ok = rcm_ik(
        px, py, pz, cx, cy, cz, d1, d3, d5, tool_offset_m, elbow_sign, cl0, cl1, cl2, cl3, cl4)
    # W1 axis m = f x k / |f x k|
    mx, my, mz = _cross(fx, fy, fz, kx, ky, kz)
    il = 1.0 / (np.sqrt(mx * mx + my * my + mz * mz) + TINY)
    mx, my, mz = mx * il, my * il, mz * il
    ikz = 1.0 / kz
    return (
        _jacobian_column(0.0, 0.0, 1.0, 0.0, 0.0, d1, px, py, pz, cx, cy, cz, kx, ky, kz, ikz, q0),
        _jacobian_column(nx, ny, nz, 0.0, 0.0, d1, px, py, pz, cx, cy, cz, kx, ky, kz, ikz, q1),
        _jacobian_column(nx, ny, nz, ex, ey, ez, px, py, pz, cx, cy, cz, kx, ky, kz, ikz, q2),
        _jacobian_column(fx, fy, fz, wx, wy, wz, px, py, pz, cx, cy, cz, kx, ky, kz, ikz, q3),
        _jacobian_column(mx, my, mz, wx, wy, wz, px, py, pz, cx, cy, cz, kx, ky, kz, ikz, q4),
        ok,
    )


@njit(inline="always", **_JIT)
def rcm_pose_singular_values(
    px, py, pz, cx, cy, cz, d1, d3, d5, tool_offset_m, elbow_sign,
    q0, q1, q2, q3, q4, cl0, cl1, cl2, cl3, cl4,
):
    """Extreme singular values of B at one pose: (sigma_min, sigma_max, status).

    Arguments as ``rcm_pose_jacobian``. Worked example (checked in tests):
    links 0.317/0.45/0.48/0.07 m, tool 0.587 m from the flange, PA10 speeds,
    RCM (0.535, 0, 0.107) m, tip 0.1 m straight below it:
    sigma_min = 0.070968 m/s, sigma_max = 1.019961 m/s.
    """
    c0, c1, c2, c3, c4, ok = rcm_pose_jacobian(
        px, py, pz, cx, cy, cz, d1, d3, d5, tool_offset_m, elbow_sign,
        q0, q1, q2, q3, q4, cl0, cl1, cl2, cl3, cl4)
    smin, smax, singular = constrained_extremes(c0, c1, c2, c3, c4)
    status = STATUS_OK if ok else STATUS_UNREACHABLE
    status = STATUS_SINGULAR if (ok and singular) else status
    return smin, smax, status


@njit(**_JIT)
def alternative_jacobian(p, c, links_m, tool_offset_m, elbow_sign, qdot_max, cos_limit):
    """J_a Q (5x5, eq. 8) at tip p about RCM c, and reachability: for tests and tools."""
    c0, c1, c2, c3, c4, ok = rcm_pose_jacobian(p[0], p[1], p[2], c[0], c[1], c[2],
                             links_m[0], links_m[1], links_m[2], tool_offset_m, elbow_sign,
                             qdot_max[0], qdot_max[1], qdot_max[2], qdot_max[3], qdot_max[4],
                             cos_limit[0], cos_limit[1], cos_limit[2], cos_limit[3], cos_limit[4])
    A = np.empty((5, 5))
    for i in range(5):
        A[i, 0], A[i, 1], A[i, 2], A[i, 3], A[i, 4] = c0[i], c1[i], c2[i], c3[i], c4[i]
    return A, ok


@njit(**_JIT)
def pose_singular_values(points, rcm, links_m, tool_offset_m, elbow_sign, qdot_max, cos_limit):
    """Per-point (sigma_min, sigma_max, status) for tips ``points`` (N, 3) about one RCM."""
    n = points.shape[0]
    smin = np.empty(n)
    smax = np.empty(n)
    status = np.empty(n, np.int64)
    _workspace_poses(rcm[0], rcm[1], rcm[2], points[:, 0] - rcm[0], points[:, 1] - rcm[1],
                     points[:, 2] - rcm[2], links_m[0], links_m[1], links_m[2],
                     tool_offset_m, elbow_sign,
                     qdot_max[0], qdot_max[1], qdot_max[2], qdot_max[3], qdot_max[4],
                     cos_limit[0], cos_limit[1], cos_limit[2], cos_limit[3], cos_limit[4],
                     smin, smax, status)
    return smin, smax, status


@njit(**_JIT)
def _workspace_poses(cx, cy, cz, ox, oy, oz, d1, d3, d5, tool_offset_m, elbow_sign,
                     q0, q1, q2, q3, q4, c0, c1, c2, c3, c4, smin, smax, status):
    """Per-point extremes for one RCM over tips c + (ox, oy, oz)[j].

    A call- and branch-free loop over structure-of-arrays inputs: with (N, 3)
    rows LLVM keeps it scalar (3.5x slower, measured).
    """
    for j in range(ox.shape[0]):
        smin[j], smax[j], status[j] = rcm_pose_singular_values(
            cx + ox[j], cy + oy[j], cz + oz[j], cx, cy, cz,
            d1, d3, d5, tool_offset_m, elbow_sign, q0, q1, q2, q3, q4, c0, c1, c2, c3, c4)


@njit(**_JIT)
def _count_unreachable(cx, cy, cz, ox, oy, oz, d1, d3, d5, tool_offset_m, elbow_sign,
                       c0, c1, c2, c3, c4):
    """Number of workspace points the IK cannot reach within the joint limits."""
    n = 0
    for j in range(ox.shape[0]):
        ok = rcm_ik(cx + ox[j], cy + oy[j], cz + oz[j], cx, cy, cz,
                    d1, d3, d5, tool_offset_m, elbow_sign, c0, c1, c2, c3, c4)[15]
        n += not ok
    return n


@njit(**_JIT)
def _reduce_extremes(smin, smax, status, n):
    lo = np.inf
    hi = 0.0
    n_unr = 0
    n_sing = 0
    for j in range(n):
        lo = min(lo, smin[j])
        hi = max(hi, smax[j])
        n_unr += status[j] == STATUS_UNREACHABLE
        n_sing += status[j] == STATUS_SINGULAR
    return lo, hi, n_unr, n_sing


@njit(**_JIT)
def rcm_candidates_extremes(rcms, offsets, links_m, tool_offset_m, elbow_sign, qdot_max, cos_limit):
    """For each RCM candidate: min sigma_min, max sigma_max over the workspace.

    ``rcms`` (M, 3) candidate RCMs, ``offsets`` (P, 3) workspace points
    relative to the RCM, ``links_m`` (d1, d3, d5). Returns (sigma_min (M,),
    sigma_max (M,), n_unreachable (M,), n_singular (M,)); the GII (eq. 7) is
    sigma_min / sigma_max when n_unreachable == 0. Reachability is checked
    first (IK only, a fifth of the cost); an infeasible candidate gets
    sigma = 0 and n_singular = 0 without evaluating its Jacobians.
    """
    m = rcms.shape[0]
    p = offsets.shape[0]
    out_min = np.empty(m)
    out_max = np.empty(m)
    out_unr = np.empty(m, np.int64)
    out_sing = np.empty(m, np.int64)
    ox = offsets[:, 0].copy()
    oy = offsets[:, 1].copy()
    oz = offsets[:, 2].copy()
    smin = np.empty(p)
    smax = np.empty(p)
    status = np.empty(p, np.int64)
    for i in range(m):
        n_unr = _count_unreachable(rcms[i, 0], rcms[i, 1], rcms[i, 2], ox, oy, oz,
                                   links_m[0], links_m[1], links_m[2], tool_offset_m, elbow_sign,
                                   cos_limit[0], cos_limit[1], cos_limit[2], cos_limit[3], cos_limit[4])
        if n_unr > 0:
            out_min[i], out_max[i], out_unr[i], out_sing[i] = 0.0, 0.0, n_unr, 0
            continue
        _workspace_poses(rcms[i, 0], rcms[i, 1], rcms[i, 2], ox, oy, oz,
                         links_m[0], links_m[1], links_m[2], tool_offset_m, elbow_sign,
                         qdot_max[0], qdot_max[1], qdot_max[2], qdot_max[3], qdot_max[4],
                         cos_limit[0], cos_limit[1], cos_limit[2], cos_limit[3], cos_limit[4],
                         smin, smax, status)
        out_min[i], out_max[i], out_unr[i], out_sing[i] = _reduce_extremes(smin, smax, status, p)
    return out_min, out_max, out_unr, out_sing


@njit(**_JIT)
def rcm_candidate_bounded(rcm, offsets, links_m, tool_offset_m, elbow_sign, qdot_max,
                          cos_limit, gii_to_beat, block):
    """Culling step (Stocco & Salcudean): evaluate one candidate block by block.

    The running ratio min sigma_min / max sigma_max over the points seen so
    far can only fall as points are added, so it bounds the final GII from
    above; evaluation stops as soon as that bound is <= ``gii_to_beat`` or a
    point is unreachable. Returns (sigma_min, sigma_max, n_unreachable,
    n_singular, points_evaluated); points_evaluated < P means culled.
    Put the points most likely to be worst first in ``offsets``.
    """
    p = offsets.shape[0]
    ox = offsets[:, 0].copy()
    oy = offsets[:, 1].copy()
    oz = offsets[:, 2].copy()
    smin = np.empty(block)
    smax = np.empty(block)
    status = np.empty(block, np.int64)
    lo = np.inf
    hi = 0.0
    n_unr = 0
    n_sing = 0
    done = 0
    while done < p:
        end = min(p, done + block)
        _workspace_poses(rcm[0], rcm[1], rcm[2], ox[done:end], oy[done:end], oz[done:end],
                         links_m[0], links_m[1], links_m[2], tool_offset_m, elbow_sign,
                         qdot_max[0], qdot_max[1], qdot_max[2], qdot_max[3], qdot_max[4],
                         cos_limit[0], cos_limit[1], cos_limit[2], cos_limit[3], cos_limit[4],
                         smin, smax, status)
        b_lo, b_hi, b_unr, b_sing = _reduce_extremes(smin, smax, status, end - done)
        lo = min(lo, b_lo)
        hi = max(hi, b_hi)
        n_unr += b_unr
        n_sing += b_sing
        done = end
        if n_unr > 0 or lo <= gii_to_beat * hi:
            break
    return lo, hi, n_unr, n_sing, done
