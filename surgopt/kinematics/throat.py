"""Throat-robot arm (Wei, Xu & Simaan): five-bar, Z-theta stage, two snake segments.

Kernels only (numba). Lengths in mm, angles in rad. The arm's geometry travels as a
``ThroatGeometry`` named tuple (see ``surgopt/robots/throat_arm.py``); joint vector q =
[q1, q2, q3, q4, theta_L, delta, phi_L', psi].

Frames follow the paper's Sec. III-A: {w} at the five-bar base (z normal to
its plane), {t} at the five-bar end-effector P_U with x_t along l6, {d} with
z_d from P_U through the fulcrum P_F and y_d = z_d x x_t (eq. 7), {b} = {d}
rotated by q4 about z_d at P_D = P_U + (La + q3) z_d (eqs. 8-9), the SLU from
{b} to the gripper base {g}, the PMU from {g} to the platform {p}, which is
the end-effector.
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np

from surgopt.jit import EXACT, njit
from surgopt.kinematics.small_linalg import cross, dot, mat_mul, mat_vec, solve_spd
from surgopt.robots.throat_arm import SutureMode


class ThroatGeometry(NamedTuple):
    """One arm's fixed geometry (mm): five-bar links (Table I), holder and segment lengths, fulcrum."""

    l1_mm: float  # ground link
    l2_mm: float  # actuated (q2)
    l3_mm: float  # distal, on the l2 side
    l4_mm: float  # distal, on the l5 side
    l5_mm: float  # actuated (q1)
    l6_mm: float  # extension of l3 to the end-effector P_U
    arm_length_mm: float  # DDU holder La
    slu_length_mm: float
    pmu_length_mm: float
    fulcrum_mm: np.ndarray  # P_F (3,) in {w}
    branch: float  # +1: C left of the directed line D -> B, -1: right


MODE_SPIN = int(SutureMode.SPIN)
MODE_ORBIT_PARALLEL = int(SutureMode.ORBIT_PARALLEL)
MODE_ORBIT_TANGENT = int(SutureMode.ORBIT_TANGENT)

#: theta_0 = phi_0 = pi/2: a straight segment (Simaan's notation).
THETA0 = np.pi / 2
#: Below this |theta_L - theta_0| the segment formulas switch to their Taylor
#: series (the closed forms are 0/0 at a straight segment).
STRAIGHT_EPS = 1e-4


