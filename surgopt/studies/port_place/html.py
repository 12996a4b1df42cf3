"""port-place's page (``surgopt report``): the patient in 3-D with every candidate site coloured by the best feasible
cost that uses it, the chosen ports and their shafts, the target coloured by the instruments' dexterity; a table of
the top layouts where clicking a row redraws the scene and the clinical checks for that layout; why layouts fail;
the metrics of the top layouts in parallel coordinates.

Aggregates only (a run holds millions of rows): the per-site best cost (one streamed pass), the TOP_FEASIBLE
least-cost feasible layouts and the TOP_INFEASIBLE least-cost infeasible ones (for the filter), the per-site
reach and isotropy tables (n_sites x n_points, from the config), the reasons' counts, and the PARALLEL best
feasible layouts' metrics."""
from __future__ import annotations

import math

import numpy as np

from surgopt.robots.dvrk.platforms import role_of
from surgopt.studies.page import View, table_html
from surgopt.studies.port_place.scene import body_trace, docked_scene, organ_traces, scene_marks
from surgopt.studies.port_place.geometry import (FRAME_TEXT, X_LABEL, Y_LABEL, Z_LABEL, from_landmark,
                                                 reference_landmark, skin_words)

TOP_FEASIBLE = 300
TOP_INFEASIBLE = 100
PARALLEL = 2000
COLOURS = {"psm1": "#d62728", "psm2": "#ff7f0e", "psm3": "#2ca02c", "ecm": "#1f77b4"}
FRAME = FRAME_TEXT[0].upper() + FRAME_TEXT[1:] + ". Costs are to be minimised."
LAYOUT_COLUMNS = ("design_id", "cost", "feasible", "common_reach", "dexterity_mean", "manipulation_angle_centre_deg",
                  "azimuth_imbalance_deg", "camera_coverage", "min_port_spacing_mm", "external_clearance_mm")
PARALLEL_COLUMNS = ("cost", "common_reach", "dexterity_mean", "manipulation_angle_centre_deg", "azimuth_imbalance_deg",
                    "camera_coverage", "min_port_spacing_mm", "psm_to_target_mm")


def _site_best(parts, arms, n_sites: int) -> np.ndarray:
    """The least cost of a feasible layout that puts any arm at each site (NaN where none does), one pass."""
    best = np.full(n_sites, np.inf)
    for t in parts.only(["feasible", "cost", *[f"{a}_site" for a in arms]]):
        ok = t["feasible"].to_numpy(zero_copy_only=False)
        if not ok.any():
            continue
        cost = t["cost"].to_numpy()[ok]
        for a in arms:
            np.minimum.at(best, t[f"{a}_site"].to_numpy()[ok], cost)
    best[~np.isfinite(best)] = np.nan
    return best


