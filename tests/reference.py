"""Slow, obviously-correct numpy reference implementations.

Every numba kernel in ``surgopt.kinematics`` is tested against a function here.
These use textbook formulations (4x4 DH matrices, angles via atan2/acos, dense
``np.linalg`` inverse and SVD, bisection, per-cell polygons) that share no code with the kernels
or the studies: only the robots' parameter tables (``surgopt/robots``, data) are read.
"""
from __future__ import annotations

import numpy as np

from surgopt.robots import pa10_7c, raven_iv

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
    """(d, a, alpha) rows of the PA10-7C standard DH table, joints S1..W2, read from the robot's
    model file (``surgopt/robots/pa10_7c.py``: data, no code shared with the kernels)."""
    links = (d1, d3, d5, d7)
    return [(0.0 if k is None else links[k], 0.0, np.radians(alpha))
            for k, alpha in zip(pa10_7c.DH_D_LINK, pa10_7c.DH_ALPHA_DEG)]


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
    (s1, o1), (s2, o2), (s3, o3) = raven_iv.DH_THETA_ROWS["left" if left else "right"]
    rows = [(s1 * theta1 + o1, np.pi - alpha), (s2 * theta2 + o2, -beta), (o3, 0.0)]
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


def raven_isotropy_at(theta2, alpha, beta):
    """Iso (eq. 35) at one theta2: 1/cond of eq. 41's top-left block by SVD."""
    c2, s2 = np.cos(theta2), np.sin(theta2)
    sa, ca, sb, cb = np.sin(alpha), np.cos(alpha), np.sin(beta), np.cos(beta)
    return isotropy_2x2(np.array([[c2 * cb * sa + sb * ca, sb], [s2 * sa, 0.0]]))


def raven_theta2_interval(alpha, beta, iso_min, lo, hi, n_scan=4001, tol=1e-13):
    """{theta2 in [lo, hi] : Iso >= iso_min} as (t_lo, t_hi), or None: a dense scan finds the
    qualifying samples, bisection on the SVD isotropy refines each end."""
    t = np.linspace(lo, hi, n_scan)
    ok = np.array([raven_isotropy_at(x, alpha, beta) >= iso_min for x in t])
    if not ok.any():
        return None
    idx = np.flatnonzero(ok)

    def crossing(good, bad):
        while abs(good - bad) > tol:
            m = 0.5 * (good + bad)
            if raven_isotropy_at(m, alpha, beta) >= iso_min:
                good = m
            else:
                bad = m
        return good

    t_lo = t[idx[0]] if idx[0] == 0 else crossing(t[idx[0]], t[idx[0] - 1])
    t_hi = t[idx[-1]] if idx[-1] == n_scan - 1 else crossing(t[idx[-1]], t[idx[-1] + 1])
    return t_lo, t_hi


def _rotation(axis, deg):
    """Rotation about a coordinate axis by Rodrigues' formula, entries below 1e-15 set to zero."""
    k = np.zeros(3)
    k[axis] = 1.0
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    a = np.radians(deg)
    R = np.eye(3) + np.sin(a) * K + (1 - np.cos(a)) * K @ K
    R[np.abs(R) < 1e-15] = 0.0
    return R


def raven_four_arm_frames(bx, by, phi_x, phi_y, phi_z, tilt_deg=90.0):
    """Ports and shoulder axes of the four-arm layout (ports (-+bx/2, +-by/2), arms 1 and 3 on the left,
    axes tilted outward along x by ``tilt_deg`` from vertical, turned by Rz Ry Rx with phi_y, phi_z
    mirrored for the left arms): the layout docs/reproduction.md describes, written out."""
    ports = np.array([[-bx / 2, by / 2, 0], [bx / 2, by / 2, 0], [-bx / 2, -by / 2, 0], [bx / 2, -by / 2, 0]], float)
    axes = []
    for left in (True, False, True, False):
        out = -1.0 if left else 1.0
        u = np.array([out * np.sin(np.radians(tilt_deg)), 0.0, np.cos(np.radians(tilt_deg))])
        u[np.abs(u) < 1e-15] = 0.0
        m = -1.0 if left else 1.0
        axes.append(_rotation(2, m * phi_z) @ _rotation(1, m * phi_y) @ _rotation(0, phi_x) @ u)
    return ports, np.array(axes)


def raven_four_arm_zero_axes(phi_x, phi_y, phi_z, tilt_deg=90.0, zero=(0.0, 1.0, 0.0)):
    """theta1's zero direction x0 of each arm of ``raven_four_arm_frames`` (tilt along x): ``zero`` (x
    negated for the left arms 1 and 3) turned by the arm's outward tilt about the y axis, then by the same
    Rz Ry Rx."""
    out = []
    for left in (True, False, True, False):
        m = -1.0 if left else 1.0
        b = np.array(zero, float) * [m, 1.0, 1.0]
        tilt = _rotation(1, m * tilt_deg)
        out.append(_rotation(2, m * phi_z) @ _rotation(1, m * phi_y) @ _rotation(0, phi_x) @ tilt @ b)
    return np.array(out)


def raven_plane_nodes(ports, depth, d4_max, step):
    """Multiples of ``step`` from two below to two above the box where every arm reaches the plane."""
    r = np.sqrt(d4_max ** 2 - depth ** 2)
    lo = (ports[:, :2] - r).max(axis=0)
    hi = (ports[:, :2] + r).min(axis=0)
    return [np.arange(np.floor(lo[i] / step) - 2, np.ceil(hi[i] / step) + 3) * step for i in (0, 1)]


def zero_contour(margin, step):
    """(length, area) of {margin > 0} on a grid (rows = x) with linearly interpolated edges:
    ``cell_contour`` on each cell that straddles the boundary, whole cells inside counted as 1."""
    v0, v1, v2, v3 = margin[:-1, :-1], margin[1:, :-1], margin[1:, 1:], margin[:-1, 1:]
    n_in = (v0 > 0).astype(int) + (v1 > 0) + (v2 > 0) + (v3 > 0)
    length, area = 0.0, float((n_in == 4).sum())
    for i, j in zip(*np.nonzero((n_in > 0) & (n_in < 4))):
        dl, da = cell_contour((v0[i, j], v1[i, j], v2[i, j], v3[i, j]))
        length += dl
        area += da
    return length * step, area * step * step


