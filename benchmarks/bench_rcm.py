"""rcm-grid throughput: numba kernel vs plain vectorised numpy, full map and cull wall times.

Run:  python benchmarks/bench_rcm.py [--quick]
Prints poses/second of the kernel (one core) and of a numpy version of the
same math (batched over poses: IK, J_a as an (N, 5, 5) stack, np.linalg.inv,
np.linalg.svd), their ratio measured in the same run, the wall time of the
paper's full 121 x 121 x 17^3 map on 2 workers, the --cull argmax time on the
5 mm grid, and `surgopt rcm-grid` end to end with a warm JIT cache.
The generic serial-chain kernel (any arm) on the same PA10 from its DH table: poses/second beside the
closed-form kernel and beside its own scalar walk (no SIMD lanes) in the same run, the same candidate,
the full map through it, and
`surgopt rcm-grid --robot ur5e` end to end.
benchmarks/rcm_floor.py says how far the per-pose ratio can go on this machine.
"""
from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time

import numpy as np


def numpy_rcm_singular_values(tips, rcm, links_m, tool_offset_m, qdot_max):
    """Plain numpy, vectorised over poses: (sigma_min, sigma_max) of J_r^-1-scaled (elbow up)."""
    d1, d3, d5 = links_m
    k = tips - rcm
    k /= np.linalg.norm(k, axis=1, keepdims=True)
    w = tips - tool_offset_m * k
    r = np.hypot(w[:, 0], w[:, 1])
    n = np.stack([-w[:, 1] / r, w[:, 0] / r, np.zeros_like(r)], axis=1)
    s = w - np.array([0.0, 0.0, d1])
    dist = np.linalg.norm(s, axis=1)
    u = s / dist[:, None]
    cos_a = (d3 ** 2 + dist ** 2 - d5 ** 2) / (2 * d3 * dist)
    sin_a = np.sqrt(np.clip(1 - cos_a ** 2, 0, None))
    v = np.cross(u, n)
    e = np.array([0.0, 0.0, d1]) + d3 * (cos_a[:, None] * u + sin_a[:, None] * v)
    f = (w - e) / d5
    m = np.cross(f, k)
    m /= np.linalg.norm(m, axis=1, keepdims=True)
    zs = [np.broadcast_to([0.0, 0.0, 1.0], tips.shape), n, n, f, m]
    os_ = [np.broadcast_to([0.0, 0.0, d1], tips.shape), np.broadcast_to([0.0, 0.0, d1], tips.shape), e, w, w]
    J = np.empty((tips.shape[0], 5, 5))
    for j, (z, o) in enumerate(zip(zs, os_)):
        J[:, :3, j] = np.cross(z, tips - o)
        g = np.cross(z, rcm - o)
        J[:, 3:, j] = g[:, :2] - (g[:, 2] / k[:, 2])[:, None] * k[:, :2]
    M = np.linalg.inv(J)[:, :, :3] / np.asarray(qdot_max)[None, :, None]
    sv = np.linalg.svd(M, compute_uv=False)
    return 1.0 / sv[:, 0], 1.0 / sv[:, -1]


def best_of(fn, repeat):
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return min(times)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="skip the full-map and end-to-end timings")
    args = ap.parse_args()
    from surgopt.jit import configure_numba

    configure_numba()
    from surgopt.config import load_embedded
    from surgopt.kinematics import pa10_rcm as K
    from surgopt.studies.rcm_grid import study as S

    cfg = load_embedded(S.DEFAULT_CONFIG, S.Config)
    arm = S.arm_model(cfg)
    links, tool, elbow, qdot, cl = arm
    off = S.workspace_offsets(cfg.workspace)
    rcm = np.array([0.535, 0.0, -0.21 + cfg.robot.link_d1_m])  # the paper's optimum: every pose reachable
    tips = rcm + off
    n = tips.shape[0]
    geom = K.workspace_geometry(off, tool)  # the whole cube, no mirror reduction
    out = (np.empty(n), np.empty(n), np.empty(n, np.int64))

    def kernel():
        for _ in range(20):
            K._workspace_poses(rcm[0], rcm[1], rcm[2], geom, *links, elbow, *qdot, *cl, *out)

    t0 = time.perf_counter()
    kernel()
    print(f"JIT load/compile: {time.perf_counter() - t0:.2f} s")
    t_nb = best_of(kernel, 7) / 20
    t_np = best_of(lambda: numpy_rcm_singular_values(tips, rcm, links, tool, qdot), 3)
    lo, hi = np.sqrt(out[0]), np.sqrt(out[1])
    lo2, hi2 = numpy_rcm_singular_values(tips, rcm, links, tool, qdot)
    agree = max(np.max(np.abs(lo / lo2 - 1)), np.max(np.abs(hi / hi2 - 1)))
    print(f"kernel (1 core, {n} poses of one candidate, every pose computed): "
          f"{n / t_nb / 1e6:6.2f} M poses/s  ({t_nb / n * 1e9:5.1f} ns/pose)")
    print(f"numpy  (same poses)                                   : "
          f"{n / t_np / 1e6:6.2f} M poses/s  ({t_np / n * 1e9:5.0f} ns/pose)")
    print(f"ratio kernel/numpy: {t_np / t_nb:.0f}x   (max relative difference {agree:.1e})")

    # the full map's kernel work on one core, in-process
    rcms = S.candidate_rcms(cfg, S.candidate_xyz(cfg))
    sub = np.ascontiguousarray(rcms[::16])
    K.rcm_candidates_extremes(sub[:1], off, arm)  # load this signature
    t_map1 = best_of(lambda: K.rcm_candidates_extremes(sub, off, arm), 1)
    est = t_map1 * rcms.shape[0] / sub.shape[0]
    print(f"full map kernel work, one core (every 16th candidate, scaled): {est:.2f} s "
          f"for {rcms.shape[0] * off.shape[0] / 1e6:.0f} M poses (mirror half of the cube; "
          f"infeasible candidates get the IK pass only)")

    cull = cfg.model_copy(update={"search": "cull"})
    S.warm_up(cull)
    t_cull = best_of(lambda: S.cull_search(cull), 3)
    print(f"--cull argmax on the 5 mm grid (in-process): {t_cull:.3f} s")

    generic(cfg, rcm, off, t_nb, args.quick)
    if args.quick:
        return
    from surgopt.runner import run_study
    from surgopt.store import Store

    with tempfile.TemporaryDirectory() as tmp:
        t = time.perf_counter()
        res = run_study(S.STUDY, cfg, config_name="bench", store=Store(tmp), jobs=2, quiet=True, force=True)
        print(f"full 121 x 121 x 17^3 map on 2 threads (store writes included): {time.perf_counter() - t:.2f} s, "
              f"{res.table.num_rows} rows")
        for extra, label in (([], "full map"), (["--cull"], "--cull")):
            t = time.perf_counter()
            subprocess.run([sys.executable, "-m", "surgopt", "rcm-grid", "--quiet", "--store", tmp, "--force", *extra],
                           check=True, capture_output=True, env=dict(os.environ))
            print(f"`surgopt rcm-grid {' '.join(extra)}` end to end, warm JIT cache: {time.perf_counter() - t:.2f} s")