def views(run, cfg, parts) -> list[View]:
    """The run's sections (``cfg``: its validated config), aggregates streamed from ``parts``."""
    from surgopt.studies.port_place.report import CLINICAL_COLUMNS, clinical_checks, least_cost_layouts
    from surgopt.studies.port_place.columns import CART_COLUMNS, arms_of, docking_columns, roll_columns
    from surgopt.studies.port_place.model import model_of
    from surgopt.studies.port_place.tables import outside_length_m

    from surgopt.studies.port_place.rolls import first_docking

    arms = list(arms_of(cfg))
    model = model_of(first_docking(cfg))  # the sites' reach at the (first) docking
    sites_m, (reach, dex) = model.sites_m, model.site_reach
    sites = sites_m * 1000
    targets = model.targets_m * 1000
    site_best = _site_best(parts, arms, len(sites))
    wanted = sorted({*LAYOUT_COLUMNS, *[f"{a}_{s}" for a in arms for s in ("site", "x_mm", "y_mm", "z_mm")],
                     *CLINICAL_COLUMNS, "infeasible",
                     *[f"{a}_elevation_deg" for a in arms[:-1]], *PARALLEL_COLUMNS,
                     *roll_columns(cfg), *docking_columns(cfg), *CART_COLUMNS} & set(parts.schema.names))
    best = least_cost_layouts(parts, max(PARALLEL, TOP_FEASIBLE), True, wanted)  # the table's and the lines'
    feasible = best.slice(0, TOP_FEASIBLE)
    infeasible = least_cost_layouts(parts, TOP_INFEASIBLE, False, wanted) if cfg.rows_stored == "all" else None
    import pyarrow as pa

    top = pa.concat_tables([t for t in (feasible, infeasible) if t is not None and t.num_rows]) \
        if (feasible.num_rows or (infeasible is not None and infeasible.num_rows)) else feasible
    layouts = {c: top[c].to_numpy(zero_copy_only=False) for c in wanted}
    mark_name, mark = reference_landmark(cfg.patient)
    skin = {}  # a site's distance along the skin, once per site (a mesh's wall is ray-cast along each leg)
    for a in arms:  # each port from the reference landmark, in words (the closing report's): top view, along the skin
        layouts[f"{a}_from"] = np.array([from_landmark(x, y, mark) for x, y in zip(layouts[f"{a}_x_mm"],
                                                                                  layouts[f"{a}_y_mm"])])
        for s, x, y in zip(layouts[f"{a}_site"], layouts[f"{a}_x_mm"], layouts[f"{a}_y_mm"]):
            if s not in skin:  # the sites are one grid for every arm
                skin[s] = skin_words(cfg.patient, mark, x, y)
        layouts[f"{a}_skin"] = np.array([skin[s] for s in layouts[f"{a}_site"]], dtype=object)
    from surgopt.kinematics.port.reasons import REASONS

    arm_lines, cam_lines = (None if lines is None else lines * 1000  # a serial arm's centre lines, every site
                            for lines in (model.instruments.docked_lines(model, sites_m),
                                          model.endoscope.docked_lines(model, sites_m)))
    reach3 = dex3 = None
    if model.third_site_reach is not None:  # the third instrument docks in frames of its own (the Si PSM3)
        reach3, dex3 = model.third_site_reach
        reach3, dex3 = np.asarray(reach3, bool).astype(np.int8), np.round(np.asarray(dex3, float), 4)
    from surgopt.studies.port_place.layout import layout_isotropy
    from surgopt.studies.port_place.designs import searched_docking

    layout_iso = None  # a search's trials docked in frames of their own: each layout's target colours, its own
    if searched_docking(cfg):
        rows = top.to_pylist()
        layout_iso = [[None if np.isnan(v) else round(float(v), 4) for v in layout_isotropy(model, r)] for r in rows]
    data = {
        "docked": docked_scene(cfg, top.to_pylist()),
        "layout_iso": layout_iso,
        "arm_lines": arm_lines, "cam_lines": cam_lines, "outside_mm": outside_length_m(cfg) * 1000,
        "arms": arms, "colours": [COLOURS[a] for a in arms], "sites": sites, "site_best": site_best,
        "targets": targets, "centre": np.asarray(cfg.target.centre_mm, float),
        "reach": np.asarray(reach, bool).astype(np.int8), "dex": np.round(np.asarray(dex, float), 4),
        "reach3": reach3, "dex3": dex3,
        "layouts": layouts, "n_layouts": top.num_rows, "body": body_trace(cfg), "organs": organ_traces(cfg),
        "checks": [[label, list(fields), digits, joiner, clinical,
                    None if band is None else [band[0], band[1] if math.isfinite(band[1]) else None]]
                   for label, fields, digits, joiner, clinical, band in clinical_checks(cfg)],
        "reasons": [[int(bit), why] for bit, why in REASONS.items()],
        "axes": [X_LABEL, Y_LABEL, Z_LABEL],
        **scene_marks(cfg),
    }
    rows = [[str(layouts[c][i]) if c == "design_id" else layouts[c][i]  # an id, not a quantity: no separators
             for c in LAYOUT_COLUMNS if c in layouts]
            + [", ".join(str(layouts[f"{a}_site"][i]) for a in arms)] for i in range(top.num_rows)]
    header = [c for c in LAYOUT_COLUMNS if c in layouts] + ["sites (" + ", ".join(arms) + ")"]
    table = table_html(header, rows, "pp-layouts", row_attrs=lambda i: f' data-i="{i}"')
    filters = ('<div><label><input type="checkbox" id="pp-feasible" checked> feasible only</label>'
               '<label>least instrument elevation (deg) <input type="number" id="pp-elev" value="" step="5" '
               'style="width:5em"></label><label>least external clearance (mm) <input type="number" id="pp-clear" '
               'value="" step="10" style="width:5em"></label><span id="pp-count" class="note"></span></div>')
    reasons = []
    if cfg.rows_stored == "all":  # one pass over one column (the infeasible rows' reasons are not kept otherwise)
        counts = dict.fromkeys(REASONS, 0)
        for t in parts.only(["infeasible"]):
            bad = t["infeasible"].to_numpy()
            for bit in counts:
                counts[bit] += int(np.count_nonzero(bad & bit))
        reasons = [(REASONS[bit], n) for bit, n in counts.items()]
    views_out = [View(
        "The layout on the patient", FRAME + (" Click a layout in the table to redraw the scene and the checks. Sites "
                                              "are coloured by the least cost of a feasible layout using them (grey: "
                                              "none); target points by the smaller isotropy of the instruments at the "
                                              "chosen ports (black: not reached by every instrument)."),
        {}, '<div class="row"><div><div id="pp-scene" class="plot" style="min-height:620px"></div></div>'
            '<div style="flex:0 1 460px"><h3 id="pp-title"></h3><table id="pp-checks"><thead><tr><th>check</th>'
            '<th>this layout</th><th>clinical number</th><th>within</th></tr></thead><tbody></tbody></table>'
            '<table id="pp-ports"><thead><tr><th>arm</th><th>site</th><th>x_mm</th><th>y_mm</th><th>z_mm</th>'
            f'<th>from the {mark_name} (mm, top view)</th><th>from the {mark_name} along the skin (across, then '
            'along)</th></tr></thead><tbody></tbody></table></div></div>'
            f"<h3>Top layouts: the {feasible.num_rows} feasible of least cost"
            + (f" and the {infeasible.num_rows} infeasible of least cost" if infeasible is not None else "")
            + f" (of {parts.num_rows:,} rows)</h3>{filters}"
            + f"<div class=\"scroll\">{table}</div>",
        data, "pp-data", SCENE_SCRIPT)]
    if feasible.num_rows:
        views_out.append(View("The best layout, top view", FRAME + " The feasible layout of least cost: each arm's port "
                              "(from the " + mark_name + "), the candidate sites, the target's centre and the "
                              "landmarks.", {"pp-top": top_view_figure(cfg, model, feasible.slice(0, 1).to_pylist()[0],
                                                                       arms)}))
    if reasons:
        views_out.append(View("Why layouts fail", "Counts of layouts failing each check (a layout can fail several).",
                              {"pp-reasons": {"data": [{"type": "bar", "orientation": "h", "y": [r for r, _ in reasons],
                                                        "x": [v for _, v in reasons]}],
                                              "layout": {"height": 360, "margin": {"l": 380},
                                                         "xaxis": {"title": {"text": "layouts"}},
                                                         "yaxis": {"autorange": "reversed"}}}}))
    par = best
    if par.num_rows > 1:
        dims = [{"label": c, "values": par[c].to_numpy(zero_copy_only=False)} for c in PARALLEL_COLUMNS
                if c in par.column_names]
        views_out.append(View("The best layouts' metrics", f"The {par.num_rows:,} feasible layouts of least cost, one "
                              "line each; drag along an axis to select a range.",
                              {"pp-parallel": {"data": [{"type": "parcoords", "dimensions": dims,
                                                         "line": {"color": par["cost"].to_numpy(),
                                                                  "colorscale": "Viridis", "reversescale": True}}],
                                               "layout": {"height": 460, "margin": {"l": 80, "r": 80}}}}))
    return views_out


