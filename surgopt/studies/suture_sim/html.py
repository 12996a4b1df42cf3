"""suture-sim's page (``surgopt report``): each run's normalised joint trajectories |q_i / q_i,max| against the
limit 1 (Wei, Xu & Simaan Fig. 7), and each joint's least margin to its range."""
from __future__ import annotations

import numpy as np

from surgopt.studies.page import View, table_html

JOINTS = 8


def views(run, cfg, parts) -> list[View]:
    """The run's sections (``cfg``: its validated config), aggregates streamed from ``parts``."""
    t = parts.table()
    c = {n: t[n].to_numpy(zero_copy_only=False) for n in t.column_names}
    runs = np.unique(c["run_id"])
    figures, rows = {}, []
    for r in runs[:12]:  # a page of at most 12 runs' trajectories (the table below lists every run)
        k = c["run_id"] == r
        label = (f"run {r}: {c['weight_set'][k][0]}, arm {c['arm_length_mm'][k][0]:.0f} mm, {c['mode'][k][0]}, "
                 f"radius {c['radius_mm'][k][0]:.0f} mm")
        data = [{"type": "scatter", "mode": "lines", "x": c["t_s"][k], "y": c[f"q{j}_norm"][k], "name": f"q{j}"}
                for j in range(1, JOINTS + 1) if f"q{j}_norm" in c]
        data.append({"type": "scatter", "mode": "lines", "x": [c["t_s"][k].min(), c["t_s"][k].max()], "y": [1, 1],
                     "name": "limit", "line": {"dash": "dash", "color": "#a4000f"}})
        figures[f"suture-run-{r}"] = {"data": data, "layout": {"title": {"text": label, "font": {"size": 12}},
                                                              "xaxis": {"title": {"text": "t (s)"}},
                                                              "yaxis": {"title": {"text": "|q_i / q_i,max|"}},
                                                              "height": 380}}
    for r in runs:
        k = c["run_id"] == r
        margins = [float(np.nanmin(c[f"q{j}_margin_rad"][k])) if f"q{j}_margin_rad" in c else
                   float(np.nanmin(c[f"q{j}_margin_mm"][k])) if f"q{j}_margin_mm" in c else np.nan
                   for j in range(1, JOINTS + 1)]
        rows.append([int(r), c["weight_set"][k][0], c["arm_length_mm"][k][0], c["mode"][k][0],
                     float(np.nanmax([np.nanmax(c[f"q{j}_norm"][k]) for j in range(1, JOINTS + 1)
                                      if f"q{j}_norm" in c])), *margins])
    header = ["run", "weights", "arm (mm)", "mode", "max |q/qmax|", *[f"q{j} margin" for j in range(1, JOINTS + 1)]]
    note = ("Each input's |q_i / q_i,max| along the suture, t in seconds; a value above 1 (the dashed line) is past the "
            "joint's range. Margins: min(q - lower, upper - q) over the run, rad (q3: mm); negative beyond a limit.")
    return [View("Joint trajectories and margins", note, figures,
                 "<h3>Every run</h3>" + table_html(header, rows, "suture-runs"))]
