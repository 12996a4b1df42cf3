"""`surgopt report` (issue 41): one self-contained HTML page per run, per comparison and per store, opened from
file:// in a real headless Chromium (Debian's, through pytest-playwright): no console error, no network request,
the figures and tables drawn, and on port-place a click on a layout redraws the 3-D scene and the checks. Small
fixtures (the CI baselines): rendering runs on the CPU. A failing browser test keeps its screenshot in
test-results/."""
from __future__ import annotations

import re
from pathlib import Path

import pytest

from surgopt.store import Store

from conftest import cli

BASE = Path(__file__).parent / "baselines"
SEARCH = """
[workspace]
points_per_side = 3
[search]
method = "tpe"
trials = 40
batch = 20
seed = 1
"""
TRACK = """
[candidates]
list_m = [[0.535, 0.0, -0.21], [0.46, 0.0, -0.3], [0.63, 0.0, -0.39]]
"""


@pytest.fixture(scope="module")
def pages(tmp_path_factory, worker_id):
    """A store with a small run of each study and a search; each run's page, a comparison page and the index.
    Built once for both test workers (pytest-xdist's recipe: a lock in the folder the workers' temporary folders
    share; the pages are only read): it took ~24 s on each."""
    import json

    from filelock import FileLock

    if worker_id == "master":  # not under xdist: this session's own
        return _make_pages(tmp_path_factory.mktemp("html"))
    shared = tmp_path_factory.getbasetemp().parent  # this session's, shared by its workers
    made = shared / "html-pages.json"
    with FileLock(str(shared / "html-pages.lock")):
        if made.exists():
            return {k: Path(v) for k, v in json.loads(made.read_text()).items()}
        out = _make_pages(shared / "html-pages")
        made.write_text(json.dumps({k: str(v) for k, v in out.items()}))
        return out


def _make_pages(tmp: Path) -> dict:
    """The pages, their runs and reports made in this process (``conftest.invoke``: 14 subprocesses took ~1 s
    each of start-up and kernel loading)."""
    from conftest import invoke

    def cli(*args):
        code, output = invoke(*args)
        assert code == 0, output
        return type("Result", (), {"stdout": output})

    tmp.mkdir(exist_ok=True)
    store = tmp / "store"
    for name, study in (("rcm_small", "rcm-grid"), ("raven_small", "raven-sweep"), ("suture_small", "suture-sim"),
                        ("port_small", "port-place")):
        cli(study, BASE / f"{name}.toml", "--store", store, "--quiet")
    (tmp / "search.toml").write_text(SEARCH)
    cli("rcm-grid", tmp / "search.toml", "--store", store, "--quiet")
    (tmp / "track.toml").write_text(TRACK)
    cli("rcm-track", tmp / "track.toml", "--store", store, "--quiet")
    out = {}
    for study in ("rcm-grid", "raven-sweep", "suture-sim", "port-place", "rcm-track"):
        r = cli("report", "--store", store, "--study", study, "--out", tmp / f"{study}.html")
        assert f"{study} run" in r.stdout  # the run it drew is named
        out[study] = tmp / f"{study}.html"
    search = next(r for r in Store(store).runs("rcm-grid")
                  if (r.manifest.get("plan") or {}).get("name") == "optuna")
    cli("report", search.key[:12], "--store", store, "--out", tmp / "search.html")
    out["search"] = tmp / "search.html"
    keys = [r.key[:12] for r in Store(store).runs("rcm-grid")]
    cli("report", *keys, "--store", store, "--out", tmp / "compare.html")
    out["compare"] = tmp / "compare.html"
    # two port-place runs on different site grids, compared (#56 item 3): their own store, the index's stays six
    ports = tmp / "ports"
    cli("port-place", BASE / "port_small.toml", "--store", ports, "--quiet")
    cli("port-place", BASE / "port_small.toml", "patient.port_region.site_spacing_mm=60", "--store", ports, "--quiet")
    cli("report", *[r.key[:12] for r in Store(ports).runs()], "--store", ports, "--out", tmp / "compare-ports.html")
    out["compare-ports"] = tmp / "compare-ports.html"
    r = cli("report", "--store-index", "--store", store)
    out["index"] = store / "_report.html"
    assert "6 runs" in r.stdout and "6 run pages written beside them, 0 kept" in r.stdout
    out["store"] = store
    return out


# --- the page as a file -----------------------------------------------------------------------------------------

