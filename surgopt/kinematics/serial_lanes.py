"""The serial-chain walk in SIMD lanes: one candidate's workspace walk cut into ``LANES`` segments that
are walked side by side, eight poses per vector instruction.

The scalar walk (``serial_chain._walk``) is one dependent sequence: each pose's Newton solve starts
from the previous pose's solution, so a CPU runs its forward kinematics, Jacobian and LU one pose at
a time (~900 ns a pose on the PA10). Here the walk order is cut into ``LANES`` contiguous segments;
each segment's first point is reached from the workspace centre by continuation (as the scalar walk
reaches its first point), and then every segment advances one point per step in lockstep: the
predictor, the five equations and their Jacobian (``lane_eval``), the Newton step's LU
(``lane_lu_solve``) and the metric (``lane_metric``, the shared ``constrained_extremes``) run for all
lanes at once. Each segment follows the scalar walk's rules (polynomial predictor on a straight run,
tangent predictor after a turn, Newton's step undamped within 1 mm and damped beyond, ``IK_TOL_M``,
``WALK_ITER`` steps, joint limits); a lane more than 5 mm off, with a singular pivot or not
converging is finished by the scalar code (``newton_rcm``, then the retry from the start's
solution), and a candidate that loses a point in lanes is walked again by the scalar walk, whose
verdict stands (near a singularity two paths to a point can disagree). So every point gets the
scalar walk's treatment and the same answer to within Newton's tolerance.

Memory layout, and why: every lane quantity is a row of ``LANES`` doubles in one flat buffer ``S``
(``S[(ROW + k) * LANES + lane]``, the rows named below), and each joint's code is written out with
its joint index a constant (``fk_joint(..., 0)`` ... ``fk_joint(..., 5)``). With one buffer and constant
offsets LLVM can prove that the lanes of a loop do not overlap and vectorises every loop over lanes
(separate arrays, or a joint index held in a variable, left the forward kinematics scalar: 19 vs
100 ns per pose-evaluation, measured). Culling is checked after each lockstep step, so a culled
walk may evaluate up to ``LANES - 1`` points more than the scalar walk would.

One module of ~800 lines: the buffer's row layout is shared by every function here (each reads and
writes rows by name), and the vectorised pieces only vectorise when inlined beside the loops that
call them; splitting it would split the layout from the code that depends on it.
"""
from __future__ import annotations

import numpy as np

from surgopt.jit import CONTRACT, njit
from surgopt.metrics import METRIC_RCM
from surgopt.kinematics.rcm_metric import constrained_extremes
from surgopt.kinematics.serial_chain import (
    CONTINUATION_STEP_M, EXTRAPOLATION, IK_TOL_M, N_ACTIVE, NEWTON_ZONE_M2, TRIG_RESYNC, TRIG_STEP_RAD, WALK_ITER,
    continue_walk, chain_walk, constraint_reference, increment_cos_sin, metric_over_solutions, newton_rcm,
    scalar_buffers, seed_solve, within_limits,
)

#: Segments walked side by side (one AVX-512 vector of doubles).
LANES = 8
#: Below this squared residual (m^2) the lanes solve a pose themselves, with the scalar walk's steps:
#: undamped Newton below ``NEWTON_ZONE_M2`` = (1 mm)^2, Levenberg-Marquardt with damping |e|^2 above
#: (``damp_lanes``). The tangent prediction after a turn of the walk lands 0.6-1.5 mm off on the PA10's
#: map (measured), so without the damped step in lanes a lane went to the scalar code at nearly every
#: turn (65 hand-offs per walk); with undamped steps there instead, the last iterate met the tolerance
#: by less and GII moved up to 3.7e-9 from the closed form's (8.9e-10 with the damped step, as the
#: scalar walk). Beyond (5 mm)^2, or where Newton fails, the scalar code takes over.
LANE_NEWTON_ZONE_M2 = 2.5e-5
#: A walk shorter than this many points per lane is walked by the scalar kernel (continuation to each
#: segment's start would cost more than the lanes save).
MIN_POINTS_PER_LANE = 16

N = N_ACTIVE
W = LANES
# rows of the lane buffer S: each name is the first of its rows
Q = 0  # joints (5)
TGT = Q + N  # tip target (3)
C = TGT + 3  # RCM (3)
REF = C + 3  # reference axis of the constraint rows (3)
CS = REF + 3  # cos of each joint (5), valid for the angles in ANG
SN = CS + N  # sin (5)
ANG = SN + N  # angles CS/SN belong to (5)
ROT = ANG + N  # running rotation (9)
POS = ROT + 9  # running origin (3)
AX = POS + 3  # joint axes (5 x 3)
OR = AX + 3 * N  # joint origins (5 x 3)
RES = OR + 3 * N  # residual (5)
JAC = RES + N  # Jacobian (5 x 5, row-major)
WORST = JAC + N * N  # max |residual|
OK = WORST + 1  # 1.0 when the last LU had no singular pivot
STEP = OK + 1  # LU solution (5)
RHS = STEP + N  # right-hand side of the tangent predictor (5)
H1 = RHS + N  # solutions one to four points back (4 x 5)
H2 = H1 + N
H3 = H2 + N
H4 = H3 + N
QP = H4 + N  # the prediction Newton starts from (5)
SMIN = QP + N  # the metric at the last point: sigma_min^2, sigma_max^2, singular
SMAX = SMIN + 1
SING = SMAX + 1
ACT = SING + 1  # 1.0 for a lane that evaluates a point this step
LO = ACT + 1  # running min sigma_min^2, max sigma_max^2, singular count
HI = LO + 1
NSING = HI + 1
DMAX = NSING + 1  # largest joint increment since the cos/sin caches' angles
PEND = DMAX + 1  # 1.0 while a lane's Newton is running
FB = PEND + 1  # 1.0 for a lane the scalar code must finish
INLIM = FB + 1  # 1.0 when a lane's joints are inside their limits as they are (no 2 pi turn needed)
KQ = INLIM + 1  # predictor weights of Q, H1..H4 (5), and 1.0 for the tangent step (1)
KT = KQ + 5
ROWS = KT + 1



