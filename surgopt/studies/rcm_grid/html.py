"""rcm-grid's page (``surgopt report``): the GII map over the RCM candidates with its argmax and, for the paper's
PA10-7C, Table I's RCMs with the paper's printed GII on hover; or the candidates as points (a list, a search)."""
from __future__ import annotations

import numpy as np

from surgopt.studies.page import View, table_html

FRAME = ("RCM candidates in the arm's base frame: x forward, z up (for the PA10-7C, z from the shoulder as in Locke & "
         "Patel 2007); GII = the Global Isotropy Index (eq. 7), dimensionless, 0 where a candidate does not reach the "
         "whole workspace.")


def _cols(parts, names):
    present = [n for n in names if n in parts.schema.names]
    t = parts.table().select(present)
    return {n: t[n].to_numpy(zero_copy_only=False) for n in present}


def grid_map(x, z, value, feasible):
    """The map as a (z, x) matrix of the best value over any other coordinate (y): NaN where nothing is feasible."""
    xs, zs = np.unique(x), np.unique(z)
    ix, iz = np.searchsorted(xs, x), np.searchsorted(zs, z)
    m = np.full((len(zs), len(xs)), np.nan)
    v = np.where(feasible, value, np.nan)
    for i, j, val in zip(iz, ix, v):
        if np.isfinite(val) and not (val <= m[i, j]):
            m[i, j] = val
    return xs, zs, m


def views(run, cfg, parts) -> list[View]:
    """The run's sections (``cfg``: its validated config), aggregates streamed from ``parts``."""
    from surgopt.studies.rcm_grid.study import PAPER_TABLE_I

    c = _cols(parts, ["candidate_id", "x_rcm_m", "y_rcm_m", "z_rcm_m", "gii", "feasible"])
    feasible = c["feasible"].astype(bool)
    best = int(np.nanargmax(np.where(feasible, c["gii"], -1))) if feasible.any() else None
    grid = cfg.candidates.grid is not None and len(c["x_rcm_m"]) == len(np.unique(c["candidate_id"])) and \
        run.manifest.get("plan", {}).get("name") in (None, "grid", "cull")
    traces = []
    if grid and len(np.unique(c["x_rcm_m"])) > 1 and len(np.unique(c["z_rcm_m"])) > 1:
        xs, zs, m = grid_map(c["x_rcm_m"], c["z_rcm_m"], c["gii"], feasible)
        traces.append({"type": "heatmap", "x": xs, "y": zs, "z": m, "colorscale": "Viridis",
                       "colorbar": {"title": {"text": "GII"}}, "hovertemplate": "x %{x:.3f} m<br>z %{y:.3f} m<br>"
                       "GII %{z:.5f}<extra></extra>", "name": "GII map"})
        title = f"GII over {len(c['x_rcm_m']):,} RCM candidates (blank: infeasible)"
    else:
        traces.append({"type": "scatter", "mode": "markers", "x": c["x_rcm_m"], "y": c["z_rcm_m"],
                       "marker": {"color": np.where(feasible, c["gii"], np.nan), "colorscale": "Viridis", "size": 8,
                                  "showscale": True, "colorbar": {"title": {"text": "GII"}}},
                       "text": [f"candidate {i}" for i in c["candidate_id"]],
                       "hovertemplate": "%{text}<br>x %{x:.3f} m<br>z %{y:.3f} m<br>GII %{marker.color:.5f}"
                                        "<extra></extra>", "name": "candidates"})
        title = f"GII of {len(c['x_rcm_m']):,} RCM candidates"
    if best is not None:
        traces.append({"type": "scatter", "mode": "markers", "x": [c["x_rcm_m"][best]], "y": [c["z_rcm_m"][best]],
                       "marker": {"symbol": "star", "size": 18, "color": "#e4572e", "line": {"color": "#000",
                                                                                              "width": 1}},
                       "name": f"argmax: GII {c['gii'][best]:.5f}",
                       "hovertemplate": "argmax<br>x %{x:.3f} m<br>z %{y:.3f} m<extra></extra>"})
    paper = cfg.robot.is_pa10
    rows = []
    if paper:
        px, pz, pg = (np.array(v) for v in zip(*PAPER_TABLE_I))
        ours = []
        for x0, z0 in zip(px, pz):
            d = np.hypot(c["x_rcm_m"] - x0, c["z_rcm_m"] - z0)
            k = int(np.argmin(d))
            ours.append(c["gii"][k] if d[k] < 0.006 else np.nan)
        traces.append({"type": "scatter", "mode": "markers", "x": px, "y": pz, "name": "Table I (the paper's RCMs)",
                       "marker": {"symbol": "circle-open", "size": 12, "color": "#fff", "line": {"width": 2}},
                       "customdata": np.stack([pg, np.array(ours, float)], axis=1),
                       "hovertemplate": "Table I<br>x %{x:.3f} m, z %{y:.3f} m<br>paper GII %{customdata[0]:.4f}"
                                        "<br>ours %{customdata[1]:.5f}<extra></extra>"})
        rows = [[f"{x0:.3f}", f"{z0:.3f}", f"{g0:.4f}", o] for x0, z0, g0, o in zip(px, pz, pg, ours)]
    layout = {"title": {"text": title}, "xaxis": {"title": {"text": "x_rcm_m (m)"}},
              "yaxis": {"title": {"text": "z_rcm_m (m)"}}, "legend": {"orientation": "h", "y": -0.2},
              "height": 560}
    html = ""
    if rows:
        html = ("<h3>Table I beside this run</h3>" + table_html(["x (m)", "z (m)", "paper GII", "this run's GII"],
                                                                  rows, "table-i"))
    out = [View("GII map", FRAME + (" Hover a circle for the paper's printed GII." if paper else ""),
                {"gii-map": {"data": traces, "layout": layout}}, html)]
    if "max_tip_error_mm" in parts.schema.names:
        out.append(_tracking(parts))
    return out


