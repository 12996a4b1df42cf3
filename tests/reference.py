"""Slow, obviously-correct numpy reference implementations.

Every numba kernel in ``surgopt.kinematics`` is tested against a function here.
These use textbook formulations (4x4 DH matrices, angles via atan2/acos, dense
``np.linalg`` inverse and SVD) that share no code with the kernels.
"""
from __future__ import annotations

import numpy as np

# ---------------------------------------------------------------------------
# PA10-7C (Locke & Patel 2007)
# ---------------------------------------------------------------------------


def dh_standard(theta, d, a, alpha):
    """Standard (distal) DH transform Rz(theta) Tz(d) Tx(a) Rx(alpha)."""
    ct, st = np.cos(theta), np.sin(theta)
    ca, sa = np.cos(alpha), np.sin(alpha)
    return np.array(
        [
            [ct, -st * ca, st * sa, a * ct],
            [st, ct * ca, -ct * sa, a * st],
            [0.0, sa, ca, d],
            [0.0, 0.0, 0.0, 1.0],
        ]
    )


def pa10_dh_table(d1, d3, d5, d7):
    """(d, a, alpha) rows of the PA10-7C standard DH table, joints S1..W2."""
    h = np.pi / 2
    return [
        (d1, 0.0, -h),
        (0.0, 0.0, h),
        (d3, 0.0, -h),
        (0.0, 0.0, h),
        (d5, 0.0, -h),
        (0.0, 0.0, h),
        (d7, 0.0, 0.0),
    ]


def pa10_frames(q7, links):
    """All frames T_0..T_7 (list of 4x4) for the 7 joint angles."""
    T = np.eye(4)
    frames = [T.copy()]
    for qi, (d, a, al) in zip(q7, pa10_dh_table(*links)):
        T = T @ dh_standard(qi, d, a, al)
        frames.append(T.copy())
    return frames


def pa10_tool_tip(q5, links, tool_m):
    """Tool tip position and axis for the 5 active joints (S3 = W2 = 0)."""
    q7 = np.array([q5[0], q5[1], 0.0, q5[2], q5[3], q5[4], 0.0])
    T = pa10_frames(q7, links)[-1]
    k = T[:3, 2]
    return T[:3, 3] + tool_m * k, k


def pa10_ik(p, k, links, tool_m, elbow_up=True):
    """Closed-form IK (S3 = W2 = 0) with angles, for tip p and tool axis k."""
    d1, d3, d5, d7 = links
    w = p - (d7 + tool_m) * k
    q1 = np.arctan2(w[1], w[0])
    r = np.hypot(w[0], w[1])
    h = w[2] - d1
    c4 = (r * r + h * h - d3 * d3 - d5 * d5) / (2 * d3 * d5)
    if abs(c4) > 1:
        return None
    q4 = np.arccos(c4) * (1.0 if elbow_up else -1.0)
    q2 = np.arctan2(r, h) - np.arctan2(d5 * np.sin(q4), d3 + d5 * np.cos(q4))
    q7 = np.array([q1, q2, 0.0, q4, 0.0, 0.0, 0.0])
    R04 = pa10_frames(q7, links)[4][:3, :3]
    k4 = R04.T @ k
    q6 = np.arccos(np.clip(k4[2], -1, 1))
    q5 = np.arctan2(k4[1], k4[0])
    return np.array([q1, q2, q4, q5, q6])


ACTIVE = (0, 1, 3, 4, 5)  # S1, S2, E1, E2, W1 (0-based DH joint index)


