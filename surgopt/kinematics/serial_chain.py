"""Any serial arm under a remote-centre-of-motion constraint: RCM-constrained IK by damped Newton, and
the RCM metric (Locke & Patel 2007, eqs. 5-8) from the chain's geometric Jacobian.

Kernels only. A chain arrives reduced to its five active joints (``surgopt/robots/chain.py`` folds
fixed and locked joints into the fixed transforms and rotates every joint frame so that the joint
moves about, or along, its own z axis):

    T(q) = P_0 M_0(q_0) P_1 M_1(q_1) ... P_4 M_4(q_4) P_5,

P_i fixed (``rot[i]``, ``pos[i]``), M_i a turn about z or a slide along z. The frame T(q) has its origin
at the tool tip and its z axis along the tool. With the tool line through the RCM c, the five
equations in the five joints are (``rcm_residual_jacobian``)

    p(q) - p* = 0                       (tip on the workspace point p*, 3 equations)
    u_1 . (m - c) = 0, u_2 . (m - c) = 0 (the tool line's offset from the RCM, 2 equations),

m = p + ((c - p) . k) k the point of the tool line nearest c, u_1, u_2 unit vectors normal to the tool
axis k. Their Jacobian columns are z_i x (p - o_i) and u . (z_i x (m - o_i)) for a revolute joint
(axis z_i through o_i), z_i and u . z_i for a prismatic one. At a solution m = c, so the last two rows
are the RCM body point's velocity normal to the tool: the constraint rows of eq. 8 in another basis
of the same span; with the columns scaled by the rated joint speeds Q they go to the shared metric
(``rcm_metric.constrained_extremes``), exactly as in the closed-form PA10 kernel.

Per candidate the IK is solved once from the seed (``seed``, then ``restarts`` around it), at the
workspace centre, carried to the walk's first point by continuation, and then along the walk (a
serpentine through the cube, ``serpentine_order``), each solution predicted from the last
(q + J^-1 dp) and corrected by Newton, so a candidate stays on the seeded branch. A point where Newton
does not reach ``IK_TOL_M`` within ``WALK_ITER`` steps, or whose solution is outside a joint limit, is
tried once more by continuation from the start's solution (a near-singular step of the walk, such as an
elbow at full stretch, is then approached from the interior); if that fails too the point is
unreachable, and the walk stops there (``n_unreachable`` is then 1: the rest is not tried).

A long walk runs in SIMD lanes instead (``serial_lanes``: eight segments side by side, this module's
Newton finishing any pose the lanes cannot). Public drivers: ``rcm_walk`` (one candidate, every joint
vector, scalar), ``chain_candidates.chain_candidates_extremes``
(many candidates, the PA10 kernel's outputs), ``chain_fk`` (tip frame and joint axes).

One module of ~700 lines: forward kinematics, the five equations and their Jacobian, the two small
solvers, the predictor and the walk are one computation compiled into one loop (the inline functions
must live beside the loop that inlines them), read together with the equations above; the standard
Jacobian's extremes (Sec. III-E) share that walk.
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np

from surgopt.jit import CONTRACT, njit
from surgopt.metrics import METRIC_RCM, METRIC_STANDARD
from surgopt.kinematics.rcm_metric import constrained_extremes, workspace_centre
from surgopt.robots.chain import Chain  # noqa: F401 - the kernel's input, defined with the data that builds it


#: Newton stops when every one of the five residuals is below this (m).
IK_TOL_M = 1e-12
#: Newton steps allowed: from the seed (and from each restart), and at each point of the walk.
SEED_ITER = 100
WALK_ITER = 12
#: Continuation from the workspace centre to the walk's first point: steps of at most this (m).
CONTINUATION_STEP_M = 0.005
N_ACTIVE = 5
#: Joint increments below this (rad) update cos/sin by series; exact evaluation every TRIG_RESYNC increments.
TRIG_STEP_RAD = 0.1
TRIG_RESYNC = 64.0
#: Below this squared residual (m^2) Newton takes undamped steps.
NEWTON_ZONE_M2 = 1e-6
TWO_PI = 2.0 * np.pi
#: The walk's extrapolation weights on (q, q1, q2, q3, q4), the solutions 1..5 points back, after a
#: straight run of 1..4 steps (linear .. quartic, ``_predict``); run 0 is the tangent step.
EXTRAPOLATION = ((1.0, 0.0, 0.0, 0.0, 0.0), (2.0, -1.0, 0.0, 0.0, 0.0), (3.0, -3.0, 1.0, 0.0, 0.0),
                 (4.0, -6.0, 4.0, -1.0, 0.0), (5.0, -10.0, 10.0, -5.0, 1.0))


@njit(inline="always", **CONTRACT)
def increment_cos_sin(d):
    """(cos d, sin d) by their series to d^11, error < 1e-19 for |d| < TRIG_STEP_RAD; multiplications
    by the reciprocal factorial ratios only (a division each cost the lanes' update 5x its time)."""
    d2 = d * d
    sd = d * (1.0 - d2 * (1.0 / 6.0) * (1.0 - d2 * (1.0 / 20.0) * (1.0 - d2 * (1.0 / 42.0) * (
        1.0 - d2 * (1.0 / 72.0) * (1.0 - d2 * (1.0 / 110.0))))))
    cd = 1.0 - d2 * 0.5 * (1.0 - d2 * (1.0 / 12.0) * (1.0 - d2 * (1.0 / 30.0) * (
        1.0 - d2 * (1.0 / 56.0) * (1.0 - d2 * (1.0 / 90.0)))))
    return cd, sd


@njit(inline="always", **CONTRACT)
def joint_cos_sin(q, i, trig):
    """cos and sin of q[i] through the cache ``trig`` (4, 5): rows cos, sin, the angle they belong to,
    and how many increments since the last exact evaluation.

    Newton's corrections and the walk's predictions move a joint by well under ``TRIG_STEP_RAD``; then
    cos/sin are turned by the increment d with its Taylor series to d^11 (error < 1e-19 for d < 0.1)
    instead of calling cos and sin (two thirds of the forward kinematics' time). Every
    ``TRIG_RESYNC`` increments, and for larger steps, they are evaluated exactly.
    """
    d = q[i] - trig[2, i]
    if d == 0.0:
        return trig[0, i], trig[1, i]
    if abs(d) < TRIG_STEP_RAD and trig[3, i] < TRIG_RESYNC:
        cd, sd = increment_cos_sin(d)
        c0, s0 = trig[0, i], trig[1, i]
        c, s = c0 * cd - s0 * sd, s0 * cd + c0 * sd
        trig[3, i] += 1.0
    else:
        c, s = np.cos(q[i]), np.sin(q[i])
        trig[3, i] = 0.0
    trig[0, i], trig[1, i], trig[2, i] = c, s, q[i]
    return c, s


def new_trig_cache() -> np.ndarray:
    """An empty cache for ``joint_cos_sin`` (the NaN angles force exact evaluation)."""
    t = np.zeros((4, N_ACTIVE))
    t[2] = np.nan
    return t


@njit(inline="always", **CONTRACT)
def chain_frames(rot, pos, prismatic, q, axes, origins, trig):
    """Forward kinematics: fills ``axes``/``origins`` (5, 3) with each joint's z axis and origin in the
    base frame; returns the tool frame (3x3 rotation R, tip p): tool axis k = R[:, 2]. ``trig``: the
    cos/sin cache of ``joint_cos_sin``."""
    r00, r01, r02, r10, r11, r12, r20, r21, r22 = 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0
    px, py, pz = 0.0, 0.0, 0.0
    for i in range(N_ACTIVE + 1):
        b0, b1, b2 = pos[i, 0], pos[i, 1], pos[i, 2]
        a00, a01, a02 = rot[i, 0, 0], rot[i, 0, 1], rot[i, 0, 2]
        a10, a11, a12 = rot[i, 1, 0], rot[i, 1, 1], rot[i, 1, 2]
        a20, a21, a22 = rot[i, 2, 0], rot[i, 2, 1], rot[i, 2, 2]
        px, py, pz = (px + r00 * b0 + r01 * b1 + r02 * b2, py + r10 * b0 + r11 * b1 + r12 * b2,
                      pz + r20 * b0 + r21 * b1 + r22 * b2)
        r00, r01, r02, r10, r11, r12, r20, r21, r22 = (
            r00 * a00 + r01 * a10 + r02 * a20, r00 * a01 + r01 * a11 + r02 * a21, r00 * a02 + r01 * a12 + r02 * a22,
            r10 * a00 + r11 * a10 + r12 * a20, r10 * a01 + r11 * a11 + r12 * a21, r10 * a02 + r11 * a12 + r12 * a22,
            r20 * a00 + r21 * a10 + r22 * a20, r20 * a01 + r21 * a11 + r22 * a21, r20 * a02 + r21 * a12 + r22 * a22)
        if i == N_ACTIVE:
            break
        axes[i, 0], axes[i, 1], axes[i, 2] = r02, r12, r22
        origins[i, 0], origins[i, 1], origins[i, 2] = px, py, pz
        if prismatic[i] != 0.0:
            px, py, pz = px + q[i] * r02, py + q[i] * r12, pz + q[i] * r22
        else:  # R <- R Rz(q): columns 0, 1 turn about column 2
            c, s = joint_cos_sin(q, i, trig)
            r00, r01 = c * r00 + s * r01, c * r01 - s * r00
            r10, r11 = c * r10 + s * r11, c * r11 - s * r10
            r20, r21 = c * r20 + s * r21, c * r21 - s * r20
    return r00, r01, r02, r10, r11, r12, r20, r21, r22, px, py, pz


@njit(inline="always", **CONTRACT)
def tool_normal_basis(kx, ky, kz, ref):
    """Two unit vectors normal to the unit tool axis k: u_1 = ref x k / |ref x k|, u_2 = k x u_1.

    ``ref`` is fixed per candidate (``reference_axis``), so the basis is a smooth function of the joints
    (Newton's Jacobian is then the derivative of the residual it solves)."""
    ux, uy, uz = ref[1] * kz - ref[2] * ky, ref[2] * kx - ref[0] * kz, ref[0] * ky - ref[1] * kx
    il = 1.0 / np.sqrt(ux * ux + uy * uy + uz * uz)
    ux, uy, uz = ux * il, uy * il, uz * il
    return ux, uy, uz, ky * uz - kz * uy, kz * ux - kx * uz, kx * uy - ky * ux


def reference_axis(direction) -> np.ndarray:
    """The base axis least aligned with a typical tool direction (the RCM to the workspace centre): at
    least 54.7 deg from it, so ref x k never vanishes over a workspace seen from the RCM."""
    d = np.abs(np.asarray(direction, np.float64))
    e = np.zeros(3)
    e[int(np.argmin(d))] = 1.0
    return e


@njit(inline="always", **CONTRACT)
def rcm_residual_jacobian(rot, pos, prismatic, q, target, c, ref, axes, origins, jac, res, trig):
    """The five RCM-constrained IK equations at ``q`` (module docstring): residual ``res`` (5,) and its
    Jacobian ``jac`` (5, 5) for tip target ``target`` and RCM ``c``; returns max |res| (m)."""
    r = chain_frames(rot, pos, prismatic, q, axes, origins, trig)
    kx, ky, kz, px, py, pz = r[2], r[5], r[8], r[9], r[10], r[11]
    s = (c[0] - px) * kx + (c[1] - py) * ky + (c[2] - pz) * kz
    mx, my, mz = px + s * kx, py + s * ky, pz + s * kz  # point of the tool line nearest the RCM
    u1x, u1y, u1z, u2x, u2y, u2z = tool_normal_basis(kx, ky, kz, ref)
    dx, dy, dz = mx - c[0], my - c[1], mz - c[2]
    res[0], res[1], res[2] = px - target[0], py - target[1], pz - target[2]
    res[3] = u1x * dx + u1y * dy + u1z * dz
    res[4] = u2x * dx + u2y * dy + u2z * dz
    for j in range(N_ACTIVE):
        zx, zy, zz = axes[j, 0], axes[j, 1], axes[j, 2]
        if prismatic[j] != 0.0:
            tx, ty, tz = zx, zy, zz
            gx, gy, gz = zx, zy, zz
        else:
            ax, ay, az = px - origins[j, 0], py - origins[j, 1], pz - origins[j, 2]
            tx, ty, tz = zy * az - zz * ay, zz * ax - zx * az, zx * ay - zy * ax
            bx, by, bz = mx - origins[j, 0], my - origins[j, 1], mz - origins[j, 2]
            gx, gy, gz = zy * bz - zz * by, zz * bx - zx * bz, zx * by - zy * bx
        jac[0, j], jac[1, j], jac[2, j] = tx, ty, tz
        jac[3, j] = u1x * gx + u1y * gy + u1z * gz
        jac[4, j] = u2x * gx + u2y * gy + u2z * gz
    worst = 0.0
    for i in range(N_ACTIVE):
        worst = max(worst, abs(res[i]))
    return worst


@njit(**CONTRACT)
def damped_solve(jac, rhs, damping, out, work):
    """out = (J^T J + damping I)^-1 J^T rhs for a 5x5 J (Cholesky; ``work`` (5, 6) scratch).

    With damping |e|^2 this is the Levenberg-Marquardt step of Sugihara (2011): Newton's step near a
    solution, a shorter one far from it or near a singularity. Returns False when not positive definite.
    """
    n = N_ACTIVE
    for i in range(n):
        for j in range(i + 1):
            acc = 0.0
            for k in range(n):
                acc += jac[k, i] * jac[k, j]
            work[i, j] = acc + (damping if i == j else 0.0)
        acc = 0.0
        for k in range(n):
            acc += jac[k, i] * rhs[k]
        work[i, n] = acc
    for j in range(n):  # L L^T in the lower triangle
        d = work[j, j]
        for k in range(j):
            d -= work[j, k] * work[j, k]
        if not d > 0.0:
            return False
        d = np.sqrt(d)
        work[j, j] = d
        for i in range(j + 1, n):
            acc = work[i, j]
            for k in range(j):
                acc -= work[i, k] * work[j, k]
            work[i, j] = acc / d
    for i in range(n):  # forward: L y = J^T rhs
        acc = work[i, n]
        for k in range(i):
            acc -= work[i, k] * out[k]
        out[i] = acc / work[i, i]
    for i in range(n - 1, -1, -1):  # back: L^T x = y
        acc = out[i]
        for k in range(i + 1, n):
            acc -= work[k, i] * out[k]
        out[i] = acc / work[i, i]
    return True


@njit(inline="always", **CONTRACT)
def lu_solve(jac, rhs, out, work):
    """out = J^-1 rhs for a 5x5 J (Gaussian elimination with partial pivoting; ``work`` (5, 6) scratch).
    Returns False when J is singular to working precision (a pivot below 1e-14 of the largest entry)."""
    n = N_ACTIVE
    scale = 0.0
    for i in range(n):
        for j in range(n):
            work[i, j] = jac[i, j]
            scale = max(scale, abs(jac[i, j]))
        work[i, n] = rhs[i]
    for k in range(n):
        piv = k
        for i in range(k + 1, n):
            if abs(work[i, k]) > abs(work[piv, k]):
                piv = i
        if not abs(work[piv, k]) > 1e-14 * scale:
            return False
        if piv != k:
            for j in range(k, n + 1):
                work[k, j], work[piv, j] = work[piv, j], work[k, j]
        inv = 1.0 / work[k, k]
        for i in range(k + 1, n):
            f = work[i, k] * inv
            for j in range(k + 1, n + 1):
                work[i, j] -= f * work[k, j]
    for i in range(n - 1, -1, -1):
        acc = work[i, n]
        for j in range(i + 1, n):
            acc -= work[i, j] * out[j]
        out[i] = acc / work[i, i]
    return True


@njit(**CONTRACT)
def newton_rcm(rot, pos, prismatic, q, target, c, ref, max_iter, bufs):
    """Damped Newton on the five equations from ``q`` (updated in place), in the ``Scratch`` ``bufs``. Returns
    the number of steps taken when max |res| < IK_TOL_M (``bufs.jac`` then holds the Jacobian at the
    solution), or -1."""
    axes, origins, jac, res, step, work, trig = bufs
    for it in range(max_iter + 1):
        worst = rcm_residual_jacobian(rot, pos, prismatic, q, target, c, ref, axes, origins, jac, res, trig)
        if worst < IK_TOL_M:
            return it
        if it == max_iter or not np.isfinite(worst):
            break
        e2 = 0.0
        for i in range(N_ACTIVE):
            e2 += res[i] * res[i]
        # near a solution Newton's own step (LU); far from it, or where J is singular, Levenberg-Marquardt
        if not (e2 < NEWTON_ZONE_M2 and lu_solve(jac, res, step, work)):
            if not damped_solve(jac, res, e2, step, work):
                break
        for i in range(N_ACTIVE):
            q[i] -= step[i]
    return -1


@njit(inline="always", **CONTRACT)
def within_limits(q, prismatic, lower, upper):
    """Whether q is inside the joint limits; a revolute joint may be taken 2 pi round (q updated)."""
    for i in range(N_ACTIVE):
        v = q[i]
        if prismatic[i] == 0.0 and not (lower[i] <= v <= upper[i]):
            if lower[i] <= v - TWO_PI <= upper[i]:
                v -= TWO_PI
            elif lower[i] <= v + TWO_PI <= upper[i]:
                v += TWO_PI
        if not (lower[i] <= v <= upper[i]):
            return False
        q[i] = v
    return True


@njit(inline="always", **CONTRACT)
def pose_extremes_from_jacobian(jac, qdot_max):
    """(sigma_min^2, sigma_max^2, singular) of the RCM metric at a solution: A = J Q into the shared
    ``constrained_extremes`` (columns: tip rows, then the two constraint rows)."""
    s0, s1, s2, s3, s4 = qdot_max[0], qdot_max[1], qdot_max[2], qdot_max[3], qdot_max[4]
    return constrained_extremes(
        (jac[0, 0] * s0, jac[1, 0] * s0, jac[2, 0] * s0, jac[3, 0] * s0, jac[4, 0] * s0),
        (jac[0, 1] * s1, jac[1, 1] * s1, jac[2, 1] * s1, jac[3, 1] * s1, jac[4, 1] * s1),
        (jac[0, 2] * s2, jac[1, 2] * s2, jac[2, 2] * s2, jac[3, 2] * s2, jac[4, 2] * s2),
        (jac[0, 3] * s3, jac[1, 3] * s3, jac[2, 3] * s3, jac[3, 3] * s3, jac[4, 3] * s3),
        (jac[0, 4] * s4, jac[1, 4] * s4, jac[2, 4] * s4, jac[3, 4] * s4, jac[4, 4] * s4))


@njit(inline="always", **CONTRACT)
def sym_eig_extremes(a, n):
    """(smallest, largest) eigenvalue of the symmetric n x n matrix in ``a`` (overwritten): cyclic Jacobi
    rotations until the off-diagonal part is below 1e-15 of the norm (at most 30 sweeps)."""
    norm = 0.0
    for i in range(n):
        for j in range(n):
            norm += a[i, j] * a[i, j]
    for _ in range(30):
        off = 0.0
        for i in range(n):
            for j in range(i + 1, n):
                off += a[i, j] * a[i, j]
        if off <= 1e-30 * norm:
            break
        for p in range(n):
            for q in range(p + 1, n):
                if a[p, q] == 0.0:
                    continue
                theta = (a[q, q] - a[p, p]) / (2.0 * a[p, q])
                t = (1.0 if theta >= 0 else -1.0) / (abs(theta) + np.sqrt(theta * theta + 1.0))
                c = 1.0 / np.sqrt(t * t + 1.0)
                s = t * c
                for k in range(n):
                    akp, akq = a[k, p], a[k, q]
                    a[k, p], a[k, q] = c * akp - s * akq, s * akp + c * akq
                for k in range(n):
                    apk, aqk = a[p, k], a[q, k]
                    a[p, k], a[q, k] = c * apk - s * aqk, s * apk + c * aqk
    lo, hi = a[0, 0], a[0, 0]
    for i in range(1, n):
        lo, hi = min(lo, a[i, i]), max(hi, a[i, i])
    return lo, hi


@njit(**CONTRACT)
def standard_extremes(axes, origins, prismatic, px, py, pz, kx, ky, kz, qdot_max, task_scale, gram):
    """(sigma_min^2, sigma_max^2) of the standard Jacobian at one pose (no RCM constraint; Locke & Patel
    Sec. III-E): the tip's linear and angular velocity rows of the geometric Jacobian of the five active
    joints and, when ``task_scale[2]`` > 0, of the tool-spin joint (axis along the tool k through the tip,
    rated speed task_scale[2]): 6 x 6, the PA10's six joints with S3 held. Rows divided by the task
    scaling (``task_scale[0]`` m/s, ``task_scale[1]`` rad/s), columns times the rated speeds; from the
    Gram matrix's extreme eigenvalues (``gram`` (6, 6) scratch)."""
    n = N_ACTIVE + (1 if task_scale[2] > 0.0 else 0)
    b = np.zeros((6, 6))
    for j in range(N_ACTIVE):
        zx, zy, zz = axes[j, 0], axes[j, 1], axes[j, 2]
        if prismatic[j] != 0.0:
            b[0, j], b[1, j], b[2, j] = zx, zy, zz
        else:
            ax, ay, az = px - origins[j, 0], py - origins[j, 1], pz - origins[j, 2]
            b[0, j], b[1, j], b[2, j] = zy * az - zz * ay, zz * ax - zx * az, zx * ay - zy * ax
            b[3, j], b[4, j], b[5, j] = zx, zy, zz
        for i in range(6):
            b[i, j] *= qdot_max[j]
    if n == 6:
        b[3, 5], b[4, 5], b[5, 5] = kx * task_scale[2], ky * task_scale[2], kz * task_scale[2]
    for j in range(n):
        for i in range(3):
            b[i, j] /= task_scale[0]
            b[i + 3, j] /= task_scale[1]
    for i in range(n):
        for j in range(n):
            acc = 0.0
            for k in range(6):
                acc += b[k, i] * b[k, j]
            gram[i, j] = acc
    lo, hi = sym_eig_extremes(gram, n)
    return max(lo, 0.0), hi


@njit(**CONTRACT)
def _predict(q, q1, q2, q3, q4, run, jac, dp, step, work):
    """Predict the next point's joints. On a straight run of the walk (``run`` earlier steps in the same
    direction; q1, q2, q3 the solutions one, two and three points back) extrapolate: cubic after three
    steps (4 q - 6 q1 + 4 q2 - q3: error O(h^4)) and quartic after four (5 q - 10 q1 + 10 q2 - 5 q3 + q4:
    O(h^5), so one Newton step usually meets the tolerance),
    quadratic after two, linear after one (weights ``EXTRAPOLATION``; the history must be finite);
    otherwise the tangent q + J^-1 (dp, 0, 0) (the RCM rows stay satisfied to first order)."""
    if run > 0:
        k0, k1, k2, k3, k4 = EXTRAPOLATION[min(run, 4)]
        for i in range(N_ACTIVE):
            q[i] = k0 * q[i] + k1 * q1[i] + k2 * q2[i] + k3 * q3[i] + k4 * q4[i]
        return
    dp[3], dp[4] = 0.0, 0.0
    if lu_solve(jac, dp, step, work):
        for i in range(N_ACTIVE):
            q[i] += step[i]


@njit(**CONTRACT)
def seed_solve(rot, pos, prismatic, lower, upper, seed, restarts, target, c, ref, q, bufs):
    """Solve at ``target`` from the seed, then from each restart; True with ``q`` set when one converges."""
    axes, origins, jac, res, step, work, trig = bufs
    for r in range(restarts.shape[0] + 1):
        for i in range(N_ACTIVE):
            q[i] = seed[i] if r == 0 else seed[i] + restarts[r - 1, i]
        if newton_rcm(rot, pos, prismatic, q, target, c, ref, SEED_ITER, bufs) >= 0:
            if within_limits(q, prismatic, lower, upper):
                return True
    return False


@njit(**CONTRACT)
def continue_walk(rot, pos, prismatic, q, target, c, ref, end, bufs):
    """Carry the solution ``q`` at ``target`` to RCM + ``end`` in equal steps of at most
    CONTINUATION_STEP_M (tangent predictor, Newton corrector). Returns the Newton steps taken, or -1."""
    axes, origins, jac, res, step, work, trig = bufs
    dp = np.empty(N_ACTIVE)
    dist = 0.0
    for i in range(3):
        dist += (c[i] + end[i] - target[i]) ** 2
    n_cont = int(np.ceil(np.sqrt(dist) / CONTINUATION_STEP_M))
    total = 0
    for s in range(n_cont):
        for i in range(3):
            new = target[i] + (c[i] + end[i] - target[i]) / (n_cont - s)
            dp[i] = new - target[i]
            target[i] = new
        _predict(q, q, q, q, q, 0, jac, dp, step, work)
        it = newton_rcm(rot, pos, prismatic, q, target, c, ref, WALK_ITER, bufs)
        if it < 0:
            return -1
        total += it
    return total


@njit(**CONTRACT)
def constraint_reference(start):
    """The constraint rows' reference axis for a walk around RCM + ``start``: the base axis least aligned
    with the RCM -> workspace-centre direction (``reference_axis``)."""
    ref = np.zeros(3)
    a0, a1, a2 = abs(start[0]), abs(start[1]), abs(start[2])
    ref[0 if (a0 <= a1 and a0 <= a2) else (1 if a1 <= a2 else 2)] = 1.0
    return ref


@njit(**CONTRACT)
def seed_and_probe(chain_arrays, seed, restarts, c, start, probes, ref, q, target, bufs):
    """Solve at RCM + ``start`` from the seed (``seed_solve``), then reach each of the ``probes`` (offsets)
    from there by continuation (IK only): a candidate that loses one is infeasible at once.

    Returns (ok, Newton steps); when ok, ``q`` is the start's solution, ``target`` = RCM + ``start`` and
    ``bufs``' Jacobian the one there."""
    rot, pos, prismatic, lower, upper, qdot_max = chain_arrays
    axes, origins, jac, res, step, work, trig = bufs
    for i in range(3):
        target[i] = c[i] + start[i]
    if not seed_solve(rot, pos, prismatic, lower, upper, seed, restarts, target, c, ref, q, bufs):
        return False, 0
    q0 = q.copy()
    steps_total = 0
    for k in range(probes.shape[0]):
        it = continue_walk(rot, pos, prismatic, q, target, c, ref, probes[k], bufs)
        if it < 0 or not within_limits(q, prismatic, lower, upper):
            return False, steps_total
        steps_total += it
        for i in range(N_ACTIVE):
            q[i] = q0[i]
        for i in range(3):
            target[i] = c[i] + start[i]
        newton_rcm(rot, pos, prismatic, q, target, c, ref, 0, bufs)
    return True, steps_total


class Scratch(NamedTuple):
    """Scratch of one scalar Newton solve (Pinocchio's Data beside its Model), what ``newton_rcm``,
    ``continue_walk`` and ``seed_solve`` take: each joint's axis and origin (5, 3), the Jacobian (5, 5), the
    residual and the step (5), the solver's work (5, 6) and the joints' cached cos / sin (4, 5)."""

    axes: np.ndarray
    origins: np.ndarray
    jac: np.ndarray
    res: np.ndarray
    step: np.ndarray
    work: np.ndarray
    trig: np.ndarray


@njit(**CONTRACT)
def scalar_buffers():
    """A fresh ``Scratch`` (``trig`` empty: exact cos/sin first)."""
    trig = np.zeros((4, N_ACTIVE))
    trig[2, :] = np.nan
    return Scratch(np.empty((N_ACTIVE, 3)), np.empty((N_ACTIVE, 3)), np.empty((N_ACTIVE, N_ACTIVE)),
                   np.empty(N_ACTIVE), np.empty(N_ACTIVE), np.empty((N_ACTIVE, N_ACTIVE + 1)), trig)


@njit(**CONTRACT)
def chain_walk(chain_arrays, seed, restarts, c, offsets, start, probes, gii_to_beat, q_out):
    """One candidate: seed solve at RCM + ``start``, the ``probes`` (offsets, each reached by continuation
    from the start and abandoned), continuation to the first point, the walk.

    Returns (min sigma_min^2, max sigma_max^2, n_unreachable, n_singular, points_evaluated, newton steps);
    ``q_out`` (P, 5) gets each point's joints (NaN where not reached). Stops early when the running
    bound min sigma_min / max sigma_max falls to ``gii_to_beat`` (the Culling step; 0 never stops).
    """
    rot, pos, prismatic, lower, upper, qdot_max = chain_arrays
    bufs = scalar_buffers()
    axes, origins, jac, res, step, work, trig = bufs
    q = np.empty(N_ACTIVE)
    target = np.empty(3)
    dp = np.empty(N_ACTIVE)  # tip step, then (dp, 0, 0) for the tangent predictor
    p = offsets.shape[0]
    q_out[:] = np.nan
    ref = constraint_reference(start)
    ok, steps_total = seed_and_probe(chain_arrays, seed, restarts, c, start, probes, ref, q, target, bufs)
    if not ok:
        return 0.0, 0.0, 1, 0, 0, steps_total
    q0 = q.copy()
    # continuation: start -> offsets[0]
    it = continue_walk(rot, pos, prismatic, q, target, c, ref, offsets[0], bufs)
    if it < 0:
        return 0.0, 0.0, 1, 0, 0, steps_total
    steps_total += it
    lo = np.inf
    hi = 0.0
    n_sing = 0
    bound2 = gii_to_beat * gii_to_beat
    q1 = np.zeros(N_ACTIVE)
    q2 = np.zeros(N_ACTIVE)
    q3 = np.zeros(N_ACTIVE)
    q4 = np.zeros(N_ACTIVE)
    qj = np.empty(N_ACTIVE)
    last = np.zeros(3)
    run = 0
    for j in range(p):
        if j > 0:
            straight = True
            for i in range(3):
                new = c[i] + offsets[j, i]
                dp[i] = new - target[i]
                target[i] = new
                straight &= abs(dp[i] - last[i]) <= 1e-12
            run = min(run + 1, 4) if straight else 0
            for i in range(3):
                last[i] = dp[i]
            for i in range(N_ACTIVE):
                qj[i] = q[i]
            _predict(q, q1, q2, q3, q4, run, jac, dp, step, work)
            for i in range(N_ACTIVE):
                q4[i], q3[i], q2[i], q1[i] = q3[i], q2[i], q1[i], qj[i]
        it = newton_rcm(rot, pos, prismatic, q, target, c, ref, WALK_ITER, bufs)
        if it < 0 or not within_limits(q, prismatic, lower, upper):
            # the walk lost the point (a near-singular step: an elbow at full stretch, a wrist with W1 ~ 0):
            # reach it once more from the start's solution, straight from the workspace centre
            for i in range(N_ACTIVE):
                q[i] = q0[i]
            for i in range(3):
                target[i] = c[i] + start[i]
            newton_rcm(rot, pos, prismatic, q, target, c, ref, 0, bufs)
            it = continue_walk(rot, pos, prismatic, q, target, c, ref, offsets[j], bufs)
            if it < 0 or not within_limits(q, prismatic, lower, upper):
                return 0.0, 0.0, 1, 0, j + 1, steps_total
            run = 0
            for i in range(3):
                last[i] = np.nan  # no straight run through the retried point
        steps_total += it
        for i in range(N_ACTIVE):
            q_out[j, i] = q[i]
        smin2, smax2, singular = pose_extremes_from_jacobian(jac, qdot_max)
        lo = min(lo, smin2)
        hi = max(hi, smax2)
        n_sing += 1 if singular else 0
        if bound2 > 0.0 and lo <= bound2 * hi:
            return lo, hi, 0, n_sing, j + 1, steps_total
    return lo, hi, 0, n_sing, p, steps_total


@njit(**CONTRACT)
def standard_over(chain_arrays, q_out, n, task_scale):
    """(min sigma_min^2, max sigma_max^2, singular count) of the standard Jacobian over the walk's first n
    solutions ``q_out`` (``standard_extremes``)."""
    rot, pos, prismatic, lower, upper, qdot_max = chain_arrays
    axes = np.empty((N_ACTIVE, 3))
    origins = np.empty((N_ACTIVE, 3))
    trig = np.zeros((4, N_ACTIVE))
    trig[2, :] = np.nan
    gram = np.empty((6, 6))
    lo = np.inf
    hi = 0.0
    n_sing = 0
    for j in range(n):
        fr = chain_frames(rot, pos, prismatic, q_out[j], axes, origins, trig)
        smin2, smax2 = standard_extremes(axes, origins, prismatic, fr[9], fr[10], fr[11], fr[2], fr[5], fr[8],
                                         qdot_max, task_scale, gram)
        lo = min(lo, smin2)
        hi = max(hi, smax2)
        n_sing += 1 if smin2 <= 1e-24 * smax2 else 0
    return lo, hi, n_sing


@njit(**CONTRACT)
def metric_over_solutions(metric, chain_arrays, q_out, n, params):
    """(min sigma_min^2, max sigma_max^2, singular count) of a metric evaluated over the walk's first n
    solutions: each ``metrics.POSE_METRICS`` code the walk does not compute itself, to its entry's ``evaluator``;
    the one place such a metric is dispatched."""
    if metric == METRIC_STANDARD:
        return standard_over(chain_arrays, q_out, n, params)
    return np.nan, np.nan, 0  # not a metric of the solutions (the RCM metric is the walk's own)


@njit(**CONTRACT)
def candidates_scalar(chain_arrays, seed, restarts, rcms, offsets, start, probes, gii_to_beat, metric, params):
    """Per candidate: the walk (``chain_walk``) and the extremes of the per-pose ``metric`` (a
    ``metrics.POSE_METRICS`` code; ``params`` its parameters). The RCM metric is the walk's own and its running bound
    may stop the walk at ``gii_to_beat``; any other is evaluated over the walk's solutions (the whole walk)."""
    m = rcms.shape[0]
    out = np.zeros((m, 2))
    counts = np.empty((m, 4), np.int64)
    q_out = np.empty((offsets.shape[0], N_ACTIVE))
    in_walk = metric == METRIC_RCM
    for i in range(m):
        g = gii_to_beat[i] if in_walk else 0.0
        lo, hi, n_unr, n_sing, n_eval, steps = chain_walk(chain_arrays, seed, restarts, rcms[i], offsets, start, probes,
                                                          g, q_out)
        if not in_walk and n_unr == 0:
            lo, hi, n_sing = metric_over_solutions(metric, chain_arrays, q_out, n_eval, params)
        if in_walk or n_unr == 0:
            out[i, 0], out[i, 1] = np.sqrt(lo), np.sqrt(hi)
        counts[i, 0], counts[i, 1], counts[i, 2], counts[i, 3] = n_unr, n_sing, n_eval, steps
    return out, counts


def serpentine_order(n: int) -> np.ndarray:
    """Indices of an n x n x n grid (x-major: (ix n + iy) n + iz) in a serpentine walk: each point a unit
    step from the one before, so every IK solution warm-starts the next.

    Example (tested): n = 2 -> [0, 1, 3, 2, 6, 7, 5, 4].
    """
    out = []
    flip_y = flip_z = False
    for ix in range(n):
        for iy in (reversed(range(n)) if flip_y else range(n)):
            out.extend((ix * n + iy) * n + iz for iz in (reversed(range(n)) if flip_z else range(n)))
            flip_z = not flip_z
        flip_y = not flip_y
    return np.array(out, dtype=np.int64)


def kernel_arrays(chain: Chain):
    """The ``Chain`` as the kernels take it: a tuple of contiguous float64 arrays."""
    return tuple(np.ascontiguousarray(a, dtype=np.float64) for a in chain)


def default_restarts(seed) -> np.ndarray:
    """Eight fixed perturbations of the seed (rad or m, sigma 0.3) tried when the seed itself fails."""
    return np.random.default_rng(20070410).normal(0.0, 0.3, (8, len(seed)))


def chain_fk(chain: Chain, q):
    """Tool frame (4x4, z along the tool, origin at the tip) and joint axes/origins (5, 3) at joints q."""
    rot, pos, prismatic = kernel_arrays(chain)[:3]
    axes, origins = np.empty((5, 3)), np.empty((5, 3))
    r = chain_frames(rot, pos, prismatic, np.asarray(q, np.float64), axes, origins, new_trig_cache())
    t = np.eye(4)
    t[:3, :3] = np.array(r[:9]).reshape(3, 3)
    t[:3, 3] = r[9:]
    return t, axes, origins


def rcm_jacobian(chain: Chain, q, target, rcm):
    """(residual (5,), Jacobian (5, 5)) of the five RCM-constrained IK equations at q (module docstring),
    the constraint rows in the basis of ``reference_axis(target - rcm)``."""
    rot, pos, prismatic = kernel_arrays(chain)[:3]
    axes, origins, jac, res = np.empty((5, 3)), np.empty((5, 3)), np.empty((5, 5)), np.empty(5)
    target, rcm = np.asarray(target, np.float64), np.asarray(rcm, np.float64)
    rcm_residual_jacobian(rot, pos, prismatic, np.asarray(q, np.float64), target, rcm,
                          reference_axis(target - rcm), axes, origins, jac, res, new_trig_cache())
    return res, jac


def rcm_walk(chain: Chain, rcm, offsets, seed, start=None, restarts=None):
    """One RCM candidate along the walk ``offsets`` (P, 3), tips relative to ``rcm``, already in walk order.

    Returns a dict: ``q`` (P, 5) joints per point (NaN past the first unreachable one), ``sigma_min``,
    ``sigma_max`` (m/s, over the points reached), ``n_unreachable``, ``n_singular``, ``points_evaluated``,
    ``newton_steps``. ``start`` (default the offsets' mean) is where the seed solve happens.
    """
    offsets = np.ascontiguousarray(offsets, dtype=np.float64).reshape(-1, 3)
    seed = np.asarray(seed, np.float64)
    start = workspace_centre(offsets) if start is None else np.asarray(start, np.float64)
    restarts = default_restarts(seed) if restarts is None else np.asarray(restarts, np.float64).reshape(-1, 5)
    q_out = np.empty((offsets.shape[0], 5))
    lo, hi, n_unr, n_sing, n_eval, steps = chain_walk(kernel_arrays(chain), seed, restarts, np.asarray(rcm, np.float64),
                                                 offsets, start, np.empty((0, 3)), 0.0, q_out)
    return {"q": q_out, "sigma_min": float(np.sqrt(lo)), "sigma_max": float(np.sqrt(hi)), "n_unreachable": n_unr,
            "n_singular": n_sing, "points_evaluated": n_eval, "newton_steps": steps}
