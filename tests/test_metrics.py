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
