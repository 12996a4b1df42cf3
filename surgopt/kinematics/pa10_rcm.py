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

Floating point: kernels allow FMA contraction (``fastmath={"contract"}``,
nothing else), so a machine without FMA differs in the last bits (~1e-14).

The per-pose quantity returned is the pair of extreme singular values of
B = A_x N, where A = J_a Q is the alternative Jacobian (eq. 8) with columns
scaled by the maximum joint speeds Q (Stocco & Salcudean), A_x its three tip
rows and N an orthonormal basis of the null space of its two constraint rows.
B is the constrained forward map from normalised joint speeds to tip velocity
(m/s); its singular values are the reciprocals of those of Q^-1 J_r (eqs. 5-6),
so GII = min sigma_min(B) / max sigma_max(B) equals eq. 7 on Q^-1 J_r.

Per candidate, the tool axis and wrist offset of every workspace point are
shared (they do not depend on the RCM: ``workspace_geometry``), and a cube
symmetric in y is evaluated on its y >= 0 half (``mirror_half``).

Public drivers: ``pose_singular_values``, ``rcm_candidates_extremes``, ``rcm_candidate_bounded``
(arrays and a ``Pa10Arm`` in, arrays out); the ``_``-prefixed functions are their compiled loops.
One module of ~450 lines: the closed-form IK, the alternative Jacobian (the shared metric is in ``rcm_metric``) and
the null-space reduction are inline functions compiled into one vectorised per-pose loop
(``_workspace_poses``); they are one computation, read together with the paper's Sec. III.
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np

from surgopt.jit import CONTRACT, njit
from surgopt.kinematics.rcm_metric import (  # noqa: F401 - the shared metric, re-exported for the tests
    SINGULAR_RTOL, STATUS_OK, STATUS_SINGULAR, STATUS_UNREACHABLE, TINY, TRISECT_CHEB, TRISECT_POLY,
    constrained_extremes, cos_third_acos, gram_lambda_max, probe_points, singular_values_3x3,
    singular_values_3x3_sq, sym3_lambda_max,
)
from surgopt.kinematics.small_linalg import cross_components


class Pa10Arm(NamedTuple):
    """The PA10-7C as the RCM kernels see it (``surgopt/robots/pa10_7c.py``; S3 = W2 = 0).

    ``links_m``: (d1, d3, d5); ``tool_offset_m``: wrist centre to tool tip along the tool axis;
    ``elbow_sign``: +1 elbow up, -1 down; ``qdot_max``: rated speeds of S1, S2, E1, E2, W1 (rad/s),
    the diagonal of Q; ``cos_limit``: cos of each of those joints' symmetric range (-1: unlimited).
    """

    links_m: np.ndarray
    tool_offset_m: float
    elbow_sign: float
    qdot_max: np.ndarray
    cos_limit: np.ndarray


@njit(inline="always", **CONTRACT)
def tool_axis_and_wrist(ox, oy, oz, tool_offset_m):
    """Tool axis and wrist centre for a tip at RCM + o (eq. 9).

    The tool passes through the RCM, so its unit axis is k = o / |o| and the
    wrist centre sits ``tool_offset_m`` back along it: w - RCM = o - T k.
    Neither depends on where the RCM is, so a workspace cube shares them
    across all candidates (``workspace_geometry``).
    """
    il = 1.0 / (np.sqrt(ox * ox + oy * oy + oz * oz) + TINY)
    kx, ky, kz = ox * il, oy * il, oz * il
    return kx, ky, kz, ox - tool_offset_m * kx, oy - tool_offset_m * ky, oz - tool_offset_m * kz