@njit(inline="always", **CONTRACT)
def _at(row, lane):
    return row * W + lane


@njit(inline="always", **CONTRACT)
def trig_taylor(S):
    """cos/sin of every lane's joints turned from the cached ones by the increment d = q - ANG (Taylor
    series to d^11, as ``serial_chain.joint_cos_sin``); returns max |d| (inf when a cache is empty)."""
    for lane in range(W):
        big = 0.0
        for i in range(N):
            d = S[_at(Q + i, lane)] - S[_at(ANG + i, lane)]
            big = max(big, abs(d)) if abs(d) == abs(d) else np.inf
            cd, sd = increment_cos_sin(d)
            c0, s0 = S[_at(CS + i, lane)], S[_at(SN + i, lane)]
            S[_at(CS + i, lane)] = c0 * cd - s0 * sd
            S[_at(SN + i, lane)] = s0 * cd + c0 * sd
            S[_at(ANG + i, lane)] = S[_at(Q + i, lane)]
        S[_at(DMAX, lane)] = big
    big = 0.0
    for lane in range(W):
        big = max(big, S[_at(DMAX, lane)])
    return big


@njit(**CONTRACT)
def trig_exact(S):
    """cos/sin of every lane's joints evaluated exactly (the caches' resynchronisation)."""
    for lane in range(W):
        for i in range(N):
            v = S[_at(Q + i, lane)]
            S[_at(CS + i, lane)], S[_at(SN + i, lane)], S[_at(ANG + i, lane)] = np.cos(v), np.sin(v), v


@njit(inline="always", **CONTRACT)
def fk_joint(rot, pos, prismatic, S, i):
    """One fixed transform P_i and (for i < 5) joint i's motion, for every lane: the running frame
    (ROT, POS) <- (ROT, POS) P_i M_i(q_i); joint i's axis and origin saved in AX, OR."""
    b0, b1, b2 = pos[i, 0], pos[i, 1], pos[i, 2]
    a00, a01, a02 = rot[i, 0, 0], rot[i, 0, 1], rot[i, 0, 2]
    a10, a11, a12 = rot[i, 1, 0], rot[i, 1, 1], rot[i, 1, 2]
    a20, a21, a22 = rot[i, 2, 0], rot[i, 2, 1], rot[i, 2, 2]
    pr = prismatic[i] if i < N else 0.0
    for lane in range(W):
        r00, r01, r02 = S[_at(ROT, lane)], S[_at(ROT + 1, lane)], S[_at(ROT + 2, lane)]
        r10, r11, r12 = S[_at(ROT + 3, lane)], S[_at(ROT + 4, lane)], S[_at(ROT + 5, lane)]
        r20, r21, r22 = S[_at(ROT + 6, lane)], S[_at(ROT + 7, lane)], S[_at(ROT + 8, lane)]
        if i == 0:
            r00, r01, r02, r10, r11, r12, r20, r21, r22 = 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0
            px, py, pz = b0, b1, b2
        else:
            px = S[_at(POS, lane)] + r00 * b0 + r01 * b1 + r02 * b2
            py = S[_at(POS + 1, lane)] + r10 * b0 + r11 * b1 + r12 * b2
            pz = S[_at(POS + 2, lane)] + r20 * b0 + r21 * b1 + r22 * b2
        n00 = r00 * a00 + r01 * a10 + r02 * a20
        n01 = r00 * a01 + r01 * a11 + r02 * a21
        n02 = r00 * a02 + r01 * a12 + r02 * a22
        n10 = r10 * a00 + r11 * a10 + r12 * a20
        n11 = r10 * a01 + r11 * a11 + r12 * a21
        n12 = r10 * a02 + r11 * a12 + r12 * a22
        n20 = r20 * a00 + r21 * a10 + r22 * a20
        n21 = r20 * a01 + r21 * a11 + r22 * a21
        n22 = r20 * a02 + r21 * a12 + r22 * a22
        if i < N:
            S[_at(AX + 3 * i, lane)], S[_at(AX + 3 * i + 1, lane)], S[_at(AX + 3 * i + 2, lane)] = n02, n12, n22
            S[_at(OR + 3 * i, lane)], S[_at(OR + 3 * i + 1, lane)], S[_at(OR + 3 * i + 2, lane)] = px, py, pz
            t = S[_at(Q + i, lane)] * pr
            cc = S[_at(CS + i, lane)] if pr == 0.0 else 1.0
            ss = S[_at(SN + i, lane)] if pr == 0.0 else 0.0
            px, py, pz = px + t * n02, py + t * n12, pz + t * n22
            n00, n01 = cc * n00 + ss * n01, cc * n01 - ss * n00
            n10, n11 = cc * n10 + ss * n11, cc * n11 - ss * n10
            n20, n21 = cc * n20 + ss * n21, cc * n21 - ss * n20
        S[_at(ROT, lane)], S[_at(ROT + 1, lane)], S[_at(ROT + 2, lane)] = n00, n01, n02
        S[_at(ROT + 3, lane)], S[_at(ROT + 4, lane)], S[_at(ROT + 5, lane)] = n10, n11, n12
        S[_at(ROT + 6, lane)], S[_at(ROT + 7, lane)], S[_at(ROT + 8, lane)] = n20, n21, n22
        S[_at(POS, lane)], S[_at(POS + 1, lane)], S[_at(POS + 2, lane)] = px, py, pz


