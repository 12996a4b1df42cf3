"""Locke & Patel Sec. III-E: the GII of the standard Jacobian beside the alternative one, and the
algorithmic singularity at the RCM that only the alternative Jacobian sees (docs/reproduction.md).

Run:  python docs/reproduce_pa10_standard.py [STORE]   (about 40 s; prints Markdown, writes
docs/figures/rcm_standard_vs_alternative.png). Both maps are rcm-grid runs of the paper's setup on a
10 mm grid (61 x 61, 17^3 cube): `metric = "alternative"` (the paper's Fig. 3) and `metric = "standard"`
(the 6 x 6 Jacobian of S1, S2, E1, E2, W1, W2 with S3 held, task scaling 10 mm/s and pi/2 rad/s).
"""
import sys
from pathlib import Path

import numpy as np

import surgopt
from surgopt.studies.rcm_track.study import rank_correlation

REPO = Path(__file__).resolve().parents[1]
store = sys.argv[1] if len(sys.argv) > 1 else str(REPO / "surgopt-store")
grid = {"candidates.grid.x_count": 61, "candidates.grid.z_count": 61}
maps = {m: surgopt.run("rcm-grid", overrides={**grid, "metric": m}, store=store) for m in ("alternative", "standard")}
a, s = maps["alternative"], maps["standard"]
f = a["feasible"] & s["feasible"]
print("| metric | feasible | best (x, z) m from the shoulder | best GII | GII range over the feasible map |")
print("|---|---|---|---|---|")
for name, df in maps.items():
    b = df.loc[df["gii"].idxmax()]
    g = df["gii"][df["feasible"]]
    print(f"| {name} | {int(df['feasible'].sum()):,} | ({b.x_rcm_m:.3f}, {b.z_rcm_m:.3f}) | {b.gii:.5f} | "
          f"{g.min():.2e} - {g.max():.2e} |")
print(f"\nSpearman rank correlation of the two maps over {int(f.sum()):,} feasible candidates: "
      f"{rank_correlation(a['gii'][f], s['gii'][f]):.3f}; standard / alternative GII: median "
      f"{np.median(s['gii'][f] / a['gii'][f]):.4f}\n")

print("| tip depth below the RCM (mm) | alternative sigma_min (m/s) | alternative GII | standard sigma_min | standard GII |")
print("|---|---|---|---|---|")
for depth in (0.2, 0.1, 0.05, 0.02, 0.01, 0.005):
    row = []
    for m in ("alternative", "standard"):
        df = surgopt.run("rcm-grid", overrides={"metric": m, "robot.kernel": "generic", "workspace.points_per_side": 1,
                                                "workspace.depth_below_rcm_m": depth,
                                                "candidates.list_m": [[0.535, -0.21]]}, store=store)
        row += [df[{"alternative": "sigma_min_m_per_s", "standard": "sigma_min_task_scaled"}[m]][0], df["gii"][0]]
    print(f"| {depth * 1e3:.0f} | {row[0]:.4f} | {row[1]:.4f} | {row[2]:.4f} | {row[3]:.6f} |")

import matplotlib  # noqa: E402

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

fig, axes = plt.subplots(1, 2, figsize=(11.5, 4.8))
fig.subplots_adjust(wspace=0.35)
for ax, (name, df) in zip(axes, maps.items()):
    xs, zs = np.sort(df["x_rcm_m"].unique()), np.sort(df["z_rcm_m"].unique())
    gii = np.where(df["feasible"], df["gii"], np.nan).reshape(len(xs), len(zs))
    im = ax.pcolormesh(xs, zs, gii.T, shading="nearest", cmap="viridis")
    fig.colorbar(im, ax=ax, label="GII")
    b = df.loc[df["gii"].idxmax()]
    ax.plot(b.x_rcm_m, b.z_rcm_m, "wx", ms=9, mew=2)
    ax.set_title(f"{name} Jacobian: best ({b.x_rcm_m:.2f}, {b.z_rcm_m:.2f}) m, GII {b.gii:.2g}", fontsize=9)
    ax.set_xlabel("x_rcm (m)")
    ax.set_ylabel("z_rcm (m, from the shoulder)")
    ax.set_aspect("equal")
fig.suptitle("Sec. III-E: the standard Jacobian's GII has the alternative one's profile, far lower values", fontsize=10)
fig.savefig(REPO / "docs" / "figures" / "rcm_standard_vs_alternative.png", dpi=110, bbox_inches="tight")