def pa10_alternative_jacobian(q5, links, tool_m, rcm):
    """J_a (eq. 8): d(x, y, z tip, e_x, e_y)/d(active joints).

    e = x,y of the intersection of the tool line with the horizontal skin plane
    through the RCM, minus the RCM (RCM frame axes parallel to the world's).
    Differentiated with the geometric Jacobian: p_dot = w x (p - o),
    k_dot = w x k for each revolute axis.
    """
    q7 = np.array([q5[0], q5[1], 0.0, q5[2], q5[3], q5[4], 0.0])
    frames = pa10_frames(q7, links)
    T = frames[-1]
    k = T[:3, 2]
    p = T[:3, 3] + tool_m * k
    J = np.zeros((5, 5))
    for col, j in enumerate(ACTIVE):
        z = frames[j][:3, 2]
        o = frames[j][:3, 3]
        pd = np.cross(z, p - o)
        kd = np.cross(z, k)
        # q = p - s k with s = (p_z - c_z)/k_z
        s = (p[2] - rcm[2]) / k[2]
        sd = (pd[2] * k[2] - (p[2] - rcm[2]) * kd[2]) / k[2] ** 2
        qd = pd - sd * k - s * kd
        J[:3, col] = pd
        J[3:, col] = qd[:2]
    return J


def pa10_alternative_fk(q5, links, tool_m, rcm):
    """(x, y, z, e_x, e_y) for finite-difference checks of J_a."""
    p, k = pa10_tool_tip(q5, links, tool_m)
    s = (p[2] - rcm[2]) / k[2]
    q = p - s * k
    return np.concatenate([p, q[:2] - np.asarray(rcm)[:2]])


def reverse_jacobian(Ja):
    """J_r = first 3 columns of J_a^-1 (eqs. 5-6)."""
    return np.linalg.inv(Ja)[:, :3]


def scaled_singular_values(q5, links, tool_m, rcm, qdot_max):
    """Singular values of Q^-1 J_r, Q = diag(max joint speeds)."""
    Ja = pa10_alternative_jacobian(q5, links, tool_m, rcm)
    M = np.diag(1.0 / np.asarray(qdot_max)) @ reverse_jacobian(Ja)
    return np.linalg.svd(M, compute_uv=False)


def workspace_cube(rcm, depth_m=0.1, side_m=0.05, n=17):
    """Grid points of the cube centred depth_m below the RCM."""
    c = np.asarray(rcm, float) - np.array([0.0, 0.0, depth_m])
    t = np.linspace(-side_m / 2, side_m / 2, n)
    X, Y, Z = np.meshgrid(t, t, t, indexing="ij")
    return c + np.stack([X.ravel(), Y.ravel(), Z.ravel()], axis=1)


def global_isotropy_index(smin, smax):
    """GII = min sigma_min / max sigma_max (eq. 7)."""
    return float(np.min(smin) / np.max(smax))


def rcm_candidate_gii(rcm, links, tool_m, qdot_max, limits_rad, n=17, elbow_up=True):
    """GII of one RCM candidate (None when any workspace point is unreachable)."""
    smins, smaxs = [], []
    for p in workspace_cube(rcm, n=n):
        k = (p - rcm) / np.linalg.norm(p - rcm)
        q = pa10_ik(p, k, links, tool_m, elbow_up)
        if q is None or np.any(np.abs(q) > limits_rad):
            return None
        s = scaled_singular_values(q, links, tool_m, rcm, qdot_max)
        smins.append(s[-1])
        smaxs.append(s[0])
    return global_isotropy_index(smins, smaxs)


# ---------------------------------------------------------------------------
# Throat-robot arm (Wei, Xu & Simaan)
# ---------------------------------------------------------------------------


def rz(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])


def ry(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, 0, s], [0, 1.0, 0], [-s, 0, c]])


def five_bar_point_c(q1, q2, links, branch=1.0):
    """Five-bar: D, B, C by the law of cosines at D (angles, not the kernel's chord construction)."""
    l1, l2, l3, l4, l5, l6 = links
    D = np.array([l5 * np.sin(q1), l5 * np.cos(q1) - l1 / 2])
    B = np.array([l2 * np.sin(q2), l2 * np.cos(q2) + l1 / 2])
    db = B - D
    d = np.hypot(*db)
    gamma = np.arccos((l4 ** 2 + d ** 2 - l3 ** 2) / (2 * l4 * d))  # angle at D between DB and DC
    heading = np.arctan2(db[1], db[0]) + branch * gamma
    C = D + l4 * np.array([np.cos(heading), np.sin(heading)])
    return D, B, C