@njit(inline="always", **CONTRACT)
def arm_ik(kx, ky, kz, wx, wy, wz, d1, d3, d5, elbow_sign, cl0, cl1, cl2, cl3, cl4):
    """Closed-form IK of S1, S2, E1 for wrist centre w, and the wrist's limits (Sec. III-C).

    Tool axis k, wrist centre w (m); ``cl0..cl4`` are cos(min(limit, pi)) of
    the S1, S2, E1, E2, W1 limits. Returns the S2/E1 axis n (n_z = 0, so two
    scalars), elbow e, forearm direction f and whether the pose is reachable
    within the joint limits (S3 = W2 = 0). Limits are tested as cosines: S1
    atan2(wy, wx), S2 the tilt of the upper arm a, E1 a.f, E2 atan2(k.n,
    k.(n x f)), W1 acos(k.f).
    """
    # S1: the arm plane holds the z axis and w; S2/E1: planar two-link IK in it
    r2 = wx * wx + wy * wy
    r = np.sqrt(r2) + TINY
    sz = wz - d1
    dist = np.sqrt(r2 + sz * sz) + TINY
    inv = 1.0 / (r * dist)  # one division for 1/r and 1/dist
    ir = dist * inv
    idist = r * inv
    nx, ny = -wy * ir, wx * ir
    ux, uy, uz = wx * idist, wy * idist, sz * idist
    cos_a = (d3 * d3 - d5 * d5 + dist * dist) * (0.5 / d3) * idist
    sin_a = elbow_sign * np.sqrt(max(0.0, 1.0 - cos_a * cos_a))
    vx, vy, vz = -uz * ny, uz * nx, ux * ny - uy * nx  # u x n: in-plane normal, "up"
    ax_, ay_, az_ = cos_a * ux + sin_a * vx, cos_a * uy + sin_a * vy, cos_a * uz + sin_a * vz
    ex, ey, ez = d3 * ax_, d3 * ay_, d1 + d3 * az_
    id5 = 1.0 / d5
    fx, fy, fz = (wx - ex) * id5, (wy - ey) * id5, (wz - ez) * id5
    bx, by, bz = ny * fz, -nx * fz, nx * fy - ny * fx  # n x f
    k4x = kx * bx + ky * by + kz * bz
    k4y = kx * nx + ky * ny
    k4z = kx * fx + ky * fy + kz * fz
    # E2: k4x >= cl3 |(k4x, k4y)|, squared (the sign of cl3 picks the form)
    # (both sides inclusive: |E2| equal to the limit is inside; with a range of 180 deg or more,
    # cl3 = -1 and E2 = 180 exactly, k4y = 0, is inside too)
    k4_sq = cl3 * cl3 * (k4x * k4x + k4y * k4y)
    e2_ok = ((k4x >= 0.0) & (k4x * k4x >= k4_sq)) if cl3 >= 0.0 else ((k4x >= 0.0) | (k4x * k4x <= k4_sq))
    ok = ((abs(cos_a) <= 1.0) & (wx >= cl0 * r) & (az_ >= cl1)
          & (ax_ * fx + ay_ * fy + az_ * fz >= cl2) & e2_ok & (k4z >= cl4))
    return nx, ny, ex, ey, ez, fx, fy, fz, ok


@njit(inline="always", **CONTRACT)
def rcm_ik(px, py, pz, cx, cy, cz, d1, d3, d5, tool_offset_m, elbow_sign, cl0, cl1, cl2, cl3, cl4):
    """Closed-form IK with the tool axis through the RCM (eq. 9), as geometry.

    Tip p, RCM c (m). Returns the tool axis k, wrist centre w, S2/E1 axis n,
    elbow e, forearm direction f (each as 3 scalars) and reachability.
    """
    kx, ky, kz, vx, vy, vz = tool_axis_and_wrist(px - cx, py - cy, pz - cz, tool_offset_m)
    wx, wy, wz = cx + vx, cy + vy, cz + vz
    nx, ny, ex, ey, ez, fx, fy, fz, ok = arm_ik(kx, ky, kz, wx, wy, wz, d1, d3, d5, elbow_sign,
                                                cl0, cl1, cl2, cl3, cl4)
    return kx, ky, kz, wx, wy, wz, nx, ny, 0.0, ex, ey, ez, fx, fy, fz, ok


@njit(inline="always", **CONTRACT)
def _constraint_rows(gx, gy, gz, kx, ky, kz):
    """x, y of g x k: k_z (de_y/dt, -de_x/dt) for the body point at the RCM moving at g (eq. 8)."""
    return gy * kz - gz * ky, gz * kx - gx * kz


