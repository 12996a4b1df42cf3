"""``surgopt report``: one self-contained HTML page per run, per comparison of runs, and per store.

A page is one file that works offline from ``file://``: Plotly's JavaScript, every style and every script are
embedded, nothing is fetched (a hospital laptop, an e-mail attachment). It never embeds a run's raw rows: each
study's views (``Study.html_views``, in ``surgopt/studies/<study>/html.py``) compute aggregates from the
Parquet parts (per-site bests, the top N, histograms, a Pareto front) and say so on the page; ``surgopt export``
gets the rest. This module knows no study by name: it lays out the page (the run's headline, the study's views,
the summary tables, the config that was hashed, provenance, notes) and the index and comparison pages.
One module (~430 lines): the three pages share one frame (its policy, scripts and stamp).
"""
from __future__ import annotations

import json

import numpy as np
from surgopt.results import config_of
from surgopt.studies.page import View, esc, headline_cell, table_html

#: What every page says about what it embeds.
AGGREGATE_NOTE = ("This page embeds aggregates of the run's rows (computed from its Parquet parts), not the rows "
                  "themselves; `surgopt export {key} --out rows.csv` writes every row.")


#: What JSON embedded in a <script> never holds as itself (issue 55 item 5): '<', '>' and '&' (so that no string can
#: end the script, open a comment ('<!--' keeps a script from running at all) or an entity), and the two line
#: separators JavaScript reads as line ends; each as its \\u escape, which JSON.parse reads back as the character.
SCRIPT_SAFE = str.maketrans({"<": "\\u003c", ">": "\\u003e", "&": "\\u0026", "\u2028": "\\u2028",
                             "\u2029": "\\u2029"})


def to_json(obj) -> str:
    """JSON for embedding in a <script>: numpy values as numbers (NaN and inf as null), '<', '>', '&' and the line
    separators escaped (``SCRIPT_SAFE``)."""
    def default(o):
        if isinstance(o, np.ndarray):
            return o.tolist()
        if isinstance(o, np.integer):
            return int(o)
        if isinstance(o, np.floating):
            return float(o)
        if isinstance(o, np.bool_):
            return bool(o)
        raise TypeError(type(o).__name__)

    text = json.dumps(_finite(obj), default=default, separators=(",", ":"), allow_nan=False)  # JSON has no NaN
    return text.translate(SCRIPT_SAFE)


