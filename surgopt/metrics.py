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


def workspace_compactness(area_cm2, perimeter_cm):
    """zeta = area / circumference (cm) of a common workspace (Li et al. eq. 33); 0 where there is none.

    Example: an annulus of radii 1 and 3 cm has area 8 pi and circumference 8 pi, zeta = 1 cm.
    """
    a = np.asarray(area_cm2, dtype=np.float64)
    p = np.asarray(perimeter_cm, dtype=np.float64)
    return np.where(p > 0, a / np.where(p > 0, p, 1.0), 0.0)


def raven_cost(zeta_cm, iso_sum, iso_min, alpha_rad, beta_rad):
    """Cost C = zeta * sum(Iso) * Iso_min / (alpha^3 + beta^3) (Li et al. eq. 43), to be maximised.

    Longer links (alpha, beta) cost more; the isotropy sum over the common workspace rewards dexterity.
    Example: zeta 2 cm, isotropy sum 100, Iso_min 0.5, alpha = beta = 1 rad -> 2 * 100 * 0.5 / 2 = 50.
    """
    return zeta_cm * iso_sum * iso_min / (np.asarray(alpha_rad) ** 3 + np.asarray(beta_rad) ** 3)