@njit(inline="always", **CONTRACT)
def jacobian_columns(px, py, pz, cx, cy, cz, kx, ky, kz, wx, wy, wz, nx, ny, ex, ey, ez, fx, fy, fz,
                     d1, q0, q1, q2, q3, q4):
    """The five columns of A = J_a Q (eq. 8), each a 5-tuple.

    Joint axis z (scaled by the joint's maximum speed) through o moves the
    tip at z x (p - o) (rows 0-2) and the body point at the RCM at
    g = z x (c - o). The RCM error e_x, e_y of eq. 8 changes at
    g_xy - (g_z / k_z) k_xy; rows 3-4 hold that pair times k_z, rotated:
    the x, y of g x k, which spans the same constraint without a division
    (only its null space enters B). ``alternative_jacobian`` gives eq. 8's rows.
    Axes: S1 e_z through the origin; S2, E1 n (n_z = 0) through the shoulder
    (0, 0, d1) and the elbow e; E2 f and W1 m = f x k / |f x k| through w.
    """
    # S1
    c0 = (-q0 * py, q0 * px, 0.0) + _constraint_rows(-q0 * cy, q0 * cx, 0.0, kx, ky, kz)
    # S2
    ax, ay = q1 * nx, q1 * ny
    pzs, czs = pz - d1, cz - d1
    c1 = ((ay * pzs, -ax * pzs, ax * py - ay * px)
          + _constraint_rows(ay * czs, -ax * czs, ax * cy - ay * cx, kx, ky, kz))
    # E1
    ax, ay = q2 * nx, q2 * ny
    pze, cze = pz - ez, cz - ez
    c2 = ((ay * pze, -ax * pze, ax * (py - ey) - ay * (px - ex))
          + _constraint_rows(ay * cze, -ax * cze, ax * (cy - ey) - ay * (cx - ex), kx, ky, kz))
    # E2 and W1 turn about axes through the wrist centre
    dpx, dpy, dpz = px - wx, py - wy, pz - wz
    dcx, dcy, dcz = cx - wx, cy - wy, cz - wz
    ax, ay, az = q3 * fx, q3 * fy, q3 * fz
    gx, gy, gz = cross_components(ax, ay, az, dcx, dcy, dcz)
    c3 = cross_components(ax, ay, az, dpx, dpy, dpz) + _constraint_rows(gx, gy, gz, kx, ky, kz)
    mx, my, mz = cross_components(fx, fy, fz, kx, ky, kz)
    il = q4 / (np.sqrt(mx * mx + my * my + mz * mz) + TINY)
    mx, my, mz = mx * il, my * il, mz * il
    gx, gy, gz = cross_components(mx, my, mz, dcx, dcy, dcz)
    c4 = cross_components(mx, my, mz, dpx, dpy, dpz) + _constraint_rows(gx, gy, gz, kx, ky, kz)
    return c0, c1, c2, c3, c4


@njit(inline="always", **CONTRACT)
def pose_extremes_sq(cx, cy, cz, px, py, pz, kx, ky, kz, wx, wy, wz, d1, d3, d5, elbow_sign,
                     q0, q1, q2, q3, q4, cl0, cl1, cl2, cl3, cl4):
    """(sigma_min^2, sigma_max^2, status) of B at one pose: IK, A (eq. 8), null space, extremes.

    RCM c, tip p, tool axis k and wrist centre w from ``tool_axis_and_wrist``.
    """
    nx, ny, ex, ey, ez, fx, fy, fz, ok = arm_ik(kx, ky, kz, wx, wy, wz, d1, d3, d5, elbow_sign,
                                                cl0, cl1, cl2, cl3, cl4)
    c0, c1, c2, c3, c4 = jacobian_columns(px, py, pz, cx, cy, cz, kx, ky, kz, wx, wy, wz,
                                          nx, ny, ex, ey, ez, fx, fy, fz, d1, q0, q1, q2, q3, q4)
    smin2, smax2, singular = constrained_extremes(c0, c1, c2, c3, c4)
    status = STATUS_OK if ok else STATUS_UNREACHABLE
    status = STATUS_SINGULAR if (ok and singular) else status
    return smin2, smax2, status


