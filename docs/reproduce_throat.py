"""Regenerate the numbers of docs/reproduction.md, throat section (Wei, Xu & Simaan).

Run:  python docs/reproduce_throat.py   (about 30 s; prints Markdown)
"""
from __future__ import annotations

import pyarrow as pa

from surgopt.config import load_embedded
from surgopt.studies.suture_sim import study as S


def summary(cfg):
    parts = [S.compute_task(cfg, 1, i) for i in range(S.n_tasks(cfg, 1))]
    table = pa.concat_tables([pa.Table.from_pydict(p, schema=S.schema()) for p in parts])
    return S.run_summary(table)


def ranges_table(s, label):
    print(f"\n{label}\n")
    runs = list(s.itertuples())
    head = " | ".join(f"{r.weight_set} {r.arm_length_mm:.0f} mm" for r in runs)
    print(f"| joint | {head} |")
    print("|---|" + "---|" * len(runs))
    for c, nc in zip(S.JOINT_COLUMNS, S.NORM_COLUMNS):
        cells = " | ".join(f"{getattr(r, c + '_range'):.4g} ({getattr(r, nc + '_peak'):.2f})" for r in runs)
        print(f"| {c} | {cells} |")
    print("| least φ_L′ (its range is [0, π]) | " + " | ".join(f"{r.q7_margin_rad_min:.4f}" for r in runs) + " |")
    print("| max pos / rot error (integrator) | " + " | ".join(
        f"{r.max_pos_err_mm:.1e} mm / {r.max_rot_err_deg:.1e}°" for r in runs) + " |")


def main():
    base = load_embedded(S.DEFAULT_CONFIG, S.Config)
    ranges_table(summary(base), "Default (spin mode): joint range, and peak |q/q_max| in brackets")
    for mode in ("orbit_parallel", "orbit_tangent"):
        cfg = S.Config.model_validate({**base.model_dump(), "task": {**base.task.model_dump(), "modes": [mode]}})
        ranges_table(summary(cfg), f"Mode {mode}")
    print("\nFulcrum position (550 mm arm, spin, W1 / W2): five-bar ranges q1, q2 (rad)\n")
    print("| fulcrum before the holder tip (mm) | W1 q1 | W1 q2 | W2 q1 | W2 q2 | W1 q4 | W2 q4 |")
    print("|---|---|---|---|---|---|---|")
    for f in (75.0, 150.0, 300.0, 450.0):
        cfg = S.Config.model_validate({**base.model_dump(), "arm_length_mm": [550.0], "fulcrum_to_tip_mm": [f]})
        s = summary(cfg).set_index("weight_set")
        print(f"| {f:.0f} | {s.loc['W1', 'q1_rad_range']:.4f} | {s.loc['W1', 'q2_rad_range']:.4f} "
              f"| {s.loc['W2', 'q1_rad_range']:.2e} | {s.loc['W2', 'q2_rad_range']:.2e} "
              f"| {s.loc['W1', 'q4_rad_range']:.3f} | {s.loc['W2', 'q4_rad_range']:.3f} |")

    assemblies(base)


def assemblies(base):
    """The five-bar's two assembly modes at the paper's start pose: P_U, whether the pentagon crosses itself,
    the size of the closure's cross product |(B - D) x (C - D)| (mm^2), and W1's q1 and delta ranges on the
    550 mm arm. The crossed one (left, the default until 2026-12-02) is refused by the config; it is built here
    without validation (model_copy) to show what it gave."""
    from surgopt.kinematics.throat import five_bar

    q0 = S.start_q(base)
    print("\nFive-bar assembly at the start pose (550 mm arm, spin, W1):\n")
    print("| branch | P_U (mm) | pentagon | closure cross product (mm^2) | W1 q1 range (rad) | W1 delta range (rad) |")
    print("|---|---|---|---|---|---|")
    for branch in ("left", "right"):
        robot = base.robot.model_copy(update={"five_bar": base.robot.five_bar.model_copy(update={"branch": branch})})
        cfg = base.model_copy(update={"robot": robot, "arm_length_mm": [550.0], "weights": {"W1": [1.0] * 8}})
        fb = robot.five_bar
        _, D, C, B, _ = S.five_bar_pentagon(fb, q0[0], q0[1])
        cross = abs((B[0] - D[0]) * (C[1] - D[1]) - (B[1] - D[1]) * (C[0] - D[0]))
        p_u = five_bar(q0[0], q0[1], S.geometry(cfg, 550.0, cfg.fulcrum_to_tip_mm[0]))[0]
        s = summary(cfg).iloc[0]
        print(f"| {branch} | ({p_u[0]:.1f}, {p_u[1]:.1f}) | {S.five_bar_crossing(fb, q0[0], q0[1]) or 'simple'} "
              f"| {cross:.0f} | {s.q1_rad_range:.3f} | {s.q6_rad_range:.2f} |")


if __name__ == "__main__":
    main()