@pytest.mark.parametrize("which", ["rcm-grid", "raven-sweep", "suture-sim", "port-place", "rcm-track", "search",
                                   "compare", "index"])
def test_a_page_is_one_self_contained_file(pages, which):
    """Everything embedded: no script, style, image or link fetched from anywhere (an offline laptop, an e-mail)."""
    text = pages[which].read_text()
    assert text.startswith("<!doctype html>") and "Plotly" in text
    markup = re.sub(r"<script\b[^>]*>.*?</script>", "<script></script>", text, flags=re.S)  # the HTML, not the JS
    assert "<script src" not in markup and markup.count("<script") >= 2  # every script inline
    for attr in re.findall(r'(?:src|href)\s*=\s*"([^"]*)"', markup):
        assert not re.match(r"(https?:)?//", attr), attr
    assert not re.search(r"<link\b|@import|url\((['\"])?https?:", markup)
    assert "default-src 'none'" in text  # the page's own policy forbids any fetch
    assert pages[which].stat().st_size < 10 * 2 ** 20


@pytest.mark.parametrize("which", ["rcm-grid", "raven-sweep", "suture-sim", "port-place", "rcm-track", "search"])
def test_a_run_page_names_its_run_and_shows_config_provenance_and_frame(pages, which):
    text = pages[which].read_text()
    assert 'id="config"' in text and 'id="provenance"' in text and "code sha256" in text
    assert "surgopt export" in text  # says how to get the rows it does not embed
    assert re.search(r"run [0-9a-f]{12}", text)


def test_the_port_place_page_embeds_aggregates_not_rows(pages):
    """port_small has 360 layouts: the page's layout table holds the TOP_FEASIBLE feasible and TOP_INFEASIBLE
    infeasible of least cost at most, never every row."""
    from surgopt.studies.port_place.html import TOP_FEASIBLE, TOP_INFEASIBLE

    text = pages["port-place"].read_text()
    rows = re.findall(r'<tr data-i="\d+"', text)
    assert 0 < len(rows) <= TOP_FEASIBLE + TOP_INFEASIBLE


def test_the_store_index_links_every_run_page(pages):
    text = pages["index"].read_text()
    links = re.findall(r'data-link="([^"]+)"', text)
    assert len(links) == 6
    for link in links:
        assert (pages["index"].parent / link).is_file()


# --- in the browser -----------------------------------------------------------------------------------------------

def _open(page, path: Path, tmp_path):
    """Open ``path`` from file://, recording console errors and every request that is not the file itself."""
    errors, requests = [], []
    page.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
    page.on("pageerror", lambda e: errors.append(str(e)))
    page.on("request", lambda r: requests.append(r.url) if not r.url.startswith(("file:", "data:", "blob:")) else None)
    page.set_viewport_size({"width": 1400, "height": 1000})
    page.goto(path.as_uri())
    page.wait_for_selector("body[data-ready]", timeout=120_000)  # the first screenful drawn
    page.evaluate("drawAllPlots()")  # and the figures further down (drawn as they are scrolled near)
    page.wait_for_selector("body[data-all]", state="attached", timeout=120_000)
    return errors, requests


def _kept_on_failure(page, tmp_path, name):
    shots = Path("test-results")
    shots.mkdir(exist_ok=True)
    path = shots / f"{name}.png"
    page.screenshot(path=str(path), full_page=True)
    return path


@pytest.mark.parametrize("which", ["rcm-grid", "raven-sweep", "suture-sim", "rcm-track", "search", "compare",
                                   "index"])
def test_a_page_renders_in_chromium_without_errors_or_requests(pages, which, page, tmp_path):
    errors, requests = _open(page, pages[which], tmp_path)
    try:
        assert not errors, errors
        assert not requests, requests
        if which != "index":
            plots = page.locator(".js-plotly-plot")
            assert plots.count() >= 1  # Plotly drew its figures
            assert page.locator(".js-plotly-plot .main-svg").count() >= 1
        assert page.locator("table").first.is_visible()
    except AssertionError:
        print("screenshot:", _kept_on_failure(page, tmp_path, f"report-{which}"))
        raise


