"""Kinematic performance measures shared by the studies (numpy, vectorised)."""
from __future__ import annotations

import numpy as np


def global_isotropy_index(sigma_min, sigma_max, feasible=True):
    """GII = min_X sigma_min(X) / max_X sigma_max(X) (Locke & Patel eq. 7; Stocco & Salcudean).

    ``sigma_min``/``sigma_max`` are the workspace extremes (already reduced
    over the workspace) of one or many designs; a design that is infeasible
    or whose largest singular value is zero gets 0, never NaN.
    Example: singular values {(1, 2), (0.5, 4)} over two points -> 0.5 / 4 = 0.125.
    """
    lo = np.asarray(sigma_min, dtype=np.float64)
    hi = np.asarray(sigma_max, dtype=np.float64)
    ok = np.asarray(feasible, dtype=bool) & (hi > 0) & np.isfinite(lo)
    return np.where(ok, lo / np.where(ok, hi, 1.0), 0.0)