@njit(inline="always", **CONTRACT)
def rcm_residual_lanes(S):
    """The five equations at the tool frame (ROT, POS) (``serial_chain.rcm_residual_jacobian``): RES,
    WORST; the line point nearest the RCM m and the basis u_1, u_2 kept in ROT's rows for the Jacobian."""
    for lane in range(W):
        kx, ky, kz = S[_at(ROT + 2, lane)], S[_at(ROT + 5, lane)], S[_at(ROT + 8, lane)]
        px, py, pz = S[_at(POS, lane)], S[_at(POS + 1, lane)], S[_at(POS + 2, lane)]
        cx, cy, cz = S[_at(C, lane)], S[_at(C + 1, lane)], S[_at(C + 2, lane)]
        s = (cx - px) * kx + (cy - py) * ky + (cz - pz) * kz
        mx, my, mz = px + s * kx, py + s * ky, pz + s * kz
        f0, f1, f2 = S[_at(REF, lane)], S[_at(REF + 1, lane)], S[_at(REF + 2, lane)]
        ux, uy, uz = f1 * kz - f2 * ky, f2 * kx - f0 * kz, f0 * ky - f1 * kx
        il = 1.0 / np.sqrt(ux * ux + uy * uy + uz * uz)
        u1x, u1y, u1z = ux * il, uy * il, uz * il
        u2x, u2y, u2z = ky * u1z - kz * u1y, kz * u1x - kx * u1z, kx * u1y - ky * u1x
        dx, dy, dz = mx - cx, my - cy, mz - cz
        e0, e1, e2 = px - S[_at(TGT, lane)], py - S[_at(TGT + 1, lane)], pz - S[_at(TGT + 2, lane)]
        e3 = u1x * dx + u1y * dy + u1z * dz
        e4 = u2x * dx + u2y * dy + u2z * dz
        S[_at(RES, lane)], S[_at(RES + 1, lane)], S[_at(RES + 2, lane)] = e0, e1, e2
        S[_at(RES + 3, lane)], S[_at(RES + 4, lane)] = e3, e4
        a, b = max(abs(e0), abs(e1)), max(abs(e2), abs(e3))
        S[_at(WORST, lane)] = max(max(a, b), abs(e4))
        S[_at(ROT, lane)], S[_at(ROT + 1, lane)], S[_at(ROT + 2, lane)] = mx, my, mz
        S[_at(ROT + 3, lane)], S[_at(ROT + 4, lane)], S[_at(ROT + 6, lane)] = u1x, u1y, u2x
        S[_at(ROT + 7, lane)], S[_at(ROT + 5, lane)], S[_at(ROT + 8, lane)] = u2y, u1z, u2z


@njit(inline="always", **CONTRACT)
def jacobian_column_lanes(prismatic, S, j):
    """Column j of the five equations' Jacobian for every lane: z_j x (p - o_j) and u . (z_j x (m - o_j))
    (revolute), z_j and u . z_j (prismatic)."""
    pr = prismatic[j]
    for lane in range(W):
        zx, zy, zz = S[_at(AX + 3 * j, lane)], S[_at(AX + 3 * j + 1, lane)], S[_at(AX + 3 * j + 2, lane)]
        ox, oy, oz = S[_at(OR + 3 * j, lane)], S[_at(OR + 3 * j + 1, lane)], S[_at(OR + 3 * j + 2, lane)]
        ax, ay, az = S[_at(POS, lane)] - ox, S[_at(POS + 1, lane)] - oy, S[_at(POS + 2, lane)] - oz
        bx, by, bz = S[_at(ROT, lane)] - ox, S[_at(ROT + 1, lane)] - oy, S[_at(ROT + 2, lane)] - oz
        tx, ty, tz = zy * az - zz * ay, zz * ax - zx * az, zx * ay - zy * ax
        gx, gy, gz = zy * bz - zz * by, zz * bx - zx * bz, zx * by - zy * bx
        if pr != 0.0:
            tx, ty, tz, gx, gy, gz = zx, zy, zz, zx, zy, zz
        S[_at(JAC + j, lane)], S[_at(JAC + N + j, lane)], S[_at(JAC + 2 * N + j, lane)] = tx, ty, tz
        u1x, u1y, u1z = S[_at(ROT + 3, lane)], S[_at(ROT + 4, lane)], S[_at(ROT + 5, lane)]
        u2x, u2y, u2z = S[_at(ROT + 6, lane)], S[_at(ROT + 7, lane)], S[_at(ROT + 8, lane)]
        S[_at(JAC + 3 * N + j, lane)] = u1x * gx + u1y * gy + u1z * gz
        S[_at(JAC + 4 * N + j, lane)] = u2x * gx + u2y * gy + u2z * gz


@njit(**CONTRACT)
def lane_eval(rot, pos, prismatic, S):
    """RES, WORST and JAC at every lane's Q (the cos/sin caches CS, SN must hold Q's)."""
    fk_joint(rot, pos, prismatic, S, 0)
    fk_joint(rot, pos, prismatic, S, 1)
    fk_joint(rot, pos, prismatic, S, 2)
    fk_joint(rot, pos, prismatic, S, 3)
    fk_joint(rot, pos, prismatic, S, 4)
    fk_joint(rot, pos, prismatic, S, 5)
    rcm_residual_lanes(S)
    jacobian_column_lanes(prismatic, S, 0)
    jacobian_column_lanes(prismatic, S, 1)
    jacobian_column_lanes(prismatic, S, 2)
    jacobian_column_lanes(prismatic, S, 3)
    jacobian_column_lanes(prismatic, S, 4)


@njit(inline="always", **CONTRACT)
def _swap_if(a, b, cond):
    """(b, a) when cond, else (a, b): two rows exchanged without a branch (partial pivoting)."""
    return (b, a) if cond else (a, b)


@njit(inline="always", **CONTRACT)
def _pivot(a, b, k):
    """Rows a, b with the larger |entry k| first."""
    return _swap_if(a, b, abs(b[k]) > abs(a[k]))


@njit(inline="always", **CONTRACT)
def _eliminate(r, p, k, inv):
    """Row r minus (r[k] / p[k]) times the pivot row p (``inv`` = 1 / p[k])."""
    f = r[k] * inv
    return (r[0] - f * p[0], r[1] - f * p[1], r[2] - f * p[2], r[3] - f * p[3], r[4] - f * p[4], r[5] - f * p[5])


@njit(inline="always", **CONTRACT)
def _row(S, lane, i, rhs):
    return (S[_at(JAC + i * N, lane)], S[_at(JAC + i * N + 1, lane)], S[_at(JAC + i * N + 2, lane)],
            S[_at(JAC + i * N + 3, lane)], S[_at(JAC + i * N + 4, lane)], S[_at(rhs + i, lane)])


@njit(inline="always", **CONTRACT)
def _row_max(r):
    return max(max(max(abs(r[0]), abs(r[1])), max(abs(r[2]), abs(r[3]))), abs(r[4]))