def raven_designs_brute_force(ports, axes, depth, step, d4_max, alphas, betas, isos, theta2_range):
    """Every (alpha, beta, Iso_min) design of one geometry, design by design and arm by arm.

    A node of the plane belongs to the common workspace when, for every arm, the angle psi between its
    shoulder axis and the direction to the node lies strictly inside the cone interval that theta2's
    range narrowed by Iso_min allows (eq. 22), and the node is within d4_max (closed: Table I's [0, 250] mm). Isotropy of a node: the
    minimum over the arms of the SVD isotropy. The boundary is the zero contour of the margin
    min((lo - c_lo) d_lo, (c_hi - hi) d_hi, min(d4_max - dist)), lo and hi the arms' lowest and
    highest cos psi and d_lo, d_hi those arms' distances. Rows (area mm^2, perimeter mm, points,
    iso sum, iso min).
    """
    xs, ys = raven_plane_nodes(ports, depth, d4_max, step)
    cos_psi, dist = raven_cone_fields(xs, ys, depth, ports, axes)
    lo, hi = cos_psi.min(axis=0), cos_psi.max(axis=0)
    cols = np.arange(lo.size)
    d_lo, d_hi = dist[cos_psi.argmin(axis=0), cols], dist[cos_psi.argmax(axis=0), cols]
    reach = (d4_max - dist).min(axis=0)
    lo2, hi2 = np.radians(theta2_range[0]), np.radians(theta2_range[1])
    rows = []
    for a in alphas:
        for b in betas:
            iso_node = raven_isotropy_from_cos_psi(cos_psi, a, b).min(axis=0)
            for m in isos:
                span = raven_theta2_interval(a, b, m, lo2, hi2)
                if span is None:
                    rows.append((0.0, 0.0, 0, 0.0, 1.0))
                    continue
                psi = [np.arccos(np.clip(np.sin(a) * np.sin(b) * np.cos(t) - np.cos(a) * np.cos(b), -1, 1))
                       for t in span]
                c_lo, c_hi = np.cos(psi[1]), np.cos(psi[0])
                inside = np.all((cos_psi > c_lo) & (cos_psi < c_hi) & (dist <= d4_max), axis=0)
                margin = np.minimum(reach, np.minimum((lo - c_lo) * d_lo, (c_hi - hi) * d_hi))
                length, area = zero_contour(margin.reshape(xs.size, ys.size), step) if inside.any() else (0.0, 0.0)
                rows.append((area, length, int(inside.sum()), iso_node[inside].sum(), iso_node[inside].min(initial=1.0)))
    return np.array(rows, dtype=float)


# ---------------------------------------------------------------------------
# Any serial arm (issue: rcm-grid for any arm)
# ---------------------------------------------------------------------------


def dh_modified(theta, d, a, alpha):
    """Modified (proximal, Craig) DH transform Rx(alpha) Tx(a) Rz(theta) Tz(d), written out."""
    ct, st = np.cos(theta), np.sin(theta)
    ca, sa = np.cos(alpha), np.sin(alpha)
    return np.array(
        [
            [ct, -st, 0.0, a],
            [st * ca, ct * ca, -sa, -sa * d],
            [st * sa, ct * sa, ca, ca * d],
            [0.0, 0.0, 0.0, 1.0],
        ]
    )


def dh_chain_transform(model, q):
    """Base -> flange of a shipped model (``surgopt.robots.models.ArmModel``, data only) at joints q (rad),
    as the product of textbook 4x4 DH matrices."""
    t = np.eye(4)
    f = dh_standard if model.convention == "standard" else dh_modified
    for row, v in zip(model.dh, q, strict=True):
        t = t @ f(v + row.theta_offset_rad, row.d_m, row.a_m, row.alpha_rad)
    return t


def tool_line_rcm_error(flange, tool_length_m, target, rcm):
    """(tip error (m), distance of the RCM from the tool line (m)) for a tool along the flange's z axis."""
    k = flange[:3, 2]
    tip = flange[:3, 3] + tool_length_m * k
    r = np.asarray(rcm) - tip
    return float(np.linalg.norm(tip - np.asarray(target))), float(np.linalg.norm(r - (r @ k) * k))


def finite_difference_jacobian(f, q, h=1e-7):
    """Central differences of a vector function f at q."""
    q = np.asarray(q, float)
    cols = []
    for i in range(q.size):
        e = np.zeros_like(q)
        e[i] = h
        cols.append((np.asarray(f(q + e)) - np.asarray(f(q - e))) / (2 * h))
    return np.stack(cols, axis=1)


def p_control_track(fk, q_ref_steps, p_ref, rcm, dt, gain, lag_s, qdot_max, speed_scale=1.0):
    """A plain Python loop of the joint-level P controller (Locke & Patel Sec. IV-A): per step the tip
    error and the RCM's distance from the tool line, then qdot_cmd = gain (q_ref - q), clipped, lagged,
    integrated. ``fk(q)`` returns (tip, tool axis); ``q_ref_steps`` (M, 5) the reference at every step.
    Returns (max tip error, max RCM error, per-step tip errors)."""
    q = np.array(q_ref_steps[0], float)
    qdot = np.zeros_like(q)
    alpha = 1.0 if lag_s <= 0 else dt / (lag_s + dt)
    errs, rerrs = [], []
    for k in range(len(p_ref)):
        tip, axis = fk(q)
        errs.append(np.linalg.norm(tip - p_ref[k]))
        r = np.asarray(rcm) - tip
        rerrs.append(np.linalg.norm(r - (r @ axis) * axis))
        if k == len(p_ref) - 1:
            break
        cmd = np.clip(gain * (q_ref_steps[k] - q), -speed_scale * qdot_max, speed_scale * qdot_max)
        qdot = qdot + alpha * (cmd - qdot)
        q = q + qdot * dt
    return max(errs), max(rerrs), np.array(errs)


