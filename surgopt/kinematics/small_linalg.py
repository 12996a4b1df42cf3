"""Small fixed-size linear algebra for numba kernels.

numba's ``@`` and ``np.linalg`` call SciPy's BLAS/LAPACK (SciPy is not a
dependency), and BLAS is slower than plain loops at 3x3 to 6x6 anyway.
"""
from __future__ import annotations

import numpy as np

from surgopt.jit import EXACT, njit


@njit(**EXACT)
def mat_mul(A, B):
    """Matrix product of small matrices."""
    n, k = A.shape
    m = B.shape[1]
    out = np.zeros((n, m))
    for i in range(n):
        for j in range(m):
            acc = 0.0
            for r in range(k):
                acc += A[i, r] * B[r, j]
            out[i, j] = acc
    return out


@njit(**EXACT)
def mat_vec(A, v):
    """Matrix-vector product A v."""
    out = np.zeros(A.shape[0])
    for i in range(A.shape[0]):
        acc = 0.0
        for r in range(A.shape[1]):
            acc += A[i, r] * v[r]
        out[i] = acc
    return out


@njit(**EXACT)
def dot(a, b):
    """Inner product of two vectors."""
    acc = 0.0
    for i in range(a.shape[0]):
        acc += a[i] * b[i]
    return acc


@njit(inline="always", **EXACT)
def cross_components(ax, ay, az, bx, by, bz):
    """a x b from components (inlined: the caller's compile flags apply)."""
    return ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx


@njit(**EXACT)
def cross(a, b):
    """a x b of two 3-vectors (arrays)."""
    x, y, z = cross_components(a[0], a[1], a[2], b[0], b[1], b[2])
    return np.array([x, y, z])


@njit(**EXACT)
def solve_spd(A, b):
    """Solve A x = b for symmetric positive definite A (Cholesky, no pivoting needed)."""
    n = A.shape[0]
    L = np.zeros((n, n))
    for j in range(n):
        d = A[j, j]
        for k in range(j):
            d -= L[j, k] * L[j, k]
        L[j, j] = np.sqrt(d)
        for i in range(j + 1, n):
            acc = A[i, j]
            for k in range(j):
                acc -= L[i, k] * L[j, k]
            L[i, j] = acc / L[j, j]
    y = np.zeros(n)
    for i in range(n):
        acc = b[i]
        for k in range(i):
            acc -= L[i, k] * y[k]
        y[i] = acc / L[i, i]
    x = np.zeros(n)
    for i in range(n - 1, -1, -1):
        acc = y[i]
        for k in range(i + 1, n):
            acc -= L[k, i] * x[k]
        x[i] = acc / L[i, i]
    return x


@njit(**EXACT)
def rigid_inverse(T):
    """Inverse of a 4x4 homogeneous transform: [R^T, -R^T p]."""
    out = np.zeros((4, 4))
    for i in range(3):
        for j in range(3):
            out[i, j] = T[j, i]
        out[i, 3] = -(T[0, i] * T[0, 3] + T[1, i] * T[1, 3] + T[2, i] * T[2, 3])
    out[3, 3] = 1.0
    return out
