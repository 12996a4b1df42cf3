"""The walk driver for any serial arm, above the scalar walk (``serial_chain``) and the walk in SIMD lanes
(``serial_lanes``): it chooses between them and hands each its arrays. Neither walk module imports this one,
so the two walks import in one direction only (lanes -> chain)."""
from __future__ import annotations

import numpy as np

from surgopt.kinematics import serial_lanes as SL
from surgopt.metrics import POSE_METRICS, PoseMetric
from surgopt.kinematics.rcm_metric import probe_points, workspace_centre
from surgopt.kinematics.serial_chain import Chain, candidates_scalar, default_restarts, kernel_arrays


def chain_candidates_extremes(rcms, offsets, chain: Chain, seed, gii_to_beat=None, start=None, probe_first=True,
                              metric: PoseMetric = POSE_METRICS["alternative"], metric_params=(), lanes=None):
    """For each RCM candidate (M, 3): the walk over ``offsets`` (P, 3, in walk order, relative to the RCM).

    Returns (sigma_min (M,), sigma_max (M,), n_unreachable (M,), n_singular (M,), points_evaluated (M,)),
    the PA10 kernel's outputs (``pa10_rcm.rcm_candidates_extremes``); an unreachable candidate has
    sigma 0 and n_unreachable 1. ``gii_to_beat`` (M,) stops a candidate's walk once its running GII bound
    falls to it (Culling; the walk's own metric only); None evaluates every point. ``probe_first``: reach the
    corner and face points from the start first (IK only), so that most infeasible candidates are known before
    any walk. ``metric``: the per-pose metric (``metrics.POSE_METRICS``), ``metric_params`` its parameters (standard:
    linear m/s, angular rad/s, the tool-spin joint's rated speed or 0). ``lanes``: walk each candidate in SIMD
    lanes (``serial_lanes``: the same points, rules and answers to within Newton's tolerance, ~5x faster);
    None chooses them when the walk is long enough to pay.
    """
    rcms = np.ascontiguousarray(rcms, dtype=np.float64).reshape(-1, 3)
    offsets = np.ascontiguousarray(offsets, dtype=np.float64).reshape(-1, 3)
    seed = np.asarray(seed, np.float64)
    centre = workspace_centre(offsets)
    start = centre if start is None else np.asarray(start, np.float64)
    g = np.zeros(rcms.shape[0]) if gii_to_beat is None else np.asarray(gii_to_beat, np.float64).reshape(-1)
    probes = np.ascontiguousarray(offsets[probe_points(offsets, centre)]) if probe_first else np.empty((0, 3))
    params = np.zeros(3)
    params[:len(metric_params)] = metric_params
    if lanes is None:
        lanes = offsets.shape[0] >= SL.LANES * SL.MIN_POINTS_PER_LANE
    arrays, restarts = kernel_arrays(chain), default_restarts(seed)
    if lanes:
        out, counts = SL.candidates_lanes(arrays, seed, restarts, rcms, offsets, start, probes, g, SL.segments(offsets),
                                          metric.code, params)
    else:
        out, counts = candidates_scalar(arrays, seed, restarts, rcms, offsets, start, probes, g, metric.code, params)
    return out[:, 0], out[:, 1], counts[:, 0], counts[:, 1], counts[:, 2]