def pa10_standard_gii(rcm, offsets, links, tool_m, qdot_max7, linear_m_s=0.01, angular_rad_s=np.pi / 2):
    """Locke & Patel Sec. III-E: GII of the standard 6 x 6 Jacobian (joints S1, S2, E1, E2, W1, W2; S3 held)
    of the tool tip at the closed-form IK poses, rows divided by the task scaling, columns times the rated
    speeds, by dense SVD. None when a pose is out of reach."""
    d1, d3, d5, d7 = links
    table = pa10_dh_table(d1, d3, d5, d7)
    lo, hi = np.inf, 0.0
    for o in offsets:
        p = np.asarray(rcm) + o
        q5 = pa10_ik(p, o / np.linalg.norm(o), links, tool_m)
        if q5 is None:
            return None
        q7 = np.array([q5[0], q5[1], 0.0, q5[2], q5[3], q5[4], 0.0])
        frames = [np.eye(4)]
        for (d, a, alpha), v in zip(table, q7):
            frames.append(frames[-1] @ dh_standard(v, d, a, alpha))
        tip = frames[-1][:3, 3] + tool_m * frames[-1][:3, 2]
        cols = []
        for i in (0, 1, 3, 4, 5, 6):
            z, org = frames[i][:3, 2], frames[i][:3, 3]
            cols.append(np.concatenate([np.cross(z, tip - org) / linear_m_s, z / angular_rad_s]) * qdot_max7[i])
        sv = np.linalg.svd(np.array(cols).T, compute_uv=False)
        lo, hi = min(lo, sv[-1]), max(hi, sv[0])
    return lo / hi


# ---------------------------------------------------------------------------
# port-place: dVRK PSM / ECM (the shared dvrk-kinematics.md tables, typed in here again)
# ---------------------------------------------------------------------------

#: (alpha, A, D, prismatic, offset) of the PSM Classic's yaw, pitch, insertion rows and the Large Needle
#: Driver's roll row, as ../shared/robots/dvrk-kinematics.md lists them (not read from surgopt).
PSM_CLASSIC_MDH = [(np.pi / 2, 0.0, 0.0, False, np.pi / 2), (-np.pi / 2, 0.0, 0.0, False, -np.pi / 2),
                   (np.pi / 2, 0.0, 0.0, True, -0.4318), (0.0, 0.0, 0.4162, False, 0.0)]
ECM_CLASSIC_MDH = [(np.pi / 2, 0.0, 0.0, False, np.pi / 2), (-np.pi / 2, 0.0, 0.0, False, -np.pi / 2),
                   (np.pi / 2, 0.0, 0.0, True, -0.3822), (0.0, 0.0, 0.3829, False, 0.0)]


def mdh_chain(rows, q):
    """Base (RCM) -> last frame of modified-DH ``rows`` at joints q (q4, the roll, 0 if not given)."""
    q = list(q) + [0.0] * (len(rows) - len(q))
    t = np.eye(4)
    for (alpha, a, d, prismatic, offset), v in zip(rows, q):
        t = t @ (dh_modified(0.0, v + offset + d, a, alpha) if prismatic else dh_modified(v + offset, d, a, alpha))
    return t


def brute_force_reach(points, rows, limits, n=(46, 31, 31)):
    """Which base-frame points a yaw/pitch/insertion arm reaches, by sampling its joint space on a grid and
    taking the nearest sample: (nearest distance per point, the grid's largest gap between neighbours)."""
    grids = [np.linspace(lo, hi, k) for (lo, hi), k in zip(limits, n)]
    q1, q2, q3 = np.meshgrid(*grids, indexing="ij")
    samples = np.stack([mdh_chain(rows, q)[:3, 3] for q in zip(q1.ravel(), q2.ravel(), q3.ravel())])
    d = np.array([np.min(np.linalg.norm(samples - p, axis=1)) for p in points])
    steps = [g[1] - g[0] for g in grids]
    rho_max = limits[2][1] + abs(rows[2][4] + rows[3][2])
    return d, max(rho_max * steps[0], rho_max * steps[1], steps[2])


# ---------------------------------------------------------------------------
# A serial arm keeping an RCM in software (port-place's instrument_serial)
# ---------------------------------------------------------------------------


def rcm_constrained_isotropy(tool, q, rcm, qdot_max, h=1e-6):
    """sigma_min / sigma_max of B = J_tip Q N, N an orthonormal basis of the null space of the RCM constraint's
    rows (J_c Q): the tip's velocities per normalised joint speed that keep the tool line through ``rcm``
    (Locke & Patel 2007 eqs. 5-8 in the form of a constrained map). ``tool(q)`` -> (tip, unit tool axis); both
    Jacobians by central differences; the constraint is the offset of the tool line's point nearest ``rcm``."""
    rcm = np.asarray(rcm, float)

    def f(qq):
        tip, k = tool(qq)
        nearest = tip + ((rcm - tip) @ k) * k
        return np.concatenate([tip, nearest - rcm])

    jac = finite_difference_jacobian(f, q, h) * np.asarray(qdot_max)[None, :]
    _, s, vt = np.linalg.svd(jac[3:])  # rank 2: the offset moves only normal to the tool
    assert s[1] > 1e3 * s[2], s
    null = vt[2:].T
    sv = np.linalg.svd(jac[:3] @ null, compute_uv=False)
    return sv[-1] / sv[0]


def segment_distance_sampled(p0, p1, q0, q1, n=401):
    """The least distance between two segments by sampling each at n points (an upper bound within the
    sampling step of the true distance)."""
    s = np.linspace(0.0, 1.0, n)[:, None]
    a = p0 + s * (p1 - p0)
    b = q0 + s * (q1 - q0)
    return float(np.min(np.linalg.norm(a[:, None, :] - b[None, :, :], axis=2)))


def segment_box_distance_sampled(p0, p1, lo, hi, n=2001):
    """The least distance from a segment to an axis-aligned box (0 inside it), sampling the segment at n points:
    each point's distance is the norm of how far it lies outside the box's slab on each axis (an upper bound
    within half the sampling step of the true distance)."""
    s = np.linspace(0.0, 1.0, n)[:, None]
    pts = np.asarray(p0, float) + s * (np.asarray(p1, float) - np.asarray(p0, float))
    outside = np.maximum(np.asarray(lo, float) - pts, 0.0) + np.maximum(pts - np.asarray(hi, float), 0.0)
    return float(np.min(np.linalg.norm(outside, axis=1)))


def ellipsoid_distance(p, semi_axes):
    """Distance from a point outside an ellipsoid (centred, axis-aligned) to it (Eberly, "Distance from a point
    to an ellipse, an ellipsoid, or a hyperellipsoid"): the root t > 0 of sum (a_i p_i / (t + a_i^2))^2 = 1 by
    bisection, the nearest point q_i = a_i^2 p_i / (t + a_i^2)."""
    a = np.asarray(semi_axes, float)
    p = np.asarray(p, float)
    f = lambda t: np.sum((a * p / (t + a * a)) ** 2) - 1.0  # noqa: E731
    lo, hi = 0.0, float(np.linalg.norm(a * p)) + 1.0
    assert f(lo) > 0 > f(hi)
    for _ in range(200):
        mid = (lo + hi) / 2
        lo, hi = (mid, hi) if f(mid) > 0 else (lo, mid)
    q = a * a * p / (lo + a * a)
    return float(np.linalg.norm(p - q))