def top_view_figure(cfg, model, row: dict, arms: list[str]) -> dict:
    """A layout seen from above (x lateral, y toward the head, mm): the body's outline (a dome's base ellipse; a
    mesh's candidate sites alone), the candidate sites, the layout's ports by arm, the target's centre and the
    landmarks; a static figure a page can hold once per run (the comparison page's, issue 56 item 3)."""
    sites = model.sites_m * 1000
    traces = []
    if cfg.patient.shape == "dome":
        a, b, _ = cfg.patient.semi_axes_mm
        t = np.linspace(0.0, 2 * math.pi, 121)
        traces.append({"type": "scatter", "mode": "lines", "x": a * np.cos(t), "y": b * np.sin(t),
                       "line": {"color": "#c9b8a6"}, "name": "body (the dome's base)", "hoverinfo": "skip"})
    traces.append({"type": "scatter", "mode": "markers", "x": sites[:, 0], "y": sites[:, 1],
                   "marker": {"size": 4, "color": "#9aa5b1"}, "name": "candidate sites"})
    for a in arms:
        traces.append({"type": "scatter", "mode": "markers+text", "x": [row[f"{a}_x_mm"]], "y": [row[f"{a}_y_mm"]],
                       "text": [role_of(a)], "textposition": "top center",
                       "marker": {"size": 13, "color": COLOURS[a]}, "name": f"{role_of(a)} port"})
    c = cfg.target.centre_mm
    traces.append({"type": "scatter", "mode": "markers", "x": [c[0]], "y": [c[1]],
                   "marker": {"size": 11, "symbol": "x", "color": "#c0392b"}, "name": "target centre"})
    marks = scene_marks(cfg)["landmarks"]
    if marks:
        traces.append({"type": "scatter", "mode": "markers+text", "x": [m[1] for m in marks],
                       "y": [m[2] for m in marks], "text": [m[0] for m in marks], "textposition": "bottom center",
                       "marker": {"size": 8, "symbol": "diamond", "color": "#7a3e9d"}, "name": "landmarks"})
    return {"data": traces, "layout": {
        "height": 460, "title": {"text": f"layout {row['design_id']} · cost {row['cost']:.4f}", "font": {"size": 13}},
        "xaxis": {"title": {"text": X_LABEL}}, "yaxis": {"title": {"text": Y_LABEL}, "scaleanchor": "x"}}}