@njit(inline="always", **CONTRACT)
def lane_lu_solve(S, rhs):
    """STEP = JAC^-1 (rows ``rhs``) for every lane, by Gaussian elimination with partial pivoting done
    with compare-and-swap (the rows are register tuples, so the lanes vectorise); OK 1.0 where no pivot
    fell below 1e-14 of the matrix's largest entry (as ``serial_chain.lu_solve``), else 0.0. Inlined,
    so that ``rhs`` is a constant row at each call (with a variable one LLVM cannot prove that STEP's
    stores do not overlap the right-hand side's loads and leaves the loop scalar)."""
    for lane in range(W):
        r0, r1, r2, r3, r4 = _row(S, lane, 0, rhs), _row(S, lane, 1, rhs), _row(S, lane, 2, rhs), \
            _row(S, lane, 3, rhs), _row(S, lane, 4, rhs)
        tol = 1e-14 * max(max(max(_row_max(r0), _row_max(r1)), max(_row_max(r2), _row_max(r3))), _row_max(r4))
        r0, r1 = _pivot(r0, r1, 0)
        r0, r2 = _pivot(r0, r2, 0)
        r0, r3 = _pivot(r0, r3, 0)
        r0, r4 = _pivot(r0, r4, 0)
        ok = abs(r0[0]) > tol
        inv = 1.0 / r0[0] if ok else 0.0
        r1, r2, r3, r4 = _eliminate(r1, r0, 0, inv), _eliminate(r2, r0, 0, inv), _eliminate(r3, r0, 0, inv), \
            _eliminate(r4, r0, 0, inv)
        r1, r2 = _pivot(r1, r2, 1)
        r1, r3 = _pivot(r1, r3, 1)
        r1, r4 = _pivot(r1, r4, 1)
        ok = ok and abs(r1[1]) > tol
        inv = 1.0 / r1[1] if ok else 0.0
        r2, r3, r4 = _eliminate(r2, r1, 1, inv), _eliminate(r3, r1, 1, inv), _eliminate(r4, r1, 1, inv)
        r2, r3 = _pivot(r2, r3, 2)
        r2, r4 = _pivot(r2, r4, 2)
        ok = ok and abs(r2[2]) > tol
        inv = 1.0 / r2[2] if ok else 0.0
        r3, r4 = _eliminate(r3, r2, 2, inv), _eliminate(r4, r2, 2, inv)
        r3, r4 = _pivot(r3, r4, 3)
        ok = ok and abs(r3[3]) > tol
        inv = 1.0 / r3[3] if ok else 0.0
        r4 = _eliminate(r4, r3, 3, inv)
        ok = ok and abs(r4[4]) > tol
        x4 = r4[5] / r4[4] if ok else 0.0
        x3 = (r3[5] - r3[4] * x4) / r3[3] if ok else 0.0
        x2 = (r2[5] - r2[3] * x3 - r2[4] * x4) / r2[2] if ok else 0.0
        x1 = (r1[5] - r1[2] * x2 - r1[3] * x3 - r1[4] * x4) / r1[1] if ok else 0.0
        x0 = (r0[5] - r0[1] * x1 - r0[2] * x2 - r0[3] * x3 - r0[4] * x4) / r0[0] if ok else 0.0
        S[_at(STEP, lane)], S[_at(STEP + 1, lane)], S[_at(STEP + 2, lane)] = x0, x1, x2
        S[_at(STEP + 3, lane)], S[_at(STEP + 4, lane)] = x3, x4
        S[_at(OK, lane)] = 1.0 if ok else 0.0


@njit(**CONTRACT)
def newton_step_lanes(S):
    """STEP = JAC^-1 RES for every lane (``lane_lu_solve`` with the residual as right-hand side)."""
    lane_lu_solve(S, RES)


@njit(**CONTRACT)
def tangent_step_lanes(S):
    """STEP = JAC^-1 RHS for every lane: the tangent predictor's step (dp, 0, 0) mapped to the joints.
    (Each inlines the LU once, with its right-hand side a constant row; compiled once each.)"""
    lane_lu_solve(S, RHS)


@njit(**CONTRACT)
def lane_metric(S, qdot_max):
    """The RCM metric at every lane's JAC (``constrained_extremes`` of J Q, as ``serial_chain`` does
    for one pose): SMIN, SMAX, SING; lanes with ACT set fold it into LO, HI, NSING."""
    s0, s1, s2, s3, s4 = qdot_max[0], qdot_max[1], qdot_max[2], qdot_max[3], qdot_max[4]
    for lane in range(W):
        smin2, smax2, singular = constrained_extremes(
            (S[_at(JAC, lane)] * s0, S[_at(JAC + 5, lane)] * s0, S[_at(JAC + 10, lane)] * s0,
             S[_at(JAC + 15, lane)] * s0, S[_at(JAC + 20, lane)] * s0),
            (S[_at(JAC + 1, lane)] * s1, S[_at(JAC + 6, lane)] * s1, S[_at(JAC + 11, lane)] * s1,
             S[_at(JAC + 16, lane)] * s1, S[_at(JAC + 21, lane)] * s1),
            (S[_at(JAC + 2, lane)] * s2, S[_at(JAC + 7, lane)] * s2, S[_at(JAC + 12, lane)] * s2,
             S[_at(JAC + 17, lane)] * s2, S[_at(JAC + 22, lane)] * s2),
            (S[_at(JAC + 3, lane)] * s3, S[_at(JAC + 8, lane)] * s3, S[_at(JAC + 13, lane)] * s3,
             S[_at(JAC + 18, lane)] * s3, S[_at(JAC + 23, lane)] * s3),
            (S[_at(JAC + 4, lane)] * s4, S[_at(JAC + 9, lane)] * s4, S[_at(JAC + 14, lane)] * s4,
             S[_at(JAC + 19, lane)] * s4, S[_at(JAC + 24, lane)] * s4))
        act = S[_at(ACT, lane)] != 0.0
        lo, hi = S[_at(LO, lane)], S[_at(HI, lane)]
        S[_at(LO, lane)] = min(lo, smin2) if act else lo
        S[_at(HI, lane)] = max(hi, smax2) if act else hi
        S[_at(NSING, lane)] += 1.0 if (act and singular) else 0.0


