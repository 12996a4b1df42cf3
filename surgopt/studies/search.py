"""Searches over a study's continuous design space that any study can use (the grid is the default).

``compass_search``: derivative-free coordinate search inside box bounds (Kolda, Lewis & Torczon 2003,
"Optimization by direct search", Sec. 3.5), a cheap local refinement of a grid's best designs.
"""
from __future__ import annotations

from typing import Callable, Sequence

import numpy as np


def compass_search(objective: Callable[[np.ndarray], float], start: Sequence[float],
                   bounds: Sequence[tuple[float, float]], steps: Sequence[float], max_evals: int,
                   min_step_fraction: float = 1e-3) -> list[np.ndarray]:
    """Maximise ``objective`` from ``start``: every evaluated point, in order (the start first).

    Each coordinate is tried at +-step (clipped to its bounds); the first improvement moves there;
    when a sweep over all coordinates improves nothing, every step halves. Stops after
    ``max_evals`` evaluations or when each step is below ``min_step_fraction`` of its range.
    A coordinate with step 0 stays fixed.
    """
    x = np.array(start, float)
    steps = np.array(steps, float)
    ranges = np.maximum(1e-9, [hi - lo for lo, hi in bounds])
    best = objective(x)
    visited = [x.copy()]
    evals = 1
    while evals < max_evals and np.any(steps > min_step_fraction * ranges):
        improved = False
        for i in range(len(x)):
            if steps[i] == 0:
                continue
            for sign in (1.0, -1.0):
                y = x.copy()
                y[i] = min(bounds[i][1], max(bounds[i][0], y[i] + sign * steps[i]))
                if y[i] == x[i]:
                    continue
                value = objective(y)
                evals += 1
                visited.append(y.copy())
                if value > best:
                    best, x, improved = value, y, True
                    break
            if evals >= max_evals:
                break
        if not improved:
            steps = steps / 2
    return visited
