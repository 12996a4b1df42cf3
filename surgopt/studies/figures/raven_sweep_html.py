"""raven-sweep's page (``surgopt report``): the best cost C (eq. 43) over each pair of design dimensions (link
angles, base tilts, port spacing), the paper's optimum marked with its rank, and the top designs."""
from __future__ import annotations

import numpy as np

from surgopt.html_report import View, table_html

PAIRS = (("alpha_deg", "beta_deg", "link angles"), ("bx_mm", "by_mm", "port spacing"),
         ("phi_x_deg", "phi_y_deg", "base tilts"))


def best_over(a: np.ndarray, b: np.ndarray, v: np.ndarray):
    """(a values, b values, matrix [b, a]) of the largest v at each (a, b) over every other dimension."""
    av, bv = np.unique(a), np.unique(b)
    m = np.full((len(bv), len(av)), -np.inf)
    np.maximum.at(m, (np.searchsorted(bv, b), np.searchsorted(av, a)), v)
    m[~np.isfinite(m)] = np.nan
    return av, bv, m


def views(run, parts) -> list[View]:
    from surgopt.studies.raven_sweep import PAPER_OPTIMUM, paper_optimum_rank

    names = ["design_id", "alpha_deg", "beta_deg", "phi_x_deg", "phi_y_deg", "phi_z_deg", "bx_mm", "by_mm", "iso_min",
             "cost", "zeta_cm", "iso_mean"]
    t = parts.table().select([n for n in names if n in parts.schema.names])
    c = {n: t[n].to_numpy(zero_copy_only=False) for n in t.column_names}
    cost = np.nan_to_num(c["cost"].astype(float), nan=-np.inf)
    rank = paper_optimum_rank(parts)
    figures = {}
    for a, b, what in PAIRS:
        if len(np.unique(c[a])) < 2 and len(np.unique(c[b])) < 2:
            continue
        av, bv, m = best_over(c[a], c[b], cost)
        data = [{"type": "heatmap", "x": av, "y": bv, "z": m, "colorscale": "Viridis",
                 "colorbar": {"title": {"text": "best C"}},
                 "hovertemplate": f"{a} %{{x}}<br>{b} %{{y}}<br>best C %{{z:.4g}}<extra></extra>"}]
        if rank is not None:
            data.append({"type": "scatter", "mode": "markers", "x": [PAPER_OPTIMUM[a]], "y": [PAPER_OPTIMUM[b]],
                         "name": f"the paper's optimum (rank {rank[0]:,})",
                         "marker": {"symbol": "star", "size": 16, "color": "#e4572e", "line": {"width": 1}}})
        figures[f"raven-{a}"] = {"data": data, "layout": {
            "title": {"text": f"best C over the {what}"}, "xaxis": {"title": {"text": a}},
            "yaxis": {"title": {"text": b}}, "height": 420, "legend": {"orientation": "h", "y": -0.25}}}
    order = np.argsort(-cost, kind="stable")[:50]
    top = [[c[n][i] for n in t.column_names] for i in order]
    note = (f"{parts.num_rows:,} designs; each map shows the largest cost C (Li et al. eq. 43, to be maximised) at "
            f"each pair of values over every other dimension. Link angles in degrees, spacings in mm.")
    if rank is not None:
        note += f" The paper's optimum ranks {rank[0]:,} here (C = {rank[1]['cost']:.4g})."
    hist = {"type": "histogram", "x": c["cost"][np.isfinite(c["cost"].astype(float))], "nbinsx": 60}
    figures["raven-hist"] = {"data": [hist], "layout": {"title": {"text": "distribution of C"},
                                                       "xaxis": {"title": {"text": "C"}}, "height": 420}}
    return [View("The design space", note, figures,
                 "<h3>Top 50 designs by C</h3><div class=\"scroll\">" + table_html(t.column_names, top, "top-designs")
                 + "</div>")]