@njit(inline="always", **CONTRACT)
def set_predictor(S, lane, run, active, first):
    """The predictor weights of one lane (KQ..KT): the scalar walk's extrapolation after a straight run
    of ``run`` steps, the tangent after a turn (run 0), the point itself at a segment's first point or
    for an idle lane."""
    r = 0 if (first or not active) else min(run, 4)
    for k in range(5):
        S[_at(KQ + k, lane)] = EXTRAPOLATION[r][k]
    S[_at(KT, lane)] = 1.0 if (r == 0 and active and not first) else 0.0


@njit(**CONTRACT)
def predict_lanes(S):
    """Q = QP = the prediction for every lane (weights KQ..KT on Q, H1..H4 and the tangent step STEP,
    applied where OK); the history H1..H4 shifted for active lanes."""
    for lane in range(W):
        act = S[_at(ACT, lane)] != 0.0
        tangent = S[_at(KT, lane)] != 0.0 and S[_at(OK, lane)] != 0.0
        k0, k1, k2, k3, k4 = (S[_at(KQ, lane)], S[_at(KQ + 1, lane)], S[_at(KQ + 2, lane)], S[_at(KQ + 3, lane)],
                              S[_at(KQ + 4, lane)])
        for i in range(N):
            qc, q1, q2, q3, q4 = (S[_at(Q + i, lane)], S[_at(H1 + i, lane)], S[_at(H2 + i, lane)],
                                  S[_at(H3 + i, lane)], S[_at(H4 + i, lane)])
            p = k0 * qc + k1 * q1 + k2 * q2 + k3 * q3 + k4 * q4
            p = p + S[_at(STEP + i, lane)] if tangent else p
            S[_at(H4 + i, lane)] = q3 if act else q4
            S[_at(H3 + i, lane)] = q2 if act else q3
            S[_at(H2 + i, lane)] = q1 if act else q2
            S[_at(H1 + i, lane)] = qc if act else q1
            S[_at(Q + i, lane)] = p
            S[_at(QP + i, lane)] = p


@njit(**CONTRACT)
def newton_check(S, it, last):
    """After an evaluation: lanes that meet IK_TOL_M stop (their ``it`` Newton steps counted); lanes that
    cannot go on in lanes (the ``last`` iteration, a non-finite residual or one beyond
    LANE_NEWTON_ZONE_M2) stop with FB set. Returns (lanes still pending, Newton steps of the lanes
    that converged now, pending lanes that need the damped step)."""
    pending = 0
    steps = 0
    damped = 0
    for lane in range(W):
        pend = S[_at(PEND, lane)] != 0.0
        worst = S[_at(WORST, lane)]
        e2 = (S[_at(RES, lane)] ** 2 + S[_at(RES + 1, lane)] ** 2 + S[_at(RES + 2, lane)] ** 2
              + S[_at(RES + 3, lane)] ** 2 + S[_at(RES + 4, lane)] ** 2)
        done = worst < IK_TOL_M
        stuck = last or not (e2 < LANE_NEWTON_ZONE_M2)  # also NaN
        S[_at(FB, lane)] = 1.0 if (pend and not done and stuck) or S[_at(FB, lane)] != 0.0 else 0.0
        still = pend and not done and not stuck
        S[_at(PEND, lane)] = 1.0 if still else 0.0
        pending += 1 if still else 0
        damped += 1 if (still and not (e2 < NEWTON_ZONE_M2)) else 0
        steps += it if (pend and done) else 0
    return pending, steps, damped


@njit(inline="always", **CONTRACT)
def _column(S, lane, j):
    return (S[_at(JAC + j, lane)], S[_at(JAC + N + j, lane)], S[_at(JAC + 2 * N + j, lane)],
            S[_at(JAC + 3 * N + j, lane)], S[_at(JAC + 4 * N + j, lane)])


@njit(inline="always", **CONTRACT)
def _dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2] + a[3] * b[3] + a[4] * b[4]


@njit(inline="always", **CONTRACT)
def _damped_row(S, lane, i, ci, c0, c1, c2, c3, c4, e, e2, damp):
    """Row i of (J^T J + e2 I | J^T e) into JAC / RES where ``damp`` (``ci`` = column i of J)."""
    row = (_dot(ci, c0), _dot(ci, c1), _dot(ci, c2), _dot(ci, c3), _dot(ci, c4))
    for j in range(N):
        a = row[j] + (e2 if i == j else 0.0)
        S[_at(JAC + i * N + j, lane)] = a if damp else S[_at(JAC + i * N + j, lane)]
    S[_at(RES + i, lane)] = _dot(ci, e) if damp else S[_at(RES + i, lane)]


@njit(**CONTRACT)
def damp_lanes(S):
    """The Levenberg-Marquardt system in place of J and the residual for pending lanes whose squared
    residual |e|^2 is at least NEWTON_ZONE_M2: (J^T J + |e|^2 I) and J^T e, so that ``lane_lu_solve``
    gives the scalar walk's damped step there (``serial_chain.damped_solve``, Sugihara 2011)."""
    for lane in range(W):
        e = (S[_at(RES, lane)], S[_at(RES + 1, lane)], S[_at(RES + 2, lane)], S[_at(RES + 3, lane)],
             S[_at(RES + 4, lane)])
        e2 = _dot(e, e)
        damp = S[_at(PEND, lane)] != 0.0 and not (e2 < NEWTON_ZONE_M2)
        c0, c1, c2, c3, c4 = _column(S, lane, 0), _column(S, lane, 1), _column(S, lane, 2), _column(S, lane, 3), \
            _column(S, lane, 4)
        _damped_row(S, lane, 0, c0, c0, c1, c2, c3, c4, e, e2, damp)
        _damped_row(S, lane, 1, c1, c0, c1, c2, c3, c4, e, e2, damp)
        _damped_row(S, lane, 2, c2, c0, c1, c2, c3, c4, e, e2, damp)
        _damped_row(S, lane, 3, c3, c0, c1, c2, c3, c4, e, e2, damp)
        _damped_row(S, lane, 4, c4, c0, c1, c2, c3, c4, e, e2, damp)


