"""Searches any study can use (surgopt/studies/search.py)."""
import numpy as np

from surgopt.studies.search import compass_search


def test_compass_search_finds_the_maximum_of_a_concave_quadratic():
    peak = np.array([0.3, -1.2, 2.0])
    f = lambda x: -float(np.sum((x - peak) ** 2))  # noqa: E731
    visited = compass_search(f, [0.0, 0.0, 0.0], [(-2, 2), (-2, 2), (-2, 3)], [0.5, 0.5, 0.5], max_evals=2000,
                             min_step_fraction=1e-5)
    best = max(visited, key=f)
    assert np.allclose(best, peak, atol=1e-4)  # resolution: 1e-5 of each range
    assert np.array_equal(visited[0], [0.0, 0.0, 0.0])


def test_compass_search_respects_bounds_budget_and_fixed_coordinates():
    f = lambda x: float(x[0] + x[1])  # noqa: E731  (maximum on the upper corner)
    visited = compass_search(f, [0.0, 5.0], [(-1, 1), (5, 5)], [0.3, 0.0], max_evals=25)
    assert len(visited) <= 25
    pts = np.array(visited)
    assert pts[:, 0].min() >= -1 and pts[:, 0].max() <= 1
    assert np.all(pts[:, 1] == 5.0)  # step 0: never moved
    assert max(visited, key=f)[0] == 1.0
