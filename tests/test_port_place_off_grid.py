"""#58's engine, first part: a layout evaluated at ports anywhere, not only at candidate sites
(``designs.evaluate_at_ports``: the grid's own tables built for those ports alone, combined by the design kernel).
Held to the enumeration: at candidate sites it is the enumeration's row in every column but the site numbers, and
a port moved onto another candidate site gives the enumerated row of the moved layout."""
import numpy as np
import pytest

from surgopt.studies.port_place import config as PC
from surgopt.studies.port_place import study as S
from surgopt.studies.port_place.designs import evaluate_at_ports

#: The cart, its setup joints and the links on a coarse grid (``tests/test_link_tables.py``'s LINKS)
LINKS = {"patient": {"port_region": {"site_spacing_mm": 36.0}}, "target": {"spacing_mm": 15.0},
         "cart": {"model": "classic", "around_step_deg": 30.0, "distance_step_mm": 300.0, "clear_of_table_mm": 0.0},
         "constraints": {"min_link_clearance_mm": 0.0}, "robot": {"docking_roll_deg": -45.0}}
ARMS = ("psm1", "psm2", "ecm")


@pytest.fixture(scope="module")
def grid():
    cfg = PC.PortPlaceConfig.model_validate(LINKS)
    return cfg, S.compute_task(cfg, S.n_total(cfg), 0)


def _row(cols, r) -> dict:
    return {c: v[r] for c, v in cols.items()}


def _ports(row) -> np.ndarray:
    return np.array([[row[f"{a}_{c}_mm"] for c in "xyz"] for a in ARMS])


#: On a row whose links overlap, the tables stop at the first overlap they find: its value is a bound above the
#: true overlap (README), found in an order the set of sites decides; the bound's columns are then held to say the
#: same (an overlap), not to the same value.
BOUND_COLUMNS = ("external_clearance_mm", "external_link_pair")


def _same_row(got: dict, want: dict) -> None:
    overlap = want["external_clearance_mm"] < 0
    if overlap:
        assert np.asarray(got["external_clearance_mm"])[0] < 0
    for c, v in got.items():
        if c.endswith("_site") or (overlap and c in BOUND_COLUMNS):
            continue
        a, b = np.asarray(v)[0], want[c]
        if isinstance(b, (float, np.floating)):
            np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-12, equal_nan=True, err_msg=c)
        else:
            assert a == b, (c, a, b)


def test_at_candidate_sites_a_layout_is_its_enumerated_row(grid):
    """Feasible rows and rows failing for different reasons (links, docking, reach): every column equal (where
    the links overlap, both say so: ``BOUND_COLUMNS``)."""
    cfg, cols = grid
    feasible = np.flatnonzero(cols["feasible"])
    failing = np.flatnonzero(~cols["feasible"])
    reasons = {int(cols["infeasible"][r]) for r in failing[:: max(1, len(failing) // 40)]}
    picks = [*feasible[:2], *[failing[cols["infeasible"][failing] == why][0] for why in sorted(reasons)[:4]]]
    assert len(feasible) >= 2 and len(reasons) >= 3  # the premise: several kinds of row
    for r in picks:
        row = _row(cols, r)
        got = evaluate_at_ports(cfg, _ports(row), int(row["design_id"]))
        _same_row(got, row)
        assert all(int(np.asarray(got[f"{a}_site"])[0]) == -1 for a in ARMS)  # not a candidate site's number


def test_a_port_moved_onto_another_site_gives_the_moved_layouts_row(grid):
    """PSM2's port of a feasible layout moved onto a neighbouring candidate site: the evaluation at the moved ports
    equals the enumeration's row of the layout with that site (found in the rows, either way round for the pair,
    as the kernel may swap which PSM docks where)."""
    from surgopt.studies.port_place.model import model_of

    cfg, cols = grid
    sites = model_of(cfg).sites_m * 1000
    row = _row(cols, np.flatnonzero(cols["feasible"])[0])
    here = sites[int(row["psm2_site"])]
    taken = {int(row[f"{a}_site"]) for a in ARMS}
    near = [s for s in np.argsort(np.linalg.norm(sites - here, axis=1)) if int(s) not in taken][0]
    moved = _ports(row)
    moved[1] = sites[near]
    pair = {int(row["psm1_site"]), int(near)}
    match = np.flatnonzero((cols["ecm_site"] == row["ecm_site"])
                           & np.isin(cols["psm1_site"], list(pair)) & np.isin(cols["psm2_site"], list(pair)))
    assert len(match) >= 1  # the premise: the moved layout is a row of the enumeration
    want = _row(cols, match[0])
    got = evaluate_at_ports(cfg, np.array([[want[f"{a}_{c}_mm"] for c in "xyz"] for a in ARMS]),
                            int(want["design_id"]))
    _same_row(got, want)
    assert np.linalg.norm(moved[1] - here) > 1.0  # it moved


def test_a_port_off_the_grid_is_evaluated_with_its_own_geometry(grid):
    """A port 5 mm off its candidate site (on the dome's skin): the row's port is that point, its spacing the
    3-D distance between the moved ports (computed here), every number finite where the enumeration's is."""
    cfg, cols = grid
    a, b, c = cfg.patient.semi_axes_mm
    row = _row(cols, np.flatnonzero(cols["feasible"])[0])
    ports = _ports(row)
    x, y = ports[0, 0] + 5.0, ports[0, 1]
    ports[0] = [x, y, c * np.sqrt(1 - (x / a) ** 2 - (y / b) ** 2)]  # on the dome
    got = evaluate_at_ports(cfg, ports)
    np.testing.assert_allclose([np.asarray(got[f"psm1_{k}_mm"])[0] for k in "xyz"] if
                               np.asarray(got["psm1_x_mm"])[0] == pytest.approx(x) else
                               [np.asarray(got[f"psm2_{k}_mm"])[0] for k in "xyz"], ports[0], atol=1e-9)
    spacing = min(np.linalg.norm(ports[i] - ports[j]) for i in range(3) for j in range(i + 1, 3))
    assert np.asarray(got["min_port_spacing_mm"])[0] == pytest.approx(spacing, abs=1e-6)
    assert np.isfinite(np.asarray(got["cost"])[0])