@njit(**CONTRACT)
def newton_update(S):
    """Q -= STEP on pending lanes whose LU had no singular pivot; the others stop with FB set."""
    for lane in range(W):
        pend = S[_at(PEND, lane)] != 0.0
        ok = S[_at(OK, lane)] != 0.0
        for i in range(N):
            v = S[_at(Q + i, lane)]
            S[_at(Q + i, lane)] = v - S[_at(STEP + i, lane)] if (pend and ok) else v
        S[_at(FB, lane)] = 1.0 if (pend and not ok) or S[_at(FB, lane)] != 0.0 else 0.0
        S[_at(PEND, lane)] = 1.0 if (pend and ok) else 0.0


@njit(**CONTRACT)
def limits_lanes(S, lower, upper):
    """INLIM: every joint of the lane inside its limits as it stands (a lane outside is checked again by
    ``within_limits``, which may take a revolute joint 2 pi round)."""
    for lane in range(W):
        inside = True
        for i in range(N):
            v = S[_at(Q + i, lane)]
            inside = inside and (lower[i] <= v) and (v <= upper[i])
        S[_at(INLIM, lane)] = 1.0 if inside else 0.0


@njit(**CONTRACT)
def newton_lanes(rot, pos, prismatic, S, sync):
    """Newton on every lane with PEND set, in lockstep, until each meets IK_TOL_M (damped where the
    scalar walk damps, ``damp_lanes``); a lane beyond LANE_NEWTON_ZONE_M2, with a singular pivot or not
    done in WALK_ITER steps gets FB (the scalar code finishes it). Returns (Newton steps of the
    converged lanes, the cos/sin caches' increments since their last exact evaluation)."""
    steps = 0
    for it in range(WALK_ITER + 1):
        big = trig_taylor(S)
        sync += 1.0
        if not (big < TRIG_STEP_RAD) or sync >= TRIG_RESYNC:
            trig_exact(S)
            sync = 0.0
        lane_eval(rot, pos, prismatic, S)
        pending, done, damped = newton_check(S, it, it == WALK_ITER)
        steps += done
        if pending == 0:
            break
        if damped:
            damp_lanes(S)
        newton_step_lanes(S)
        newton_update(S)
    return steps, sync


@njit(inline="always", **CONTRACT)
def _lane_to_scalar(S, lane, row, out, n):
    for i in range(n):
        out[i] = S[_at(row + i, lane)]


@njit(inline="always", **CONTRACT)
def _scalar_to_lane(S, lane, row, src, n):
    for i in range(n):
        S[_at(row + i, lane)] = src[i]


@njit(**CONTRACT)
def continue_from_start(chain_arrays, q, q0, target, c, start, ref, end, bufs):
    """``continue_walk`` from the start's solution ``q0`` at RCM + ``start`` to RCM + ``end`` (the scalar
    walk's way to a point it lost); ``q``, ``target`` and ``bufs`` end at the solution. Returns the
    Newton steps taken, or -1."""
    rot, pos, prismatic = chain_arrays[0], chain_arrays[1], chain_arrays[2]
    axes, origins, jac, res, step, work, trig = bufs
    for i in range(N):
        q[i] = q0[i]
    for i in range(3):
        target[i] = c[i] + start[i]
    newton_rcm(rot, pos, prismatic, q, target, c, ref, 0, bufs)
    return continue_walk(rot, pos, prismatic, q, target, c, ref, end, bufs)


@njit(inline="always", **CONTRACT)
def newton_from_prediction(rot, pos, prismatic, S, lane, c, ref, q, target, bufs):
    """The scalar ``newton_rcm`` (damped where it must be) from one lane's prediction QP at its target
    TGT, as the scalar walk would run it; ``q`` ends at the solution. Returns its steps, or -1."""
    axes, origins, jac, res, step, work, trig = bufs
    _lane_to_scalar(S, lane, QP, q, N)
    _lane_to_scalar(S, lane, TGT, target, 3)
    return newton_rcm(rot, pos, prismatic, q, target, c, ref, WALK_ITER, bufs)


@njit(inline="always", **CONTRACT)
def solution_to_lane(S, lane, q, jac):
    """A scalar solution and its Jacobian into one lane (its cos/sin cache marked stale)."""
    _scalar_to_lane(S, lane, Q, q, N)
    for i in range(N):
        for k in range(N):
            S[_at(JAC + i * N + k, lane)] = jac[i, k]
    S[_at(ANG, lane)] = np.nan


