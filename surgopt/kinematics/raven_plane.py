"""Raven IV kernels: the common workspace of several arms on a reference plane (Sec. III, IV).

Kernels only (numba); lengths mm, angles rad. Inputs travel as ``PlaneGrid`` and ``DesignGrid``
named tuples; ``surgopt.kinematics.raven_workspace`` is the public driver.

One module of ~640 lines because ``evaluate_designs`` and the inline helpers it compiles into one
loop (node bounds, nested design levels, per-cell contours, the mirror-symmetry halving) are one
computation, read together; the shoulder-range test it calls lives in
``surgopt.kinematics.raven_shoulder``.
"""
from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from surgopt.jit import EXACT, VECTOR, njit
from surgopt.kinematics.raven_shoulder import shoulder_design, shoulder_fields, theta1_inside_row, theta1_margin


#: A node's level: how many of the nested Iso_min designs hold it, at most the number of Iso_min values
#: (a sweep parameter has at most 10,001 values, ``surgopt.studies.raven_sweep.config``; int16 holds 32,767).
LEVEL = np.int16


class PlaneGrid(NamedTuple):
    """The reference plane the common workspace is measured on (Sec. III-A)."""

    depth_mm: float  # below the ports
    step_mm: float  # node spacing
    d4_max_mm: float  # tool insertion limit: the reach of every arm


class DesignGrid(NamedTuple):
    """The (alpha, beta, Iso_min) designs evaluated for each geometry, with their cone-angle intervals.

    ``psi_lo_rad``, ``psi_hi_rad``, ``has_interval`` are (A, B, I): the angle psi between the shoulder
    axis and the tool axis that theta2's range, narrowed by Iso_min, allows (``cone_angle_intervals``
    in ``surgopt.kinematics.raven_workspace``); ``has_interval`` False where no theta2 qualifies.
    """

    alphas_rad: np.ndarray
    betas_rad: np.ndarray
    iso_mins: np.ndarray
    psi_lo_rad: np.ndarray
    psi_hi_rad: np.ndarray
    has_interval: np.ndarray


# ---------------------------------------------------------------------------
# common workspace on the reference plane (Sec. III, IV)
# ---------------------------------------------------------------------------


@njit(**VECTOR)
def arm_cone_geometry(xs, ys, depth, port, axis, cos_psi, dist):
    """Per grid node: cos of the angle psi between the shoulder axis and the direction to the node, and distance.

    Node (xs[i], ys[j], -depth); fills cos_psi[i*ny + j], dist[i*ny + j]. These
    are independent of alpha, beta and Iso_min, so one geometry serves 125
    designs. (cos psi, not psi: no acos, and cos is what eq. 22 and the
    isotropy need.)
    """
    ny = ys.shape[0]
    for i in range(xs.shape[0]):
        _arm_row(xs[i], ys, depth, port[0], port[1], port[2], axis[0], axis[1], axis[2],
                 cos_psi[i * ny:(i + 1) * ny], dist[i * ny:(i + 1) * ny])


@njit(inline="always", **EXACT)
def _iso_parts(cos_psi, sa, ca, sb, cb, k):
    """(D^2, S + sqrt(S^2 - 4 D^2)) of ``isotropy`` at the theta2 of cos psi (eq. 22): Iso = 2 D / (S + ...)."""
    c2 = min(1.0, max(-1.0, (cos_psi + ca * cb) * k))
    a = c2 * cb * sa + sb * ca
    c_sq = (1.0 - c2 * c2) * sa * sa  # (s2 sa)^2: no square root for s2
    S = a * a + sb * sb + c_sq
    D2 = sb * sb * c_sq
    return D2, S + math.sqrt(max(0.0, S * S - 4.0 * D2))


