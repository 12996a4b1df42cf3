"""Locke & Patel Sec. III-B, "the shortest tool is best": the best RCM and its GII for each tool length.

Run:  python docs/reproduce_pa10_tool_length.py [STORE]   (about 15 s; prints Markdown, writes
docs/figures/rcm_tool_length.png). Each length is one stored rcm-grid run of the paper's map with the
Culling search (exact argmax), made through the Python API with an override.
"""
import sys
from pathlib import Path

import numpy as np

import surgopt

REPO = Path(__file__).resolve().parents[1]
store = sys.argv[1] if len(sys.argv) > 1 else str(REPO / "surgopt-store")
lengths = np.round(np.arange(0.45, 0.7501, 0.05), 3)
rows = []
for L in lengths:
    df = surgopt.run("rcm-grid", overrides={"robot.tool_length_m": float(L), "search": "cull"}, store=store)
    best = df[df["gii_is_exact"] & df["feasible"]].nlargest(1, "gii").iloc[0]
    rows.append((L, best.x_rcm_m, best.z_rcm_m, best.gii, int(df["feasible"].sum())))

print("| tool length (m) | best x_rcm (m) | best z_rcm (m) | best GII | feasible candidates |")
print("|---|---|---|---|---|")
for L, x, z, g, n in rows:
    print(f"| {L:.3f} | {x:.3f} | {z:.3f} | {g:.5f} | {n:,} |")

import matplotlib  # noqa: E402

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

fig, ax = plt.subplots(figsize=(5.2, 3.6))
ax.plot([r[0] * 1000 for r in rows], [r[3] for r in rows], "o-")
ax.axvline(587, color="0.6", ls="--", lw=0.8, label="the paper's 587 mm tool")
ax.set_xlabel("tool length (mm, from the flange)")
ax.set_ylabel("best GII over the 121 x 121 map")
ax.set_title("Sec. III-B: the shorter the tool, the better the best RCM", fontsize=9)
ax.legend(fontsize=8)
fig.savefig(REPO / "docs" / "figures" / "rcm_tool_length.png", dpi=110, bbox_inches="tight")

# Per RCM: each of Table I's 15 candidates over the same lengths (0.40 m added; GII 0 where infeasible).
from surgopt.studies.rcm_grid.study import PAPER_TABLE_I  # noqa: E402

per_length = np.round(np.arange(0.40, 0.7501, 0.05), 3)
cands = [[float(r[0]), float(r[1])] for r in PAPER_TABLE_I]
gii = np.array([np.where(d["feasible"], d["gii"], 0.0) for d in (
    surgopt.run("rcm-grid", overrides={"robot.tool_length_m": float(L), "candidates.list_m": cands}, store=store)
    for L in per_length)]).T
print("\n| Table I RCM (x, z) m | " + " | ".join(f"{L:.2f}" for L in per_length) + " | over 0.40-0.75 m |")
print("|---|" + "---|" * len(per_length) + "---|")
falls = 0
for (x, z), g in zip(cands, gii):
    d = np.diff(g)
    kind = "falls" if np.all(d <= 0) else ("rises" if np.all(d >= 0) else "not monotone")
    falls += kind == "falls"
    print(f"| ({x:.3f}, {z:.3f}) | " + " | ".join(f"{v:.4f}" for v in g) + f" | {kind} |")
print(f"\n{falls} of {len(cands)} Table I RCMs have a GII that falls monotonically with the tool length.")