@njit(**CONTRACT)
def continue_lanes(chain_arrays, S, q0, jac0, c, start, ref, ends, sync, bufs):
    """Carry the start's solution ``q0`` (Jacobian ``jac0``) from RCM + ``start`` to RCM + each of ``ends``
    (k <= LANES offsets, one per lane) by continuation in lanes: the scalar ``continue_walk``'s equal steps
    of at most CONTINUATION_STEP_M, tangent predictor, Newton corrector. A lane the lanes' Newton cannot
    finish is carried by ``continue_walk`` itself. Lane l ends with its solution in Q, its Jacobian in JAC.

    Returns (ok (k,) bool, Newton steps, ``sync``): ok False where the continuation failed."""
    rot, pos, prismatic = chain_arrays[0], chain_arrays[1], chain_arrays[2]
    axes, origins, jac, res, step, work, trig = bufs
    k = ends.shape[0]
    q = np.empty(N)
    target = np.empty(3)
    n_steps = np.zeros(W, np.int64)
    scalar = np.zeros(W, np.bool_)
    longest = 0
    for lane in range(W):
        for i in range(N):
            S[_at(Q + i, lane)] = q0[i]
            for j in range(N):
                S[_at(JAC + i * N + j, lane)] = jac0[i, j]
        dist = 0.0
        for i in range(3):
            S[_at(TGT + i, lane)], S[_at(C + i, lane)], S[_at(REF + i, lane)] = c[i] + start[i], c[i], ref[i]
            if lane < k:
                dist += (ends[lane, i] - start[i]) ** 2
        S[_at(ANG, lane)] = np.nan
        n_steps[lane] = int(np.ceil(np.sqrt(dist) / CONTINUATION_STEP_M)) if lane < k else 0
        longest = max(longest, n_steps[lane])
    steps_total = 0
    for s in range(longest):
        for lane in range(W):
            act = s < n_steps[lane] and not scalar[lane]
            flag = 1.0 if act else 0.0
            S[_at(ACT, lane)], S[_at(PEND, lane)], S[_at(FB, lane)] = flag, flag, 0.0
            for i in range(3):
                d = (c[i] + ends[min(lane, k - 1), i] - S[_at(TGT + i, lane)]) / (n_steps[lane] - s) if act else 0.0
                S[_at(RHS + i, lane)] = d
                S[_at(TGT + i, lane)] += d
            S[_at(RHS + 3, lane)], S[_at(RHS + 4, lane)] = 0.0, 0.0
            set_predictor(S, lane, 0, act, False)
        tangent_step_lanes(S)
        predict_lanes(S)
        steps, sync = newton_lanes(rot, pos, prismatic, S, sync)
        steps_total += steps
        for lane in range(W):  # this step of a lane the lanes' Newton could not finish, by the scalar one
            if S[_at(FB, lane)] != 0.0:
                it = newton_from_prediction(rot, pos, prismatic, S, lane, c, ref, q, target, bufs)
                if it >= 0:
                    steps_total += it
                    solution_to_lane(S, lane, q, jac)
                else:
                    scalar[lane] = True
    ok = np.ones(k, np.bool_)
    for lane in range(k):
        if scalar[lane]:
            it = continue_from_start(chain_arrays, q, q0, target, c, start, ref, ends[lane], bufs)
            ok[lane] = it >= 0
            steps_total += max(it, 0)
            solution_to_lane(S, lane, q, jac)
            _scalar_to_lane(S, lane, TGT, target, 3)
    return ok, steps_total, sync


@njit(inline="always", **CONTRACT)
def lanes_extremes(S):
    """(min sigma_min^2, max sigma_max^2, singular count) over every lane's points so far."""
    lo, hi, n_sing = np.inf, 0.0, 0
    for lane in range(W):
        lo, hi, n_sing = min(lo, S[_at(LO, lane)]), max(hi, S[_at(HI, lane)]), n_sing + int(S[_at(NSING, lane)])
    return lo, hi, n_sing


@njit(**CONTRACT)
def walk_lanes(chain_arrays, seed, restarts, c, offsets, start, probes, gii_to_beat, q_out, seg):
    """``serial_chain.chain_walk`` for one candidate with the walk cut into ``LANES`` segments
    (``seg`` (LANES + 1,) their boundaries in walk order) walked side by side. Same returns; an
    n_unreachable of -1 means a segment's first point could not be reached from the start, and the
    caller walks this candidate with the scalar kernel (whose walk gets there step by step)."""
    rot, pos, prismatic, lower, upper, qdot_max = chain_arrays
    bufs = scalar_buffers()
    axes, origins, jac, res, step, work, trig = bufs
    q = np.empty(N)
    target = np.empty(3)
    ref = constraint_reference(start)
    q_out[:] = np.nan
    for i in range(3):
        target[i] = c[i] + start[i]
    if not seed_solve(rot, pos, prismatic, lower, upper, seed, restarts, target, c, ref, q, bufs):
        return 0.0, 0.0, 1, 0, 0, 0
    q0 = q.copy()
    jac0 = jac.copy()
    S = np.zeros(ROWS * W)
    sync = TRIG_RESYNC
    steps_total = 0
    for b in range(0, probes.shape[0], W):  # probes first (IK only): losing one makes the candidate infeasible
        ok, steps, sync = continue_lanes(chain_arrays, S, q0, jac0, c, start, ref, probes[b:b + W], sync, bufs)
        steps_total += steps
        for lane in range(ok.shape[0]):
            _lane_to_scalar(S, lane, Q, q, N)
            if not (ok[lane] and within_limits(q, prismatic, lower, upper)):
                return 0.0, 0.0, 1, 0, 0, steps_total
    starts = np.empty((W, 3))
    for lane in range(W):
        for i in range(3):
            starts[lane, i] = offsets[min(seg[lane], offsets.shape[0] - 1), i]
    ok, steps, sync = continue_lanes(chain_arrays, S, q0, jac0, c, start, ref, starts, sync, bufs)
    steps_total += steps
    for lane in range(W):
        if not ok[lane]:
            return 0.0, 0.0, -1, 0, 0, steps_total
        S[_at(LO, lane)] = np.inf
        S[_at(HI, lane)] = 0.0
        S[_at(NSING, lane)] = 0.0
    last = np.full((W, 3), np.nan)
    run = np.zeros(W, np.int64)
    bound2 = gii_to_beat * gii_to_beat
    n_eval = 0
    longest = 0
    for lane in range(W):
        longest = max(longest, seg[lane + 1] - seg[lane])
    for t in range(longest):
        tangent = False
        for lane in range(W):  # the segment's next point, and the predictor its step calls for
            j = seg[lane] + t
            act = j < seg[lane + 1]
            S[_at(ACT, lane)] = 1.0 if act else 0.0
            S[_at(PEND, lane)] = 1.0 if act else 0.0
            S[_at(FB, lane)] = 0.0
            if act and t > 0:
                straight = True
                for i in range(3):
                    new = c[i] + offsets[j, i]
                    d = new - S[_at(TGT + i, lane)]
                    S[_at(RHS + i, lane)], S[_at(TGT + i, lane)] = d, new
                    straight &= abs(d - last[lane, i]) <= 1e-12
                    last[lane, i] = d
                S[_at(RHS + 3, lane)], S[_at(RHS + 4, lane)] = 0.0, 0.0
                run[lane] = min(run[lane] + 1, 4) if straight else 0
                tangent |= run[lane] == 0
            set_predictor(S, lane, run[lane], act, t == 0)
        if tangent:
            tangent_step_lanes(S)  # the tangent q + J^-1 (dp, 0, 0), J at the last solution
        predict_lanes(S)
        steps, sync = newton_lanes(rot, pos, prismatic, S, sync)
        steps_total += steps
        limits_lanes(S, lower, upper)
        for lane in range(W):
            if S[_at(ACT, lane)] == 0.0 or (S[_at(FB, lane)] == 0.0 and S[_at(INLIM, lane)] != 0.0):
                continue
            j = seg[lane] + t
            fallback = S[_at(FB, lane)] != 0.0
            if not fallback:  # outside a limit as it stands: perhaps inside 2 pi round
                _lane_to_scalar(S, lane, Q, q, N)
                ok = within_limits(q, prismatic, lower, upper)
                _scalar_to_lane(S, lane, Q, q, N)
            else:  # the scalar Newton from the same prediction (damped where it must be)
                it = newton_from_prediction(rot, pos, prismatic, S, lane, c, ref, q, target, bufs)
                ok = it >= 0 and within_limits(q, prismatic, lower, upper)
                steps_total += max(it, 0)
            if not ok:  # reach the point once more from the start's solution (as the scalar walk does)
                it = continue_from_start(chain_arrays, q, q0, target, c, start, ref, offsets[j], bufs)
                if it < 0 or not within_limits(q, prismatic, lower, upper):
                    return 0.0, 0.0, 1, 0, n_eval + 1, steps_total
                steps_total += it
                run[lane] = 0
                for i in range(3):
                    last[lane, i] = np.nan
            if fallback or not ok:
                solution_to_lane(S, lane, q, jac)
        lane_metric(S, qdot_max)
        for lane in range(W):
            if S[_at(ACT, lane)] != 0.0:
                _lane_to_scalar(S, lane, Q, q_out[seg[lane] + t], N)
                n_eval += 1
        if bound2 > 0.0:
            lo, hi, _ = lanes_extremes(S)
            if lo <= bound2 * hi:
                break
    lo, hi, n_sing = lanes_extremes(S)
    return lo, hi, 0, n_sing, n_eval, steps_total