def test_clicking_a_layout_redraws_the_3d_scene_and_its_checks(pages, page, tmp_path):
    """port-place: the 3-D scene (WebGL) is drawn; a click on another layout row changes the scene's layout, its
    title, the checks shown and the ports; the feasible-only filter hides the infeasible rows."""
    errors, requests = _open(page, pages["port-place"], tmp_path)
    try:
        assert not errors and not requests, (errors, requests)
        # a headline value as long as the default run's links_clear (~330 characters) wraps inside its section
        page.evaluate("document.querySelector('#headline td + td').textContent = 'design 884280 with ... '.repeat(15)")
        assert page.evaluate("document.querySelector('#headline table').getBoundingClientRect().right <= "
                             "document.querySelector('#headline').getBoundingClientRect().right")
        scene = page.locator("#pp-scene")
        assert page.locator("#pp-scene .gl-container canvas, #pp-scene canvas").count() >= 1  # a WebGL scene
        first = scene.get_attribute("data-layout")
        rows = page.locator("#pp-layouts tbody tr:visible")
        assert rows.count() >= 2
        target = rows.nth(1)
        design = target.locator("td").first.inner_text()
        assert design.isdigit()  # #56 item 4: an id, without thousands separators
        target.click()
        page.wait_for_function(f"document.getElementById('pp-scene').dataset.layout === '{design}'", timeout=30_000)
        assert scene.get_attribute("data-layout") == design != first
        assert page.evaluate("+document.getElementById('pp-scene').dataset.paintedMs") > 0  # checks painted first
        assert page.locator("#pp-title").inner_text().startswith(f"Layout {design}")
        # #56 item 4: the scene marks the landmarks (the dome's, said to be assumed) and the sides
        traces = page.evaluate("document.getElementById('pp-scene').data.map(t => [t.name, t.text || null])")
        named = {name: text for name, text in traces}
        assert "umbilicus" in named["landmarks (assumed: the dome has none of its own)"]
        assert set(named["sides"]) == {"patient's left", "patient's right", "head", "feet"}
        assert "marked region" not in named  # none marked in this run
        assert page.locator("#pp-ports tbody tr").count() >= 3
        assert "selected" in (target.get_attribute("class") or "")
        all_rows = page.locator("#pp-layouts tbody tr").count()
        page.locator("#pp-feasible").uncheck()
        assert page.locator("#pp-layouts tbody tr:visible").count() == all_rows
        page.locator("#pp-feasible").check()
        assert page.locator("#pp-layouts tbody tr:visible").count() <= all_rows
    except AssertionError:
        print("screenshot:", _kept_on_failure(page, tmp_path, "report-port-place"))
        raise


def test_no_figure_moves_when_those_below_the_first_screenful_are_drawn(pages, page):
    """Every figure's room is kept before it is drawn (its layout's height), so that nothing below it moves when
    it is: a row a user aims at while the page loads stays where it was (the premise: some figures are not drawn
    when the first screenful is)."""
    page.set_viewport_size({"width": 1400, "height": 1000})
    page.goto(pages["port-place"].as_uri())
    page.wait_for_selector("body[data-ready]", state="attached", timeout=120_000)
    boxes = ("Array.from(document.querySelectorAll('.plot')).map(e => [e.id, Math.round(e.getBoundingClientRect()"
             ".height), Math.round(e.getBoundingClientRect().top + window.scrollY)])")
    before = page.evaluate(boxes)
    assert page.locator(".plot:not(.js-plotly-plot)").count() >= 1  # the premise: not every figure drawn yet
    page.evaluate("drawAllPlots()")
    page.wait_for_selector("body[data-all]", state="attached", timeout=120_000)
    assert page.locator(".plot:not(.js-plotly-plot)").count() == 0 and page.evaluate(boxes) == before


def test_a_header_click_sorts_a_table(pages, page, tmp_path):
    _open(page, pages["raven-sweep"], tmp_path)
    header = page.locator("#top-designs th", has_text="cost")
    header.click()  # ascending
    cells = page.locator("#top-designs tbody tr td:nth-child(%d)" % (
        1 + [h.strip() for h in page.locator("#top-designs th").all_inner_texts()].index("cost")))
    values = [float(v.replace(",", "")) for v in cells.all_inner_texts()]
    assert values == sorted(values)


def test_embedded_data_is_json_with_null_for_nan_and_infinity():
    """A site no feasible layout uses has no least cost (NaN): the page's data must stay valid JSON (JSON has no
    NaN; the PA10 example's page failed to parse and drew nothing)."""
    import json

    import numpy as np

    from surgopt.html_report import to_json

    text = to_json({"a": np.array([1.0, np.nan, np.inf]), "b": [np.float64("nan"), 2.5], "c": np.float32("inf"),
                    "d": np.array([[np.nan, 1.0]])})
    assert json.loads(text) == {"a": [1.0, None, None], "b": [None, 2.5], "c": None, "d": [[None, 1.0]]}