@njit(**VECTOR)
def node_isotropy(lo, hi, alpha, beta, out):
    """min(Iso at cos psi = lo[j], Iso at hi[j]) per node: the minimum over the arms (eq. 35).

    Iso is unimodal in theta2 (a single maximum for every alpha, beta; tested),
    hence in cos psi (eq. 22), so over the arms' cos psi values at a node it is
    smallest at the lowest or the highest. The smaller of the two is picked
    by comparing D1^2 M2^2 with D2^2 M1^2 (Iso = 2 D / M), so one node costs
    three square roots and one division.
    """
    sa, ca, sb, cb = math.sin(alpha), math.cos(alpha), math.sin(beta), math.cos(beta)
    k = 1.0 / (sa * sb)
    for j in range(out.shape[0]):
        d1, m1 = _iso_parts(lo[j], sa, ca, sb, cb, k)
        d2, m2 = _iso_parts(hi[j], sa, ca, sb, cb, k)
        first = d1 * m2 * m2 <= d2 * m1 * m1
        d = d1 if first else d2
        m = m1 if first else m2
        out[j] = 2.0 * math.sqrt(d) / (m + 1e-300)


@njit(inline="always", **EXACT)
def _cell_contour(v0, v1, v2, v3):
    """(length, area) in cell units of the zero contour and of {m > 0} inside one cell.

    Corner values v0 (0, 0), v1 (1, 0), v2 (1, 1), v3 (0, 1); the crossing on
    edge k (corner k to k + 1) is interpolated linearly, t_k = v_k / (v_k - v_k+1)
    from corner k. Around corner k the crossings lie dA_k = t_k along edge k
    and dB_k = 1 - t_k-1 along edge k - 1, so the inside part is a corner
    triangle (dA dB / 2), its complement, or a trapezoid (dB_k + dA_k+1) / 2;
    a saddle (diagonal corners inside) is resolved by the mean of the corners
    for the length, and its area is the square less the two outside corners.
    """
    i0, i1, i2, i3 = v0 > 0, v1 > 0, v2 > 0, v3 > 0
    n_in = i0 + i1 + i2 + i3
    if n_in == 0:
        return 0.0, 0.0
    if n_in == 4:
        return 0.0, 1.0
    t0 = v0 / (v0 - v1) if i0 != i1 else 0.0
    t1 = v1 / (v1 - v2) if i1 != i2 else 0.0
    t2 = v2 / (v2 - v3) if i2 != i3 else 0.0
    t3 = v3 / (v3 - v0) if i3 != i0 else 0.0
    # corner legs (dA_k, dB_k)
    a0, b0 = t0, 1.0 - t3
    a1, b1 = t1, 1.0 - t0
    a2, b2 = t2, 1.0 - t1
    a3, b3 = t3, 1.0 - t2
    if n_in == 1 or n_in == 3:
        odd = i0 if n_in == 1 else not i0  # the corner that differs from the other three
        if odd:
            a, b = a0, b0
        elif (i1 if n_in == 1 else not i1):
            a, b = a1, b1
        elif (i2 if n_in == 1 else not i2):
            a, b = a2, b2
        else:
            a, b = a3, b3
        tri = 0.5 * a * b
        return math.sqrt(a * a + b * b), (tri if n_in == 1 else 1.0 - tri)
    if i0 == i2:  # saddle
        centre = 0.25 * (v0 + v1 + v2 + v3)
        if (centre > 0) == i0:  # corners 1 and 3 cut off
            length = math.sqrt(a1 * a1 + b1 * b1) + math.sqrt(a3 * a3 + b3 * b3)
        else:
            length = math.sqrt(a0 * a0 + b0 * b0) + math.sqrt(a2 * a2 + b2 * b2)
        if i0:
            return length, 1.0 - 0.5 * (a1 * b1 + a3 * b3)
        return length, 1.0 - 0.5 * (a0 * b0 + a2 * b2)
    # two adjacent corners k, k + 1 inside: edge k is inside
    if i0 and i1:
        b, a = b0, a1
    elif i1 and i2:
        b, a = b1, a2
    elif i2 and i3:
        b, a = b2, a3
    else:
        b, a = b3, a0
    return math.sqrt(1.0 + (a - b) * (a - b)), 0.5 * (a + b)


