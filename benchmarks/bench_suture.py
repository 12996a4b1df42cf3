"""suture-sim throughput: numba steps/second vs a plain numpy version, paper runs, end to end.

Run:  python benchmarks/bench_suture.py
Prints steps/second of the numba suture loop and of the same loop in plain
numpy (the reference FK/Jacobian of tests/reference.py would be unfair; this
numpy version uses the same closed forms with numpy arrays and np.linalg.solve),
the time of both paper runs (550 mm, W1 and W2; 3,770 steps each at dt 0.01 s)
after JIT, and `surgopt suture-sim` end to end with a warm JIT cache.
"""
from __future__ import annotations

import math
import os
import subprocess
import sys
import tempfile
import time

import numpy as np


def numpy_suture_run(q0, geo, w, radius, speed, arc, dt):
    """The same spin-mode loop, calling the kernels' pure-Python bodies (numpy, no JIT)."""
    from surgopt.kinematics import throat as T

    fk, jac = T.forward_kinematics.py_func, T.jacobian.py_func
    omega = speed / radius
    n = int(round(arc / omega / dt))
    q = q0.copy()
    p0, R0 = fk(q, geo)
    pd, Rd = p0, R0
    for k in range(n):
        p, R = fk(q, geo)
        pn, Rn = p0, R0 @ T.rot_z.py_func(min(arc, omega * (k + 1) * dt))
        dx = np.concatenate([(pn - pd) + (pd - p),
                             T.rotation_vector.py_func(Rn @ Rd.T) + T.rotation_vector.py_func(Rd @ R.T)])
        J = jac(q, geo)
        WJt = J.T / w[:, None]
        q = q + WJt @ np.linalg.solve(J @ WJt, dx)
        pd, Rd = pn, Rn
    return q


def main():
    from surgopt.jit import configure_numba

    configure_numba()
    from surgopt.config import load_embedded
    from surgopt.kinematics.throat import suture_run
    from surgopt.studies.suture_sim import study as S

    cfg = load_embedded(S.DEFAULT_CONFIG, S.Config)
    geo = S.geometry(cfg, 550.0, 150.0)
    q0 = S.start_q(cfg)
    t = time.perf_counter()
    S.warm_up(cfg)
    print(f"JIT load/compile: {time.perf_counter() - t:.2f} s")
    w1, w2 = np.ones(8), np.array([1000.0, 1000.0] + [0.1] * 6)
    t = time.perf_counter()
    n = 0
    for w in (w1, w2):
        n += len(suture_run(q0, geo, w, 0, 6.0, 0.5, math.pi, 0.01, 1.0, 0.0)[0]) - 1
    t_nb = time.perf_counter() - t
    print(f"both paper runs (550 mm, W1 + W2, {n} steps): {t_nb:.3f} s -> {n / t_nb:,.0f} steps/s (numba)")
    steps_np = 200
    t = time.perf_counter()
    numpy_suture_run(q0, geo, w1, 6.0, 0.5 * 3770 / steps_np, math.pi, 0.01)
    t_np = time.perf_counter() - t
    print(f"plain numpy, same loop: {steps_np / t_np:,.0f} steps/s; numba / numpy = {(n / t_nb) / (steps_np / t_np):.0f}x")
    with tempfile.TemporaryDirectory() as tmp:
        t = time.perf_counter()
        subprocess.run([sys.executable, "-m", "surgopt", "suture-sim", "--quiet", "--store", tmp],
                       check=True, capture_output=True, env=dict(os.environ))
        print(f"`surgopt suture-sim` end to end (4 runs, 15,080 steps), warm JIT cache: {time.perf_counter() - t:.2f} s")


if __name__ == "__main__":
    main()
