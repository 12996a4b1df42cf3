"""The RCM metric shared by every RCM kernel: extreme singular values of the constrained, speed-scaled map.

Given the five columns of A = J_a Q at one pose (J_a: three tip rows and two rows of the RCM error,
Locke & Patel eq. 8; Q: rated joint speeds), ``constrained_extremes`` returns the squared extreme
singular values of B = A_x N, N an orthonormal basis of the null space of the two constraint rows:
the reciprocals of those of Q^-1 J_r (eqs. 5-6). Only that null space enters, so any invertible
combination of the constraint rows gives the same B. The closed-form PA10 kernel
(``pa10_rcm``) and the generic serial-chain kernel (``serial_chain``) both call it: one
implementation of the metric. Everything here is trigonometry-free and branch-free, so that the
PA10 kernel's per-pose loop vectorises. ``probe_points`` (which workspace points to try first) is
shared too.
"""
from __future__ import annotations

import numpy as np
from numpy.polynomial import chebyshev as _chebyshev

from surgopt.jit import CONTRACT, njit

#: J_a counts as singular when a constraint row or sigma_min of B falls below this fraction of sigma_max.
SINGULAR_RTOL = 1e-12
#: Guards against 0/0 in branch-free normalisations.
TINY = 1e-300

STATUS_OK = 0
STATUS_UNREACHABLE = 1  # out of reach or outside a joint limit
STATUS_SINGULAR = 2  # J_a rank deficient (eq. 5 text): GII contribution 0



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
#: The same polynomial in monomial form (Horner is a third of Clenshaw's work;
#: coefficients fall ~3.5x per degree, so the conversion loses nothing: tested).
TRISECT_POLY = tuple(float(v) for v in _chebyshev.cheb2poly(np.array(TRISECT_CHEB)))


@njit(inline="always", **CONTRACT)
def cos_third_acos(x):
    """cos(acos(x) / 3) for x in [-1, 1] without trigonometric calls (vectorisable)."""
    s = np.sqrt(0.5 * (1.0 + x))
    t = 2.0 * s - 1.0
    # Horner in t (monomial coefficients of the same series): 16 fused multiply-adds
    c = TRISECT_POLY
    h = c[16]
    h = h * t + c[15]
    h = h * t + c[14]
    h = h * t + c[13]
    h = h * t + c[12]
    h = h * t + c[11]
    h = h * t + c[10]
    h = h * t + c[9]
    h = h * t + c[8]
    h = h * t + c[7]
    h = h * t + c[6]
    h = h * t + c[5]
    h = h * t + c[4]
    h = h * t + c[3]
    h = h * t + c[2]
    h = h * t + c[1]
    return h * t + c[0]


@njit(inline="always", **CONTRACT)
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


@njit(inline="always", **CONTRACT)
def gram_lambda_max(b00, b01, b02, b10, b11, b12, b20, b21, b22):
    """Largest eigenvalue of B^T B, i.e. sigma_max(B)^2, for a 3x3 B."""
    return sym3_lambda_max(b00 * b00 + b10 * b10 + b20 * b20,
                           b01 * b01 + b11 * b11 + b21 * b21,
                           b02 * b02 + b12 * b12 + b22 * b22,
                           b00 * b01 + b10 * b11 + b20 * b21,
                           b00 * b02 + b10 * b12 + b20 * b22,
                           b01 * b02 + b11 * b12 + b21 * b22)