def test_a_searched_dockings_page_and_figure_colour_the_target_by_the_trials_own_frames(page, tmp_path):
    """A [search] that docks each PSM in frames of its own (its docking yaw and pitch, ``robot.docking_range_deg``,
    and its roll, ``robot.docking_roll = 'search'``; no cart): the page colours the shown layout's target by the
    isotropy in those frames (``study.layout_isotropy``), not by the grid's at its sites, and so does the layout
    figure. Held to the design kernel: where the layout reaches the whole
    target, the mean of the pair's smaller isotropy is its row's dexterity_mean (eq. P5, computed apart, from the
    trial's own tables); premise: the grid's colours at those sites differ there."""
    import json

    import numpy as np
    import pyarrow as pa

    from surgopt.studies.port_place import config as C
    from surgopt.studies.port_place import figures as F
    from surgopt.studies.port_place import study as S
    from surgopt.studies.port_place.layout import layout_isotropy
    from surgopt.studies.port_place.model import model_of

    (tmp_path / "r.toml").write_text(
        "[patient.port_region]\nsite_spacing_mm = 36.0\n[target]\nspacing_mm = 15.0\n[robot]\n"
        "docking_roll = \"search\"\ndocking_range_deg = 30.0\n[search]\nmethod = \"tpe\"\ntrials = 24\nbatch = 12\n"
        "seed = 4\n")
    cli("port-place", "r.toml", "--store", tmp_path / "s", "--quiet", cwd=tmp_path)
    cli("report", "latest", "--store", tmp_path / "s", "--out", tmp_path / "r.html", cwd=tmp_path)
    errors, requests = _open(page, tmp_path / "r.html", tmp_path)
    assert not errors and not requests, (errors, requests)
    page.wait_for_function("document.getElementById('pp-scene').dataset.layout !== undefined", timeout=60_000)
    data = json.loads(page.evaluate("document.getElementById('pp-data').textContent"))
    first = int(page.evaluate("document.getElementById('pp-scene').dataset.layout"))
    shown = page.evaluate("document.getElementById('pp-scene').data.find(t => t.name === 'target (isotropy)')"
                          ".marker.color")
    cfg = C.PortPlaceConfig.model_validate(tomllib_load(tmp_path / "r.toml"))
    (run,) = Store(tmp_path / "s").runs("port-place")
    rows = run.parts(S.STUDY.schema_for(run.manifest["config"])).table().to_pylist()
    row = next(r for r in rows if r["design_id"] == first)
    own = layout_isotropy(model_of(cfg), row)
    got = np.array([np.nan if v is None else v for v in shown], float)
    np.testing.assert_array_equal(np.isnan(got), np.isnan(own))
    np.testing.assert_allclose(got[~np.isnan(got)], own[~np.isnan(own)], atol=1e-4)  # the page rounds to 1e-4
    grid = np.min([model_of(cfg).grid[2][row[f"{a}_site"]] for a in ("psm1", "psm2")], axis=0)
    reached = [r for r in rows if r["common_reach"] == 1.0 and abs(r["psm1_docking_yaw_deg"]) > 1]
    assert reached  # the premise: a trial reaching the whole target docked in frames of its own
    for r in reached:
        assert np.nanmean(layout_isotropy(model_of(cfg), r)) == pytest.approx(r["dexterity_mean"], abs=1e-9)
    assert data["layout_iso"] is not None and np.nanmax(np.abs(np.nan_to_num(grid) - np.nan_to_num(own))) > 1e-3
    seen = {}
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(F, "save", lambda fig, path: seen.setdefault(path.name, fig) and path)
        F.figures(cfg, pa.Table.from_pylist(rows), tmp_path, design_id=first)
    scatter = [c for c in seen["port_place_layout_3d.png"].axes[0].collections if c.get_array() is not None]
    colours = np.ma.filled(scatter[-1].get_array(), np.nan).astype(float)  # the target points, drawn last
    np.testing.assert_allclose(colours[~np.isnan(own)], own[~np.isnan(own)], atol=1e-12)


def tomllib_load(path):
    import tomllib

    return tomllib.loads(path.read_text())


HOSTILE = ("]]>-->", "<!--<script>", "</script><script>alert(1)</script>", "a & b <b>", "\u2028x\u2029")