def _tracking(parts) -> View:
    """rcm-track: the helical path's tip and RCM errors at each candidate (Table I's error column)."""
    c = _cols(parts, ["candidate_id", "x_rcm_m", "z_rcm_m", "gii", "feasible", "max_tip_error_mm",
                      "mean_tip_error_mm", "max_rcm_error_mm"])
    label = [f"({x:.3f}, {z:.3f})" for x, z in zip(c["x_rcm_m"], c["z_rcm_m"])]
    traces = [{"type": "bar", "x": label, "y": c[k], "name": k} for k in ("max_tip_error_mm", "mean_tip_error_mm",
                                                                           "max_rcm_error_mm") if k in c]
    layout = {"barmode": "group", "title": {"text": "tracking error at each RCM (NaN: the path is not reachable)"},
              "xaxis": {"title": {"text": "RCM (x, z) m"}}, "yaxis": {"title": {"text": "error (mm)"}}, "height": 460}
    g = {"type": "scatter", "mode": "markers", "x": c["gii"], "y": c["max_tip_error_mm"], "text": label,
         "hovertemplate": "RCM %{text}<br>GII %{x:.4f}<br>max tip error %{y:.2f} mm<extra></extra>",
         "marker": {"size": 9}}
    return View("Tracking the helical path (rcm-track)",
                "Joint-level P control along the paper's helical test path at each RCM (Sec. IV): does a good GII "
                "mean a small error? Errors in mm; the RCM error is the RCM's distance from the tool line.",
                {"track-errors": {"data": traces, "layout": layout},
                 "track-vs-gii": {"data": [g], "layout": {"title": {"text": "max tip error against GII"},
                                                          "xaxis": {"title": {"text": "GII"}},
                                                          "yaxis": {"title": {"text": "max tip error (mm)"}},
                                                          "height": 460}}})
