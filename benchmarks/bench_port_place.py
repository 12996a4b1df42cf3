"""port-place throughput: the numba kernels against plain numpy versions of the same math, same run.

Run:  python benchmarks/bench_port_place.py
Prints, for the default config (164 candidate sites, 915 target points, 2,165,292 designs):
- per-port tables (RCM inverse kinematics + limits + isotropy at every site x target point): numba vs a
  numpy version vectorised over the points (one site at a time), and vs plain numpy point by point (a sample of
  sites);
- per-pair tables (common reach, smaller isotropy, manipulation angle statistics over the points both reach):
  numba vs numpy vectorised over the points (one pair at a time), and vs plain numpy point by point (a sample);
- combining designs (design_columns) in designs/s, with two PSMs and with three (a slice of the 348,612,012);
- `surgopt port-place` end to end, warm, and the estimate it printed beforehand: the default, and the full 3-PSM
  enumeration with only its feasible rows stored;
- a serial instrument arm (the PA10-7C keeping the RCM in software, configs/port_place_pa10.toml): the generic
  Newton kernel's per-port tables in site-points/s against the PA10's closed-form kernel (pa10_rcm, the fast path
  it generalises) on the same (port, point) pairs, one core each, with the two checked equal.
"""
from __future__ import annotations

import math
import subprocess
import sys
import tempfile
import time

import numpy as np

from surgopt.kinematics.port import designs as D
from surgopt.kinematics.port import place as K
from surgopt.robots import dvrk
from surgopt.robots.models import get_model
from surgopt.studies.port_place import config as C
from surgopt.studies.port_place import geometry as G
from surgopt.studies.port_place import tables as T
from surgopt.studies.port_place import model as M
from surgopt.studies.port_place import study as S


def numpy_instrument_tables(sites, rot, targets, arm, length):
    reach = np.zeros((len(sites), len(targets)), bool)
    dex = np.zeros((len(sites), len(targets)))
    for i in range(len(sites)):
        p = (targets - sites[i]) @ rot[i]  # rot^T (p - site), row-wise
        rho = np.linalg.norm(p, axis=1)
        q2 = -np.arcsin(np.clip(p[:, 1] / rho, -1, 1))
        q1 = np.arctan2(p[:, 0], -p[:, 2])
        q3 = rho - arm.along_shaft_m
        ok = ((arm.yaw_lo <= q1) & (q1 <= arm.yaw_hi) & (arm.pitch_lo <= q2) & (q2 <= arm.pitch_hi)
              & (arm.insertion_lo <= q3) & (q3 <= arm.insertion_hi))
        sv = np.stack([rho * np.cos(q2) / length, rho / length, np.ones_like(rho)])
        reach[i] = ok
        dex[i] = np.where(ok, sv.min(axis=0) / sv.max(axis=0), 0.0)
    return reach, dex


def numpy_pair_angles(sites, reach, dex, targets, lo, hi, pairs):
    out = []
    for i, j in pairs:
        both = reach[i] & reach[j]
        a, b = sites[i] - targets[both], sites[j] - targets[both]
        ang = np.arctan2(np.linalg.norm(np.cross(a, b), axis=1), (a * b).sum(axis=1))
        out.append((both.sum(), np.minimum(dex[i, both], dex[j, both]).mean(), ang.mean(), ang.min(), ang.max(),
                    ((ang >= lo) & (ang <= hi)).mean()))
    return out


def plain_instrument_tables(sites, rot, targets, arm, length):
    """The same math point by point: numpy on 3-vectors, no vectorisation over the points (the kernel's loop
    body in numpy, as in the other benchmarks' 'plain numpy' columns)."""
    reach = np.zeros((len(sites), len(targets)), bool)
    dex = np.zeros((len(sites), len(targets)))
    for i in range(len(sites)):
        for k in range(len(targets)):
            p = rot[i].T @ (targets[k] - sites[i])
            rho = np.linalg.norm(p)
            q2 = -np.arcsin(np.clip(p[1] / rho, -1, 1))
            q1 = np.arctan2(p[0], -p[2])
            q3 = rho - arm.along_shaft_m
            if (arm.yaw_lo <= q1 <= arm.yaw_hi and arm.pitch_lo <= q2 <= arm.pitch_hi
                    and arm.insertion_lo <= q3 <= arm.insertion_hi):
                sv = np.array([rho * np.cos(q2) / length, rho / length, 1.0])
                reach[i, k] = True
                dex[i, k] = sv.min() / sv.max()
    return reach, dex


