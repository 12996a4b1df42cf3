"""Kinematic performance measures shared by the studies (numpy, vectorised), and the RCM studies' per-pose
metrics in one registry (``POSE_METRICS``; numba-free, so a config can name them without loading a compiler).

The per-pose metrics (#24): what a candidate's rows measure at each pose
of its walk, reduced to the extremes over the workspace (sigma_min, sigma_max; the GII is their ratio, eq. 7).

- ``alternative`` (Locke & Patel eqs. 5-8): the RCM-constrained, speed-scaled map, computed inside the walk by
  the shared ``rcm_metric.constrained_extremes`` (its running bound can stop a candidate: culling). Singular
  values in m/s.
- ``standard`` (Sec. III-E): the standard Jacobian at the walk's IK solutions, task-scaled (rows divided by a
  linear m/s and an angular rad/s scale), evaluated after the walk (``serial_chain.metric_over_solutions``).
  Dimensionless.

A new metric is one entry here (its code, unit, column names and ``evaluator``, the kernel that evaluates it over
a walk's solutions), that kernel, its branch in ``serial_chain.metric_over_solutions`` (the one dispatch point;
tests/test_metrics.py holds every entry's branch to its evaluator) and its parameters in the config
(``RcmGridConfig.metric_params``). Kernels take the metric as its integer code and numba branches on it: a
kernel taking the evaluator itself as an argument misses numba's on-disk cache in every new process (the
argument's type carries the function's identity: measured, a three-line kernel recompiled in each of three
fresh processes), which for the walk would be its ~26 s compile per process and metric. Rows and schemas take
the names from here, so every column says its unit.
"""
from __future__ import annotations

from typing import NamedTuple

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


#: Kernel codes (module-level ints: numba reads them as constants).
METRIC_RCM = 0
METRIC_STANDARD = 1


class PoseMetric(NamedTuple):
    """One per-pose metric: its config name, kernel code, whether the walk computes it (else it is evaluated
    over the walk's solutions afterwards), the unit and column suffix of its singular values, and what they are."""

    name: str
    code: int
    in_walk: bool
    unit: str
    suffix: str
    meaning: str
    #: the jitted kernel that evaluates it over a walk's IK solutions, "module:function" (None: the walk's own)
    evaluator: str | None = None
    #: time per pose of a walk with this metric against the chain kernel's cost model for the RCM metric (the
    #: estimate's and the chunk size's scale by it). Measured on the PA10's default map, whose walk is cheaper
    #: than the model's average arm (benchmarks/bench_readme_estimates.py)
    relative_cost: float = 1.0

    @property
    def sigma_columns(self) -> tuple[str, str]:
        """The rows' (sigma_min, sigma_max) column names: unit-true."""
        return f"sigma_min{self.suffix}", f"sigma_max{self.suffix}"


POSE_METRICS = {
    "alternative": PoseMetric(
        "alternative", METRIC_RCM, True, "m/s", "_m_per_s",
        "singular values of the RCM-constrained, speed-scaled forward map (1 / those of Q^-1 J_r; eqs. 5-8)"),
    "standard": PoseMetric(
        "standard", METRIC_STANDARD, False, "1", "_task_scaled",
        "singular values of the standard Jacobian at the same IK poses, columns times the rated speeds, rows "
        "divided by the task scaling (Sec. III-E): dimensionless",
        evaluator="surgopt.kinematics.serial_chain:standard_over",
        relative_cost=5.0),  # a 6 x 6 Gram matrix's Jacobi eigenvalues at each pose, after the walk
}