# ---- the dVRK's setup joints (SUJ), typed again from ../shared/robots/dvrk-kinematics.md and the dVRK's
# suj-si-simulated.json: (world -> SUJ translation, rotation), rows (alpha, A, D, offset, prismatic), fixed rows
# (alpha, A, theta), tip -> tool translation; the tip -> tool rotation is the same for every arm.
_RZ_FLIP = [[-1, 0, 0], [0, -1, 0], [0, 0, 1]]
_RZ_PLUS = [[0, -1, 0], [1, 0, 0], [0, 0, 1]]
_RZ_MINUS = [[0, 1, 0], [-1, 0, 0], [0, 0, 1]]
_EYE = [[1, 0, 0], [0, 1, 0], [0, 0, 1]]
SUJ_TIP_ROTATION = [[0, 1, 0], [-1, 0, 0], [0, 0, 1]]
_PSM12_ROWS = [(0, 0.0896, 0, 0, True), (0, 0, 0.4166, 0, False), (0, 0.4318, 0.1429, 0, False),
               (0, 0.4318, -0.1302, 1.5708, False), (1.5708, 0, 0.4089, 0, False),
               (-1.5708, 0, -0.1029, -1.5708, False)]
SUJ_REFERENCE = {
    ("classic", "PSM1"): ((-0.1016, -0.1016, 0.43), _RZ_FLIP, _PSM12_ROWS, [], (0.4864, 0, 0.1524)),
    ("classic", "PSM2"): ((0.1016, -0.1016, 0.43), _EYE, _PSM12_ROWS, [], (0.4864, 0, 0.1524)),
    ("classic", "PSM3"): ((0, 0, 0.1264), _RZ_PLUS,
                          [(0, 0.0896, 0, 0, True), (0, 0, 0.3404, 0, False), (0, 0.5842, 0.1429, 0, False),
                           (0, 0.4318, 0.2571, 1.5708, False), (1.5708, 0, 0.4089, 0, False),
                           (-1.5708, 0, -0.1029, -1.5708, False)], [], (0.4864, 0, 0.1524)),
    ("classic", "ECM"): ((0, 0, 0.43), _RZ_PLUS,
                         [(0, 0.0896, 0, 0, True), (0, 0, 0.4166, 0, False), (0, 0.4318, 0.1429, 0, False),
                          (0, 0.4318, -0.3459, 1.5708, False), (-0.7853, 0, 0, 1.5708, False),
                          (0, -0.0667, 0, 0, False)], [], (0.6126, 0, 0.1016)),
    ("si", "PSM1"): ((-0.2019, -0.0757, 0), _RZ_FLIP,
                     [(0, 0, 0.1471, 0, True), (0, 0, 0.6654, 0, False), (0, 0.4572, 0.1397, 0, False),
                      (0, 0.4572, -0.1301, 0, False)], [(1.5708, 0.049, -0.7854), (-1.5708, 0, 0)], (0.8343, 0, 0)),
    ("si", "PSM2"): ((0.2019, -0.0757, 0), _EYE,
                     [(0, 0, 0.1471, 0, True), (0, 0, 0.6654, 0, False), (0, 0.4572, 0.1397, 0, False),
                      (0, 0.4572, -0.1301, 0, False)], [(1.5708, 0.049, -0.7854), (-1.5708, 0, 0)], (0.8343, 0, 0)),
    ("si", "PSM3"): ((0, -0.2776, 0), _RZ_MINUS,
                     [(0, 0, 0.0455, 0, True), (0, 0, 0.5887, 0, False), (0, 0.3429, -0.2667, 0, False),
                      (0, 0.4572, 0.1397, 0, False), (0, 0.4572, -0.1864, 0, False)],
                     [(1.5708, 0.0483, -0.2618), (-1.5708, 0, 0)], (0.8343, 0, 0)),
    ("si", "ECM"): ((0, 0.1262, 0), _RZ_PLUS,
                    [(0, 0, 0.1471, 0, True), (0, 0, 0.5861, 0, False), (0, 0.3302, 0.1397, 0, False),
                     (0, 0.3302, 0.0549, 0, False)], [(1.5708, 0.1352, -1.2217), (-1.5708, 0, 0)], (0.8343, 0, 0)),
}


def suj_frame_origins_reference(cart, arm, q):
    """(rows + fixed + 1, 3) The origins of the SUJ's frames in the cart's world frame: world->SUJ, then after each
    modified-DH row at q (the jointed, then the fixed at their theta): the polyline its links are drawn along."""
    trans, rot, rows, fixed, _ = SUJ_REFERENCE[(cart, arm)]
    t = np.eye(4)
    t[:3, :3], t[:3, 3] = rot, trans
    out = [t[:3, 3].copy()]
    for (alpha, a, d, offset, prismatic), v in zip(rows, q, strict=True):
        t = t @ (dh_modified(offset, d + v, a, alpha) if prismatic else dh_modified(v + offset, d, a, alpha))
        out.append(t[:3, 3].copy())
    for alpha, a, theta in fixed:
        t = t @ dh_modified(theta, 0.0, a, alpha)
        out.append(t[:3, 3].copy())
    return np.array(out)


def suj_forward_reference(cart, arm, q):
    """The arm's base (RCM) frame in the cart's world frame: world->SUJ, the modified-DH products of the rows at
    q (a prismatic row: D + q; a revolute one: offset + q), the fixed rows at their theta, the tip -> tool."""
    trans, rot, rows, fixed, tip = SUJ_REFERENCE[(cart, arm)]
    t = np.eye(4)
    t[:3, :3], t[:3, 3] = rot, trans
    for (alpha, a, d, offset, prismatic), v in zip(rows, q, strict=True):
        t = t @ (dh_modified(offset, d + v, a, alpha) if prismatic else dh_modified(v + offset, d, a, alpha))
    for alpha, a, theta in fixed:
        t = t @ dh_modified(theta, 0.0, a, alpha)
    tool = np.eye(4)
    tool[:3, :3], tool[:3, 3] = SUJ_TIP_ROTATION, tip
    return t @ tool


