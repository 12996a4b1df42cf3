"""The Python API in a notebook or script (README, "Python API"); tests/test_api.py runs this file.

Run:  python docs/api_example.py [STORE]
"""
import sys

import surgopt

store = sys.argv[1] if len(sys.argv) > 1 else "surgopt-store"

# A small RCM map for the PA10 with a shorter tool: the overrides are validated like a config file's.
small = {"candidates.grid.x_count": 13, "candidates.grid.z_count": 13, "workspace.points_per_side": 5}
df = surgopt.run("rcm-grid", overrides={**small, "robot.tool_length_m": 0.45}, store=store)
best = df[df["feasible"]].nlargest(1, "gii").iloc[0]
print(f"{len(df)} candidates, best GII {best.gii:.4f} at x = {best.x_rcm_m:.3f} m, z = {best.z_rcm_m:.3f} m")

# What the store holds, and a run read back (every part verified) by its key prefix.
runs = surgopt.runs(store=store)
print(runs[["study", "config_name", "rows", "state"]].to_string(index=False))
again = surgopt.load(runs["key"].iloc[-1][:12], store=store)
assert again.equals(df)