@njit(**EXACT)
def marching_squares(m, nx, ny, step, i0=0, i1=-1, j0=0, j1=-1):
    """Length and enclosed area of the zero contour of a node field m (nx*ny, row i = x).

    Only cells with lower corner in [i0, i1) x [j0, j1) are visited (all when
    i1, j1 < 0): pass a box that holds every node with m > 0 plus one cell of
    margin. Area is the area of {m > 0} with the same interpolated boundary.
    See ``_cell_contour`` for one cell.
    """
    length = 0.0
    area = 0.0
    i1 = nx - 1 if i1 < 0 else min(i1, nx - 1)
    j1 = ny - 1 if j1 < 0 else min(j1, ny - 1)
    for i in range(max(0, i0), i1):
        for j in range(max(0, j0), j1):
            v0 = m[i * ny + j]            # (0, 0)
            v1 = m[(i + 1) * ny + j]      # (1, 0)
            v2 = m[(i + 1) * ny + j + 1]  # (1, 1)
            v3 = m[i * ny + j + 1]        # (0, 1)
            n_in = (v0 > 0) + (v1 > 0) + (v2 > 0) + (v3 > 0)
            if n_in == 0:
                continue
            if n_in == 4:
                area += 1.0
                continue
            dl, da = _cell_contour(v0, v1, v2, v3)
            length += dl
            area += da
    return length * step, area * step * step


@njit(inline="always", **EXACT)
def _node_margin(lo, hi, d_lo, d_hi, reach, k, c_lo, c_hi):
    """Membership margin of node k for the cone interval [c_lo, c_hi] of cos psi.

    min((lo - c_lo) d_lo, (c_hi - hi) d_hi, reach): the arms with the lowest
    and highest cos psi (at distances d_lo, d_hi), and the reach margin
    d4_max - dist. Positive inside the common workspace, zero on its boundary
    and smooth along it, which is all marching squares needs (about
    dist * sin(psi) * angle, mm-like near the boundary).
    """
    return min(reach[k], min((lo[k] - c_lo) * d_lo[k], (c_hi - hi[k]) * d_hi[k]))


@njit(**VECTOR)
def _arm_row(x, ys, depth, px, py, pz, ax, ay, az, c_row, r_row):
    """cos psi between the shoulder axis a and the direction to the nodes (x, ys[j], -depth) from port p,
    and their distance (one grid row of ``arm_cone_geometry``)."""
    for j in range(ys.shape[0]):
        vx, vy, vz = x - px, ys[j] - py, -depth - pz
        r = math.sqrt(vx * vx + vy * vy + vz * vz)
        c_row[j] = min(1.0, max(-1.0, (vx * ax + vy * ay + vz * az) / r))
        r_row[j] = r


@njit(**VECTOR)
def _bounds_init(c_row, r_row, d4_max, lo, hi, d_lo, d_hi, reach):
    for j in range(c_row.shape[0]):
        lo[j], hi[j], d_lo[j], d_hi[j], reach[j] = c_row[j], c_row[j], r_row[j], r_row[j], d4_max - r_row[j]


@njit(**VECTOR)
def _bounds_update(c_row, r_row, d4_max, lo, hi, d_lo, d_hi, reach):
    for j in range(c_row.shape[0]):
        c, r = c_row[j], r_row[j]
        d_lo[j] = r if c < lo[j] else d_lo[j]
        d_hi[j] = r if c > hi[j] else d_hi[j]
        lo[j] = min(lo[j], c)
        hi[j] = max(hi[j], c)
        reach[j] = min(reach[j], d4_max - r)


@njit(**VECTOR)
def _member_lo(lo, reach, member):
    for j in range(lo.shape[0]):
        member[j] = lo[j] if reach[j] >= 0.0 else -2.0  # Table I's insertion range is closed: d4 = d4_max is in