@njit(**CONTRACT)
def alternative_jacobian(p, c, arm):
    """J_a Q (5x5, eq. 8: rows x, y, z, e_x, e_y) at tip p about RCM c for a ``Pa10Arm``, and reachability."""
    links_m, tool_offset_m, elbow_sign, qdot_max, cos_limit = arm
    kx, ky, kz, wx, wy, wz, nx, ny, _, ex, ey, ez, fx, fy, fz, ok = rcm_ik(
        p[0], p[1], p[2], c[0], c[1], c[2], links_m[0], links_m[1], links_m[2], tool_offset_m, elbow_sign,
        cos_limit[0], cos_limit[1], cos_limit[2], cos_limit[3], cos_limit[4])
    cols = jacobian_columns(p[0], p[1], p[2], c[0], c[1], c[2], kx, ky, kz, wx, wy, wz,
                            nx, ny, ex, ey, ez, fx, fy, fz, links_m[0],
                            qdot_max[0], qdot_max[1], qdot_max[2], qdot_max[3], qdot_max[4])
    A = np.empty((5, 5))
    for j in range(5):
        col = cols[j]
        A[0, j], A[1, j], A[2, j] = col[0], col[1], col[2]
        A[3, j], A[4, j] = -col[4] / kz, col[3] / kz  # back from k_z (e_y', -e_x') to (e_x', e_y')
    return A, ok


@njit(**CONTRACT)
def _workspace_poses(cx, cy, cz, geom, d1, d3, d5, elbow_sign,
                     q0, q1, q2, q3, q4, c0, c1, c2, c3, c4, smin2, smax2, status):
    """Per-point squared extremes for one RCM c over the workspace ``geom`` (``workspace_geometry``).

    A call- and branch-free loop over structure-of-arrays inputs, so that
    LLVM vectorises it (with (N, 3) rows it stays scalar: 3.5x slower).
    """
    ox, oy, oz, kx, ky, kz, vx, vy, vz = geom[0], geom[1], geom[2], geom[3], geom[4], geom[5], geom[6], geom[7], geom[8]
    for j in range(ox.shape[0]):
        smin2[j], smax2[j], status[j] = pose_extremes_sq(
            cx, cy, cz, cx + ox[j], cy + oy[j], cz + oz[j], kx[j], ky[j], kz[j],
            cx + vx[j], cy + vy[j], cz + vz[j], d1, d3, d5, elbow_sign,
            q0, q1, q2, q3, q4, c0, c1, c2, c3, c4)


@njit(**CONTRACT)
def _count_unreachable(cx, cy, cz, geom, mult, d1, d3, d5, elbow_sign, c0, c1, c2, c3, c4):
    """Workspace points (with multiplicity) the IK cannot reach within the joint limits."""
    kx, ky, kz, vx, vy, vz = geom[3], geom[4], geom[5], geom[6], geom[7], geom[8]
    n = 0
    for j in range(kx.shape[0]):
        ok = arm_ik(kx[j], ky[j], kz[j], cx + vx[j], cy + vy[j], cz + vz[j],
                    d1, d3, d5, elbow_sign, c0, c1, c2, c3, c4)[8]
        n += 0 if ok else mult[j]
    return n


@njit(**CONTRACT)
def _reduce_extremes(smin2, smax2, status, mult, n):
    """(min sigma_min^2, max sigma_max^2, unreachable, singular) over n points, counts with multiplicity."""
    lo = np.inf
    hi = 0.0
    n_unr = 0
    n_sing = 0
    for j in range(n):
        lo = min(lo, smin2[j])
        hi = max(hi, smax2[j])
        n_unr += mult[j] if status[j] == STATUS_UNREACHABLE else 0
        n_sing += mult[j] if status[j] == STATUS_SINGULAR else 0
    return lo, hi, n_unr, n_sing


def mirror_half(offsets):
    """Points with y >= 0 and their multiplicity, when the set is mirror symmetric in y.

    With the RCM on the x-z plane (y = 0), S3 = W2 = 0 and symmetric joint
    limits, the arm's pose for the mirror image (x, -y, z) of a tip is the
    mirror image of its pose: S1, E2 change sign, every limit test and every
    singular value is unchanged. So a workspace symmetric in y needs only its
    y >= 0 half, each y > 0 point counted twice. Returns ``(offsets, ones)``
    when the set is not exactly symmetric.
    """
    offsets = np.ascontiguousarray(offsets, dtype=np.float64)
    y = offsets[:, 1]
    pos, neg = offsets[y > 0], offsets[y < 0] * np.array([1.0, -1.0, 1.0])
    if pos.shape != neg.shape or not np.array_equal(pos[np.lexsort(pos.T)], neg[np.lexsort(neg.T)]):
        return offsets, np.ones(offsets.shape[0], np.int64)
    keep = y >= 0
    return np.ascontiguousarray(offsets[keep]), np.where(y[keep] > 0, 2, 1).astype(np.int64)


