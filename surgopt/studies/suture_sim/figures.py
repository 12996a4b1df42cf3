"""suture-sim figures: |q_i / q_imax| against time per weight set (Fig. 7 style) and the tracked path."""
from __future__ import annotations

import numpy as np

from surgopt.kinematics.throat import forward_kinematics
from surgopt.studies.plotting import columns, pyplot, save
from surgopt.studies.suture_sim.study import JOINT_COLUMNS, NORM_COLUMNS, geometry


def figures(cfg, table, out, design_id=None):
    plt = pyplot()
    c = columns(table)
    paths = []
    keys = ["arm_length_mm", "fulcrum_to_tip_mm", "mode", "radius_mm", "speed_mm_s"]
    combos = sorted({tuple(c[k][i] for k in keys) for i in np.unique(c["run_id"], return_index=True)[1]},
                    key=lambda t: (t[0], t[1], t[2]))
    for n_combo, combo in enumerate(combos):
        sel = np.ones(len(c["run_id"]), bool)
        for k, v in zip(keys, combo):
            sel &= c[k] == v
        sets = list(dict.fromkeys(c["weight_set"][sel]))
        fig, axes = plt.subplots(1, len(sets), figsize=(5.2 * len(sets), 3.8), squeeze=False, sharey=True)
        for k, w in enumerate(sets):
            s = sel & (c["weight_set"] == w)
            ax = axes[0, k]
            for j, name in enumerate(NORM_COLUMNS):
                ax.plot(c["t_s"][s], c[name][s], label=JOINT_COLUMNS[j].rsplit("_", 1)[0])  # q1, not q1_rad
            ax.axhline(1.0, color="k", lw=0.6, ls="--")
            ax.set_title(f"{w}", fontsize=9)
            ax.set_xlabel("t (s)")
        axes[0, 0].set_ylabel("|q_i / q_imax|")
        axes[0, -1].legend(fontsize=7, loc="center left", bbox_to_anchor=(1, 0.5))
        fig.suptitle("joint motion, arm {:.0f} mm, fulcrum {:.0f} mm, {}, r {:g} mm at {:g} mm/s".format(*combo), fontsize=9)
        paths.append(save(fig, out / f"suture_joints_{n_combo}.png"))
        # the tracked path of the platform (and of a needle tip held radius off its axis)
        geo = geometry(cfg, combo[0], combo[1])
        fig, ax = plt.subplots(figsize=(5, 5))
        for w in sets:
            s = sel & (c["weight_set"] == w)
            qs = np.column_stack([c[name][s] for name in JOINT_COLUMNS])
            poses = [forward_kinematics(q, geo) for q in qs[:: max(1, len(qs) // 400)]]
            p0, R0 = poses[0]
            pts = np.array([R0.T @ (p - p0) for p, _ in poses])
            needle = np.array([R0.T @ (p + combo[3] * R[:, 0] - p0) for p, R in poses])
            ax.plot(pts[:, 0], pts[:, 1], marker="o", ms=3, markevery=max(1, len(pts) // 12),
                    label=f"{w}: platform")  # markers: a platform that spins in place is a point
            ax.plot(needle[:, 0], needle[:, 1], "--", label=f"{w}: needle tip ({combo[3]:g} mm off axis)")
        ax.set_aspect("equal")
        ax.set_xlabel("x in the start gripper frame (mm)")
        ax.set_ylabel("y in the start gripper frame (mm)")
        ax.set_title("tracked path, arm {:.0f} mm, fulcrum {:.0f} mm, {}, r {:g} mm".format(*combo[:4]), fontsize=9)
        ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.02, 1.0))  # beside the path, not on it
        paths.append(save(fig, out / f"suture_path_{n_combo}.png"))
    return paths