@njit(**EXACT)
def plane_node_bounds(xs, ys, depth, ports, axes, d4_max, buffer=None):
    """Per node of the plane grid: the arms' lowest and highest cos psi, those arms' distances, reach.

    Returns (lo, hi, d_lo, d_hi, reach, member), each (nx*ny,). A node lies
    in every arm's cone interval [c_lo, c_hi] of cos psi exactly when
    c_lo < lo and hi < c_hi, so these numbers decide membership for every
    (alpha, beta, Iso_min) design of the geometry; reach = min over arms of
    d4_max - dist; ``member`` is lo, or -2 (never inside) where some arm
    cannot reach the node. cos psi and dist as in ``arm_cone_geometry``. ``buffer``: at least 6 nx ny
    floats to hold them instead of allocating (fresh memory costs page faults on every geometry).
    """
    nx, ny = xs.shape[0], ys.shape[0]
    n = nx * ny
    if buffer is None:
        buffer = np.empty(6 * n)
    lo, hi, d_lo, d_hi = buffer[:n], buffer[n:2 * n], buffer[2 * n:3 * n], buffer[3 * n:4 * n]
    reach, member = buffer[4 * n:5 * n], buffer[5 * n:6 * n]
    c_row = np.empty(ny)
    r_row = np.empty(ny)
    for a in range(ports.shape[0]):
        px, py, pz = ports[a, 0], ports[a, 1], ports[a, 2]
        ax, ay, az = axes[a, 0], axes[a, 1], axes[a, 2]
        for i in range(nx):
            s, e = i * ny, (i + 1) * ny
            _arm_row(xs[i], ys, depth, px, py, pz, ax, ay, az, c_row, r_row)
            if a == 0:
                _bounds_init(c_row, r_row, d4_max, lo[s:e], hi[s:e], d_lo[s:e], d_hi[s:e], reach[s:e])
            else:
                _bounds_update(c_row, r_row, d4_max, lo[s:e], hi[s:e], d_lo[s:e], d_hi[s:e], reach[s:e])
    _member_lo(lo, reach, member)
    return lo, hi, d_lo, d_hi, reach, member


@njit(**EXACT)
def plane_grid(ports, depth, d4_max, step):
    """Node coordinates (xs, ys) covering every point all arms can reach (|X - port| <= d4_max), 2 nodes of margin."""
    reach = math.sqrt(d4_max * d4_max - depth * depth)
    lo_x, lo_y = -np.inf, -np.inf
    hi_x, hi_y = np.inf, np.inf
    for a in range(ports.shape[0]):
        lo_x, lo_y = max(lo_x, ports[a, 0] - reach), max(lo_y, ports[a, 1] - reach)
        hi_x, hi_y = min(hi_x, ports[a, 0] + reach), min(hi_y, ports[a, 1] + reach)
    if hi_x <= lo_x or hi_y <= lo_y:
        return np.zeros(0), np.zeros(0)
    return _grid_axis(lo_x, hi_x, step), _grid_axis(lo_y, hi_y, step)


@njit(**EXACT)
def covering_plane_grid(ports, depth, d4_max, step):
    """Node coordinates (xs, ys) covering every point some arm can reach, 2 nodes of margin (figures)."""
    reach = math.sqrt(d4_max * d4_max - depth * depth)
    lo_x, lo_y = np.inf, np.inf
    hi_x, hi_y = -np.inf, -np.inf
    for a in range(ports.shape[0]):
        lo_x, lo_y = min(lo_x, ports[a, 0] - reach), min(lo_y, ports[a, 1] - reach)
        hi_x, hi_y = max(hi_x, ports[a, 0] + reach), max(hi_y, ports[a, 1] + reach)
    return _grid_axis(lo_x, hi_x, step), _grid_axis(lo_y, hi_y, step)


@njit(inline="always", **EXACT)
def _grid_axis(lo, hi, step):
    """Multiples of step from 2 below floor(lo / step) to 2 above ceil(hi / step)."""
    return np.arange(math.floor(lo / step) - 2, math.ceil(hi / step) + 3) * step


@njit(**VECTOR)
def node_margins(bounds, c_lo, c_hi, out):
    """``_node_margin`` of every node for the cone interval [c_lo, c_hi] of cos psi (figures)."""
    lo, hi, d_lo, d_hi, reach, _ = bounds
    for k in range(out.shape[0]):
        out[k] = _node_margin(lo, hi, d_lo, d_hi, reach, k, c_lo, c_hi)


@njit(**VECTOR)
def _row_extent(lo, hi, c_lo, c_hi):
    """First and last index j with c_lo < lo[j] and hi[j] < c_hi; (n, -1) if none (vectorisable)."""
    n = lo.shape[0]
    first, last = n, -1
    for j in range(n):
        inside = (lo[j] > c_lo) & (hi[j] < c_hi)
        first = min(first, j if inside else n)
        last = max(last, j if inside else -1)
    return first, last