@njit(**CONTRACT)
def workspace_geometry(offsets, tool_offset_m):
    """(9, P) rows o_x, o_y, o_z, k_x, k_y, k_z, (w - c)_x, _y, _z for tips at RCM + o (eq. 9)."""
    p = offsets.shape[0]
    g = np.empty((9, p))
    for j in range(p):
        ox, oy, oz = offsets[j, 0], offsets[j, 1], offsets[j, 2]
        kx, ky, kz, vx, vy, vz = tool_axis_and_wrist(ox, oy, oz, tool_offset_m)
        g[0, j], g[1, j], g[2, j], g[3, j], g[4, j], g[5, j], g[6, j], g[7, j], g[8, j] = \
            ox, oy, oz, kx, ky, kz, vx, vy, vz
    return g


def pose_singular_values(points, rcm, arm: Pa10Arm):
    """Per-point (sigma_min, sigma_max, status) for tips ``points`` (N, 3) about one RCM.

    Worked example (tests): the paper's best RCM (0.535, 0, -0.210) m from the shoulder, i.e.
    (0.535, 0, 0.107) m in the base frame, tip 0.1 m straight below it, the default arm
    (587 mm tool from the flange, Table I speeds): sigma_min 0.070968, sigma_max 1.019961 m/s.
    """
    links_m, tool_offset_m, elbow_sign, qdot_max, cos_limit = arm
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    rcm = np.asarray(rcm, dtype=np.float64)
    geom = workspace_geometry(np.ascontiguousarray(points - rcm), tool_offset_m)
    n = points.shape[0]
    smin2, smax2, status = np.empty(n), np.empty(n), np.empty(n, np.int64)
    _workspace_poses(rcm[0], rcm[1], rcm[2], geom, links_m[0], links_m[1], links_m[2], elbow_sign,
                     *qdot_max[:5], *cos_limit[:5], smin2, smax2, status)
    return np.sqrt(smin2), np.sqrt(smax2), status


@njit(**CONTRACT)
def _candidates_extremes(rcms, geom, mult, probes, d1, d3, d5, elbow_sign, q, cl):
    m = rcms.shape[0]
    p = geom.shape[1]
    out_min = np.empty(m)
    out_max = np.empty(m)
    out_unr = np.empty(m, np.int64)
    out_sing = np.empty(m, np.int64)
    smin2 = np.empty(p)
    smax2 = np.empty(p)
    status = np.empty(p, np.int64)
    for i in range(m):
        cx, cy, cz = rcms[i, 0], rcms[i, 1], rcms[i, 2]
        probe_ok = True
        for j in probes:
            probe_ok &= arm_ik(geom[3, j], geom[4, j], geom[5, j], cx + geom[6, j], cy + geom[7, j],
                               cz + geom[8, j], d1, d3, d5, elbow_sign, cl[0], cl[1], cl[2], cl[3], cl[4])[8]
        if not probe_ok:
            n_unr = _count_unreachable(cx, cy, cz, geom, mult, d1, d3, d5, elbow_sign,
                                       cl[0], cl[1], cl[2], cl[3], cl[4])
            out_min[i], out_max[i], out_unr[i], out_sing[i] = 0.0, 0.0, n_unr, 0
            continue
        _workspace_poses(cx, cy, cz, geom, d1, d3, d5, elbow_sign, q[0], q[1], q[2], q[3], q[4],
                         cl[0], cl[1], cl[2], cl[3], cl[4], smin2, smax2, status)
        lo, hi, n_unr, n_sing = _reduce_extremes(smin2, smax2, status, mult, p)
        if n_unr > 0:
            out_min[i], out_max[i], out_unr[i], out_sing[i] = 0.0, 0.0, n_unr, 0
        else:
            out_min[i], out_max[i], out_unr[i], out_sing[i] = np.sqrt(lo), np.sqrt(hi), 0, n_sing
    return out_min, out_max, out_unr, out_sing


