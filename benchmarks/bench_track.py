"""rcm-track throughput: the P-controller kernel against a plain numpy loop, Table I and the full map.

Run:  python benchmarks/bench_track.py [--quick]
Prints control steps per second of the numba kernel (one core) and of a plain Python/numpy loop of the
same controller (tests/reference.py's, forward kinematics as 4x4 matrix products), their ratio in the
same run; all 15 Table I candidates x 10,000 steps in-process (target <= 1 s on 2 cores) and end to
end; and the full 121 x 121 grid tracked (target <= 60 s on 2 cores).
"""
from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="skip the full-map timing")
    args = ap.parse_args()
    import reference as ref

    from surgopt.config import load_embedded, validate
    from surgopt.kinematics import rcm_track as K
    from surgopt.kinematics.serial_chain import kernel_arrays, rcm_walk
    from surgopt.robots import pa10_7c
    from surgopt.runner import run_study
    from surgopt.store import Store
    from surgopt.studies.rcm_grid import study as G
    from surgopt.studies.rcm_track import study as S

    cfg = load_embedded(S.DEFAULT_CONFIG, S.Config)
    S.warm_up(cfg)
    chain, _, seed = cfg.robot.chain()
    rcm = G.candidate_rcms(cfg, G.candidate_xyz(cfg)[7:8])[0]
    _, off, _ = S.reference_path(cfg)
    walk = rcm_walk(chain, rcm, off, seed, start=np.array([0.0, 0.0, -0.1]))
    p_ref = np.ascontiguousarray(rcm + off)
    m = p_ref.shape[0]
    trace = np.zeros((1, 6))
    args_k = (kernel_arrays(chain), walk["q"], 1, p_ref, rcm, 1e-3, S.CALIBRATED_GAIN_PER_S, 0.0, True, 1.0, 0, trace)
    K.track(*args_k)
    t_k = min(_time(lambda: K.track(*args_k)) for _ in range(5))
    def fk(q5):
        return ref.pa10_tool_tip(q5, pa10_7c.LINKS_BIELEFELD_M, pa10_7c.TOOL_LENGTH_M)

    qmax = np.array([pa10_7c.MAX_JOINT_SPEED_RAD_S[n] for n in pa10_7c.ACTIVE_JOINTS])
    n_np = 1000
    t_np = _time(lambda: ref.p_control_track(fk, walk["q"][:n_np], p_ref[:n_np], rcm, 1e-3,
                                             S.CALIBRATED_GAIN_PER_S, 0.0, qmax)) * m / n_np
    print(f"controller kernel (1 core, {m} steps): {m / t_k / 1e6:6.2f} M steps/s ({t_k * 1e3:.1f} ms per candidate)")
    print(f"numpy loop (same steps, extrapolated from {n_np}): {m / t_np / 1e3:6.1f} k steps/s; ratio {t_np / t_k:.0f}x")
    t_ik = min(_time(lambda: rcm_walk(chain, rcm, off[::10], seed, start=np.array([0.0, 0.0, -0.1]))) for _ in range(3))
    print(f"reference IK along the path (every 10th step, {off[::10].shape[0]} points): {t_ik * 1e3:.1f} ms per candidate")
    t = time.perf_counter()
    S.compute_task(cfg, 15, 0)
    print(f"all 15 Table I candidates x {m - 1} steps, in-process, one core: {time.perf_counter() - t:.2f} s "
          f"(target <= 1 s on 2 cores)")
    with tempfile.TemporaryDirectory() as tmp:
        t = time.perf_counter()
        run_study(S.STUDY, cfg, config_name="bench", store=Store(tmp), jobs=2, quiet=True, force=True)
        print(f"the same through the runner on 2 threads (store writes included): {time.perf_counter() - t:.2f} s")
        if args.quick:
            return
        full = validate({}, S.Config, "bench")
        t = time.perf_counter()
        res = run_study(S.STUDY, full, config_name="bench-map", store=Store(tmp), jobs=2, quiet=True, force=True)
        print(f"full 121 x 121 grid tracked on 2 threads: {time.perf_counter() - t:.1f} s, {res.table.num_rows} rows "
              f"(target <= 60 s)")


def _time(fn):
    t = time.perf_counter()
    fn()
    return time.perf_counter() - t


if __name__ == "__main__":
    main()