def plain_pair_angles(sites, reach, dex, targets, lo, hi, pairs):
    """The pair statistics point by point (numpy on 3-vectors)."""
    out = []
    for i, j in pairs:
        n, iso, s, mn, mx, inside = 0, 0.0, 0.0, np.inf, -np.inf, 0
        for k in range(len(targets)):
            if reach[i, k] and reach[j, k]:
                a, b = sites[i] - targets[k], sites[j] - targets[k]
                ang = np.arctan2(np.linalg.norm(np.cross(a, b)), a @ b)
                n, iso, s = n + 1, iso + min(dex[i, k], dex[j, k]), s + ang
                mn, mx, inside = min(mn, ang), max(mx, ang), inside + (lo <= ang <= hi)
        out.append((n, iso / n, s / n, mn, mx, inside / n) if n else (0, 0.0, 0.0, 0.0, 0.0, 0.0))
    return out


def best_of(f, repeat=3):
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        out = f()
        times.append(time.perf_counter() - t)
    return min(times), out


def main() -> None:
    cfg = C.PortPlaceConfig()
    sites = G.sites_mm(cfg) / 1000
    targets = G.target_points_mm(cfg.target) / 1000
    centre = np.asarray(cfg.target.centre_mm) / 1000
    arm = T.arm_limits(get_model("dvrk_psm_classic"))
    crit = T.criteria(cfg)
    rot = K.docking_frames(sites, centre, T.LATERAL)
    n, m = len(sites), len(targets)
    print(f"default config: {n} sites, {m} target points, {S.n_designs(n):,} designs")
    K.instrument_tables(sites, rot, targets, arm, 0.1, T.approach(cfg.target, dvrk.LND_WRIST_BEND_RAD))  # compiled or loaded
    tk, (reach, dex) = best_of(lambda: K.instrument_tables(sites, rot, targets, arm, 0.1, T.approach(cfg.target, dvrk.LND_WRIST_BEND_RAD)))
    tn, (reach_np, dex_np) = best_of(lambda: numpy_instrument_tables(sites, rot, targets, arm, 0.1))
    assert np.array_equal(reach, reach_np) and np.allclose(dex, dex_np, atol=1e-12)
    print(f"per-port tables: numba {n * m / tk / 1e6:.1f} M site-points/s, numpy {n * m / tn / 1e6:.2f} M/s, "
          f"ratio {tn / tk:.1f}x")
    few = slice(0, n, 20)  # every 20th site, point by point
    tp, (reach_p, dex_p) = best_of(lambda: plain_instrument_tables(sites[few], rot[few], targets, arm, 0.1), repeat=1)
    assert np.array_equal(reach_p, reach[few]) and np.allclose(dex_p, dex[few], atol=1e-12)
    n_few = len(range(0, n, 20))
    print(f"per-port tables, plain numpy point by point ({n_few} sites): {n_few * m / tp / 1e6:.3f} M site-points/s, "
          f"numba / plain {(tp / (n_few * m)) / (tk / (n * m)):.0f}x (one core each)")
    K.pair_tables(sites, reach, dex, targets, centre, crit)
    tk, pairs = best_of(lambda: K.pair_tables(sites, reach, dex, targets, centre, crit), repeat=2)
    some = [(i, j) for i in range(0, n, 7) for j in range(i + 1, n, 7)]  # a sample of pairs for numpy
    tn, ref = best_of(lambda: numpy_pair_angles(sites, reach, dex, targets, crit.angle_lo_rad, crit.angle_hi_rad,
                                                some), repeat=1)
    for (i, j), r in zip(some, ref):
        assert pairs[0][i, j] == r[0] and math.isclose(pairs[2][i, j], r[2], rel_tol=1e-12)
    n_pairs = n * (n - 1) // 2
    print(f"per-pair tables: numba {n_pairs * m / tk / 1e6:.1f} M pair-points/s ({tk:.2f} s for {n_pairs:,} pairs), "
          f"numpy {len(some) * m / tn / 1e6:.2f} M/s, ratio {(tn / len(some)) / (tk / n_pairs):.1f}x")
    fewer = some[::25]
    tp, plain = best_of(lambda: plain_pair_angles(sites, reach, dex, targets, crit.angle_lo_rad, crit.angle_hi_rad,
                                                  fewer), repeat=1)
    for (i, j), r in zip(fewer, plain):
        assert pairs[0][i, j] == r[0] and math.isclose(pairs[2][i, j], r[2], rel_tol=1e-12)
    print(f"per-pair tables, plain numpy point by point ({len(fewer)} pairs): {len(fewer) * m / tp / 1e6:.3f} M "
          f"pair-points/s, numba / plain {(tp / len(fewer)) / (tk / n_pairs):.0f}x (one core each)")
    model = M.model_of(cfg)
    t, crit = model.grid.tables, model.criteria
    total = S.n_designs(n)

    def chunked(instruments, start, stop, feasible_only=False):  # task by task, as the runner calls it
        for c in range(start, stop, S.CHUNK):
            D.design_columns(t, crit, c, min(stop, c + S.CHUNK), instruments, feasible_only)

    tk2, _ = best_of(lambda: chunked(2, 0, total), repeat=2)
    print(f"design_columns, 2 PSMs: {total / tk2 / 1e6:.1f} M designs/s (all {total:,}, {S.CHUNK:,} a call)")
    start, some3 = S.n_designs(n, 3) // 2, 10 * S.CHUNK  # a slice of the 3-PSM enumeration, from its middle
    for feasible_only in (False, True):
        tk3, _ = best_of(lambda: chunked(3, start, start + some3, feasible_only), repeat=2)
        print(f"design_columns, 3 PSMs{', feasible rows only' if feasible_only else ''}: {some3 / tk3 / 1e6:.1f} M "
              f"designs/s ({some3:,} of {S.n_designs(n, 3):,}); per design / 2 PSMs' {(tk3 / some3) / (tk2 / total):.2f}x")
    for label, args in (("2 PSMs", []), ("3 PSMs, feasible rows stored", ["robot.instrument_count=3",
                                                                         "rows_stored=feasible"])):
        with tempfile.TemporaryDirectory() as tmp:
            est = subprocess.run([sys.executable, "-m", "surgopt", "port-place", *args, "--dry-run"],
                                 capture_output=True, text=True)
            line = [x for x in est.stdout.splitlines() if "port designs" in x]
            t0 = time.perf_counter()
            subprocess.run([sys.executable, "-m", "surgopt", "port-place", *args, "--store", tmp, "-q"], check=True,
                           capture_output=True)
            print(f"surgopt port-place, {label}, end to end (warm, 2 threads): {time.perf_counter() - t0:.1f} s; "
                  f"dry-run said: {' '.join(line[0].split()) if line else '?'}")
    serial()