# ---------------------------------------------------------------------------
# The dVRK patient cart's setup joints (S1-S7), plain Python pose by pose (issue 53: the naive twin of the rows'
# solvers, ``kinematics/port/suj_batch.py`` (S2, S4 jitted) and ``si_docking.si_solutions`` (S3, S7); production
# runs only those). Its own DH, wrap and Si-orientation helpers: nothing here calls the package's solvers; the
# solvers' shared constants (MARGIN_TIE, the grids' steps) and the SUJ data are read.
# ---------------------------------------------------------------------------
import math  # noqa: E402
from typing import NamedTuple  # noqa: E402

from surgopt.kinematics.port.suj import ECM_GRID_STEPS, MARGIN_TIE, SI_REDUNDANT_STEPS  # noqa: E402


def _suj_mdh(alpha: float, a: float, theta: float, d: float) -> np.ndarray:
    return dh_modified(theta, d, a, alpha)


def _suj_link(row, q: float) -> np.ndarray:
    """One SUJ DH row at joint value q: theta + q for a revolute joint, d + q for the column."""
    if row.prismatic:
        return _suj_mdh(row.alpha_rad, row.a_m, row.theta_offset_rad, row.d_m + q)
    return _suj_mdh(row.alpha_rad, row.a_m, row.theta_offset_rad + q, row.d_m)


def _suj_wrap(angle: float) -> float:
    """An angle in (-pi, pi]."""
    a = math.remainder(angle, 2 * math.pi)
    return math.pi if a == -math.pi else a


def _suj_planar(suj, n_planar: int):
    """(the column's x offset A_c, its D, the planar joints' A (from the second on) and D, their offsets)."""
    col = suj.links[0]
    rows = suj.links[1:1 + n_planar]
    return col.a_m, col.d_m, [r.a_m for r in rows], [r.d_m for r in rows], [r.theta_offset_rad for r in rows]


def _fixed_links(suj) -> np.ndarray:
    g = np.eye(4)
    for row in suj.fixed:
        g = g @ _suj_link(row, 0.0)
    return g


def _si_orientation(suj, yaw_rad: float) -> np.ndarray:
    """(S3) R(W) Rz(yaw) R(fixed links) R_tip."""
    r = np.asarray(suj.world_to_suj, float)[:3, :3] @ _suj_mdh(0, 0, yaw_rad, 0)[:3, :3] @ _fixed_links(suj)[:3, :3]
    return r @ np.asarray(suj.tip_to_tool, float)[:3, :3]


def _least_absorbed(suj, aim: np.ndarray) -> tuple[float, float]:
    """(S6) psi* and the least angle the arm's own joints absorb, for a unit aim in the cart's world."""
    v = _fixed_links(suj)[:3, :3] @ np.asarray(suj.tip_to_tool, float)[:3, :3] @ np.array([0.0, 0.0, -1.0])
    e = np.asarray(suj.world_to_suj, float)[:3, :3].T @ (aim / np.linalg.norm(aim))
    psi = math.atan2(e[1], e[0]) - math.atan2(v[1], v[0])
    return _suj_wrap(psi), abs(math.asin(max(-1.0, min(1.0, v[2]))) - math.asin(max(-1.0, min(1.0, e[2]))))


def _own_joints(base_rot: np.ndarray, aim: np.ndarray) -> tuple[float, float, float]:
    """(P2) q1, q2 that point the shaft along aim from a base of rotation base_rot, and the angle absorbed."""
    a = base_rot.T @ (aim / np.linalg.norm(aim))
    return (math.atan2(a[0], -a[2]), -math.asin(max(-1.0, min(1.0, a[1]))), math.acos(max(-1.0, min(1.0, -a[2]))))


class SujSolution(NamedTuple):
    """The SUJ's joints (m, rad) and the least margin to their ranges (m for the column, rad otherwise; negative:
    outside, by that much) with the joint it belongs to."""

    joints: tuple
    margin: float
    tightest: str


class SujAnswer(NamedTuple):
    """Every solution within the ranges (``within``), the ones outside them (``outside``, nearest first), and why
    there is none within (empty when there is)."""

    within: tuple
    outside: tuple
    reason: str


def _margin(suj, q) -> tuple[float, str]:
    """The least distance of the joints inside their ranges, and the joint's name (a revolute joint's value
    wrapped into its range's turn when it fits there)."""
    worst, name = math.inf, ""
    for row, v, (lo, hi) in zip(suj.links, q, suj.ranges):
        m = min(v - lo, hi - v)
        if m < worst:
            worst, name = m, row.name
    return worst, name


def _solution(suj, q) -> SujSolution:
    q = tuple(float(v) for v in q)
    return SujSolution(q, *_margin(suj, q))


def best_first(sols: list) -> list:
    """Solutions best first: the head the first that no later one beats by MARGIN_TIE, the rest by margin."""
    if not sols:
        return []
    head = sols[0]
    for s in sols[1:]:
        if s.margin > head.margin + MARGIN_TIE:
            head = s
    return [head] + sorted((s for s in sols if s is not head), key=lambda s: -s.margin)


def _answer(suj, candidates) -> SujAnswer:
    sols = best_first([_solution(suj, q) for q in candidates])
    within = tuple(s for s in sols if s.margin >= 0)
    outside = tuple(s for s in sols if s.margin < 0)
    if within:
        return SujAnswer(within, outside, "")
    if not outside:
        return SujAnswer((), (), "out of reach: no joint values put the base there")
    best = outside[0]
    lo, hi = suj.ranges[[r.name for r in suj.links].index(best.tightest)]
    value = best.joints[[r.name for r in suj.links].index(best.tightest)]
    unit = "m" if best.tightest == "column" else "deg"
    k = 1.0 if unit == "m" else 180 / math.pi
    return SujAnswer((), outside, f"{suj.cart} {suj.arm} SUJ {best.tightest} = {value * k:.4g} {unit}, outside "
                                  f"its range [{lo * k:.4g}, {hi * k:.4g}] {unit} (the nearest of "
                                  f"{len(outside)} solution(s))")