@njit(**CONTRACT)
def line_starts(offsets):
    """Indices j where a straight line of the walk starts: the step j -> j+1 differs from the step into j
    (j-1 -> j), and the step after it (j+1 -> j+2) is the same as it."""
    n = offsets.shape[0]
    bend = np.zeros(n, np.bool_)  # bend[j]: the walk changes direction at point j
    for j in range(1, n - 1):
        for i in range(3):
            bend[j] |= abs((offsets[j + 1, i] - offsets[j, i]) - (offsets[j, i] - offsets[j - 1, i])) > 1e-12
    out = np.empty(n, np.int64)
    k = 0
    for j in range(1, n - 2):
        if bend[j] and not bend[j + 1]:
            out[k] = j
            k += 1
    return out[:k]


def segments(offsets, lanes: int = LANES) -> np.ndarray:
    """Boundaries of ``lanes`` contiguous segments of the walk ``offsets`` (P, 3), as equal as can be,
    each starting where a straight line of the walk starts (the step out of the point differs from the
    step into it, and the step after is the same as the step out).

    Starting every segment at a turn keeps the lanes in phase on a serpentine: they turn at the same
    steps, so the tangent predictor's LU and the low-order steps after a turn, which need more Newton
    iterations, happen for all lanes at once instead of holding up a lockstep step nearly every time.
    Without a turn near a split point the split stays where it is.

    Example (tested): a serpentine over a 17^3 cube (lines of 17) gives boundaries at multiples of 17."""
    offsets = np.ascontiguousarray(offsets, dtype=np.float64).reshape(-1, 3)
    even = np.round(np.linspace(0, offsets.shape[0], lanes + 1)).astype(np.int64)
    return _cut_at_line_starts(offsets, even)


@njit(**CONTRACT)
def _cut_at_line_starts(offsets, even):
    """``segments``' work (in numba: in numpy it cost ~40 us a call, a tenth of a short walk)."""
    n = offsets.shape[0]
    cut = even.copy()
    if n < 4:
        return cut
    turns = line_starts(offsets)
    if turns.size == 0:
        return cut
    lanes = even.shape[0] - 1
    for k in range(1, lanes):
        near = turns[np.argmin(np.abs(turns - even[k]))]
        if abs(near - even[k]) <= n / lanes / 4:
            cut[k] = near
    for k in range(lanes):
        if not cut[k + 1] > cut[k]:
            return even.copy()
    return cut


@njit(**CONTRACT)
def candidates_lanes(chain_arrays, seed, restarts, rcms, offsets, start, probes, gii_to_beat, seg, metric, params):
    """``serial_chain.candidates_scalar`` with each walk in lanes (``walk_lanes``; the scalar walk where a
    segment's start is out of the continuation's reach): the same metrics (``metrics.POSE_METRICS`` codes), the same
    answers to within Newton's tolerance."""
    m = rcms.shape[0]
    out = np.zeros((m, 2))
    counts = np.empty((m, 4), np.int64)
    q_out = np.empty((offsets.shape[0], N))
    in_walk = metric == METRIC_RCM
    for i in range(m):
        g = gii_to_beat[i] if in_walk else 0.0
        lo, hi, n_unr, n_sing, n_eval, steps = walk_lanes(chain_arrays, seed, restarts, rcms[i], offsets, start,
                                                          probes, g, q_out, seg)
        if n_unr < 0 or (n_unr > 0 and n_eval > 0):
            # a segment start out of the continuation's reach, or a point lost mid-walk: the verdict is
            # the scalar walk's (a lane reaches its points along another path than the scalar walk, and
            # near a singularity the two can differ; the scalar walk defines the seeded branch)
            lo, hi, n_unr, n_sing, n_eval, steps = chain_walk(chain_arrays, seed, restarts, rcms[i], offsets, start,
                                                              probes, g, q_out)
        if not in_walk and n_unr == 0:
            lo, hi, n_sing = metric_over_solutions(metric, chain_arrays, q_out, offsets.shape[0], params)
        if in_walk or n_unr == 0:
            out[i, 0], out[i, 1] = np.sqrt(lo), np.sqrt(hi)
        counts[i, 0], counts[i, 1], counts[i, 2], counts[i, 3] = n_unr, n_sing, n_eval, steps
    return out, counts