def serial() -> None:
    from surgopt.kinematics.pa10_rcm import pose_singular_values
    from surgopt.studies.port_place.serial_arms import serial_tables
    from surgopt.studies.rcm_grid.study import arm_model
    from surgopt.studies.rcm_grid.config import RcmGridConfig

    cfg = C.PortPlaceConfig.model_validate({"robot": {"instrument_serial": {
        "model": "pa10_7c", "rcm_in_base_m": [0.65, 0.0, 0.5]}}, "constraints": {"min_external_clearance_mm": 150.0}})
    sites = G.sites_mm(cfg) / 1000
    targets = G.target_points_mm(cfg.target) / 1000
    n, m = len(sites), len(targets)
    serial_tables(M.prepare(cfg), sites)  # compiled or loaded, Prim's order cached
    tk, st = best_of(lambda: serial_tables(M.prepare(cfg), sites))
    arm = arm_model(RcmGridConfig())
    rcm = np.asarray(cfg.robot.instrument_serial.rcm_in_base_m)

    def closed_form():
        out = np.zeros((n, m))
        for i in range(n):
            smin, smax, status = pose_singular_values((targets - st.base_pos[i]) @ st.base_rot[i], rcm, arm)
            out[i] = np.where(status == 0, smin / np.where(smax > 0, smax, 1.0), 0.0)
        return out

    closed_form()
    tc, iso = best_of(closed_form)
    both = st.reach & (iso > 0)
    assert np.allclose(st.dexterity[both], iso[both], rtol=1e-6)
    print(f"serial arm (PA10-7C, software RCM), per-port tables: generic Newton {n * m / tk / 1e6:.2f} M site-points/s "
          f"({tk:.2f} s for {n} sites x {m} points, {st.reach.mean():.0%} reached), the PA10's closed form "
          f"{n * m / tc / 1e6:.2f} M/s: generic / closed form {tk / tc:.1f}x the time")


if __name__ == "__main__":
    main()