def rcm_candidates_extremes(rcms, offsets, arm: Pa10Arm, mirror=True, probe_first=True):
    """For each RCM candidate: min sigma_min, max sigma_max over the workspace.

    ``rcms`` (M, 3) candidate RCMs (y = 0 for ``mirror``), ``offsets`` (P, 3)
    workspace points relative to the RCM, ``arm`` a ``Pa10Arm``. Returns
    (sigma_min (M,), sigma_max (M,), n_unreachable (M,), n_singular (M,));
    the GII (eq. 7) is sigma_min / sigma_max when n_unreachable == 0. The
    workspace's corner and face points are tried first (IK only); when one
    is out of reach the candidate only gets its unreachable count (IK only,
    a fifth of the cost) and sigma = 0, n_singular = 0. With ``mirror``
    and RCMs on y = 0, a y-symmetric workspace is evaluated on its y >= 0
    half (``mirror_half``): 9 of 17 layers for the paper's cube. ``probe_first`` False skips the
    corner and face probes (the result is the same; only the order of work differs).
    """
    links_m, tool_offset_m, elbow_sign, qdot_max, cos_limit = arm
    rcms = np.ascontiguousarray(rcms, dtype=np.float64).reshape(-1, 3)
    offsets = np.ascontiguousarray(offsets, dtype=np.float64).reshape(-1, 3)
    if mirror and np.all(rcms[:, 1] == 0.0):
        offsets, mult = mirror_half(offsets)
    else:
        mult = np.ones(offsets.shape[0], np.int64)
    geom = workspace_geometry(offsets, tool_offset_m)
    probes = probe_points(offsets) if probe_first else np.empty(0, np.int64)
    return _candidates_extremes(rcms, geom, mult, probes, links_m[0], links_m[1], links_m[2],
                                elbow_sign, np.asarray(qdot_max, np.float64), np.asarray(cos_limit, np.float64))


@njit(**CONTRACT)
def _candidate_bounded(cx, cy, cz, geom, mult, d1, d3, d5, elbow_sign, q, cl, gii_to_beat, block):
    p = geom.shape[1]
    smin2 = np.empty(block)
    smax2 = np.empty(block)
    status = np.empty(block, np.int64)
    lo = np.inf
    hi = 0.0
    n_unr = 0
    n_sing = 0
    done = 0
    n_eval = 0
    while done < p:
        end = min(p, done + block)
        _workspace_poses(cx, cy, cz, geom[:, done:end], d1, d3, d5, elbow_sign, q[0], q[1], q[2], q[3], q[4],
                         cl[0], cl[1], cl[2], cl[3], cl[4], smin2, smax2, status)
        b_lo, b_hi, b_unr, b_sing = _reduce_extremes(smin2, smax2, status, mult[done:end], end - done)
        lo = min(lo, b_lo)
        hi = max(hi, b_hi)
        n_unr += b_unr
        n_sing += b_sing
        for j in range(done, end):
            n_eval += mult[j]
        done = end
        if n_unr > 0 or lo <= gii_to_beat * gii_to_beat * hi:
            break
    return np.sqrt(lo), np.sqrt(hi), n_unr, n_sing, n_eval


def rcm_candidate_bounded(rcm, offsets, arm: Pa10Arm, gii_to_beat, block, mirror=True):
    """Culling step (Stocco & Salcudean): evaluate one candidate block by block.

    The running ratio min sigma_min / max sigma_max over the points seen so
    far can only fall as points are added, so it bounds the final GII from
    above; evaluation stops as soon as that bound is <= ``gii_to_beat`` or a
    point is unreachable. Returns (sigma_min, sigma_max, n_unreachable,
    n_singular, points_evaluated); points_evaluated < P means culled.
    Put the points most likely to be worst first in ``offsets`` (the mirror
    reduction keeps their order).
    """
    links_m, tool_offset_m, elbow_sign, qdot_max, cos_limit = arm
    rcm = np.asarray(rcm, dtype=np.float64)
    offsets = np.ascontiguousarray(offsets, dtype=np.float64).reshape(-1, 3)
    if mirror and rcm[1] == 0.0:
        offsets, mult = mirror_half(offsets)
    else:
        mult = np.ones(offsets.shape[0], np.int64)
    geom = workspace_geometry(offsets, tool_offset_m)
    return _candidate_bounded(rcm[0], rcm[1], rcm[2], geom, mult, links_m[0], links_m[1], links_m[2],
                              elbow_sign, np.asarray(qdot_max, np.float64), np.asarray(cos_limit, np.float64),
                              float(gii_to_beat), int(block))
