"""raven-sweep throughput: numba kernel vs plain vectorised numpy, full Table II sweep, end to end.

Run:  python benchmarks/bench_raven.py [--quick]
Prints designs/second of the kernel (one core, one geometry's 125 designs at
the default 2 mm step) and of a numpy version of the same math (broadcast cone
margins, isotropy and a vectorised marching squares), their ratio from the
same run, the full 250,000-design Table II sweep on 2 threads (computed, and
through the runner with the store), and
`surgopt raven-sweep configs/raven_table2.toml` end to end with a warm JIT cache.
"""
from __future__ import annotations

import argparse
import math
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]


def numpy_marching_squares(m, nx, ny, step):
    """Contour length of m = 0 over all cells, vectorised (saddles by the centre value)."""
    g = m.reshape(nx, ny)
    v = [g[:-1, :-1], g[1:, :-1], g[1:, 1:], g[:-1, 1:]]
    px = [0.0, 1.0, 1.0, 0.0]
    py = [0.0, 0.0, 1.0, 1.0]
    pts = []
    for k in range(4):
        a, b = v[k], v[(k + 1) % 4]
        cross = (a > 0) != (b > 0)
        with np.errstate(divide="ignore", invalid="ignore"):
            t = np.where(cross, a / (a - b), np.nan)
        pts.append((px[k] + t * (px[(k + 1) % 4] - px[k]), py[k] + t * (py[(k + 1) % 4] - py[k])))
    X = np.stack([p[0] for p in pts])
    Y = np.stack([p[1] for p in pts])
    n = np.sum(~np.isnan(X), axis=0)
    two = n == 2
    order = np.argsort(np.isnan(X), axis=0, kind="stable")[:2]
    xa = np.take_along_axis(X, order[:1], 0)[0]
    ya = np.take_along_axis(Y, order[:1], 0)[0]
    xb = np.take_along_axis(X, order[1:2], 0)[0]
    yb = np.take_along_axis(Y, order[1:2], 0)[0]
    length = np.nansum(np.where(two, np.hypot(xb - xa, yb - ya), 0.0))
    four = n == 4
    if four.any():
        c = 0.25 * (v[0] + v[1] + v[2] + v[3])
        same = (c > 0) == (v[0] > 0)
        d01 = np.hypot(X[1] - X[0], Y[1] - Y[0]) + np.hypot(X[3] - X[2], Y[3] - Y[2])
        d30 = np.hypot(X[3] - X[0], Y[3] - Y[0]) + np.hypot(X[2] - X[1], Y[2] - Y[1])
        length += np.sum(np.where(four, np.where(same, d01, d30), 0.0))
    return length * step


def numpy_cone_geometry(xs, ys, depth, ports, axes):
    """(arms, nx*ny) cos psi and distance of every plane node from every port."""
    X, Y = np.meshgrid(xs, ys, indexing="ij")
    v = np.stack([X.ravel(), Y.ravel(), np.full(X.size, -depth)], axis=1)[None] - ports[:, None, :]
    dist = np.linalg.norm(v, axis=2)
    cos_psi = np.clip(np.einsum("anj,aj->an", v, axes) / dist, -1, 1)
    return cos_psi, dist