def _elbows(x: float, y: float, l1: float, l2: float) -> list[tuple[float, float]]:
    """Both solutions (theta1, theta2) of a planar two-link chain from the origin to (x, y): l1 u(t1) +
    l2 u(t1 + t2) = (x, y); none when the point is out of the links' reach."""
    r2 = x * x + y * y
    c = (r2 - l1 * l1 - l2 * l2) / (2 * l1 * l2)
    if c > 1 + 1e-12 or c < -1 - 1e-12:
        return []
    c = min(1.0, max(-1.0, c))
    out = []
    for s in (math.sqrt(1 - c * c), -math.sqrt(1 - c * c)):
        t2 = math.atan2(s, c)
        t1 = math.atan2(y, x) - math.atan2(l2 * s, l1 + l2 * c)
        out.append((_suj_wrap(t1), _suj_wrap(t2)))
    return out if out[0] != out[1] else out[:1]


def _planar_ik(suj, x: float, y: float, z: float, psi: float) -> list[tuple]:
    """The column and the three planar joints that put the planar chain's last frame at (x, y, z) with yaw psi
    (its x axis's heading): the two elbows."""
    a_c, d_c, a, d, off = _suj_planar(suj, 3)
    column = z - d_c - sum(d)
    out = []
    for t1, t2 in _elbows(x - a_c, y, a[1], a[2]):
        t3 = _suj_wrap(psi - t1 - t2 - off[2])  # t1, t2: the first two links' headings, offsets included
        out.append((column, t1 - off[0], t2 - off[1], t3))
    return out


def _to_suj(suj, pose: np.ndarray) -> np.ndarray:
    """The pose (the base's frame in the cart's world) in the SUJ's base frame, the tip transform taken off."""
    return np.linalg.inv(np.asarray(suj.world_to_suj, float)) @ pose @ np.linalg.inv(np.asarray(suj.tip_to_tool, float))


def classic_psm_ik(suj, pose: np.ndarray) -> SujAnswer:
    """(S2) Every Classic PSM SUJ solution that puts the arm's base frame at ``pose`` (4x4, cart world)."""
    t = _to_suj(suj, pose)
    j4, j5 = suj.links[4], suj.links[5]
    # t = H Rx(a4) Rz(q4) Tz(d4) Rx(a5) Rz(q5 + o5) Tz(d5) with H = Trans(p) Rz(psi)
    a4, a5 = j4.alpha_rad, j5.alpha_rad
    rx4, rx5 = _suj_mdh(a4, 0, 0, 0)[:3, :3], _suj_mdh(a5, 0, 0, 0)[:3, :3]
    m = t[:3, :3]  # = Rz(psi) rx4 Rz(q4) rx5 Rz(q5 + o5)
    z = np.array([0.0, 0.0, 1.0])
    # z.m z = z.rx4 Rz(q4) rx5 z: Rz(psi) and Rz(q5) leave z alone
    u, v = rx4.T @ z, rx5 @ z  # z.(rx4 Rz(q4) rx5 z) = u.(Rz(q4) v)
    # u.Rz(q)v = (ux vx + uy vy) cos q + (ux vy - uy vx) sin q + uz vz
    ca, sa, k = u[0] * v[0] + u[1] * v[1], u[1] * v[0] - u[0] * v[1], u[2] * v[2]
    target = m[2, 2] - k
    amp = math.hypot(ca, sa)
    if amp < 1e-12 or abs(target) > amp * (1 + 1e-12):
        return SujAnswer((), (), f"{suj.cart} {suj.arm} SUJ: no wrist angle tilts the arm's base so "
                                 f"(its z is {math.degrees(math.acos(max(-1, min(1, m[2, 2])))):.1f} deg off vertical)")
    phase = math.atan2(sa, ca)
    spread = math.acos(max(-1.0, min(1.0, target / amp)))
    candidates = []
    for th4 in sorted({_suj_wrap(phase + spread), _suj_wrap(phase - spread)}):
        r4 = rx4 @ _suj_mdh(0, 0, th4, 0)[:3, :3] @ rx5  # m = Rz(psi) r4 Rz(th5), th = q + offset
        # m z = Rz(psi) r4 z: psi from the horizontal parts of m z and r4 z
        w, g = m @ z, r4 @ z
        psi = math.atan2(w[1], w[0]) - math.atan2(g[1], g[0])
        rest = r4.T @ _suj_mdh(0, 0, -psi, 0)[:3, :3] @ m  # = Rz(q5 + o5)
        th5 = math.atan2(rest[1, 0], rest[0, 0])
        q4, q5 = _suj_wrap(th4 - j4.theta_offset_rad), _suj_wrap(th5 - j5.theta_offset_rad)
        g4 = _suj_mdh(a4, j4.a_m, th4, j4.d_m) @ _suj_mdh(a5, j5.a_m, th5, j5.d_m)
        h = t @ np.linalg.inv(g4)  # = Trans(x, y, z) Rz(psi)
        for q in _planar_ik(suj, h[0, 3], h[1, 3], h[2, 3], math.atan2(h[1, 0], h[0, 0])):
            candidates.append((*q, q4, q5))
    return _answer(suj, candidates)


def _redundant_planar_ik(suj, x: float, y: float, z: float, psi: float, steps: int) -> list[tuple]:
    """(S7) The Si PSM3's column and four planar joints that put the chain's last frame at (x, y, z) with yaw psi:
    four revolute joints for three planar degrees of freedom, so the first, theta1, is free; at each of ``steps``
    values of it over a turn the rest is the three-joint chain's inverse (two elbows) from the end of the first
    link, A_2 u(theta1)."""
    a_c, d_c, a, d, off = _suj_planar(suj, 4)
    column = z - d_c - sum(d)
    out = []
    for k in range(steps):
        t1 = -math.pi + 2 * math.pi * k / steps  # the first link's heading, its offset included
        px, py = x - a_c - a[1] * math.cos(t1), y - a[1] * math.sin(t1)
        c, s = math.cos(t1), math.sin(t1)
        for h2, t3 in _elbows(c * px + s * py, -s * px + c * py, a[2], a[3]):  # in the first link's frame
            t4 = _suj_wrap(psi - t1 - h2 - t3 - off[3])
            out.append((column, _suj_wrap(t1 - off[0]), _suj_wrap(h2 - off[1]), _suj_wrap(t3 - off[2]), t4))
    return out