def test_embedded_json_holds_no_character_that_could_end_or_stop_a_script():
    """#55 item 5: every JSON a page embeds in a script goes through ``to_json``: '<', '>', '&' and the line
    separators escaped, and it reads back as the same value."""
    import json

    from surgopt.html_report import to_json

    value = {"names": list(HOSTILE), "nested": {h: [h] for h in HOSTILE}}
    text = to_json(value)
    assert not set("<>&\u2028\u2029") & set(text) and json.loads(text) == value


def test_hostile_strings_in_a_pages_figures_and_data_keep_every_figure_drawing(page, tmp_path):
    """#55 item 5: a page whose figures' names, titles and embedded data hold '<!--<script>' and the like (a name a
    user controls: before, one such string stopped the page's script, no figure drawn) draws every figure in
    Chromium, with no console error, and shows the strings as text."""
    from surgopt import html_report as H
    from surgopt.studies.page import View

    sections, scripts, data = [], [], {}
    for k, h in enumerate(HOSTILE):
        view = View(title=f"view {k}", figures={f"f{k}": {"data": [{"x": [1, 2], "y": [k, k + 1], "name": h,
                                                                       "type": "scatter"}],
                                                             "layout": {"title": {"text": h}}}},
                      data={"label": h}, data_id=f"d{k}")
        section, more, blocks = H.render_view(view, k)
        sections.append(section)
        scripts += more
        data.update(blocks)
    path = tmp_path / "hostile.html"
    path.write_text(H.page("hostile", "strings", sections, scripts, data))
    errors, requests = _open(page, path, tmp_path)
    assert not errors and not requests, errors
    assert page.locator(".js-plotly-plot .main-svg").count() >= len(HOSTILE)  # every figure drawn
    assert page.locator("#d1").text_content() and "<!--<script>" in page.locator("#f1").text_content()


def test_only_the_pages_own_scripts_run_and_index_links_are_paths(page, tmp_path):
    """#55 item 4: the policy names the page's two scripts by their sha256 and allows no other inline script: a
    script or an inline handler that reached the page's HTML does not run in Chromium (the page's own still do:
    its figure draws); the store index's links are percent-encoded relative paths from './', so a store folder
    named 'javascript:alert(7)%2F%2F' is a path, not a scheme."""
    import re as _re

    from surgopt import html_report as H
    from surgopt.studies.page import View

    injected = ('<script>document.body.dataset.injected="1"</script>'
                '<img src="data:," onerror="document.body.dataset.handler=\'1\'">')
    view = View(title="v", figures={"f": {"data": [{"x": [1, 2], "y": [1, 2], "type": "scatter"}]}}, html=injected)
    section, scripts, data = H.render_view(view, 0)
    text = H.page("t", "s", [section], scripts, data)
    policy = _re.search(r'Content-Security-Policy" content="([^"]*)"', text).group(1)
    script_src = policy.split("script-src ")[1].split(";")[0].split()
    assert "'unsafe-inline'" not in script_src and sum(s.startswith("'sha256-") for s in script_src) == 2
    path = tmp_path / "p.html"
    path.write_text(text)
    page.set_viewport_size({"width": 1200, "height": 900})
    page.goto(path.as_uri())
    page.wait_for_selector("body[data-ready]", timeout=120_000)
    assert page.locator(".js-plotly-plot .main-svg").count() >= 1  # the page's own script ran
    assert page.evaluate("document.body.dataset.injected") is None and page.evaluate("document.body.dataset.handler") is None

    class Store:
        root = tmp_path / "javascript:alert(7)%2F%2F"

    record = {"study": "rcm-grid", "key": "ab" * 32, "link": "javascript:alert(7)%2F%2F/study=rcm-grid/key=ab/_report.html"}
    index = H.index_page(Store(), [record])
    (link,) = _re.findall(r'data-link="([^"]*)"', index)
    assert link == "./javascript%3Aalert%287%29%252F%252F/study=rcm-grid/key=ab/_report.html"