@njit(**EXACT)
def _bounding_box(lo, hi, c_lo, c_hi, nx, ny):
    """Node index box (i0, i1, j0, j1) of {c_lo < lo, hi < c_hi}; i1 < i0 when empty."""
    b0, b1, c0, c1 = nx, -1, ny, -1
    for i in range(nx):
        first, last = _row_extent(lo[i * ny:(i + 1) * ny], hi[i * ny:(i + 1) * ny], c_lo, c_hi)
        if last >= 0:
            b0, b1 = min(b0, i), i
            c0, c1 = min(c0, first), max(c1, last)
    return b0, b1, c0, c1


@njit(**VECTOR)
def _row_levels(lo, hi, c_los, c_his, n_lev, level):
    """level[j] = how many of the nested intervals (c_los[m], c_his[m]) hold the node with lo[j], hi[j]."""
    for j in range(level.shape[0]):
        level[j] = 0
    for m in range(n_lev):
        c_lo, c_hi = c_los[m], c_his[m]
        for j in range(level.shape[0]):
            level[j] += (lo[j] > c_lo) & (hi[j] < c_hi)


@njit(**VECTOR)
def _row_cell_levels(row0, row1, lmin, lmax):
    """Lowest and highest corner level of the cells between node rows row0 and row1 (len(lmin) cells);
    returns how many cells have lmin != lmax (boundary cells)."""
    n_edge = 0
    for j in range(lmin.shape[0]):
        a, b, c, d = row0[j], row1[j], row1[j + 1], row0[j + 1]
        lo = min(min(a, b), min(c, d))
        hi = max(max(a, b), max(c, d))
        lmin[j] = lo
        lmax[j] = hi
        n_edge += lo != hi
    return n_edge


@njit(**VECTOR)
def _count_above(lmin, m):
    """Number of entries > m (vectorisable)."""
    n = 0
    for j in range(lmin.shape[0]):
        n += lmin[j] > m
    return n


@njit(**VECTOR)
def _theta1_levels(inside, level):
    """level[j] = 0 where theta1's test ``inside[j]`` (``theta1_inside_row``) is not positive."""
    for j in range(level.shape[0]):
        level[j] = level[j] if inside[j] > 0.0 else 0


@njit(**VECTOR)
def _positive_extent(level):
    """First and last index j with level[j] > 0; (n, -1) if none (vectorisable)."""
    n = level.shape[0]
    first, last = n, -1
    for j in range(n):
        inside = level[j] > 0
        first = min(first, j if inside else n)
        last = max(last, j if inside else -1)
    return first, last


@njit(inline="always", **EXACT)
def _theta1_margin_once(shoulder, d, k, pair, t1m, stamp):
    """``theta1_margin`` at node k for design pair ``pair``, computed once per pair (stamp[k] == pair)."""
    if stamp[k] != pair:
        t1m[k] = theta1_margin(shoulder, k, d)
        stamp[k] = pair
    return t1m[k]