def si_ik(suj, pose: np.ndarray, tolerance_rad: float = 1e-9, steps: int = SI_REDUNDANT_STEPS) -> SujAnswer:
    """(S3) Every Si SUJ solution (PSM1, PSM2, ECM: a column and three planar joints) that puts the base at
    ``pose``; refused when its orientation is off the reachable family by more than ``tolerance_rad``. The Si
    PSM3 (four planar joints, redundant: S7): its solutions on a grid of ``steps`` values of its first planar
    joint, the best (the largest least range margin) first."""
    if len(suj.links) not in (4, 5):
        raise ValueError(f"{suj.cart} {suj.arm}: {len(suj.links) - 1} planar joints; si_ik solves three or four")
    t = _to_suj(suj, pose)
    g = np.eye(4)
    for row in suj.fixed:
        g = g @ _suj_link(row, 0.0)
    h = t @ np.linalg.inv(g)  # must be Trans(x, y, z) Rz(psi)
    off = math.degrees(math.atan2(math.hypot(h[0, 2], h[1, 2]), h[2, 2]))  # not acos: exact near 0 (1e-16, not 1e-8)
    if off > math.degrees(tolerance_rad):
        return SujAnswer((), (), f"{suj.cart} {suj.arm} SUJ: the Si sets only the base's yaw; this docking is "
                                 f"tilted {off:.2f} deg off the orientations it can give")
    psi = math.atan2(h[1, 0], h[0, 0])
    if len(suj.links) == 5:
        return _answer(suj, _redundant_planar_ik(suj, h[0, 3], h[1, 3], h[2, 3], psi, steps))
    return _answer(suj, _planar_ik(suj, h[0, 3], h[1, 3], h[2, 3], psi))


def _rz(a: np.ndarray) -> np.ndarray:
    """Rotations about z by each angle of ``a`` (..., 3, 3)."""
    c, s = np.cos(a), np.sin(a)
    z, o = np.zeros_like(a), np.ones_like(a)
    return np.stack([np.stack([c, -s, z], -1), np.stack([s, c, z], -1), np.stack([z, z, o], -1)], -2)