@njit(**EXACT)
def rot_z(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


@njit(**EXACT)
def rot_y(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


@njit(**EXACT)
def segment_tip_in_plane(theta_l, length):
    """(x, z, dx/dtheta_L, dz/dtheta_L) of a constant-curvature segment in its bending plane.

    x = int_0^L cos(theta(s)) ds, z = int_0^L sin(theta(s)) ds with theta
    linear from theta_0 = pi/2 to theta_L (eq. 10). With d = theta_L - pi/2:
    x = L (cos d - 1) / d, z = L sin d / d; Taylor series near d = 0.
    """
    d = theta_l - THETA0
    if abs(d) < STRAIGHT_EPS:
        d2 = d * d
        x = length * (-d / 2 + d * d2 / 24)
        z = length * (1 - d2 / 6 + d2 * d2 / 120)
        dx = length * (-0.5 + d2 / 8)
        dz = length * (-d / 3 + d * d2 / 30)
    else:
        c, s = np.cos(d), np.sin(d)
        x = length * (c - 1) / d
        z = length * s / d
        dx = length * (-d * s - c + 1) / (d * d)
        dz = length * (d * c - s) / (d * d)
    return x, z, dx, dz


@njit(**EXACT)
def segment_kinematics(theta_l, delta, length):
    """Tip position, end rotation and their rates for one snake segment (eqs. 10-11, 22-23).

    In the segment's base frame: p = Rz(-delta) [x, 0, z] (eq. 10),
    R = Rz(-delta) Ry(theta_0 - theta_L) Rz(delta) (eq. 11 with {g} defined
    like {b}). Returns p, R, dp/dtheta_L, dp/ddelta, and the angular
    velocities per unit rate w_theta = -y_1, w_delta = -z_1 + z_e (eq. 23).
    Worked example (tests): L = 25, theta_L = pi/3, delta = pi/4 ->
    p = (4.523, -4.523, 23.873) mm.
    """
    x, z, dx, dz = segment_tip_in_plane(theta_l, length)
    Rd = rot_z(-delta)
    p = mat_vec(Rd, np.array([x, 0.0, z]))
    R = mat_mul(mat_mul(Rd, rot_y(THETA0 - theta_l)), rot_z(delta))
    dp_dtheta = mat_vec(Rd, np.array([dx, 0.0, dz]))
    dp_ddelta = np.array([p[1], -p[0], 0.0])  # -z x p
    w_theta = mat_vec(Rd, np.array([0.0, -1.0, 0.0]))
    w_delta = R[:, 2] - np.array([0.0, 0.0, 1.0])
    return p, R, dp_dtheta, dp_ddelta, w_theta, w_delta


@njit(**EXACT)
def five_bar(q1, q2, geo):
    """Five-bar forward kinematics and rates (eqs. 2-6, 14-18).

    D = [l5 sin q1, l5 cos q1 - l1/2] (eq. 3), B = [l2 sin q2, l2 cos q2 +
    l1/2] (eq. 4), C at distance l4 from D and l3 from B on the side of the
    line D -> B given by geo.branch (+1 left, -1 right), P_U = B + l6 u with
    u = (C - B)/l3 = x_t (eqs. 5-6). Returns P_U (2), u (2), dP_U/dq (2x2),
    du/dq (2x2), and the closure determinant (0 at a five-bar singularity,
    NaN when the loop cannot close).
    """
    l1, l2, l3, l4, l5, l6 = geo.l1_mm, geo.l2_mm, geo.l3_mm, geo.l4_mm, geo.l5_mm, geo.l6_mm
    s1, c1, s2, c2 = np.sin(q1), np.cos(q1), np.sin(q2), np.cos(q2)
    D = np.array([l5 * s1, l5 * c1 - l1 / 2])
    B = np.array([l2 * s2, l2 * c2 + l1 / 2])
    e = B - D
    d = np.sqrt(e[0] * e[0] + e[1] * e[1])
    a = (l4 * l4 - l3 * l3 + d * d) / (2 * d)
    h = np.sqrt(l4 * l4 - a * a)  # NaN when the loop cannot close
    eh = e / d
    C = D + a * eh + geo.branch * h * np.array([-eh[1], eh[0]])
    u = (C - B) / l3
    P = B + l6 * u
    # rates: (C-D).(dC - dD) = 0, (C-B).(dC - dB) = 0
    cd = C - D
    cb = C - B
    det = cd[0] * cb[1] - cd[1] * cb[0]
    dD = np.array([l5 * c1, -l5 * s1])  # per unit dq1
    dB = np.array([l2 * c2, -l2 * s2])  # per unit dq2
    dP = np.empty((2, 2))
    du = np.empty((2, 2))
    for j in range(2):
        r0 = (cd[0] * dD[0] + cd[1] * dD[1]) if j == 0 else 0.0
        r1 = (cb[0] * dB[0] + cb[1] * dB[1]) if j == 1 else 0.0
        dCx = (r0 * cb[1] - r1 * cd[1]) / det
        dCy = (cd[0] * r1 - cb[0] * r0) / det
        dBj = dB if j == 1 else np.zeros(2)
        du[0, j] = (dCx - dBj[0]) / l3
        du[1, j] = (dCy - dBj[1]) / l3
        dP[0, j] = dBj[0] + l6 * du[0, j]
        dP[1, j] = dBj[1] + l6 * du[1, j]
    return P, u, dP, du, det


@njit(**EXACT)
def arm_frame(P_U, u, geo):
    """Snake-arm frame {d}: z_d from P_U through P_F, y_d = z_d x x_t / |.|, x_d = y_d x z_d (eq. 7)."""
    PU = np.array([P_U[0], P_U[1], 0.0])
    xt = np.array([u[0], u[1], 0.0])
    r = geo.fulcrum_mm - PU
    rho = np.sqrt(dot(r, r))
    z = r / rho
    yr = cross(z, xt)
    ny = np.sqrt(dot(yr, yr))
    y = yr / ny
    x = cross(y, z)
    return PU, xt, x, y, z, rho, ny


@njit(**EXACT)
def arm_chain(q, geo):
    """Every frame along the chain, shared by the kinematics and the Jacobian.

    Returns (five-bar rates dP, du; arm frame PU, x_t, x, y, z, rho, |z x x_t|;
    R_b, P_D; SLU tip p1, rotation R1 and rates; P_L, R_g; PMU tip p2,
    rotation R2 and rates; platform position P_E and rotation R_E).
    """
    P_U, u, dP, du, _ = five_bar(q[0], q[1], geo)
    PU, xt, x, y, z, rho, ny = arm_frame(P_U, u, geo)
    Rd = np.empty((3, 3))
    Rd[:, 0], Rd[:, 1], Rd[:, 2] = x, y, z
    Rb = mat_mul(Rd, rot_z(q[3]))
    PD = PU + (geo.arm_length_mm + q[2]) * z
    seg1 = segment_kinematics(q[4], q[5], geo.slu_length_mm)
    PL = PD + mat_vec(Rb, seg1[0])
    Rg = mat_mul(Rb, seg1[1])
    seg2 = segment_kinematics(q[6], q[7], geo.pmu_length_mm)
    PE = PL + mat_vec(Rg, seg2[0])
    return dP, du, PU, xt, x, y, z, rho, ny, Rb, PD, seg1, PL, Rg, seg2, PE, mat_mul(Rg, seg2[1])


@njit(**EXACT)
def forward_kinematics(q, geo):
    """Platform (end-effector) position (mm) and rotation in {w} for joints q (eqs. 2-13)."""
    chain = arm_chain(q, geo)
    return chain[15], chain[16]


@njit(**EXACT)
def jacobian(q, geo):
    """6x8 Jacobian in {w}: rows (v, omega) of the platform, columns q1..psi (eq. 30).

    Five-bar columns: P_U and x_t move (eqs. 14-18), which swings frame {d}
    about the fulcrum; everything distal rides rigidly with {d}. Z-theta
    columns: v = z_d, and omega = z_d about P_D (eqs. 19-21). SLU and PMU
    columns: eqs. 22-29. The delta (psi) column vanishes for a straight SLU
    (PMU); nothing divides by it.
    """
    dP, du, PU, xt, x, y, z, rho, ny, Rb, PD, seg1, PL, Rg, seg2, PE, _ = arm_chain(q, geo)
    _, _, dp1_dt, dp1_dd, w1_t, w1_d = seg1
    _, _, dp2_dt, dp2_dd, w2_t, w2_d = seg2
    J = np.zeros((6, 8))
    for j in range(2):
        dPU = np.array([dP[0, j], dP[1, j], 0.0])
        dxt = np.array([du[0, j], du[1, j], 0.0])
        dz = -(dPU - z * dot(z, dPU)) / rho
        dyr = cross(dz, xt) + cross(z, dxt)
        dy = (dyr - y * dot(y, dyr)) / ny
        dx = cross(dy, z) + cross(y, dz)
        w = dot(dy, z) * x + dot(dz, x) * y + dot(dx, y) * z
        dPD = dPU + (geo.arm_length_mm + q[2]) * dz
        J[:3, j] = dPD + cross(w, PE - PD)
        J[3:, j] = w
    J[:3, 2] = z
    J[:3, 3] = cross(z, PE - PD)
    J[3:, 3] = z
    for j, (dp, w) in enumerate(((dp1_dt, w1_t), (dp1_dd, w1_d))):
        ww = mat_vec(Rb, w)
        J[:3, 4 + j] = mat_vec(Rb, dp) + cross(ww, PE - PL)
        J[3:, 4 + j] = ww
    for j, (dp, w) in enumerate(((dp2_dt, w2_t), (dp2_dd, w2_d))):
        J[:3, 6 + j] = mat_vec(Rg, dp)
        J[3:, 6 + j] = mat_vec(Rg, w)
    return J


@njit(**EXACT)
def weighted_least_norm_step(J, w_diag, dx, damping):
    """dq = W^-1 J^T (J W^-1 J^T + damping^2 I)^-1 dx (eq. 32; damped when damping > 0).

    Minimises dq^T W dq subject to J dq = dx (eq. 31). With damping > 0 it is
    the weighted damped least-squares step, which stays bounded near
    singularities at the price of a tracking error ~ damping^2.
    """
    Winv_Jt = np.empty((J.shape[1], J.shape[0]))
    for i in range(J.shape[1]):
        for j in range(J.shape[0]):
            Winv_Jt[i, j] = J[j, i] / w_diag[i]
    A = mat_mul(J, Winv_Jt)
    for i in range(A.shape[0]):
        A[i, i] += damping * damping
    return mat_vec(Winv_Jt, solve_spd(A, dx))


@njit(**EXACT)
def rotation_vector(R):
    """Axis * angle of a rotation matrix (log map), accurate near angle 0."""
    c = min(1.0, max(-1.0, 0.5 * (R[0, 0] + R[1, 1] + R[2, 2] - 1.0)))
    v = 0.5 * np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    s = np.sqrt(dot(v, v))
    angle = np.arctan2(s, c)
    if s < 1e-12:
        return v  # angle ~ s, axis * angle ~ v
    return v * (angle / s)


@njit(**EXACT)
def _axis_rotation(axis, a):
    """Rodrigues rotation matrix about a unit axis."""
    K = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]], [-axis[1], axis[0], 0.0]])
    return np.eye(3) + np.sin(a) * K + (1 - np.cos(a)) * mat_mul(K, K)