def numpy_designs(cos_psi, dist, nx, ny, step, d4_max, al, be, iso, plo, phi, has):
    """The kernel's math, broadcast over nodes: membership and margin from the arms' lowest and highest cos psi."""
    reach = np.min(d4_max - dist, axis=0)
    arm_lo, arm_hi = np.argmin(cos_psi, axis=0), np.argmax(cos_psi, axis=0)
    cols = np.arange(cos_psi.shape[1])
    lo, hi = cos_psi[arm_lo, cols], cos_psi[arm_hi, cols]
    d_lo, d_hi = dist[arm_lo, cols], dist[arm_hi, cols]
    out = []
    for ia, a in enumerate(al):
        for ib, b in enumerate(be):
            sa, ca, sb, cb = math.sin(a), math.cos(a), math.sin(b), math.cos(b)
            c2 = np.clip((cos_psi + ca * cb) / (sa * sb), -1, 1)
            s2 = np.sqrt(1 - c2 * c2)
            A = c2 * cb * sa + sb * ca
            C = s2 * sa
            S = A * A + sb * sb + C * C
            D = np.abs(sb * C)
            iso_node = np.min(2 * D / (S + np.sqrt(np.maximum(0, S * S - 4 * D * D)) + 1e-300), axis=0)
            for k in range(len(iso)):
                if not has[ia, ib, k]:
                    out.append((0.0, 0, 0.0))
                    continue
                c_lo, c_hi = math.cos(phi[ia, ib, k]), math.cos(plo[ia, ib, k])
                m = np.minimum(reach, np.minimum((lo - c_lo) * d_lo, (c_hi - hi) * d_hi))
                inside = m > 0
                out.append((numpy_marching_squares(m, nx, ny, step), int(inside.sum()), float(iso_node[inside].sum())))
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="skip the full sweep and the end-to-end run")
    args = ap.parse_args()
    from surgopt.jit import configure_numba

    configure_numba()
    from surgopt.config import load_config, load_embedded
    from surgopt.kinematics import raven_workspace as W
    from surgopt.kinematics.raven_plane import evaluate_geometries, plane_grid
    from surgopt.robots import raven_iv
    from surgopt.studies.raven_sweep import study as S

    cfg = load_embedded(S.DEFAULT_CONFIG, S.Config)
    t = time.perf_counter()
    S.warm_up(cfg)
    print(f"JIT load/compile: {time.perf_counter() - t:.2f} s")
    geo = cfg.geometry
    layout, plane = S.arm_layout(geo), S.plane(geo)
    ports, axes, zero_axes = W.arm_frames(layout, 20.0, 10.0, -20.0, 100.0, 50.0)
    left, unlimited = W.left_arms(layout), W.shoulder_range(None)  # the numpy comparison has no theta1
    xs, ys = plane_grid(ports, geo.depth_mm, geo.d4_max_mm, geo.step_mm)
    n = xs.size * ys.size
    al = np.radians(S.values(cfg.sweep.alpha_deg))
    be = np.radians(S.values(cfg.sweep.beta_deg))
    iso = np.array(S.values(cfg.sweep.iso_min))
    designs = W.cone_angle_intervals(al, be, iso, geo.theta2_range_deg)
    plo, phi, has = designs.psi_lo_rad, designs.psi_hi_rad, designs.has_interval
    out = np.zeros((125, 6))
    P, A, X = ports[None].copy(), axes[None].copy(), zero_axes[None].copy()
    reps = 20
    t = time.perf_counter()
    for _ in range(reps):
        evaluate_geometries(P, A, X, left, plane, designs, unlimited, out)
    t_nb = (time.perf_counter() - t) / reps
    # the same on the whole plane (the sweep evaluates the half x >= 0 of a mirror-symmetric layout)
    from surgopt.kinematics.raven_plane import evaluate_designs, plane_node_bounds
    from surgopt.kinematics.raven_shoulder import shoulder_fields

    full_out, buffer = np.zeros((125, 6)), np.empty(6 * n)
    scratch = (np.empty(n, np.int16), np.full(n, -1, np.int64), np.empty(n))
    none = shoulder_fields(xs[:0], ys[:0], geo.depth_mm, ports, axes, zero_axes, left)
    bounds = plane_node_bounds(xs, ys, geo.depth_mm, ports, axes, geo.d4_max_mm, buffer)
    evaluate_designs(bounds, xs.size, ys.size, geo.step_mm, designs, none, unlimited, full_out, scratch)  # compile
    t = time.perf_counter()
    for _ in range(reps):
        bounds = plane_node_bounds(xs, ys, geo.depth_mm, ports, axes, geo.d4_max_mm, buffer)
        evaluate_designs(bounds, xs.size, ys.size, geo.step_mm, designs, none, unlimited, full_out, scratch)
    t_full = (time.perf_counter() - t) / reps
    t = time.perf_counter()
    cos_psi, dist = numpy_cone_geometry(xs, ys, geo.depth_mm, ports, axes)
    ref = numpy_designs(cos_psi, dist, xs.size, ys.size, geo.step_mm, geo.d4_max_mm, al, be, iso, plo, phi, has)
    t_np = time.perf_counter() - t
    agree = max(abs(r[0] - o[1]) / max(o[1], 1) + abs(r[1] - o[2]) for r, o in zip(ref, out))
    print(f"one geometry ({n:,} plane nodes x 4 arms, 125 designs, plane geometry included): numba {t_nb * 1e3:.2f} ms "
          f"({125 / t_nb:,.0f} designs/s, one core); numpy {t_np * 1e3:.0f} ms ({125 / t_np:,.0f} designs/s)")
    print(f"the kernel on the whole plane (the numpy version's work; the sweep halves a mirror-symmetric layout): "
          f"{t_full * 1e3:.2f} ms; ratio numba / numpy, same work: {t_np / t_full:.0f}x, as the sweep runs: "
          f"{t_np / t_nb:.0f}x (max relative perimeter difference + point-count difference {agree:.1e})")
    if args.quick:
        return
    from concurrent.futures import ThreadPoolExecutor

    from surgopt.runner import run_study
    from surgopt.store import Store

    table2 = load_config(REPO / "configs" / "raven_table2.toml", S.Config)
    geo2, sw = table2.geometry, table2.sweep
    al2, be2, iso2 = S.values(sw.alpha_deg), S.values(sw.beta_deg), S.values(sw.iso_min)
    designs2 = W.cone_angle_intervals(np.radians(al2), np.radians(be2), np.asarray(iso2, float), geo2.theta2_range_deg)
    placed = [W.arm_frames(S.arm_layout(geo2), *g) for g in S.geometry_grid(table2)]
    P2, A2, X2 = (np.ascontiguousarray(np.array([f[i] for f in placed])) for i in range(3))
    halves = [slice(0, len(placed) // 2), slice(len(placed) // 2, len(placed))]
    outs = [np.zeros(((h.stop - h.start) * 125, 6)) for h in halves]

    def kernel_half(k):
        evaluate_geometries(P2[halves[k]], A2[halves[k]], X2[halves[k]], W.left_arms(S.arm_layout(geo2)),
                            S.plane(geo2), designs2, unlimited, outs[k])

    with ThreadPoolExecutor(2) as pool:
        t = time.perf_counter()
        list(pool.map(kernel_half, range(2)))
        dt = time.perf_counter() - t
    print(f"Table II, theta1 unlimited, all {len(placed):,} geometries evaluated (no sharing of identical ones), "
          f"250,000 designs on 2 threads: {dt:.2f} s ({250_000 / dt:,.0f} designs/s)")
    def study_seconds(cfg):
        chunk = S.auto_chunk(cfg)
        W.clear_memo()
        with ThreadPoolExecutor(2) as pool:
            t = time.perf_counter()
            rows = sum(len(r["design_id"]) for r in pool.map(lambda i: S.compute_task(cfg, chunk, i),
                                                             range(S.n_tasks(cfg, chunk))))
            return rows, time.perf_counter() - t

    rows, dt = study_seconds(table2)
    print(f"Table II sweep as the study computes it ({rows:,} designs; the default geometry, the shoulder limited to "
          f"the Raven II's {list(raven_iv.THETA1_RANGE_RAVEN_II_DEG)} deg), 2 threads, no store: {dt:.2f} s "
          f"({rows / dt:,.0f} designs/s)")
    free = table2.model_copy(update={"geometry": geo2.model_copy(update={"theta1_range_deg": None})})
    rows_f, dt_f = study_seconds(free)
    print(f"the same with theta1 unlimited (identical geometries evaluated once: 400 of 2,000): {dt_f:.2f} s; "
          f"the limited sweep takes {dt / dt_f:.2f}x as long")
    W.clear_memo()
    with tempfile.TemporaryDirectory() as tmp:
        t = time.perf_counter()
        res = run_study(S.STUDY, table2, config_name="bench", store=Store(tmp), jobs=2, quiet=True)
        dt = time.perf_counter() - t
        print(f"Table II sweep through the runner, {res.table.num_rows:,} designs on 2 threads (store writes and "
              f"reading the table back included): {dt:.2f} s ({res.table.num_rows / dt:,.0f} designs/s)")
        t = time.perf_counter()
        subprocess.run([sys.executable, "-m", "surgopt", "raven-sweep", str(REPO / "configs" / "raven_table2.toml"),
                        "--quiet", "--force", "--store", tmp], check=True, capture_output=True, env=dict(os.environ))
        print(f"`surgopt raven-sweep configs/raven_table2.toml` end to end, warm JIT cache: "
              f"{time.perf_counter() - t:.2f} s")


if __name__ == "__main__":
    main()
