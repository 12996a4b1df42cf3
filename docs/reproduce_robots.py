"""docs/robots.md: each shipped model's default rcm-grid study, its GII map and best RCM.

Run:  python docs/reproduce_robots.py [STORE]   (about 30 s warm; prints Markdown, writes
docs/figures/robots/<model>_gii_map.png). Each model is `surgopt rcm-grid --robot NAME` on its own
default (the model file's seed, locks, tool, workspace and grid), run through the Python API; the PA10
also through the generic kernel, beside its closed-form kernel on the same grid.
"""
import sys
from pathlib import Path

import surgopt
from surgopt.compose import variants
from surgopt.robots.models import MODELS, get_model
from surgopt.studies import get_study

REPO = Path(__file__).resolve().parents[1]
store = sys.argv[1] if len(sys.argv) > 1 else str(REPO / "surgopt-store")
out = REPO / "docs" / "figures" / "robots"
out.mkdir(parents=True, exist_ok=True)
study = get_study("rcm-grid")
print("| model | kernel | candidates (grid) | feasible | best (x, y, z) m | best GII |")
print("|---|---|---|---|---|---|")
cases = [(name, {"robot.model": name}) for name in MODELS if name != "pa10_7c"]
cases += [("pa10_7c", {}), ("pa10_7c", {"robot.kernel": "generic"})]
for name, over in cases:
    df = surgopt.run("rcm-grid", overrides=over, store=store)
    (v,) = variants(study, None, over)
    best = df[df["gii_is_exact"] & df["feasible"]].nlargest(1, "gii").iloc[0]
    g = v.config.candidates.grid
    kernel = "closed form" if v.config.robot.closed_form else "generic"
    ref = " (z from the shoulder)" if v.config.candidates.z_reference == "shoulder" else ""
    print(f"| {get_model(name).title} | {kernel} | {len(df):,} ({g.x_count} x {g.z_count}, "
          f"{(g.x_max_m - g.x_min_m) / max(1, g.x_count - 1) * 1000:.0f} mm) | {int(df['feasible'].sum()):,} | "
          f"({best.x_rcm_m:.3f}, {best.y_rcm_m:.3f}, {best.z_rcm_m:.3f}){ref} | {best.gii:.4f} |")
    if kernel == "generic" or name != "pa10_7c":
        import pyarrow as pa

        paths = study.figures(v.config, pa.Table.from_pandas(df, preserve_index=False), out)
        for p in paths:
            p.rename(out / f"{name}{'_generic' if name == 'pa10_7c' else ''}_{p.name.removeprefix('rcm_')}")
