"""A surgeon's own layout, scored beside the answer (#57 item 3: ``[given_layout]``).

Each arm's given port (a top-view point, or a landmark and offsets) is taken to the nearest candidate site (top
view; the distance is said) and the layout of those sites is evaluated as the enumeration evaluates every layout
(``designs.evaluate_designs``: the same tables, checks, docking, links and cost as its row). The closing report then
says what it fails on, its rank among the run's feasible layouts by cost, and the cheapest feasible layout whose every
port lies within ``within_mm`` (3-D) of the given one's (cheaper than it, when it is feasible itself).
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np

from surgopt.robots.dvrk.platforms import role_of
from surgopt.studies.port_place.columns import arms_of
from surgopt.studies.port_place.geometry import from_landmark, landmarks_mm, reference_landmark


class GivenScore(NamedTuple):
    """The given layout as a row (every column the rows have), each arm's given top-view point (mm), its candidate
    site and how far that lies from the point (mm, top view)."""

    row: dict
    points_mm: dict
    sites: dict
    moved_mm: dict


def _distance(a: dict, arm_a: str, b: dict, arm_b: str) -> float:
    """The 3-D distance (mm) between row ``a``'s port of ``arm_a`` and row ``b``'s of ``arm_b``."""
    return float(np.sqrt(sum((a[f"{arm_a}_{c}_mm"] - b[f"{arm_b}_{c}_mm"]) ** 2 for c in "xyz")))


def _moves(better: dict, row: dict, arms) -> dict:
    """How far (mm) each of ``row``'s ports moves to ``better``'s: the working pair matched either way round (the
    nearer way), the others arm to arm."""
    straight = {a: _distance(better, a, row, a) for a in arms}
    crossed = {**straight, "psm1": _distance(better, "psm2", row, "psm1"), "psm2": _distance(better, "psm1", row, "psm2")}
    return min((straight, crossed), key=lambda m: max(m.values()))


def given_points_mm(cfg) -> dict:
    """Each arm's given port as a top-view point (x, y mm, the patient frame)."""
    marks = landmarks_mm(cfg.patient)
    out = {}
    for arm in arms_of(cfg):
        port = getattr(cfg.given_layout, arm)
        if port.landmark is None:
            out[arm] = (port.x_mm, port.y_mm)
        else:
            lx, ly = marks[port.landmark]
            out[arm] = (lx + port.left_mm, ly + port.cranial_mm)
    return out


def score_given(cfg) -> GivenScore:
    """The given layout evaluated as the enumeration evaluates its rows (``evaluate_designs``), at the candidate
    sites nearest its ports (top view); with the docking rolls enumerated, at each of them, the cheapest feasible
    docking taken (else the cheapest), as a team would choose its roll."""
    from surgopt.studies.port_place.designs import evaluate_designs, nearest_sites
    from surgopt.studies.port_place.model import model_of
    from surgopt.studies.port_place.rolls import at_docking, dockings, first_docking

    model = model_of(first_docking(cfg))
    points = given_points_mm(cfg)
    arms = arms_of(cfg)
    xy = np.array([points[a] for a in arms], float)
    sites = nearest_sites(model.sites_m[:, :2] * 1000, xy)
    moved = {a: float(np.hypot(*(model.sites_m[s, :2] * 1000 - xy[k]))) for k, (a, s) in enumerate(zip(arms, sites))}
    rows = []
    for docking in dockings(cfg):
        cols = evaluate_designs(at_docking(cfg, docking), sites[None].astype(float), np.array([-1]), "given")
        rows.append({c: (v[0].item() if hasattr(v[0], "item") else v[0]) for c, v in cols.items()})
    row = min(rows, key=lambda r: (not r["feasible"], r["cost"]))
    return GivenScore(row, points, {a: int(s) for a, s in zip(arms, sites)}, moved)


def rank_among(parts, cost: float) -> tuple[int, int]:
    """(how many of the run's feasible layouts cost less than ``cost``, how many are feasible)."""
    cheaper = total = 0
    for t in parts.only(["feasible", "cost"]):
        ok = t["feasible"].to_numpy(zero_copy_only=False)
        total += int(ok.sum())
        cheaper += int(np.count_nonzero(t["cost"].to_numpy()[ok] < cost))
    return cheaper, total