SCENE_SCRIPT = r"""
(function(){
const D = JSON.parse(document.getElementById('pp-data').textContent);
const L = D.layouts, arms = D.arms;
function col(name, i){ return L[name] ? L[name][i] : null; }
function fmt(v, d){ return (v === null || v === undefined) ? 'n/a' : (typeof v === 'number' ? v.toFixed(d) : String(v)); }
function base(){
  const body = D.body;
  const used = D.sites.map((p, i) => i).filter(i => D.site_best[i] !== null);
  const unused = D.sites.map((p, i) => i).filter(i => D.site_best[i] === null);
  const pick = (idx, k) => idx.map(i => D.sites[i][k]);
  const sites = {type:'scatter3d', mode:'markers', x:pick(used, 0), y:pick(used, 1), z:pick(used, 2),
    marker:{size:3.5, color:used.map(i => D.site_best[i]), colorscale:'Viridis', reversescale:true, showscale:true,
            colorbar:{title:{text:'least feasible cost'}, x:1.0, y:0.25, len:0.45}}, name:'candidate sites',
    text:used.map(i => 'site '+i+'<br>least feasible cost '+fmt(D.site_best[i],4)), hoverinfo:'text'};
  const none = {type:'scatter3d', mode:'markers', x:pick(unused, 0), y:pick(unused, 1), z:pick(unused, 2),
    marker:{size:2.5, color:'#9aa5b1'}, name:'sites no feasible layout uses',
    text:unused.map(i => 'site '+i+': no feasible layout uses it'), hoverinfo:'text'};
  const marks = D.landmarks.length ? [{type:'scatter3d', mode:'markers+text', x:D.landmarks.map(m=>m[1]),
    y:D.landmarks.map(m=>m[2]), z:D.landmarks.map(m=>m[3]), text:D.landmarks.map(m=>m[0]), textposition:'top center',
    marker:{size:5, symbol:'diamond', color:'#7a3e9d'}, name:D.landmarks_assumed ? 'landmarks (assumed: the dome has none of its own)' : 'landmarks',
    hoverinfo:'text'}] : [];
  const region = D.region ? [{type:'scatter3d', mode:'lines', x:D.region.map(p=>p[0]), y:D.region.map(p=>p[1]),
    z:D.region.map(p=>p[2]), line:{color:'#d9822b', width:5}, name:'marked region', hoverinfo:'skip'}] : [];
  const sides = {type:'scatter3d', mode:'text', x:D.sides.map(s=>s[1]), y:D.sides.map(s=>s[2]), z:D.sides.map(s=>s[3]),
    text:D.sides.map(s=>s[0]), textfont:{size:12, color:'#52606d'}, name:'sides', showlegend:false, hoverinfo:'skip'};
  const pt = (k) => D.bedside.map(p => p === null ? null : p[k]);
  const bedside = D.bedside.length ? [{type:'scatter3d', mode:'lines', x:pt(0), y:pt(1), z:pt(2),
    line:{color:'#8d6e63', width:2}, name:"the bedside the links clear, near the body (table, rails, the patient's arms and legs)",
    hoverinfo:'skip', connectgaps:false}] : [];
  const lp = (k) => (D.landmark_lines || []).map(p => p === null ? null : p[k]);
  const lines = (D.landmark_lines || []).length ? [{type:'scatter3d', mode:'lines', x:lp(0), y:lp(1), z:lp(2),
    line:{color:'#7a3e9d', width:3, dash:'dot'}, name:'lines between the landmarks, on the skin', hoverinfo:'name',
    connectgaps:false}] : [];
  return [body, ...(D.organs || []), sites, none, ...marks, ...lines, ...region, sides, ...bedside];
}
function draw(i){
  // the checks, ports and title at once; the scene on the next frame, once they are painted (software WebGL takes
  // seconds), and only for the latest click: a click while a scene is drawn replaces the one waiting
  showLayout(i);
  const el = document.getElementById('pp-scene'); el.dataset.requested = String(i);
  return new Promise(r => requestAnimationFrame(() => setTimeout(() => {  // painted: when (ms since navigation)
    el.dataset.paintedMs = String(Math.round(performance.now())); r(); }, 0))).then(() => {
    if (el.dataset.requested !== String(i)) return null;
    return Plotly.react('pp-scene', sceneTraces(i), sceneLayout(i), {displaylogo:false, responsive:true}).then(() => {
      if (el.dataset.requested === String(i)) el.dataset.layout = String(col('design_id', i)); });
  });
}
function sceneTraces(i){
  const traces = base();
  const ins = arms.slice(0, -1).map(a => col(a+'_site', i));
  // the third instrument's own tables where it docks in frames of its own (the Si PSM3), else the shared ones
  const R = ins.map((s, a) => (a === 2 && D.reach3) ? D.reach3[s] : D.reach[s]);
  const X = ins.map((s, a) => (a === 2 && D.dex3) ? D.dex3[s] : D.dex[s]);
  const reachAll = D.targets.map((p, k) => R.every(r => r[k] === 1));
  const iso = D.layout_iso ? D.layout_iso[i]  // a searched trial's own docking
    : D.targets.map((p, k) => reachAll[k] ? Math.min.apply(null, X.map(x => x[k])) : null);
  traces.push({type:'scatter3d', mode:'markers', x:D.targets.map(p=>p[0]), y:D.targets.map(p=>p[1]), z:D.targets.map(p=>p[2]),
    marker:{size:2.5, color:iso.map(v=>v===null?NaN:v), colorscale:'Magma', showscale:true,
            colorbar:{title:{text:'isotropy'}, x:1.0, y:0.75, len:0.45}}, name:'target (isotropy)',
    text:iso.map(v=>v===null?'not reached by every instrument':'smaller isotropy '+v.toFixed(3)), hoverinfo:'text'});
  arms.forEach((a, j) => {
    const p = [col(a+'_x_mm', i), col(a+'_y_mm', i), col(a+'_z_mm', i)];
    traces.push({type:'scatter3d', mode:'lines+markers', x:[p[0], D.centre[0]], y:[p[1], D.centre[1]], z:[p[2], D.centre[2]],
      line:{color:D.colours[j], width:6}, marker:{size:[7, 0.1], color:D.colours[j]}, name:a.toUpperCase()+' site '+col(a+'_site', i)});
    const serial = (j < arms.length - 1) ? D.arm_lines : D.cam_lines;
    const site = col(a+'_site', i);
    if (serial && serial[site]) {  // a serial arm's centre line at its docked pose: base, joints, flange, port
      const l = serial[site].filter(q => q[0] !== null);
      traces.push({type:'scatter3d', mode:'lines+markers', x:l.map(q=>q[0]), y:l.map(q=>q[1]), z:l.map(q=>q[2]),
        line:{color:D.colours[j], width:9}, marker:{size:3, color:'#333'}, opacity:0.8, name:a.toUpperCase()+' arm',
        hoverinfo:'name'});
    } else if (!serial) {  // an RCM arm: its instrument's shaft outside the body, behind the port
      const d = [p[0]-D.centre[0], p[1]-D.centre[1], p[2]-D.centre[2]]; const n = Math.hypot(d[0], d[1], d[2]) || 1;
      const q = [0, 1, 2].map(k => p[k] + d[k] / n * D.outside_mm);
      traces.push({type:'scatter3d', mode:'lines', x:[p[0], q[0]], y:[p[1], q[1]], z:[p[2], q[2]], showlegend:j === 0,
        line:{color:D.colours[j], width:3, dash:'dash'}, name:'shafts outside (' + D.outside_mm.toFixed(0) + ' mm)',
        hoverinfo:'name'});
    }
  });
  const dock = D.docked ? D.docked[i] : null;  // the cart and its arms as this layout's row docks them
  if (dock) {
    const xyz = (l, k) => l.map(q => q === null ? null : q[k]);
    // one legend entry for them all: a click on it hides the cart and its arms (the scene back to the body's scale)
    const group = {legendgroup:'docked'};
    dock.arms.forEach(([role, l], k) => { const j = arms.indexOf(role.toLowerCase());
      traces.push({type:'scatter3d', mode:'lines', x:xyz(l, 0), y:xyz(l, 1), z:xyz(l, 2), connectgaps:false,
        line:{color:j >= 0 ? D.colours[j] : '#333', width:4}, name:role+' setup joints and links (docked)',
        showlegend:false, hoverinfo:'name', ...group}); });
    traces.push({type:'scatter3d', mode:'lines', x:xyz(dock.cart, 0), y:xyz(dock.cart, 1), z:xyz(dock.cart, 2),
      connectgaps:false, line:{color:'#333', width:3}, hoverinfo:'name', ...group,
      name:"the cart (its base on the floor, its column) and its arms as docked: click to hide or show"});
  }
  return traces;
}
function sceneLayout(i){
  return {uirevision:'keep', height:620, margin:{l:0, r:0, t:30, b:0}, showlegend:true, legend:{orientation:'v', x:0, y:1, font:{size:10}, bgcolor:'rgba(255,255,255,0.7)'},
    title:{text:'layout '+col('design_id', i)+' · cost '+fmt(col('cost', i), 4)+(col('feasible', i)?'':' · INFEASIBLE'), font:{size:13}},
    scene:{aspectmode:'data', xaxis:{title:{text:D.axes[0]}}, yaxis:{title:{text:D.axes[1]}},
           zaxis:{title:{text:D.axes[2]}}, camera:{eye:{x:-1.2, y:-1.6, z:1.0}}}};
}
function showLayout(i){
  document.getElementById('pp-title').textContent = 'Layout ' + col('design_id', i) + (col('feasible', i) ? '' :
    ' (infeasible)');
  const body = document.querySelector('#pp-checks tbody'); body.innerHTML = '';
  D.checks.forEach(c => { const tr = document.createElement('tr');
    const v = c[1].map(f => fmt(col(f, i), c[2])).join(c[3]);
    const out = c[5] && c[1].some(f => col(f, i) < c[5][0] || (c[5][1] !== null && col(f, i) > c[5][1]));
    if (out) tr.className = 'flag';
    [c[0], v, c[4], c[5] ? (out ? 'OUTSIDE' : 'yes') : ''].forEach(t => { const td = document.createElement('td'); td.textContent = t; tr.appendChild(td); });
    body.appendChild(tr); });
  const bad = col('infeasible', i);
  if (bad) { D.reasons.forEach(r => { if (bad & r[0]) { const tr = document.createElement('tr'); tr.className = 'flag';
    tr.innerHTML = '<td colspan="4"></td>'; tr.firstChild.textContent = 'fails: ' + r[1]; body.appendChild(tr); } }); }
  const ports = document.querySelector('#pp-ports tbody'); ports.innerHTML = '';
  arms.forEach(a => { const tr = document.createElement('tr');
    [a.toUpperCase(), col(a+'_site', i), fmt(col(a+'_x_mm', i), 0), fmt(col(a+'_y_mm', i), 0), fmt(col(a+'_z_mm', i), 0),
     col(a+'_from', i), col(a+'_skin', i)]
      .forEach(t => { const td = document.createElement('td'); td.textContent = t; tr.appendChild(td); });
    ports.appendChild(tr); });
  document.querySelectorAll('#pp-layouts tbody tr').forEach(tr => tr.classList.toggle('selected', +tr.dataset.i === i));
  document.getElementById('pp-scene').dataset.shown = String(col('design_id', i));
}
function filter(){
  const feas = document.getElementById('pp-feasible').checked;
  const elev = parseFloat(document.getElementById('pp-elev').value);
  const clear = parseFloat(document.getElementById('pp-clear').value);
  let shown = 0;
  document.querySelectorAll('#pp-layouts tbody tr').forEach(tr => { const i = +tr.dataset.i;
    let ok = !feas || col('feasible', i);
    if (!isNaN(elev)) ok = ok && Math.min.apply(null, arms.slice(0, -1).map(a => col(a+'_elevation_deg', i))) >= elev;
    if (!isNaN(clear)) ok = ok && col('external_clearance_mm', i) >= clear;
    tr.style.display = ok ? '' : 'none'; shown += ok ? 1 : 0; });
  document.getElementById('pp-count').textContent = ' ' + shown + ' of ' + D.n_layouts + ' layouts shown';
}
document.querySelectorAll('#pp-layouts tbody tr').forEach(tr => { tr.style.cursor = 'pointer';
  tr.addEventListener('click', () => draw(+tr.dataset.i)); });
['pp-feasible', 'pp-elev', 'pp-clear'].forEach(id => document.getElementById(id).addEventListener('input', filter));
filter();
PLOTS.unshift(['pp-scene', function(){ const t0 = performance.now();
  if (document.getElementById('pp-scene').dataset.requested) return;  // a click asked for it first
  const done = D.n_layouts > 0 ? draw(0) : Plotly.newPlot('pp-scene', base(), {height:620, scene:{aspectmode:'data'}});
  return Promise.resolve(done).then(function(){ document.body.dataset.sceneMs = String(Math.round(performance.now() - t0)); }); }]);
})();
"""