def five_bar_end(q1, q2, links, branch=1.0):
    D, B, C = five_bar_point_c(q1, q2, links, branch)
    u = (C - B) / links[2]
    return B + links[5] * u, u


def segment_by_quadrature(theta_l, delta, length, n=4001):
    """Tip of a constant-curvature segment by integrating cos/sin of theta(s) numerically (eq. 10)."""
    s = np.linspace(0, length, n)
    theta = np.pi / 2 + (theta_l - np.pi / 2) * s / length
    w = np.full(n, 2.0)
    w[1:-1:2] = 4.0
    w[0] = w[-1] = 1.0
    h = length / (n - 1)
    x = h / 3 * np.sum(w * np.cos(theta))
    z = h / 3 * np.sum(w * np.sin(theta))
    p = rz(-delta) @ np.array([x, 0, z])
    R = rz(-delta) @ ry(np.pi / 2 - theta_l) @ rz(delta)
    return p, R


def throat_fk(q, links, arm_length, slu, pmu, fulcrum, branch=1.0):
    """Platform pose by composing homogeneous transforms (eqs. 2-13)."""
    P_U, u = five_bar_end(q[0], q[1], links, branch)
    PU = np.array([P_U[0], P_U[1], 0.0])
    xt = np.array([u[0], u[1], 0.0])
    z = (fulcrum - PU) / np.linalg.norm(fulcrum - PU)
    y = np.cross(z, xt)
    y /= np.linalg.norm(y)
    x = np.cross(y, z)
    T = np.eye(4)
    T[:3, :3] = np.column_stack([x, y, z])
    T[:3, 3] = PU
    Tz = np.eye(4)
    Tz[:3, :3] = rz(q[3])
    Tz[2, 3] = arm_length + q[2]
    T = T @ Tz
    for th, de, L in ((q[4], q[5], slu), (q[6], q[7], pmu)):
        p, R = segment_by_quadrature(th, de, L)
        Ts = np.eye(4)
        Ts[:3, :3] = R
        Ts[:3, 3] = p
        T = T @ Ts
    return T[:3, 3], T[:3, :3]


def throat_jacobian_fd(q, *args, h=1e-6):
    """6x8 Jacobian (v, omega in the world) by central differences of throat_fk."""
    p0, R0 = throat_fk(q, *args)
    J = np.zeros((6, 8))
    for j in range(8):
        e = np.zeros(8)
        e[j] = h
        pp, Rp = throat_fk(q + e, *args)
        pm, Rm = throat_fk(q - e, *args)
        J[:3, j] = (pp - pm) / (2 * h)
        W = (Rp - Rm) / (2 * h) @ R0.T
        J[3:, j] = [W[2, 1], W[0, 2], W[1, 0]]
    return J


def weighted_least_norm_kkt(J, w, dx):
    """min dq^T W dq s.t. J dq = dx, solved as the KKT system [[W, J^T], [J, 0]]."""
    n, m = J.shape[1], J.shape[0]
    K = np.zeros((n + m, n + m))
    K[:n, :n] = np.diag(w)
    K[:n, n:] = J.T
    K[n:, :n] = J
    rhs = np.concatenate([np.zeros(n), dx])
    return np.linalg.solve(K, rhs)[:n]


# ---------------------------------------------------------------------------
# Raven IV (Li et al. 2011)
# ---------------------------------------------------------------------------