def better_nearby(parts, row: dict, within_mm: float, arms) -> dict | None:
    """The cheapest feasible row whose every arm's port lies within ``within_mm`` (3-D) of ``row``'s, and which costs
    less than it when it is feasible itself; None when there is none."""
    cols = ["design_id", "feasible", "cost", *(f"{a}_{c}_mm" for a in arms for c in "xyz")]
    best = None
    for t in parts.only(cols):
        ok = t["feasible"].to_numpy(zero_copy_only=False)
        if not ok.any():
            continue
        def close(mine: str, theirs: str) -> np.ndarray:
            d = np.sqrt(sum((t[f"{mine}_{c}_mm"].to_numpy() - row[f"{theirs}_{c}_mm"]) ** 2 for c in "xyz"))
            return d <= within_mm

        near = ok.copy()
        for a in arms[2:]:  # a third instrument and the camera on their own
            near &= close(a, a)
        # the working pair either way round: a row's psm1 is the arm on PSM1's setup joints, whichever port it takes
        near &= (close("psm1", "psm1") & close("psm2", "psm2")) | (close("psm1", "psm2") & close("psm2", "psm1"))
        cost = t["cost"].to_numpy()
        if row["feasible"]:
            near &= cost < row["cost"]
        if near.any():
            k = int(np.flatnonzero(near)[np.argmin(cost[near])])
            if best is None or cost[k] < best["cost"]:
                best = {c: (t[c][k].as_py()) for c in cols}
    return best


def given_report(parts, cfg) -> tuple[str, list]:
    """(the headline's words, the closing report's table) of the config's given layout."""
    from surgopt.studies.port_place.export import fails_on

    score = score_given(cfg)
    row, arms, within = score.row, arms_of(cfg), cfg.given_layout.within_mm
    mark_name, mark = reference_landmark(cfg.patient)
    if row["feasible"]:
        cheaper, total = rank_among(parts, row["cost"])
        words = (f"feasible, cost {row['cost']:.4f}: rank {cheaper + 1:,} of the run's {total:,} feasible layouts by "
                 f"cost")
    else:
        words = f"INFEASIBLE: fails on {', '.join(fails_on(int(row['infeasible'])))} (cost {row['cost']:.4f}"
        if "external_link_pair" in row and not np.isfinite(row["external_clearance_mm"]):
            words += "; its links not checked: the rows check them on layouts that pass every other check"
        elif "external_link_pair" in row and row["external_clearance_mm"] < 0 and row["external_link_pair"] >= 0:
            from surgopt.studies.port_place.link_tables import pair_name

            words += (f"; its links overlap by {-row['external_clearance_mm']:.0f} mm: "
                      f"{pair_name(int(row['external_link_pair']), cfg.cart.model)}")
        words += ")"
    better = better_nearby(parts, row, within, arms)
    if better is not None:
        shifts = ", ".join(f"{role_of(a)} {d:.0f}" for a, d in _moves(better, row, arms).items())
        words += (f"; within {within:g} mm of each port, design {better['design_id']} (cost {better['cost']:.4f}) is "
                  f"feasible{' and cheaper' if row['feasible'] else ''} (ports moved {shifts} mm)")
    else:
        words += f"; no {'cheaper ' if row['feasible'] else ''}feasible layout has every port within {within:g} mm"
    given_of_site = {}  # the rows' psm1 is the arm on PSM1's setup joints: each row arm's given port by its site
    for a, s in score.sites.items():
        given_of_site.setdefault(s, a)
    body = []
    for a in arms:
        source = given_of_site.get(int(row[f"{a}_site"]), a)
        x, y = score.points_mm[source]
        site = [row[f"{a}_{c}_mm"] for c in "xyz"]
        body.append([role_of(a), f"{role_of(source)}'s: {x:.0f}, {y:.0f}", str(row[f"{a}_site"]),
                     f"{site[0]:.0f}, {site[1]:.0f}, {site[2]:.0f}", f"{score.moved_mm[source]:.0f}",
                     from_landmark(site[0], site[1], mark)])
    table = (f"your layout (given_layout): {words}",
             ["arm", "given x, y (mm)", "site", "site x, y, z (mm)", "site from the given point (mm, top view)",
              f"from the {mark_name} (mm, top view)"], body)
    return words, [table]