def generic(cfg, rcm, off, t_closed, quick):
    """The serial-chain kernel on the PA10 (from its DH table) beside the closed-form kernel."""
    from surgopt.config import validate
    from surgopt.kinematics import pa10_rcm as K
    from surgopt.kinematics import chain_candidates as CC
    from surgopt.kinematics import serial_chain as C
    from surgopt.studies.rcm_grid import study as S

    gcfg = validate({"robot": {"kernel": "generic"}}, S.Config, "bench")
    chain, _, seed = gcfg.robot.chain()
    walk = np.ascontiguousarray(off[C.serpentine_order(gcfg.workspace.points_per_side)])
    n = walk.shape[0]
    CC.chain_candidates_extremes(rcm[None], walk, chain, seed)
    t_g = best_of(lambda: CC.chain_candidates_extremes(np.repeat(rcm[None], 4, 0), walk, chain, seed), 5) / 4
    steps = C.rcm_walk(chain, rcm, walk, seed)["newton_steps"]
    print(f"generic kernel (1 core, the same {n} poses, Newton walk from the seed): "
          f"{n / t_g / 1e6:6.2f} M poses/s  ({t_g / n * 1e9:5.0f} ns/pose, {steps / n:.2f} Newton steps/pose)")
    print(f"ratio generic/closed-form per pose: {t_g / t_closed:.1f}x  (target <= 10x)")
    t_s = best_of(lambda: CC.chain_candidates_extremes(np.repeat(rcm[None], 4, 0), walk, chain, seed, lanes=False), 3) / 4
    print(f"the same walk on the scalar kernel (no SIMD lanes): {t_s / n * 1e9:5.0f} ns/pose; lanes {t_s / t_g:.1f}x faster")
    # the same candidates through both kernels (the closed form with its mirror half, as the study runs it)
    rcms = S.candidate_rcms(cfg, S.candidate_xyz(cfg))
    sub = np.ascontiguousarray(rcms[::97])
    arm = S.arm_model(cfg)
    t_cf = best_of(lambda: K.rcm_candidates_extremes(sub, off, arm), 3)
    t_gm = best_of(lambda: CC.chain_candidates_extremes(sub, walk, chain, seed), 1)
    print(f"every 97th candidate of the map ({sub.shape[0]}), as the study runs them: closed form {t_cf:.3f} s, "
          f"generic {t_gm:.2f} s ({t_gm / t_cf:.0f}x; one core)")
    if quick:
        return
    from surgopt.runner import run_study
    from surgopt.store import Store

    with tempfile.TemporaryDirectory() as tmp:
        t = time.perf_counter()
        res = run_study(S.STUDY, gcfg, config_name="bench", store=Store(tmp), jobs=2, quiet=True, force=True)
        print(f"full 121 x 121 x 17^3 PA10 map through the generic kernel on 2 threads: "
              f"{time.perf_counter() - t:.2f} s, {res.table.num_rows} rows (target <= 10 s)")
        for extra in (["--robot", "ur5e"],):
            subprocess.run([sys.executable, "-m", "surgopt", "rcm-grid", "--quiet", "--store", tmp, *extra],
                           check=True, capture_output=True, env=dict(os.environ))  # compile / load the cache
            t = time.perf_counter()
            subprocess.run([sys.executable, "-m", "surgopt", "rcm-grid", "--quiet", "--store", tmp, "--force", *extra],
                           check=True, capture_output=True, env=dict(os.environ))
            print(f"`surgopt rcm-grid {' '.join(extra)}` end to end, warm JIT cache: {time.perf_counter() - t:.2f} s "
                  f"(target <= 10 s)")


if __name__ == "__main__":
    main()
