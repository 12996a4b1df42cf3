"""Locke & Patel Sec. IV: Table I's "Max error" column, the gain calibration and what the unknown
controller moves (docs/reproduction.md).

Run:  python docs/reproduce_pa10_track.py [STORE]   (about 30 s; prints Markdown, writes
docs/figures/rcm_track_*.png). The Table I run is `surgopt rcm-track` on its embedded default; the
sensitivity rows recalibrate the gain on the best candidate's 5.1 mm for each controller variant.
"""
import sys
from pathlib import Path

import numpy as np

import surgopt
from surgopt.config import load_embedded
from surgopt.studies import get_study
from surgopt.studies.rcm_track import study as S

REPO = Path(__file__).resolve().parents[1]
store = sys.argv[1] if len(sys.argv) > 1 else str(REPO / "surgopt-store")
base = load_embedded(S.DEFAULT_CONFIG, S.Config)
paper = np.array(S.PAPER_MAX_ERROR_MM)

print(f"Calibrated gain on (0.535, -0.210) = 5.1 mm: {S.calibrate_gain(base, 7, 5.1):.3f} /s "
      f"(default {S.CALIBRATED_GAIN_PER_S})\n")
df = surgopt.run("rcm-track", store=store)
e = df["max_tip_error_mm"].to_numpy()
print("| x_rcm (m) | z_rcm (m) | GII | paper max error (mm) | ours (mm) | ours mean (mm) | max RCM error (mm) | "
      "saturated (s) | joint at its rated speed |")
print("|---|---|---|---|---|---|---|---|---|")
for i, r in df.iterrows():
    peaks = [r[f"peak_qdot_ratio_{j}"] for j in range(1, 6)]
    sat = ", ".join(n for n, p in zip(("S1", "S2", "E1", "E2", "W1"), peaks) if p >= 0.999) or "-"
    print(f"| {r.x_rcm_m:.3f} | {r.z_rcm_m:.3f} | {r.gii:.4f} | {paper[i]:.1f} | {r.max_tip_error_mm:.2f} | "
          f"{r.mean_tip_error_mm:.2f} | {r.max_rcm_error_mm:.2f} | {r.saturated_s:.2f} | {sat} |")
rho = S.rank_correlation(paper, e)
top3 = set(np.argsort(-e)[:3]) == {12, 13, 14}
print(f"\nSpearman rho (ours vs paper, 15 rows) = {rho:.3f}; the three x = 0.260 rows the three largest: {top3}; "
      f"their error / the best's: ours {e[12:].mean() / e[7]:.1f}x, paper {paper[12:].mean() / paper[7]:.1f}x; "
      f"Spearman (GII vs -error, ours) = {S.rank_correlation(df['gii'], -e):.3f}, "
      f"(GII vs -error, paper) = {S.rank_correlation(df['gii'], -paper):.3f}\n")

print("| velocity lag (s) | saturation at x rated speed | gain (1/s) | Spearman | x = 0.26 rows largest | "
      "x = 0.26 errors (mm) | other rows (mm) | Spearman, the other 12 rows (held out) |")
print("|---|---|---|---|---|---|---|---|")
for lag in (0.0, 0.02, 0.05):
    for scale in (1.0, 1.5, 1.75, 2.0):
        tr = base.track.model_copy(update={"velocity_lag_s": lag, "saturation_speed_scale": scale, "keep": []})
        cfg = base.model_copy(update={"track": tr})
        g = S.calibrate_gain(cfg, 7, 5.1)
        cfg = cfg.model_copy(update={"track": tr.model_copy(update={"gain_per_s": g})})
        v = S.compute_task(cfg, 15, 0)["max_tip_error_mm"]
        print(f"| {lag:g} | {scale:g} | {g:.2f} | {S.rank_correlation(paper, v):.3f} | "
              f"{set(np.argsort(-v)[:3]) == {12, 13, 14}} | {', '.join(f'{x:.1f}' for x in v[12:])} | "
              f"{v[:12].min():.1f}-{v[:12].max():.1f} | {S.rank_correlation(paper[:12], v[:12]):.2f} |")

# the path's shape, the other lever: more helix turns at the same length (a wider margin, a smaller radius)
side = base.workspace.cube_side_m


def helix_length(turns, margin):
    return float(np.hypot(2 * np.pi * (side / 2 - margin) * turns, side - 2 * margin))


length = helix_length(base.track.turns, base.track.radius_margin_m)
print(f"\n| helix turns (length {1000 * length:.1f} mm) | radius margin (mm) | x = 0.26 errors (mm) | other rows (mm) |")
print("|---|---|---|---|")
for turns in (2.5, 3.0, 3.5, 4.0):
    lo, hi = 0.0, side / 2 - 1e-9  # the margin that keeps the length: the length falls as the margin grows
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if helix_length(turns, mid) > length else (lo, mid)
    tr = base.track.model_copy(update={"turns": turns, "radius_margin_m": lo, "keep": []})
    v = S.compute_task(base.model_copy(update={"track": tr}), 15, 0)["max_tip_error_mm"]
    print(f"| {turns:g} | {1000 * lo:.2f} | {', '.join(f'{x:.1f}' for x in v[12:])} | "
          f"{v[:12].min():.1f}-{v[:12].max():.1f} |")

import pyarrow as pa  # noqa: E402

study = get_study("rcm-track")
out = REPO / "docs" / "figures"
for p in study.figures(base, pa.Table.from_pandas(df, preserve_index=False), out):
    print(f"\nwrote {p.relative_to(REPO)}", end="")
print()