@njit(**EXACT)
def evaluate_designs(bounds, nx, ny, step, designs, shoulder, shoulder_rng, out, scratch=None, pair_base=0,
                     mirrored=False):
    """All (alpha, beta, Iso_min) designs of one geometry (ports and shoulder axes fixed).

    ``bounds``: ``plane_node_bounds`` of the geometry's plane grid; ``designs``:
    a ``DesignGrid`` (the designs and the cone-angle interval of each). A node is in
    the common workspace when for every arm psi_lo < psi < psi_hi and
    dist <= d4_max (Table I's closed insertion range), and, when ``shoulder_rng.limited``, theta1 inside its range
    (``surgopt.kinematics.raven_shoulder``; ``shoulder`` its ``ShoulderFields``);
    marching squares runs on the margin of ``_node_margin`` (zero on the boundary),
    the smaller of it and the theta1 margin when theta1 is limited. A node's isotropy is the minimum
    over the arms (``node_isotropy``). ``out`` (A*B*I, 6): area_mm2, perimeter_mm, n_points,
    iso_sum, iso_min_actual, 1 if any point. ``scratch``: (levels, stamps, margins) of at least nx ny
    each to reuse across geometries, stamps never above ``pair_base`` (the stamps of (alpha, beta) pairs
    here are pair_base + pair), or None to allocate. ``mirrored``: the grid is the half x >= 0 of one
    whose common workspace is symmetric in x = 0 (``mirror_symmetric``), row 0 the nodes on x = 0:
    every other node and every cell then stands for itself and its mirror image, and counts twice.

    Work sharing. Per geometry: each node's lowest and highest cos psi over
    the arms decide its membership for every design (``plane_node_bounds``). Per
    (alpha, beta): a stricter Iso_min only narrows the cone interval, so the
    Iso_mins are nested; one pass over the loosest design's box gives each
    node a level (how many of the nested designs contain it), and the
    counts, isotropy sums and minima of all Iso_mins at once. One pass over
    the box's cells then counts, per level, the cells inside (their area is
    one cell) and sends only boundary cells to the contour routine, with the
    margin of each design whose boundary crosses them.
    """
    lo, hi, d_lo, d_hi, reach, member = bounds
    alphas, betas, iso_mins = designs.alphas_rad, designs.betas_rad, designs.iso_mins
    psi_lo, psi_hi, has_interval = designs.psi_lo_rad, designs.psi_hi_rad, designs.has_interval
    n_iso = iso_mins.shape[0]
    order = np.argsort(iso_mins)
    if scratch is None:
        scratch = (np.empty(nx * ny, LEVEL), np.full(nx * ny, -1, np.int64), np.empty(nx * ny))
    level = scratch[0][:nx * ny]  # every node of a design's box is set before it is read
    iso_node = np.empty(ny)
    t1_row = np.empty(ny)
    lmin = np.empty(ny, LEVEL)
    lmax = np.empty(ny, LEVEL)
    c_los = np.empty(n_iso)
    c_his = np.empty(n_iso)
    cnt = np.zeros(n_iso + 1, np.int64)
    tot = np.zeros(n_iso + 1)
    mn = np.ones(n_iso + 1)
    full = np.zeros(n_iso + 1, np.int64)
    length = np.zeros(n_iso + 1)
    part = np.zeros(n_iso + 1)
    limited = shoulder_rng.limited
    cells = 2.0 if mirrored else 1.0  # each cell and its mirror image
    t1m = scratch[2][:nx * ny]  # theta1 margins of the nodes, per (alpha, beta) ...
    stamp = scratch[1][:nx * ny]  # ... of the pair stamped here
    for ia in range(alphas.shape[0]):
        for ib in range(betas.shape[0]):
            base = (ia * betas.shape[0] + ib) * n_iso
            for k in range(n_iso):
                out[base + k, :] = 0.0
            # the nested designs, loosest first, while theta2 still qualifies
            n_lev = 0
            for k in order:
                if not has_interval[ia, ib, k]:
                    break
                c_los[n_lev], c_his[n_lev] = math.cos(psi_hi[ia, ib, k]), math.cos(psi_lo[ia, ib, k])
                if n_lev > 0:  # nested by construction; keep them so through the bisection's rounding
                    c_los[n_lev] = max(c_los[n_lev], c_los[n_lev - 1])
                    c_his[n_lev] = min(c_his[n_lev], c_his[n_lev - 1])
                n_lev += 1
            if n_lev == 0:
                continue
            pair = pair_base + ia * betas.shape[0] + ib
            t1d = shoulder_design(alphas[ia], betas[ib], shoulder_rng)
            b0, b1, d0, d1 = _bounding_box(member, hi, c_los[0], c_his[0], nx, ny)
            if b1 < b0:
                continue
            i0, i1, j0, j1 = max(0, b0 - 1), min(nx - 1, b1 + 1), max(0, d0 - 1), min(ny - 1, d1 + 1)
            w = j1 - j0 + 1
            cnt[:] = 0
            tot[:] = 0.0
            mn[:] = 1.0
            full[:] = 0
            length[:] = 0.0
            part[:] = 0.0
            # nodes: level, isotropy (min over arms) of the inside ones, per-level sums
            tb0, tb1, tc0, tc1 = nx, -1, w, -1  # with theta1 limited: the box of the nodes it leaves inside
            for i in range(i0, i1 + 1):
                s = i * ny + j0
                _row_levels(member[s:s + w], hi[s:s + w], c_los, c_his, n_lev, level[s:s + w])
                f, e = _row_extent(member[s:s + w], hi[s:s + w], c_los[0], c_his[0])
                if e < f:
                    continue
                if limited:  # theta1 depends on (alpha, beta) and the node, not on Iso_min: every level at once
                    theta1_inside_row(shoulder, s + f, s + e + 1, t1d, t1_row)
                    _theta1_levels(t1_row[:e + 1 - f], level[s + f:s + e + 1])
                    f2, e2 = _positive_extent(level[s + f:s + e + 1])
                    if e2 < f2:
                        continue
                    f, e = f + f2, f + e2
                    tb0, tb1, tc0, tc1 = min(tb0, i), i, min(tc0, f), max(tc1, e)
                node_isotropy(lo[s + f:s + e + 1], hi[s + f:s + e + 1], alphas[ia], betas[ib], iso_node[:e + 1 - f])
                twice = mirrored and i > 0  # the node and its mirror image
                for j in range(f, e + 1):
                    lev = level[s + j]
                    if lev > 0:
                        v = iso_node[j - f]
                        cnt[lev] += 2 if twice else 1
                        mn[lev] = min(mn[lev], v)
                        v = v + v if twice else v
                        for m in range(lev):  # per design, in node order: the sum a design gets alone
                            tot[m] += v
            # cells: inside ones per level, boundary ones through the contour routine; with theta1 limited
            # only those touching a node it leaves inside (the others have every corner at level 0)
            ci0, ci1, cj, cw = i0, i1, j0, w
            if limited:
                if tb1 < 0:
                    continue
                ci0, ci1 = max(i0, tb0 - 1), min(i1, tb1 + 1)
                cj, cw = j0 + max(0, tc0 - 1), min(w - 1, tc1 + 1) - max(0, tc0 - 1) + 1
            for i in range(ci0, ci1):
                s = i * ny + cj
                n_edge = _row_cell_levels(level[s:s + cw], level[s + ny:s + ny + cw], lmin[:cw - 1], lmax[:cw - 1])
                for m in range(n_lev):
                    full[m + 1] += _count_above(lmin[:cw - 1], m)  # cells inside design m
                if n_edge == 0:
                    continue
                for j in range(cw - 1):
                    if lmin[j] == lmax[j]:
                        continue
                    k = s + j
                    t0 = t1 = t2 = t3 = np.inf  # theta1 margins of the corners (inf: unlimited)
                    if limited:
                        t0 = _theta1_margin_once(shoulder, t1d, k, pair, t1m, stamp)
                        t1 = _theta1_margin_once(shoulder, t1d, k + ny, pair, t1m, stamp)
                        t2 = _theta1_margin_once(shoulder, t1d, k + ny + 1, pair, t1m, stamp)
                        t3 = _theta1_margin_once(shoulder, t1d, k + 1, pair, t1m, stamp)
                    for m in range(lmin[j], lmax[j]):  # designs m (0-based) whose boundary crosses the cell
                        c_lo, c_hi = c_los[m], c_his[m]
                        dl, da = _cell_contour(min(t0, _node_margin(lo, hi, d_lo, d_hi, reach, k, c_lo, c_hi)),
                                               min(t1, _node_margin(lo, hi, d_lo, d_hi, reach, k + ny, c_lo, c_hi)),
                                               min(t2, _node_margin(lo, hi, d_lo, d_hi, reach, k + ny + 1, c_lo, c_hi)),
                                               min(t3, _node_margin(lo, hi, d_lo, d_hi, reach, k + 1, c_lo, c_hi)))
                        length[m] += dl
                        part[m] += da
            # design m contains the nodes of level > m (full[m + 1] already counts its inside cells)
            n_pts, iso_low = 0, 1.0
            for m in range(n_lev - 1, -1, -1):
                n_pts += cnt[m + 1]
                iso_low = min(iso_low, mn[m + 1])
                n_full = full[m + 1]
                if n_pts == 0:
                    continue
                row = base + order[m]
                out[row, 0] = (n_full + part[m]) * cells * step * step
                out[row, 1] = length[m] * cells * step
                out[row, 2] = n_pts
                out[row, 3] = tot[m]
                out[row, 4] = iso_low
                out[row, 5] = 1.0