def test_the_store_index_keeps_each_run_page_that_is_current(pages):
    """#56 item 5: ``report --store-index`` rebuilt every run's page each time (minutes on a store of port-place
    runs). A page stamped with what it was built from (the run's key and manifest, the package's source) is kept;
    a page that is gone, or whose stamp is not the run's now, is built again, and only those."""
    from surgopt import html_report as H
    from surgopt.store import Store

    from conftest import invoke

    store = pages["store"]
    runs = sorted(Store(store).runs(), key=lambda r: r.key)
    files = [r.path / H.REPORT_FILE for r in runs]
    assert all(H.current_page(r, f) for r, f in zip(runs, files))  # the premise: every page is current
    before = {f: f.stat().st_mtime_ns for f in files}
    code, out = invoke("report", "--store-index", "--store", store)
    assert code == 0 and "0 run pages written beside them, 6 kept: current" in out, out
    assert {f: f.stat().st_mtime_ns for f in files} == before  # not one page rewritten
    files[0].unlink()
    files[1].write_text(files[1].read_text().replace(H.page_stamp(runs[1]), "0" * 64))  # another run's page
    code, out = invoke("report", "--store-index", "--store", store)
    assert code == 0 and "2 run pages written beside them, 4 kept: current" in out, out
    assert all(H.current_page(r, f) for r, f in zip(runs, files))


def test_a_comparison_of_port_layouts_draws_each_runs_best_layout_and_says_why_the_counts_differ(pages, page,
                                                                                                   tmp_path):
    """#56 item 3: comparing two port-place runs drew the headlines and the config differences, then under each run
    a caption and no figure. Each run's best feasible layout is drawn from above (its ports by arm, the sites, the
    target's centre, the landmarks), and a table says how many more or fewer layouts fail each check."""
    errors, requests = _open(page, pages["compare-ports"], tmp_path)
    try:
        assert not errors and not requests, (errors, requests)
        for cell in ("c0-pp-top", "c1-pp-top"):
            names = page.evaluate(f"document.getElementById('{cell}').data.map(t => t.name)")
            assert {"PSM1 port", "PSM2 port", "ECM port", "target centre", "candidate sites"} <= set(names), names
        text = page.locator("#feasibility").inner_text()
        assert "Why the feasible counts differ" in text and "layouts fail it" in text
    except AssertionError:
        print("screenshot:", _kept_on_failure(page, tmp_path, "report-compare-ports"))
        raise


def test_a_headlines_design_id_is_written_without_thousands_separators():
    """#56 item 4: the comparison page's and a run page's headline wrote best_design_id 548211 as "548,211" (an id
    is a name, not a quantity); counts keep their separators."""
    from surgopt.studies.page import headline_cell, table_html

    rows = [[k, headline_cell(k, v)] for k, v in (("best_design_id", 548211), ("designs", 2165292),
                                                  ("feasible", 1061519))]
    html = table_html(["quantity", "value"], rows, sortable=False)
    assert ">548211<" in html and "548,211" not in html
    assert ">2,165,292<" in html and ">1,061,519<" in html  # counts as before


def test_the_scene_draws_a_marked_region_with_the_landmarks_and_sides_in_chromium(tmp_path, page):
    """#56 item 4, read back from the drawn scene: a run with a marked port region draws its outline on the wall
    ('marked region', every point inside the polygon's box, 2 mm over the wall), with the landmarks and the sides,
    and no cart where none is modelled."""
    from conftest import invoke

    poly = [[-150.0, -200.0], [150.0, -200.0], [150.0, 40.0], [-150.0, 40.0]]
    (tmp_path / "region.toml").write_text(
        (BASE / "port_small.toml").read_text().replace(
            "site_spacing_mm = 72.0", f"site_spacing_mm = 60.0\npolygon_mm = {poly}"))
    assert invoke("port-place", tmp_path / "region.toml", "--store", tmp_path / "s", "--quiet")[0] == 0
    assert invoke("report", "latest", "--store", tmp_path / "s", "--out", tmp_path / "r.html")[0] == 0
    errors, requests = _open(page, tmp_path / "r.html", tmp_path)
    assert not errors and not requests, (errors, requests)
    page.wait_for_function("document.getElementById('pp-scene').dataset.layout !== undefined", timeout=60_000)
    traces = page.evaluate("document.getElementById('pp-scene').data.map(t => [t.name, t.x || null, t.y || null])")
    named = {name: (x, y) for name, x, y in traces}
    x, y = named["marked region"]
    assert len(x) > 10 and min(x) >= -150.0 - 1e-6 and max(x) <= 150.0 + 1e-6
    assert min(y) >= -200.0 - 1e-6 and max(y) <= 40.0 + 1e-6
    assert any(n.startswith("landmarks") for n in named) and "sides" in named
    assert not any("cart" in n for n in named)  # docking assumed: no cart drawn