def raven_tool_axis(theta1, theta2, alpha, beta, left=True):
    """z3 of the spherical mechanism (theta3 = 0) by plain DH matrix products."""
    if left:
        rows = [(theta1, np.pi - alpha), (-theta2, -beta), (np.pi / 2, 0.0)]
    else:
        rows = [(np.pi - theta1, np.pi - alpha), (theta2, -beta), (1.5 * np.pi, 0.0)]
    T = np.eye(4)
    for th, al in rows:
        T = T @ dh_standard(th, 0.0, 0.0, al)
    return T[:3, 2], T[:3, :3]


def isotropy_2x2(M):
    s = np.linalg.svd(M, compute_uv=False)
    return s[-1] / s[0]


def annulus_zeta_mm(r_in, r_out):
    """Area / circumference of an annulus (both circles count): (r_out - r_in) / 2."""
    return (np.pi * (r_out ** 2 - r_in ** 2)) / (2 * np.pi * (r_out + r_in))


def cell_inside_polygon(v):
    """Inside part of a unit cell with corner values v = (v0 (0,0), v1 (1,0), v2 (1,1), v3 (0,1)):
    walk the square, keep inside corners and linearly interpolated edge crossings. Returns the
    polygon (k, 2) and the crossings (ordered from edge 0-1 on)."""
    px, py = [0.0, 1.0, 1.0, 0.0], [0.0, 0.0, 1.0, 1.0]
    poly, cross = [], []
    for k in range(4):
        a, b = v[k], v[(k + 1) % 4]
        if a > 0:
            poly.append((px[k], py[k]))
        if (a > 0) != (b > 0):
            t = a / (a - b)
            p = (px[k] + t * (px[(k + 1) % 4] - px[k]), py[k] + t * (py[(k + 1) % 4] - py[k]))
            poly.append(p)
            cross.append(p)
    return np.array(poly).reshape(-1, 2), np.array(cross).reshape(-1, 2)


def cell_contour(v):
    """(contour length, inside area) of one cell by shoelace on ``cell_inside_polygon``; a saddle's
    crossings are paired by the sign of the corner mean."""
    poly, e = cell_inside_polygon(v)
    area = 0.0
    if len(poly):
        x, y = poly[:, 0], poly[:, 1]
        area = 0.5 * abs(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))
    if len(e) == 2:
        return float(np.hypot(*(e[1] - e[0]))), area
    if len(e) == 4:
        if (np.mean(v) > 0) == (v[0] > 0):
            pairs = [(0, 1), (2, 3)]
        else:
            pairs = [(0, 3), (1, 2)]
        return float(sum(np.hypot(*(e[i] - e[j])) for i, j in pairs)), area
    return 0.0, area


def raven_cone_fields(xs, ys, depth, ports, axes):
    """(arms, nx*ny) cos psi between each shoulder axis and the direction to each plane node, and distance."""
    X, Y = np.meshgrid(xs, ys, indexing="ij")
    v = np.stack([X.ravel(), Y.ravel(), np.full(X.size, -depth)], axis=1)[None] - ports[:, None, :]
    dist = np.linalg.norm(v, axis=2)
    return np.clip(np.einsum("anj,aj->an", v, axes) / dist, -1, 1), dist


def raven_isotropy_from_cos_psi(cos_psi, alpha, beta):
    """Iso (eq. 35) by an SVD of J_s at theta2 = acos((cos psi + ca cb) / (sa sb)) (eq. 22), any shape."""
    sa, ca, sb, cb = np.sin(alpha), np.cos(alpha), np.sin(beta), np.cos(beta)
    t2 = np.arccos(np.clip((np.asarray(cos_psi) + ca * cb) / (sa * sb), -1, 1))
    out = np.empty(t2.shape)
    for idx, t in np.ndenumerate(t2):
        c2, s2 = np.cos(t), np.sin(t)
        J = np.array([[c2 * cb * sa + sb * ca, sb], [s2 * sa, 0.0]])  # eq. 41's top-left block
        out[idx] = isotropy_2x2(J)
    return out
