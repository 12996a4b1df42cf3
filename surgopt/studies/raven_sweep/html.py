"""raven-sweep's page (``surgopt report``): the best cost C (eq. 43) over each pair of design dimensions (link
angles, base tilts, port spacing), the paper's optimum marked with its rank, and the top designs."""
from __future__ import annotations

import numpy as np

from surgopt.studies.page import View, table_html

PAIRS = (("alpha_deg", "beta_deg", "link angles"), ("bx_mm", "by_mm", "port spacing"),
         ("phi_x_deg", "phi_y_deg", "base tilts"))


def best_over(a: np.ndarray, b: np.ndarray, v: np.ndarray):
    """(a values, b values, matrix [b, a]) of the largest v at each (a, b) over every other dimension."""
    av, bv = np.unique(a), np.unique(b)
    m = np.full((len(bv), len(av)), -np.inf)
    np.maximum.at(m, (np.searchsorted(bv, b), np.searchsorted(av, a)), v)
    m[~np.isfinite(m)] = np.nan
    return av, bv, m


def views(run, cfg, parts) -> list[View]:
    """The run's sections (``cfg``: its validated config), aggregates streamed from ``parts``."""
    from surgopt.studies.raven_sweep.study import PAPER_OPTIMUM, PARAMS, paper_optimum_rank

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
    shown = [int(i) for i in order[:WORKSPACES]]
    spaces = [_workspace(cfg, {p: float(c[p][i]) for p in PARAMS}) for i in shown]
    labels = [f"design {c['design_id'][i]} (C {c['cost'][i]:.4g})" for i in shown]
    if rank is not None:
        spaces.append(_workspace(cfg, dict(PAPER_OPTIMUM)))
        labels.append(f"the paper's optimum (rank {rank[0]:,})")
    note = (f"{parts.num_rows:,} designs; each map shows the largest cost C (Li et al. eq. 43, to be maximised) at "
            f"each pair of values over every other dimension. Link angles in degrees, spacings in mm.")
    if rank is not None:
        note += f" The paper's optimum ranks {rank[0]:,} here (C = {rank[1]['cost']:.4g})."
    hist = {"type": "histogram", "x": c["cost"][np.isfinite(c["cost"].astype(float))], "nbinsx": 60}
    figures["raven-hist"] = {"data": [hist], "layout": {"title": {"text": "distribution of C"},
                                                       "xaxis": {"title": {"text": "C"}}, "height": 420}}
    space_view = View(
        "A design's common workspace", "The region of the reference plane all four arms reach (blue), mm, with each "
        "arm's port (triangles), for the top designs and the paper's optimum; choose one below (Li et al. Fig. 8).",
        {}, '<select id="rv-design">' + "".join(f'<option value="{k}">{lab}</option>' for k, lab in enumerate(labels))
        + '</select><div id="rv-space" class="plot"></div>', {"spaces": spaces, "labels": labels}, "rv-data",
        WORKSPACE_SCRIPT)
    return [View("The design space", note, figures,
                 "<h3>Top 50 designs by C</h3><div class=\"scroll\">" + table_html(t.column_names, top, "top-designs")
                 + "</div>"), space_view]


#: Designs whose common workspace the page carries (the top ones by C; the paper's optimum besides).
WORKSPACES = 10
#: The most grid cells a side of an embedded workspace keeps (every other cell beyond).
MAX_CELLS = 120


def _workspace(cfg, params: dict) -> dict:
    """One design's common workspace on the reference plane (a 0/1 grid, thinned to MAX_CELLS a side) and ports."""
    from surgopt.studies.raven_sweep.study import design_fields

    xs, ys, ports, _, common = design_fields(cfg, params)
    sx, sy = max(1, -(-len(xs) // MAX_CELLS)), max(1, -(-len(ys) // MAX_CELLS))
    grid = (np.asarray(common)[::sx, ::sy] > 0).astype(np.int8)
    return {"x": np.asarray(xs)[::sx], "y": np.asarray(ys)[::sy], "z": grid.T, "ports": np.asarray(ports)[:, :2]}


WORKSPACE_SCRIPT = r"""
(function(){
const D = JSON.parse(document.getElementById('rv-data').textContent);
function show(k){ const w = D.spaces[k];
  const data = [{type:'heatmap', x:w.x, y:w.y, z:w.z, showscale:false, colorscale:[[0,'rgba(255,255,255,0)'],[1,'#9ecae1']], zmin:0, zmax:1,
                 hoverinfo:'skip'},
                {type:'scatter', mode:'markers', x:w.ports.map(p=>p[0]), y:w.ports.map(p=>p[1]), name:'ports',
                 marker:{symbol:'triangle-up', size:12, color:'#d62728'}}];
  return Plotly.react('rv-space', data, {title:{text:D.labels[k]}, height:520, xaxis:{title:{text:'x (mm)'}},
                      yaxis:{title:{text:'y (mm)'}, scaleanchor:'x'}}, {displaylogo:false, responsive:true}); }
document.getElementById('rv-design').addEventListener('change', e => show(+e.target.value));
PLOTS.push(['rv-space', function(){ return show(0); }]);
})();
"""
