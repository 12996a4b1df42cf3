"""Performance measures (surgopt/metrics.py): the worked examples of their docstrings and edge cases."""
import math

import numpy as np

from surgopt.metrics import global_isotropy_index, raven_cost, workspace_compactness


def test_gii_worked_example_and_degenerate_designs():
    # singular values {(1, 2), (0.5, 4)} over two points -> 0.5 / 4
    assert global_isotropy_index(min(1, 0.5), max(2, 4)) == 0.125
    g = global_isotropy_index([0.5, 0.5, np.nan, 0.2], [4.0, 0.0, 1.0, 1.0], [True, True, True, False])
    assert g.tolist() == [0.125, 0.0, 0.0, 0.0]  # zero largest value, NaN, infeasible: 0, never NaN


def test_zeta_of_an_annulus_and_of_nothing():
    area, circumference = math.pi * (3 ** 2 - 1 ** 2), 2 * math.pi * (3 + 1)  # cm
    assert workspace_compactness(area, circumference) == 1.0
    assert workspace_compactness([0.0], [0.0]).tolist() == [0.0]


def test_raven_cost_worked_example():
    assert raven_cost(2.0, 100.0, 0.5, 1.0, 1.0) == 50.0
    # longer links cost more: the same workspace at alpha = beta = 2 rad is 8x cheaper
    assert raven_cost(2.0, 100.0, 0.5, 2.0, 2.0) == 50.0 / 8


def test_every_pose_metric_dispatches_to_its_registered_evaluator():
    """metrics.POSE_METRICS names each metric's evaluator; serial_chain.metric_over_solutions (the kernels' one
    dispatch on the metric's code) must call exactly it: the same numbers over random in-range UR5e poses. A
    metric the walk computes itself has no evaluator and evaluates to NaN there."""
    import importlib

    from surgopt.kinematics.serial_chain import kernel_arrays, metric_over_solutions
    from surgopt.metrics import POSE_METRICS
    from surgopt.studies.rcm_grid.config import RcmGridConfig

    rng = np.random.default_rng(24)
    checked = 0
    for name, metric in POSE_METRICS.items():
        cfg = RcmGridConfig.model_validate({"robot": {"model": "ur5e"}, "metric": name})
        chain, _, _ = cfg.robot.chain()
        arrays = kernel_arrays(chain)
        lower, upper = np.maximum(arrays[3], -3.0), np.minimum(arrays[4], 3.0)
        q = rng.uniform(lower, upper, (40, len(lower)))
        params = np.zeros(3)  # as chain_candidates_extremes hands them to the kernels
        params[:len(cfg.metric_params())] = cfg.metric_params()
        got = metric_over_solutions(metric.code, arrays, q, len(q), params)
        if metric.evaluator is None:
            assert metric.in_walk and np.isnan(got[0]) and np.isnan(got[1])
            continue
        module, function = metric.evaluator.split(":")
        want = getattr(importlib.import_module(module), function)(arrays, q, len(q), params)
        assert got == want and np.isfinite(got[0])
        checked += 1
    assert checked >= 1  # the premise: a metric evaluated over the solutions was checked