@njit(**EXACT)
def mirror_symmetric(ports, axes, zero_axes, left, limited):
    """Whether the arms, as a set, are their own mirror image in the plane x = 0: every arm's mirror
    (port, shoulder axis and, when theta1 is ``limited``, its zero direction with x negated, and the other
    side) is one of the arms, every number equal. Then every quantity of a node at (x, y) equals the
    one at (-x, y), to the last bit (the mirrored arm's products are the same products), and the common
    workspace is symmetric: the four-arm and two-arm layouts with the left arms mirroring the right
    ones (``mirror_left_phi``, ``mirror_plane = "yz"``), whatever phi, tilt and theta1 range."""
    n = ports.shape[0]
    for a in range(n):
        found = False
        for b in range(n):
            same = (ports[b, 0] == -ports[a, 0] and ports[b, 1] == ports[a, 1] and ports[b, 2] == ports[a, 2]
                    and axes[b, 0] == -axes[a, 0] and axes[b, 1] == axes[a, 1] and axes[b, 2] == axes[a, 2])
            if same and limited:
                same = (left[b] != left[a] and zero_axes[b, 0] == -zero_axes[a, 0]
                        and zero_axes[b, 1] == zero_axes[a, 1] and zero_axes[b, 2] == zero_axes[a, 2])
            if same:
                found = True
                break
        if not found:
            return False
    return True