def _finite(obj):
    if isinstance(obj, float):
        return obj if np.isfinite(obj) else None
    if isinstance(obj, np.ndarray) and obj.dtype.kind == "f":  # NaN and inf as null, the rest to 6 decimals
        out = np.round(obj, 6).astype(object)
        out[~np.isfinite(obj)] = None
        return out.tolist()
    if isinstance(obj, np.floating):
        return float(obj) if np.isfinite(obj) else None
    if isinstance(obj, dict):
        return {k: _finite(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_finite(v) for v in obj]
    return obj


def plotly_js() -> str:
    """Plotly's bundled JavaScript (from the ``plotly`` package: no network)."""
    from plotly.offline import get_plotlyjs

    return get_plotlyjs()


STYLE = """
body{font-family:system-ui,-apple-system,Segoe UI,Roboto,sans-serif;margin:0;color:#1b1f24;background:#fafbfc}
header{background:#1f3a5f;color:#fff;padding:14px 24px}header h1{margin:0;font-size:20px}
header p{margin:4px 0 0;font-size:13px;opacity:.9}main{padding:8px 24px 40px;max-width:1500px}
section{background:#fff;border:1px solid #dde2e8;border-radius:6px;margin:14px 0;padding:10px 16px}
h2{font-size:16px;margin:6px 0 8px}p.note{font-size:13px;color:#44505c;margin:4px 0 8px}
table{border-collapse:collapse;font-size:12px;margin:6px 0}th,td{border-bottom:1px solid #e6e9ee;padding:3px 8px;
text-align:right;white-space:nowrap}th{background:#f1f4f8;cursor:pointer}.scroll th{position:sticky;top:0}
td:first-child,th:first-child{text-align:left}tr.selected td{background:#ffe9a8}tbody tr:hover td{background:#eef5ff}
.scroll{max-height:420px;overflow:auto}.plot{width:100%;min-height:420px}.row{display:flex;gap:16px;flex-wrap:wrap}
.row>div{flex:1 1 480px;min-width:380px}pre{font-size:12px;background:#f6f8fa;padding:8px;overflow:auto;max-height:360px}
.flag{color:#a4000f;font-weight:600}.ok{color:#176d2c}label{font-size:12px;margin-right:12px}
nav a{color:#fff;margin-right:14px;font-size:13px}#pp-checks td,#pp-checks th{white-space:normal}
#headline td{white-space:normal}#headline td+td,#headline th+th{text-align:left;max-width:110ch}
"""

#: Figures are drawn one after another once the page has loaded, those near the top first; the ones further down
#: when they are scrolled near (software WebGL, on a machine without a GPU, takes seconds for a 3-D scene or
#: parallel coordinates: drawing them all at once kept the page busy for 8 s). ``body[data-ready]`` is set when the
#: first screenful is drawn; ``drawAllPlots()`` draws the rest now (``body[data-all]`` then: tests, screenshots).
#: Each figure is drawn in a task of its own (a click waiting between two is answered before the next).
PLOTS_SCRIPT = """
const LATER=[];let busy=Promise.resolve();
function drawOne(entry){if(entry.done)return busy;entry.done=true;
  busy=busy.then(function(){return new Promise(function(go){setTimeout(go,0);});}).then(function(){let r;
  try{r=entry[1]();}catch(e){console.error(e);}return Promise.resolve(r).catch(function(e){console.error(e);});});
  return busy;}
function drawAllPlots(){return Promise.all(PLOTS.map(drawOne)).then(function(){document.body.dataset.all='1';});}
function drawPlots(){const near=window.innerHeight*1.5;const first=[];
  PLOTS.forEach(function(entry){const el=document.getElementById(entry[0]);
    if(!el||el.getBoundingClientRect().top<near){first.push(entry);}else{LATER.push(entry);}});
  Promise.all(first.map(drawOne)).then(function(){document.body.dataset.ready='1';});
  if('IntersectionObserver' in window){const io=new IntersectionObserver(function(seen){seen.forEach(function(s){
      if(!s.isIntersecting)return;io.unobserve(s.target);
      const entry=LATER.find(function(e){return e[0]===s.target.id;});if(entry)drawOne(entry);});},
    {rootMargin:'600px 0px'});LATER.forEach(function(e){const el=document.getElementById(e[0]);if(el)io.observe(el);});}
  else{LATER.forEach(drawOne);}}
if(document.readyState==='complete'){drawPlots();}else{window.addEventListener('load',drawPlots);}
"""

#: Sortable tables.
TABLE_SCRIPT = """
function cellValue(td){const t=td.textContent.replace(/,/g,'');const v=parseFloat(t);return isNaN(v)?t:v}
document.querySelectorAll('table.sortable').forEach(function(table){
  table.querySelectorAll('th').forEach(function(th,col){th.addEventListener('click',function(){
    const body=table.tBodies[0];const rows=Array.from(body.rows);const asc=th.dataset.dir!=='asc';
    table.querySelectorAll('th').forEach(h=>delete h.dataset.dir);th.dataset.dir=asc?'asc':'desc';
    rows.sort(function(a,b){const x=cellValue(a.cells[col]),y=cellValue(b.cells[col]);
      return (x<y?-1:x>y?1:0)*(asc?1:-1)});rows.forEach(r=>body.appendChild(r));});});});
"""


def page(title: str, subtitle: str, sections: list[str], scripts: list[str], data: dict[str, str],
         stamp: str = "") -> str:
    """The whole page: Plotly and every script inline, data as JSON script blocks. Its content-security policy
    lets run only the page's own two scripts, by their sha256 (issue 55 item 4: no other inline script, no inline
    handler, nothing fetched); the JSON blocks are data, never run."""
    blocks = "".join(f'<script type="application/json" id="{esc(k)}">{v}</script>' for k, v in data.items())
    plotly, main = plotly_js(), f"const PLOTS=[];{TABLE_SCRIPT}{''.join(map(_guarded, scripts))}{PLOTS_SCRIPT}"
    allowed = " ".join(f"'{script_hash(s)}'" for s in (plotly, main))
    return ("<!doctype html><html lang=\"en\"><head><meta charset=\"utf-8\">"
            + (f'<meta name="surgopt-page" content="{esc(stamp)}">' if stamp else "")
            + f"<meta http-equiv=\"Content-Security-Policy\" content=\"default-src 'none'; script-src {allowed} "
            "'unsafe-eval'; style-src 'unsafe-inline'; img-src data: blob:; font-src data:; worker-src blob:\">"
            f"<title>{esc(title)}</title><style>{STYLE}</style><script>{plotly}</script></head><body>"
            f"<header><h1>{esc(title)}</h1><p>{esc(subtitle)}</p></header><main>{''.join(sections)}</main>"
            f"{blocks}<script>{main}</script></body></html>")


def script_hash(script: str) -> str:
    """A content-security policy's source of one inline script: 'sha256-' and the base64 of its UTF-8 bytes'
    digest (CSP Level 2)."""
    import base64
    import hashlib

    return "sha256-" + base64.b64encode(hashlib.sha256(script.encode("utf-8")).digest()).decode()


def page_link(relative: str) -> str:
    """A link from one page to another: a relative path, percent-encoded, that starts with './' (so that no folder
    name can make it a scheme: a store named 'javascript:...' is a path here, issue 55 item 4)."""
    from urllib.parse import quote

    return "" if not relative else "./" + quote(relative.replace("\\", "/"), safe="/=")


def _guarded(script: str) -> str:
    """One view's script, so that an error in it is reported and the other views still draw."""
    return f"try{{{script}}}catch(e){{console.error(e);}}"


#: Plotly's height of a figure whose layout gives none (px).
PLOTLY_DEFAULT_HEIGHT_PX = 450


def figure_div(fig_id: str, figure: dict, css: str = "plot") -> tuple[str, str]:
    """(div, script) drawing ``figure`` ({data, layout}) with Plotly in a div of that id."""
    config = {"displaylogo": False, "responsive": True}
    spec = to_json({"data": figure.get("data", []), "layout": {"margin": {"l": 50, "r": 20, "t": 40, "b": 45},
                                                              **figure.get("layout", {})}})
    # its room kept before it is drawn, so that nothing below it moves when it is (a click aimed below still lands)
    height = figure.get("layout", {}).get("height", PLOTLY_DEFAULT_HEIGHT_PX)
    return (f'<div id="{esc(fig_id)}" class="{css}" style="min-height:{int(height)}px"></div>',
            f"PLOTS.push(['{fig_id}',function(){{const f={spec};return Plotly.newPlot('{fig_id}',f.data,f.layout,"
            f"{to_json(config)});}}]);")


def render_view(view: View, index: int) -> tuple[str, list[str], dict[str, str]]:
    """A view's section, its scripts and its data blocks."""
    divs, scripts = [], []
    for fig_id, figure in view.figures.items():
        div, script = figure_div(fig_id, figure)
        divs.append(div)
        scripts.append(script)
    figs = f'<div class="row">{"".join(f"<div>{d}</div>" for d in divs)}</div>' if len(divs) > 1 else "".join(divs)
    note = f'<p class="note">{view.note}</p>' if view.note else ""
    data = {view.data_id: to_json(view.data)} if view.data is not None and view.data_id else {}
    if view.script:
        scripts.append(view.script)
    return (f'<section id="view-{index}"><h2>{esc(view.title)}</h2>{note}{figs}{view.html}</section>', scripts, data)


def search_views(study, run, parts) -> list[View]:
    """An optimiser's run: the feasible trials' objective on its own scale (``Study.reported_objective``: not a
    penalised score) and its best so far, against the same config's grid when the store holds it; or, for several
    objectives, the Pareto front of the feasible trials."""
    from surgopt.plans.search import best_so_far, pareto_front

    cfg = config_of(study, run)
    plan = study.search_plan(cfg) if study.search_plan is not None else None
    if plan is None or not parts.num_rows:
        return []
    t = parts.table()
    order = np.argsort(t[study.key_columns[0]].to_numpy(), kind="stable")
    ok = np.asarray(study.feasible_mask(t), bool)[order]
    trial = np.arange(1, len(order) + 1)
    if len(plan.objectives) == 1:
        col, direction = study.reported_objective or plan.objectives[0]
        y = t[col].to_numpy(zero_copy_only=False).astype(float)[order]
        best = best_so_far(np.where(ok, y, np.nan), direction)
        best = np.where(np.isfinite(best), best, np.nan)
        data = [{"type": "scatter", "mode": "markers", "x": trial[ok], "y": y[ok], "name": "feasible trials",
                 "marker": {"size": 4, "color": "#9aa5b1"}},
                {"type": "scatter", "mode": "lines", "x": trial, "y": best, "name": "best feasible so far",
                 "line": {"color": "#1f77b4", "width": 2}}]
        from surgopt.results import grid_best
        from surgopt.store import Store

        ref = grid_best(Store(run.path.parent.parent), study, cfg, col, direction, feasible_only=True)
        if ref is not None:
            data.append({"type": "scatter", "mode": "lines", "x": [1, len(trial)], "y": [ref[1], ref[1]],
                         "name": f"{ref[0]}: {ref[1]:.6g}", "line": {"dash": "dash", "color": "#a4000f"}})
        note = (f"{plan.spec.method}, seed {plan.spec.seed}: {int(ok.sum()):,} of {len(ok):,} trials feasible; "
                f"{col} ({direction}) of the feasible trials only, on its own scale.")
        return [View("Search convergence", note, {"search-convergence": {"data": data, "layout": {
            "xaxis": {"title": {"text": "trial"}}, "yaxis": {"title": {"text": col}}, "height": 420}}})]
    (cx, dx), (cy, dy) = plan.objectives[:2]
    x = t[cx].to_numpy(zero_copy_only=False).astype(float)[order]
    y = t[cy].to_numpy(zero_copy_only=False).astype(float)[order]
    kept = np.flatnonzero(ok)
    front = kept[pareto_front(np.column_stack([x[kept], y[kept]]), [dx, dy])] if len(kept) else kept
    front = front[np.argsort(x[front])]
    data = [{"type": "scatter", "mode": "markers", "x": x[ok], "y": y[ok], "name": "feasible trials",
             "marker": {"size": 4, "color": "#9aa5b1"}},
            {"type": "scatter", "mode": "lines+markers", "x": x[front], "y": y[front],
             "name": f"Pareto front ({len(front)})"}]
    note = f"{plan.spec.method}: the {len(kept):,} feasible of {len(ok):,} trials; {cx} ({dx}) against {cy} ({dy})."
    return [View("Pareto front", note, {"search-front": {"data": data, "layout": {
        "xaxis": {"title": {"text": cx}}, "yaxis": {"title": {"text": cy}}, "height": 460}}})]


def provenance_rows(run) -> list[list]:
    m = run.manifest
    versions = m.get("versions", {})
    rows = [["key", run.key], ["study", run.study], ["config name", m.get("config_name", "?")],
            ["name", m.get("name", "")], ["tags", ", ".join(f"{k}={v}" for k, v in (m.get("tags") or {}).items())],
            ["created", m.get("created", "?")], ["completed", m.get("completed", "not complete")],
            ["parts", f"{len(m.get('parts', {}))} of {m.get('n_tasks', '?')}"],
            ["rows", sum(p.get("rows", 0) for p in m.get("parts", {}).values())],
            ["wall time (s)", m.get("wall_time_s", "?")], ["plan", json.dumps(m.get("plan", {}))],
            ["kernel version", m.get("kernel_version", "?")], ["code sha256", m.get("code_sha256", "?")],
            ["git commit", m.get("git_commit") or "not from a checkout"],
            ["backend, jobs", f"{m.get('last_backend', m.get('backend', '?'))}, {m.get('last_jobs', m.get('jobs', '?'))}"],
            ["host", m.get("host", "?")]]
    rows += [[f"{k} version", v] for k, v in versions.items()]
    return rows


def run_sections(study, run, parts, added=None) -> tuple[list[str], list[str], dict[str, str], dict]:
    """The sections of one run's page: headline, the study's views, the summary tables, notes, config,
    provenance; with the scripts and data they need, and the headline numbers. ``added``: what the config the
    user named the run by adds (``added_report``: port-place's given layout), shown as the closing report shows
    it, ahead of the run's own tables."""
    from surgopt.config import to_toml
    from surgopt.report import best_edges

    from surgopt.report import run_summary

    sections, scripts, data = [], [], {}
    summary = run_summary(study, run, parts) if parts.num_rows else None  # the closing report's, kept
    if summary:
        summary = summary.with_added(added)
    headline = dict(summary.headline) if summary else {}
    complete = len(run.manifest["parts"]) == run.manifest["n_tasks"]
    state = ("complete" if complete else
             f'<span class="flag">PARTIAL: {len(run.manifest["parts"])} of {run.manifest["n_tasks"]} chunks '
             f"stored; rerun the study to finish it</span>")
    head = [[k, headline_cell(k, v)] for k, v in headline.items()] + [["rows", parts.num_rows]]
    if summary:
        head += [[k, v] for k, v in summary.feasibility.items() if k not in headline]
    sections.append(f'<section id="headline"><h2>Headline</h2><p class="note">State: {state}. '
                    f'{esc(AGGREGATE_NOTE.format(key=run.key[:12]))}</p>'
                    f'{table_html(["quantity", "value"], head, "headline-table", sortable=False)}</section>')
    notes = list(best_edges(study, run, parts)) if parts.num_rows else []
    if study.advice is not None:

        notes += study.advice(config_of(study, run))
    if notes:
        sections.append('<section id="notes"><h2>Notes</h2><ul>' + "".join(f"<li>{esc(n)}</li>" for n in notes)
                        + "</ul></section>")
    plan_name = (run.manifest.get("plan") or {}).get("name", "grid")
    views = search_views(study, run, parts) if plan_name not in ("grid", "cull", "refine") else []
    if study.html_views is not None and parts.num_rows:
        views += study.html_views(run, config_of(study, run), parts)
    if views:
        for i, view in enumerate(views):
            sec, scr, dat = render_view(view, i)
            sections.append(sec)
            scripts += scr
            data.update(dat)
    if summary:
        for title, header, rows in summary.tables:
            sections.append(f"<section><h2>{esc(title)}</h2>{table_html(header, rows)}</section>")
    sections.append('<section id="config"><h2>Config (what was hashed into the key)</h2>'
                    f"<pre>{esc(to_toml(run.manifest['config']))}</pre></section>")
    sections.append(f'<section id="provenance"><h2>Provenance</h2>'
                    f'{table_html(["field", "value"], provenance_rows(run), sortable=False)}</section>')
    return sections, scripts, data, headline


def added_report(study, given, parts):
    """``Study.config_report(given, parts)``, or None without a config or anything to add."""
    if given is None or study.config_report is None:
        return None
    return study.config_report(given, parts)


def run_page(study, run, parts, given=None) -> str:
    """One run's page; ``given``: the config the user named it by (``run_sections``). A page that shows what such a
    config adds is stamped apart (``page_stamp``), so that ``--store-index`` builds the run's own page again."""
    added = added_report(study, given, parts) if parts.num_rows else None  # once: it scores a layout
    sections, scripts, data, _ = run_sections(study, run, parts, added)
    name = run.manifest.get("name") or run.manifest.get("config_name", "")
    extra = "" if added is None else "\nwith " + canonical_of(given)
    return page(f"surgopt {study.name}: {name}", f"run {run.key[:12]} · {run.manifest.get('created', '')} · "
                f"{parts.num_rows:,} rows · {run.path}", sections, scripts, data, page_stamp(run, extra))


def canonical_of(cfg) -> str:
    """The config's whole JSON (fields out of the key included): what a page built for it differs by."""
    return cfg.model_dump_json()


#: What a run page's stamp is read from: the head of the file (the stamp is the page's first meta but one).
STAMP_BYTES = 4096


def page_stamp(run, extra: str = "") -> str:
    """What a run's page was built from: the run's key, its manifest (the parts with their sha256, its name, tags
    and headline) and the source of the package that drew it. ``report --store-index`` reuses a page whose stamp
    is this one (issue 56 item 5: it rebuilt every run's page each time)."""
    import hashlib

    from surgopt.derived import package_sha256

    manifest = json.dumps(run.manifest, sort_keys=True, default=str)
    return hashlib.sha256(f"{run.key}\n{manifest}\n{package_sha256()}{extra}".encode()).hexdigest()


def current_page(run, path) -> bool:
    """Whether the page at ``path`` was built from this run as it is now, by this code (``page_stamp``)."""
    try:
        with open(path, "rb") as f:
            head = f.read(STAMP_BYTES).decode("utf-8", "replace")
    except OSError:
        return False
    return f'<meta name="surgopt-page" content="{page_stamp(run)}">' in head




def comparison_page(items) -> str:
    """Several runs (``items``: (study, run, parts)): their headlines side by side, their config differences, then
    each run's first view, side by side where they share a study."""
    from surgopt.report import run_summary
    from surgopt.results import flat_config

    heads, configs, feasibility = [], [], []
    for study, run, parts in items:
        s = run_summary(study, run, parts) if parts.num_rows else None  # each run's closing report, kept
        heads.append(dict(s.headline) if s else {})
        feasibility.append(dict(s.feasibility) if s else {})
        configs.append(flat_config(run.manifest["config"]))
    labels = [run.manifest.get("name") or f"{run.key[:8]} {run.manifest.get('config_name', '')}" for _, run, _ in items]
    keys = list(dict.fromkeys(k for h in heads for k in h))
    rows = [[k, *[headline_cell(k, h.get(k, "")) for h in heads]] for k in keys]
    sections = [f'<section id="headline"><h2>Headlines</h2>{table_html(["quantity", *labels], rows, sortable=False)}'
                f"</section>"]
    fields = sorted({k for c in configs for k in c})
    differ = [[f, *[json.dumps(c.get(f)) for c in configs]] for f in fields
              if len({json.dumps(c.get(f)) for c in configs}) > 1]
    sections.append(f'<section id="differences"><h2>Config fields that differ ({len(differ)})</h2>'
                    f'{table_html(["field", *labels], differ, sortable=False)}</section>')
    sections.append(feasibility_section(labels, feasibility))
    scripts, data, cells = [], {}, []
    for i, (study, run, parts) in enumerate(items):
        if study.html_views is None or not parts.num_rows:
            continue
        views = study.html_views(run, config_of(study, run), parts)
        if not views:
            continue
        view = next((v for v in views if v.figures), views[0])  # a figure a page can hold twice (port-place's
        # scene is drawn by a script of its own: its top view of the best layout instead)
        view.figures = {f"c{i}-{k}": v for k, v in view.figures.items()}
        view.data, view.script, view.html = None, "", ""
        sec, scr, dat = render_view(view, 100 + i)
        cells.append(f'<div><h2 style="overflow-wrap:anywhere">{esc(labels[i])}</h2>{sec}</div>')  # long config names wrap
        scripts += scr
    if cells:
        sections.append(f'<section id="views"><div class="row">{"".join(cells)}</div></section>')
    return page(f"surgopt: {len(items)} runs compared", " · ".join(labels), sections, scripts, data)


def feasibility_section(labels: list[str], feasibility: list[dict]) -> str:
    """Why the runs' feasible counts differ (issue 56 item 3): each check's count of failing layouts run by run and,
    for two runs, how many more or fewer fail it in the second, in words; counted over each run's own rows (not
    joined layout by layout; a layout can fail several checks)."""
    keys = list(dict.fromkeys(k for f in feasibility for k in f))
    if not keys:
        return ""

    def number(v):
        return v if isinstance(v, (int, float)) and not isinstance(v, bool) else None

    rows = []
    for k in keys:
        values = [f.get(k, "") for f in feasibility]
        row = [k, *values]
        if len(values) == 2 and number(values[0]) is not None and number(values[1]) is not None:
            change = values[1] - values[0]
            row.append("no change" if change == 0 else
                       f"{abs(change):,} {'more' if change > 0 else 'fewer'} layouts fail it"
                       if k.startswith("infeasible:") else f"{abs(change):,} {'more' if change > 0 else 'fewer'}")
        rows.append(row)
    header = ["count", *labels] + (["second against first"] if len(labels) == 2 else [])
    return (f'<section id="feasibility"><h2>Why the feasible counts differ</h2><p class="note">Each check\'s count of '
            f"layouts failing it, run by run (each run's own rows, not joined layout by layout; a layout can fail "
            f"several checks).</p>{table_html(header, rows, sortable=False)}</section>")


def index_page(store, records: list[dict]) -> str:
    """Every run of the store: name, tags, study, state, rows, headline, and a link to its page."""
    rows, links = [], []
    for r in records:
        link = page_link(r.get("link", ""))
        rows.append([r.get("name") or "", r["study"], r["key"][:12], r.get("config_name", ""), r.get("state", ""),
                     r.get("rows", ""), r.get("created", ""), ", ".join(f"{k}={v}" for k, v in (r.get("tags") or {}).items()),
                     r.get("headline", "")])
        links.append(link)
    header = ["name", "study", "key", "config", "state", "rows", "created", "tags", "headline"]
    body = table_html(header, rows, "runs", row_attrs=lambda i: f' data-link="{esc(links[i])}"')
    script = ("document.querySelectorAll('#runs tbody tr').forEach(function(tr){if(!tr.dataset.link)return;"
              "tr.style.cursor='pointer';tr.addEventListener('click',function(){window.location.href=tr.dataset.link;"
              "});});")
    sections = [f'<section><h2>Runs ({len(records)})</h2><p class="note">Click a run to open its page (written '
                f'beside it by <code>surgopt report KEY</code> or this index).</p><div class="scroll">{body}</div>'
                f"</section>"]
    return page(f"surgopt store: {store.root}", f"{len(records)} runs", sections, [script], {})


#: A run's page, kept with the run: the leading "_" makes Parquet readers skip it, like ``_figures``.
REPORT_FILE = "_report.html"