def ecm_classic_dock(suj, yaw_rad: tuple, pitch_rad: tuple, origins: np.ndarray, aims: np.ndarray,
                     psi_steps: int = ECM_GRID_STEPS[0], aim_steps: int = ECM_GRID_STEPS[1],
                     q4_steps: int = ECM_GRID_STEPS[2]):
    """(S4) The Classic ECM's setup joints for an endoscope base at each of ``origins`` (n, 3: the RCM, at its
    port, in the cart's world frame) whose own yaw and pitch (within ``yaw_rad``, ``pitch_rad``) aim its shaft
    along ``aims`` (n, 3, unit: port to the target's centre).

    The ECM's SUJ ends in two parallel joints about an axis alpha_4 = -0.7853 rad off the vertical, so its base's
    z axis is always tilted |alpha_4| from the vertical at the planar chain's heading psi, and turned about
    itself by sigma = theta4 + theta5: the base orientation is Rz(psi) Rx(alpha_4) Rz(sigma) R_tip. In the base
    frame the aim u = R^T d has u_z fixed by psi and its horizontal part turned by sigma, so the aim is a choice
    of the angle phi of that part: the shaft's pitch -asin(u_y) and yaw atan2(u_x, -u_z) must lie in their
    ranges. The base's origin adds Rz(psi) Rx(alpha_4) (Rz(theta4) (A_5, 0, 0) + Rz(sigma) p_tip) to the planar
    chain's end, whose two elbows and column follow (S2's planar inverse). Searched on a grid of psi
    (``psi_steps``), phi (``aim_steps``) and theta4 (``q4_steps``); returns per origin (least margin, or -inf where
    no grid point docks; SUJ joints (6,), ECM yaw and pitch (2,)) of the grid point with the largest least margin
    (rad; the column's in m) over the SUJ's ranges and the ECM's yaw and pitch ranges."""
    col, j1, j2, j3, j4, j5 = suj.links
    w = np.asarray(suj.world_to_suj, float)
    tip = np.asarray(suj.tip_to_tool, float)
    p_tip = tip[:3, 3]
    tip_angle = math.atan2(tip[1, 0], tip[0, 0])  # R_tip = Rz(tip_angle)
    a4 = j4.alpha_rad
    n = len(origins)
    o = (origins - w[:3, 3]) @ w[:3, :3]  # in the SUJ's base frame
    d = aims @ w[:3, :3]
    psi = np.linspace(-math.pi, math.pi, psi_steps, endpoint=False)
    # v = Rx(-a4) Rz(-psi) d: (n, P, 3)
    dz = np.einsum("pij,nj->npi", _rz(-psi), d)
    ca, sa = math.cos(a4), math.sin(a4)
    v = np.stack([dz[..., 0], ca * dz[..., 1] + sa * dz[..., 2], -sa * dz[..., 1] + ca * dz[..., 2]], -1)
    uz = v[..., 2]
    r = np.sqrt(np.maximum(0.0, 1.0 - uz * uz))
    # the aim's grid k * step, k = -F/2 .. F/2 - 1 (F even: each aim's twin pi - phi is on it, below)
    if aim_steps % 2:
        raise ValueError(f"aim_steps must be even, not {aim_steps}")
    phi = (2 * math.pi / aim_steps) * np.arange(-(aim_steps // 2), aim_steps - aim_steps // 2)
    cos_phi, sin_phi = np.cos(np.abs(phi)), np.copysign(np.sin(np.abs(phi)), phi)
    ux, uy = r[..., None] * cos_phi, r[..., None] * sin_phi  # (n, P, F)
    pitch = -np.arcsin(np.clip(uy, -1.0, 1.0))
    yaw = np.arctan2(ux, -uz[..., None])
    aim_margin = np.minimum.reduce([yaw - yaw_rad[0], yaw_rad[1] - yaw, pitch - pitch_rad[0], pitch_rad[1] - pitch])
    # the aim with the largest margin, and its twin pi - phi: with the yaw range symmetric the two tie exactly
    # (ux changes sign, uy does not), and which one lets the setup joints dock differs, so both are solved
    # (an argmax alone picked one of them by rounding: which ECM docks changed with the CPU and the batch size)
    first = aim_margin.argmax(axis=2)  # (n, P)
    half = aim_steps // 2
    twin = (half - (first - half) + half) % aim_steps  # pi - phi on the grid (k - half = j  ->  half - j)
    q4 = np.linspace(-math.pi, math.pi, q4_steps, endpoint=False)
    th4 = q4 + j4.theta_offset_rad
    rx = np.array([[1.0, 0.0, 0.0], [0.0, ca, -sa], [0.0, sa, ca]])
    a_c, l2, l3 = col.a_m, j2.a_m, j3.a_m
    best = np.full(n, -np.inf)
    joints = np.full((n, 6), np.nan)
    ecm = np.full((n, 2), np.nan)
    lim = suj.ranges
    for best_phi in (first, twin):
        aim = np.take_along_axis(aim_margin, best_phi[..., None], 2)[..., 0]
        # u_xy = Rz(-sigma - tip_angle) v_xy  ->  phi = angle(v_xy) - sigma - tip_angle
        sigma = np.arctan2(v[..., 1], v[..., 0]) - phi[best_phi] - tip_angle
        # the base's origin less the planar chain's end: Rz(psi) Rx(a4) (Rz(th4) (A5, 0, 0) + Rz(sigma) p_tip)
        inner = (np.stack([np.cos(th4), np.sin(th4), np.zeros_like(th4)], -1)[None, None] * j5.a_m
                 + np.einsum("npij,j->npi", _rz(sigma), p_tip)[:, :, None, :])  # (n, P, Q, 3)
        off = np.einsum("pij,npqj->npqi", _rz(psi), inner @ rx.T)
        end = o[:, None, None, :] - off  # the planar chain's end (n, P, Q, 3)
        x, y = end[..., 0] - a_c, end[..., 1]
        c2 = (x * x + y * y - l2 * l2 - l3 * l3) / (2 * l2 * l3)
        reach = np.abs(c2) <= 1.0
        c2 = np.clip(c2, -1.0, 1.0)
        column = end[..., 2] - col.d_m - j1.d_m - j2.d_m - j3.d_m
        for sign in (1.0, -1.0):
            s2 = sign * np.sqrt(1.0 - c2 * c2)
            t2 = np.arctan2(s2, c2)
            t1 = np.arctan2(y, x) - np.arctan2(l3 * s2, l2 + l3 * c2)
            qs = [column, t1 - j1.theta_offset_rad, t2 - j2.theta_offset_rad,
                  psi[None, :, None] - t1 - t2 - j3.theta_offset_rad, np.broadcast_to(q4, column.shape),
                  sigma[:, :, None] - th4 - j5.theta_offset_rad]
            qs = [qs[0]] + [np.remainder(q + math.pi, 2 * math.pi) - math.pi for q in qs[1:]]
            margin = np.minimum.reduce([np.minimum(q - lo, hi - q) for q, (lo, hi) in zip(qs, lim)])
            margin = np.where(reach, np.minimum(margin, aim[:, :, None]), -np.inf)
            flat = margin.reshape(n, -1)
            k = flat.argmax(axis=1)
            better = flat[np.arange(n), k] > best
            if better.any():
                ip, iq = np.unravel_index(k, margin.shape[1:])
                rows = np.flatnonzero(better)
                best[rows] = flat[rows, k[rows]]
                joints[rows] = np.stack([q[rows, ip[rows], iq[rows]] for q in qs], -1)
                f = best_phi[rows, ip[rows]]
                uxy = r[rows, ip[rows]]
                u = np.stack([uxy * cos_phi[f], uxy * sin_phi[f], uz[rows, ip[rows]]], -1)
                ecm[rows] = np.stack([np.arctan2(u[:, 0], -u[:, 2]), -np.arcsin(np.clip(u[:, 1], -1, 1))], -1)
    return best, joints, ecm


#: The yaws tried besides psi*: a grid of this step over a whole turn (rad).
YAW_STEP_RAD = math.radians(1.0)


class SiDocking(NamedTuple):
    """One way the Si docks an arm on a port: the planar chain's yaw ``yaw_rad`` (S5), the base frame there
    (4x4, cart world, its origin the port), the SUJ's best solution (``suj.SujSolution``), the arm's own yaw
    and pitch that point its shaft along the aim (rad), and the angle they absorb (rad)."""

    yaw_rad: float
    base: np.ndarray
    suj: SujSolution
    q1: float
    q2: float
    absorbed_rad: float


class SiAnswer(NamedTuple):
    """Every docking found (least absorbed angle first, then the SUJ's margin), and why there is none."""

    dockings: tuple
    reason: str


def si_docking(suj, port: np.ndarray, aim: np.ndarray, limits) -> SiAnswer:
    """Every Si docking of an arm on ``port`` (m, cart world) whose own yaw and pitch (``limits``: ``yaw_lo``,
    ``yaw_hi``, ``pitch_lo``, ``pitch_hi``, rad) point its shaft along ``aim``: psi* (S6) and a whole turn of
    yaws at ``YAW_STEP_RAD``, each where the SUJ solves within its ranges (S3). None: the reason (the SUJ
    reaches the port at no yaw; or where it does, the arm's yaw or pitch would leave its range, by how much)."""
    port = np.asarray(port, float)
    best_psi, _ = _least_absorbed(suj, aim)
    yaws = [best_psi] + [_suj_wrap(best_psi + k * YAW_STEP_RAD) for k in range(1, round(2 * math.pi / YAW_STEP_RAD))]
    found, reached, nearest = [], 0, (math.inf, "")
    for psi in yaws:
        base = np.eye(4)
        base[:3, :3], base[:3, 3] = _si_orientation(suj, psi), port
        answer = si_ik(suj, base)
        if not answer.within:
            continue
        reached += 1
        q1, q2, absorbed = _own_joints(base[:3, :3], aim)
        over = max(limits.yaw_lo - q1, q1 - limits.yaw_hi, limits.pitch_lo - q2, q2 - limits.pitch_hi)
        if over > 0:
            if over < nearest[0]:
                nearest = (over, f"yaw {math.degrees(q1):.1f} deg" if max(limits.yaw_lo - q1, q1 - limits.yaw_hi) == over
                           else f"pitch {math.degrees(q2):.1f} deg")
            continue
        found.append(SiDocking(psi, base, answer.within[0], q1, q2, absorbed))
    found.sort(key=lambda d: (round(d.absorbed_rad, 12), -d.suj.margin))
    if found:
        return SiAnswer(tuple(found), "")
    if not reached:
        return SiAnswer((), f"{suj.cart} {suj.arm} SUJ: reaches the port at no yaw of its planar chain (within its "
                            f"ranges)")
    return SiAnswer((), f"{suj.cart} {suj.arm}: at every yaw where its SUJ reaches the port ({reached} of "
                        f"{len(yaws)} tried) the arm's own joints cannot point the shaft along the aim (nearest: "
                        f"{nearest[1]}, {math.degrees(nearest[0]):.1f} deg past its range)")
