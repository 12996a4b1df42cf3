"""#57 item 3: a surgeon's own layout (``[given_layout]``) scored as the rows score a layout: its row equals the
enumeration's row of the same ports in every column, its rank is the count of cheaper feasible rows, and the better
layout nearby is the cheapest feasible row with every port within reach of the given one's, each held to a brute
force over the stored rows (pandas, apart from the code under test)."""
import numpy as np
import pytest

from surgopt.runner import run_study
from surgopt.store import Store
from surgopt.studies.port_place import config as C
from surgopt.studies.port_place import given as G
from surgopt.studies.port_place import study as S

SMALL = {"patient": {"port_region": {"site_spacing_mm": 36.0}}, "target": {"spacing_mm": 15.0},
         "cart": {"model": "none"}}


def _given(row: dict) -> dict:
    return {a: {"x_mm": row[f"{a}_x_mm"], "y_mm": row[f"{a}_y_mm"]} for a in ("psm1", "psm2", "ecm")}


@pytest.fixture(scope="module")
def small():
    cfg = C.PortPlaceConfig.model_validate(SMALL)
    cols = S.compute_task(cfg, S.n_total(cfg), 0)
    return cfg, cols


def test_a_given_layout_at_candidate_sites_is_its_enumerated_row(small):
    cfg, cols = small
    feasible, infeasible = np.flatnonzero(cols["feasible"]), np.flatnonzero(~cols["feasible"])
    assert len(feasible) and len(infeasible)  # the premise: both kinds
    for r in (int(feasible[len(feasible) // 2]), int(infeasible[len(infeasible) // 3])):
        row = {c: v[r].item() if hasattr(v[r], "item") else v[r] for c, v in cols.items()}
        given = C.PortPlaceConfig.model_validate({**SMALL, "given_layout": _given(row)})
        score = G.score_given(given)
        assert all(d < 1e-6 for d in score.moved_mm.values())  # each port on its own site
        for c, v in row.items():
            if c != "design_id":
                assert score.row[c] == pytest.approx(v, abs=1e-9, nan_ok=True), c


def test_a_given_port_by_a_landmark_is_its_offset_from_it():
    cfg = C.PortPlaceConfig.model_validate({**SMALL, "given_layout": {
        "psm1": {"landmark": "umbilicus", "left_mm": 72.0, "cranial_mm": -18.0},
        "psm2": {"landmark": "xiphoid", "left_mm": -36.0}, "ecm": {"x_mm": 10.0, "y_mm": 20.0}}})
    points = G.given_points_mm(cfg)
    xiphoid_y = 0.85 * cfg.patient.semi_axes_mm[1]  # the dome's default landmarks (geometry.DOME_LANDMARKS)
    assert points == {"psm1": (72.0, -18.0), "psm2": (-36.0, xiphoid_y), "ecm": (10.0, 20.0)}


@pytest.mark.parametrize("which", ["feasible", "infeasible"])
def test_the_closing_report_ranks_it_and_names_the_cheapest_better_layout_nearby(tmp_path, small, which):
    cfg, cols = small
    pick = np.flatnonzero(cols["feasible"] if which == "feasible" else ~cols["feasible"])
    order = pick[np.argsort(cols["cost"][pick])]
    ports = np.stack([np.column_stack([cols[f"{a}_{c}_mm"] for c in "xyz"]) for a in ("psm1", "psm2", "ecm")], 1)
    ok_ports = ports[cols["feasible"]]

    def has_neighbour(k):  # a feasible row with every port within 80 mm (the pair either way round): brute force
        d = np.linalg.norm(ok_ports - ports[k], axis=2)
        crossed = np.linalg.norm(ok_ports[:, [1, 0, 2]] - ports[k], axis=2)
        return bool(((d <= 80).all(axis=1) | (crossed <= 80).all(axis=1)).sum() > (1 if which == "feasible" else 0))

    r = int(next(k for k in order[len(order) // 2:] if has_neighbour(k)))
    row = {c: v[r].item() if hasattr(v[r], "item") else v[r] for c, v in cols.items()}
    given = C.PortPlaceConfig.model_validate({**SMALL, "given_layout": {**_given(row), "within_mm": 80.0}})
    store = Store(tmp_path / "s")
    run_study(S.STUDY, given, config_name="given", store=store, jobs=1, quiet=True)
    (run,) = store.runs("port-place")
    df = run.parts(S.STUDY.schema_for(run.manifest["config"])).table().to_pandas()
    head, tables = S.STUDY.config_report(given, run.parts(S.STUDY.schema_for(run.manifest["config"])))
    words = head["given_layout"]
    ok = df[df.feasible]
    if which == "feasible":
        assert words.startswith(f"feasible, cost {row['cost']:.4f}: rank {int((ok.cost < row['cost']).sum()) + 1:,} "
                                f"of the run's {len(ok):,} feasible")
    else:
        assert words.startswith("INFEASIBLE: fails on ")

    def d(a, b):
        return np.sqrt(sum((ok[f"{a}_{c}_mm"] - row[f"{b}_{c}_mm"]) ** 2 for c in "xyz"))

    near = ((d("psm1", "psm1") <= 80) & (d("psm2", "psm2") <= 80)) | ((d("psm1", "psm2") <= 80) & (d("psm2", "psm1") <= 80))
    near &= d("ecm", "ecm") <= 80
    if which == "feasible":
        near &= ok.cost < row["cost"]
    want = ok[near].sort_values("cost")
    assert len(want)  # the premise: a better layout lies within 80 mm (the median feasible row, an infeasible one)
    assert f"design {int(want.iloc[0].design_id)} (cost {want.iloc[0].cost:.4f})" in words
    assert tables[0][0].startswith("your layout (given_layout)")


def test_a_given_layout_is_refused_by_name_when_it_does_not_fit_the_run():
    with pytest.raises(ValueError, match="given_layout.psm1.landmark: 'navel'"):
        C.PortPlaceConfig.model_validate({"given_layout": {"psm1": {"landmark": "navel"}, "psm2": {"x_mm": 0, "y_mm": 0},
                                                           "ecm": {"x_mm": 0, "y_mm": 0}}})
    with pytest.raises(ValueError, match="given_layout.psm3"):
        C.PortPlaceConfig.model_validate({"robot": {"instrument_count": 3}, "given_layout": {
            "psm1": {"x_mm": 0, "y_mm": 0}, "psm2": {"x_mm": 0, "y_mm": 0}, "ecm": {"x_mm": 0, "y_mm": 0}}})
    with pytest.raises(ValueError, match="one of the two"):
        C.PortPlaceConfig.model_validate({"given_layout": {"psm1": {"x_mm": 1.0}, "psm2": {"x_mm": 0, "y_mm": 0},
                                                           "ecm": {"x_mm": 0, "y_mm": 0}}})


def test_a_given_layout_is_scored_against_the_stored_run_without_running_it_again(tmp_path):
    """#57 item 3: "surgopt port-place CONFIG with a [given_layout] answers in seconds": the given layout is not in
    the run's key, so a config that only adds one reuses the stored rows (a cache hit), and the closing report
    scores it there (its table first); the run's kept summary never holds it, and such a command line is not
    answered from ``_hits`` (which replays a kept report)."""
    from conftest import cli
    from surgopt.config import study_key

    plain = C.PortPlaceConfig.model_validate(SMALL)
    given = C.PortPlaceConfig.model_validate({**SMALL, "given_layout": {"psm1": {"landmark": "umbilicus", "left_mm": 60},
                                                                        "psm2": {"landmark": "umbilicus", "left_mm": -60},
                                                                        "ecm": {"landmark": "umbilicus", "cranial_mm": 60}}})
    assert study_key("port-place", plain, S.KERNEL_VERSION) == study_key("port-place", given, S.KERNEL_VERSION)
    import yaml

    (tmp_path / "plain.yaml").write_text(yaml.safe_dump(SMALL))
    (tmp_path / "given.yaml").write_text(yaml.safe_dump({**SMALL, "given_layout": given.given_layout.model_dump(
        exclude_none=True)}))
    hits = tmp_path / "s" / "_hits"
    first = cli("port-place", tmp_path / "plain.yaml", "--store", tmp_path / "s")
    recorded = sorted(p for p in hits.rglob("*") if p.is_file())
    assert recorded  # the premise: a plain command line is recorded
    assert "your layout" not in first.stdout and "│ given_layout" not in first.stdout
    again = cli("port-place", tmp_path / "given.yaml", "--store", tmp_path / "s")
    assert "cache hit" in again.stderr + again.stdout  # the stored rows, not a second enumeration
    assert "your layout (given_layout)" in again.stdout and "│ given_layout" in again.stdout
    store = Store(tmp_path / "s")
    (run,) = store.runs("port-place")
    assert "given_layout" not in run.manifest.get("headline", {})
    assert sorted(p for p in hits.rglob("*") if p.is_file()) == recorded  # the given layout's line is not
    # the page of the run named by the given layout's config shows it as the closing report does; the run's own
    # page (--store-index) is built again, not taken for it
    page = cli("report", tmp_path / "given.yaml", "--store", tmp_path / "s")
    beside = run.path / "_report.html"
    text = beside.read_text()
    assert "your layout (given_layout)" in text and "given_layout" in text and "report.html" in page.stdout + page.stderr
    index = cli("report", "--store-index", "--store", tmp_path / "s")
    assert "1 run pages written beside them, 0 kept" in index.stdout
    assert "your layout (given_layout)" not in beside.read_text()  # the run's own page again
