"""Lower bounds for the rcm kernel's time per pose on this machine, next to the 300x-numpy budget.

Run:  python benchmarks/rcm_floor.py

Issue #2 asks for >= 300x the numpy version per pose. This script measures
what that needs and what the kernel's own instruction stream allows:

  1. the numpy version's time per pose (benchmarks/bench_rcm.py's function)
     and the kernel time per pose that 300x would need;
  2. the kernel's vector instructions per pose, counted in the machine code
     LLVM generates for `_workspace_poses` (compiled here without the cache,
     since numba cannot show cached code): square roots, divisions and the
     other floating-point operations;
  3. this core's throughput for each kind, measured with vectorised loops of
     independent operations (so the numbers are throughput, not latency);
  4. two floors: the divider's (roots and divisions only) and the FP ports'
     (all other floating-point operations at the measured peak rate). The
     kernel cannot beat the larger; when the two do not overlap it pays their
     sum. Both floors come from counts and throughputs, not from the kernel's
     timing, so they hold for any schedule of these instructions.
"""
from __future__ import annotations

import collections
import re
import sys

import numpy as np


def vector_op_counts(asm, reg="zmm"):
    """Floating-point instructions on ``reg`` registers in a function's machine code, by kind."""
    counts = collections.Counter()
    for line in asm.splitlines():
        line = line.strip()
        if reg not in line or line.startswith(("#", ".")):
            continue
        op = line.split()[0]
        if op.startswith("vsqrtp"):
            counts["sqrt"] += 1
        elif op.startswith("vdivp"):
            counts["div"] += 1
        elif re.match(r"v(f(n)?m(add|sub)\d*p|mulp|addp|subp|minp|maxp|cmp\w*p|andp|xorp|orp|blendm)", op):
            counts["fp"] += 1
        else:
            counts["other"] += 1  # moves, loads, stores, broadcasts
    return counts


def main():
    from surgopt.jit import CONTRACT, configure_numba

    configure_numba()  # before numba is imported: it reads NUMBA_CPU_FEATURES once
    from numba import njit

    from surgopt.config import load_embedded
    from surgopt.kinematics import pa10_rcm as K
    from surgopt.studies.rcm_grid import study as S

    sys.path.insert(0, __file__.rsplit("/", 1)[0])
    from bench_rcm import best_of, numpy_rcm_singular_values

    cfg = load_embedded(S.DEFAULT_CONFIG, S.Config)
    arm = S.arm_model(cfg)
    links, tool, elbow, qdot, cl = arm
    off = S.workspace_offsets(cfg.workspace)
    rcm = np.array([0.535, 0.0, -0.21 + cfg.robot.link_d1_m])
    n = off.shape[0]
    geom = K.workspace_geometry(off, tool)
    out = (np.empty(n), np.empty(n), np.empty(n, np.int64))
    opts = {k: v for k, v in CONTRACT.items() if k != "cache"}
    kernel = njit(**opts)(K._workspace_poses.py_func)
    args = (rcm[0], rcm[1], rcm[2], geom, *links, elbow, *qdot, *cl, *out)
    kernel(*args)
    asm = next(iter(kernel.inspect_asm().values()))
    reg, lanes = ("zmm", 8) if "zmm" in asm else ("ymm", 4)  # the width LLVM chose
    counts = vector_op_counts(asm, reg)
    per_pose = dict(counts)  # one vector instruction is one operation for each of `lanes` poses

    @njit(fastmath={"contract"}, error_model="numpy")
    def fma_peak(x, y):
        for j in range(x.shape[0]):  # 8 independent chains of 16 FMAs per element
            a = x[j]
            b, c, d, e, f, g, h = a + 1.0, a + 2.0, a + 3.0, a + 4.0, a + 5.0, a + 6.0, a + 7.0
            for _ in range(16):
                a, b, c, d = a * 0.999 + 1e-3, b * 0.999 + 1e-3, c * 0.999 + 1e-3, d * 0.999 + 1e-3
                e, f, g, h = e * 0.999 + 1e-3, f * 0.999 + 1e-3, g * 0.999 + 1e-3, h * 0.999 + 1e-3
            y[j] = a + b + c + d + e + f + g + h

    @njit(fastmath={"contract"}, error_model="numpy")
    def sqrt_rate(x, y):
        for j in range(x.shape[0]):
            a = x[j]
            for _ in range(16):
                a = np.sqrt(a) + 0.5
            y[j] = a

    @njit(fastmath={"contract"}, error_model="numpy")
    def div_rate(x, y):
        for j in range(x.shape[0]):
            a = x[j]
            for _ in range(16):
                a = 1.0 / a + 0.5
            y[j] = a

    x = np.random.default_rng(0).random(n) + 1.0
    y = np.empty_like(x)
    rates = {}
    for name, fn, ops in (("fp", fma_peak, 128), ("sqrt", sqrt_rate, 16), ("div", div_rate, 16)):
        fn(x, y)
        rates[name] = best_of(lambda: [fn(x, y) for _ in range(20)], 15) / 20 / (n * ops) * 1e9  # ns per operation per element

    t_kernel = best_of(lambda: [kernel(*args) for _ in range(20)], 7) / 20 / n * 1e9
    tips = rcm + off
    t_numpy = best_of(lambda: numpy_rcm_singular_values(tips, rcm, links, tool, qdot), 5) / n * 1e9

    divider = per_pose.get("sqrt", 0) * rates["sqrt"] + per_pose.get("div", 0) * rates["div"]
    fp_ports = per_pose.get("fp", 0) * rates["fp"]
    print(f"vector width {lanes} ({reg}); per pose the kernel issues {per_pose.get('sqrt', 0):.0f} square roots, "
          f"{per_pose.get('div', 0):.0f} divisions, {per_pose.get('fp', 0):.0f} other floating-point operations "
          f"and {per_pose.get('other', 0):.0f} moves/loads/stores")
    print(f"measured throughput, ns per operation per pose: square root {rates['sqrt']:.3f}, "
          f"division {rates['div']:.3f}, FMA-port operation {rates['fp']:.4f}")
    print(f"floor from the divider (roots + divisions):   {divider:5.1f} ns/pose")
    print(f"floor from the FP ports (everything else):    {fp_ports:5.1f} ns/pose")
    print(f"the two added (no overlap):                   {divider + fp_ports:5.1f} ns/pose")
    print(f"kernel measured, every pose computed:         {t_kernel:5.1f} ns/pose")
    print(f"numpy version, same poses:                    {t_numpy:5.0f} ns/pose  "
          f"-> 300x needs {t_numpy / 300:.1f} ns/pose; kernel/numpy now {t_numpy / t_kernel:.0f}x")
    print(f"ratio these instructions allow: at most {t_numpy / max(divider, fp_ports):.0f}x (divider and FP ports "
          f"fully overlapped), {t_numpy / (divider + fp_ports):.0f}x if they do not overlap")


if __name__ == "__main__":
    main()