@njit(inline="always", **EXACT)
def _mirror_row(xs):
    """The index of x = 0 in a grid axis symmetric about it (xs[k] = -xs[-1 - k] for every k), or -1."""
    n = xs.shape[0]
    if n % 2 == 0 or xs[n // 2] != 0.0:
        return -1
    for k in range(n // 2):
        if xs[k] != -xs[n - 1 - k]:
            return -1
    return n // 2


@njit(**EXACT)
def evaluate_geometries(ports, axes, zero_axes, left, plane, designs, shoulder_rng, out):
    """``evaluate_designs`` for G geometries: ``ports``, ``axes`` (G, arms, 3) mm and unit vectors,
    ``zero_axes`` the shoulder's zero directions x0 (G, arms, 3), ``left`` (arms,) True for mirrored arms,
    ``plane`` a ``PlaneGrid``, ``designs`` a ``DesignGrid``, ``shoulder_rng`` a ``ShoulderRange``;
    ``out`` (G*A*B*I, 6).

    The loop over geometries runs here, without the interpreter (and the GIL).
    """
    depth, step, d4_max = plane.depth_mm, plane.step_mm, plane.d4_max_mm
    per = designs.alphas_rad.shape[0] * designs.betas_rad.shape[0] * designs.iso_mins.shape[0]
    # memory reused from geometry to geometry, grown to the largest plane grid: fresh megabytes would
    # cost page faults on every geometry (with theta1 limited, half its time)
    buffer, bounds_buffer = np.empty(0), np.empty(0)
    scratch = (np.empty(0, LEVEL), np.empty(0, np.int64), np.empty(0))
    pairs = designs.alphas_rad.shape[0] * designs.betas_rad.shape[0]
    for g in range(ports.shape[0]):
        block = out[g * per:(g + 1) * per]
        block[:, :] = 0.0
        xs, ys = plane_grid(ports[g], depth, d4_max, step)
        if xs.shape[0] == 0:
            continue
        half = _mirror_row(xs) if mirror_symmetric(ports[g], axes[g], zero_axes[g], left, shoulder_rng.limited) else -1
        if half >= 0:  # the half x >= 0, x = 0 its row 0
            xs = xs[half:]
        n = xs.shape[0] * ys.shape[0]
        if bounds_buffer.shape[0] < 6 * n:
            bounds_buffer = np.empty(6 * n)
            scratch = (np.empty(n, LEVEL), np.full(n, -1, np.int64), np.empty(n))
        bounds = plane_node_bounds(xs, ys, depth, ports[g], axes[g], d4_max, bounds_buffer)
        if shoulder_rng.limited and buffer.shape[0] < 3 * ports.shape[1] * n:
            buffer = np.empty(3 * ports.shape[1] * n)
        if shoulder_rng.limited:
            shoulder = shoulder_fields(xs, ys, depth, ports[g], axes[g], zero_axes[g], left, buffer)
        else:
            shoulder = shoulder_fields(xs[:0], ys[:0], depth, ports[g], axes[g], zero_axes[g], left, buffer)
        evaluate_designs(bounds, xs.shape[0], ys.shape[0], step, designs, shoulder, shoulder_rng, block, scratch,
                         g * pairs, half >= 0)