@njit(**EXACT)
def suture_target(mode, p0, R0, radius, angle):
    """Desired platform pose after turning ``angle`` along the suture (Sec. IV, Fig. 6).

    spin: the gripper spins about its own axis z_p at a fixed point, so a
    needle held ``radius`` off that axis traces the half circle.
    orbit_parallel: the platform moves on a circle of ``radius`` in its own
    x-y plane, orientation fixed (axis parallel to the circle's axis).
    orbit_tangent: the platform moves on a circle in its y-z plane with its
    axis z_p kept tangent to the path (rotates about x_p0).
    """
    x0, y0, z0 = R0[:, 0], R0[:, 1], R0[:, 2]
    if mode == MODE_SPIN:
        return p0.copy(), mat_mul(R0, rot_z(angle))
    if mode == MODE_ORBIT_PARALLEL:
        c = p0 - radius * x0
        return c + radius * (np.cos(angle) * x0 + np.sin(angle) * y0), R0.copy()
    c = p0 - radius * y0
    return c + radius * (np.cos(angle) * y0 + np.sin(angle) * z0), mat_mul(_axis_rotation(x0, angle), R0)


@njit(**EXACT)
def suture_run(q0, geo, w_diag, mode, radius_mm, speed_mm_s, arc_rad, dt_s, gain, damping):
    """Track the suture path with weighted least-norm steps (eq. 32), closed loop.

    Each step asks for dx = (x_d(t+dt) - x_d(t)) + gain (x_d(t) - x(q)), the
    rotational part as rotation vectors, so tracking errors do not drift.
    Returns t, q (rows, 8), position error (mm) and orientation error (deg)
    after each step, N + 1 rows with N = round(arc * radius / (speed * dt)),
    fewer if a step became non-finite (J W^-1 J^T singular: use damping > 0);
    the rows stop before that step, so nothing returned is NaN.
    """
    omega = speed_mm_s / radius_mm
    n = int(np.round(arc_rad / omega / dt_s))
    t = np.arange(n + 1) * dt_s
    qs = np.empty((n + 1, 8))
    pos_err = np.zeros(n + 1)
    rot_err = np.zeros(n + 1)
    q = q0.copy()
    qs[0] = q
    p0, R0 = forward_kinematics(q, geo)
    pd, Rd = p0, R0
    for k in range(n):
        p, R = forward_kinematics(q, geo)
        pn, Rn = suture_target(mode, p0, R0, radius_mm, min(arc_rad, omega * t[k + 1]))
        dx = np.empty(6)
        dx[:3] = (pn - pd) + gain * (pd - p)
        dx[3:] = rotation_vector(mat_mul(Rn, Rd.T)) + gain * rotation_vector(mat_mul(Rd, R.T))
        dq = weighted_least_norm_step(jacobian(q, geo), w_diag, dx, damping)
        if not np.all(np.isfinite(dq)):
            return t[:k + 1], qs[:k + 1], pos_err[:k + 1], rot_err[:k + 1]
        q = q + dq
        qs[k + 1] = q
        pd, Rd = pn, Rn
        p, R = forward_kinematics(q, geo)
        e = pd - p
        pos_err[k + 1] = np.sqrt(dot(e, e))
        rv = rotation_vector(mat_mul(Rd, R.T))
        rot_err[k + 1] = np.degrees(np.sqrt(dot(rv, rv)))
    return t, qs, pos_err, rot_err