@njit(inline="always", **CONTRACT)
def singular_values_3x3_sq(b00, b01, b02, b10, b11, b12, b20, b21, b22):
    """Squared extreme singular values (sigma_min^2, sigma_max^2) of a 3x3 B, closed form.

    sigma_max^2 = lambda_max(B^T B). sigma_min = |det B| / sigma_max(cof B),
    since the cofactor matrix has singular values sigma_i sigma_j and its
    largest is sigma_1 sigma_2. Cofactors and the determinant are formed
    from B itself, so sigma_min keeps a relative accuracy ~eps * cond(B)
    (the Gram route B^T B alone would give eps * cond(B)^2). Squares, so
    that a caller reducing over many poses takes the roots once.
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
    return det * det / (cmax2 + TINY), smax2


@njit(inline="always", **CONTRACT)
def singular_values_3x3(b00, b01, b02, b10, b11, b12, b20, b21, b22):
    """Extreme singular values (sigma_min, sigma_max) of a 3x3 matrix B, closed form.

    See ``singular_values_3x3_sq``: no iteration (the Jacobi SVD this
    replaced spent 70% of the kernel's time).
    """
    smin2, smax2 = singular_values_3x3_sq(b00, b01, b02, b10, b11, b12, b20, b21, b22)
    return np.sqrt(smin2), np.sqrt(smax2)


@njit(inline="always", **CONTRACT)
def _dot5(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2] + a[3] * b[3] + a[4] * b[4]


@njit(inline="always", **CONTRACT)
def _reflect5(row, v, two_over_vv):
    """Householder reflection (I - 2 v v^T / v^T v) applied to a row 5-tuple."""
    f = two_over_vv * _dot5(row, v)
    return (row[0] - f * v[0], row[1] - f * v[1], row[2] - f * v[2],
            row[3] - f * v[3], row[4] - f * v[4])


@njit(inline="always", **CONTRACT)
def constrained_extremes(c0, c1, c2, c3, c4):
    """Squared extreme singular values of B = A_x N from the five columns of A.

    Two Householder reflections, applied from the right, map the constraint
    rows A[3], A[4] onto the first two coordinates; what remains of the tip
    rows in the last three coordinates is B (eqs. 5-6 without forming J_a^-1).
    Only the null space of the constraint rows matters, so any invertible
    combination of them gives the same B. Returns (sigma_min^2, sigma_max^2,
    singular); sigma_min^2 is 0 when J_a is rank deficient, i.e. a constraint
    row or sigma_min falls below ``SINGULAR_RTOL`` times sigma_max.
    """
    r0 = (c0[0], c1[0], c2[0], c3[0], c4[0])
    r1 = (c0[1], c1[1], c2[1], c3[1], c4[1])
    r2 = (c0[2], c1[2], c2[2], c3[2], c4[2])
    r3 = (c0[3], c1[3], c2[3], c3[3], c4[3])
    r4 = (c0[4], c1[4], c2[4], c3[4], c4[4])
    # reflection 1: row 3 -> (-+|r3|, 0, 0, 0, 0); v.v = 2 |r3| (|r3| + |r3_0|)
    n3 = np.sqrt(_dot5(r3, r3))
    v = (r3[0] + (n3 if r3[0] >= 0.0 else -n3), r3[1], r3[2], r3[3], r3[4])
    vv = 1.0 / (n3 * (n3 + abs(r3[0])) + TINY)
    r0 = _reflect5(r0, v, vv)
    r1 = _reflect5(r1, v, vv)
    r2 = _reflect5(r2, v, vv)
    r4 = _reflect5(r4, v, vv)
    # reflection 2: row 4 (coordinates 1..4) -> (*, -+|.|, 0, 0, 0)
    n4 = np.sqrt(r4[1] * r4[1] + r4[2] * r4[2] + r4[3] * r4[3] + r4[4] * r4[4])
    v = (0.0, r4[1] + (n4 if r4[1] >= 0.0 else -n4), r4[2], r4[3], r4[4])
    vv = 1.0 / (n4 * (n4 + abs(r4[1])) + TINY)
    r0 = _reflect5(r0, v, vv)
    r1 = _reflect5(r1, v, vv)
    r2 = _reflect5(r2, v, vv)
    smin2, smax2 = singular_values_3x3_sq(r0[2], r0[3], r0[4], r1[2], r1[3], r1[4],
                                          r2[2], r2[3], r2[4])
    tol2 = SINGULAR_RTOL * SINGULAR_RTOL * smax2
    singular = (n3 * n3 <= tol2) or (n4 * n4 <= tol2) or (smin2 <= tol2)
    return (0.0 if singular else smin2), smax2, singular


#: The 8 corner and 6 face directions along which ``probe_points`` looks for the workspace's extremes.
PROBE_DIRECTIONS = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]
                            + [[s if i == a else 0 for i in range(3)] for a in range(3) for s in (-1, 1)], float)


@njit(**CONTRACT)
def workspace_centre(offsets):
    """The mean of the workspace points (P, 3) (a plain loop: numpy's axis-0 mean of a narrow array
    costs ~60 us here, more than a short kernel call)."""
    c = np.zeros(3)
    for j in range(offsets.shape[0]):
        for i in range(3):
            c[i] += offsets[j, i]
    return c / offsets.shape[0]


@njit(**CONTRACT)
def _farthest_along(offsets, centre, directions):
    """For each direction d, the first point maximising (p - centre) . d."""
    m = directions.shape[0]
    out = np.zeros(m, np.int64)
    best = np.full(m, -np.inf)
    for j in range(offsets.shape[0]):
        x, y, z = offsets[j, 0] - centre[0], offsets[j, 1] - centre[1], offsets[j, 2] - centre[2]
        for k in range(m):
            v = x * directions[k, 0] + y * directions[k, 1] + z * directions[k, 2]
            if v > best[k]:
                best[k] = v
                out[k] = j
    return out


def probe_points(offsets, centre=None):
    """Indices of the 8 corner-most and 6 face-most points: where a workspace is left first (sorted,
    each once). ``centre``: the points' mean (``workspace_centre``), when the caller has it."""
    offsets = np.ascontiguousarray(offsets, dtype=np.float64).reshape(-1, 3)
    centre = workspace_centre(offsets) if centre is None else np.asarray(centre, np.float64)
    return np.array(sorted(set(_farthest_along(offsets, centre, PROBE_DIRECTIONS).tolist())), np.int64)
