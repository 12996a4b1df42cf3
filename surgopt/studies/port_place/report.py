"""port-place's closing report: the feasible count and each reason's, the best layout's clinical checks beside
the literature, its ports (and from a landmark), its cart pose and setup joints docked as the export docks it,
why the best layouts without the cart do not dock, the links' screen of the best layouts (with each PSM's roll
where they overlap; the answer is always the rows' best feasible layout, and a cheaper one that clears only rolled
is said beside it as advice), and the least-cost layouts the report and the page list (one of each layout).

Read from the stored rows and the run's config in their metadata (a report of an old run is the run's); the
study (``study.STUDY``) names ``summary`` here by module, imported when a report is made. One module of ~450
lines: the tables of one report, which read one another's rows (the screen's rows are the least-cost layouts',
the headline's layout is the screen's, the docking tables show its docking).
"""
from __future__ import annotations

import json
import math

import numpy as np

from surgopt.studies import Summary
from surgopt.studies.port_place.clashes import in_feasible
from surgopt.robots.dvrk.links import LINK_MODEL_WORDS
from surgopt.robots.dvrk.platforms import PLATFORMS
from surgopt.studies.port_place.config import PortPlaceConfig
from surgopt.studies.port_place.geometry import FRAME_TEXT, from_landmark, skin_words
from surgopt.studies.port_place.hands import pairing_words
from surgopt.studies.port_place.rolls import at_docking, dockings, docking_words, model_for, per_roll
from surgopt.studies.port_place.columns import links_of


def clinical_checks(cfg=None) -> tuple:
    """A layout's clinical checks beside the numbers it is held to: (quantity, row columns, decimals, how the
    columns' values are joined, the number and its source, its band (lo, hi) where there is one: a value outside it
    is marked). The bands are the run's own constraints (``cfg``; None: the defaults), each said beside the
    literature's value it defaults to: a run with min_port_spacing_mm = 60 is checked against 60, not 80. The
    closing report and the HTML page read it."""
    k = (cfg.constraints if cfg is not None else PortPlaceConfig().constraints)
    spacing, (near, far), (a_lo, a_hi) = k.min_port_spacing_mm, k.port_to_target_mm, k.manipulation_angle_deg
    three_d = k.port_to_target_measure == "3d"  # the column is 3-D: a horizontal constraint is not its band
    return (
        ("port spacing (mm)", ("min_port_spacing_mm",), 0, "",
         f">= {spacing:g} (constraints.min_port_spacing_mm; default 80: an assumption, 8 cm)", (spacing, math.inf)),
        ("instrument port to target centre, 3-D (mm)", ("psm_to_target_mm",), 0, "",
         (f"{near:g}-{far:g} (constraints.port_to_target_mm" if three_d else
          f"{near:g}-{far:g} horizontal (constraints.port_to_target_mm, not this 3-D distance")
         + "; <= 180: J Endourol 2004, port to pubis)", (near, far) if three_d else None),
        ("manipulation angle at the centre (deg)", ("manipulation_angle_centre_deg",), 1, "",
         f"{a_lo:g}-{a_hi:g} (constraints.manipulation_angle_deg; 45-75, 60 best: Hanna 1997)", (a_lo, a_hi)),
        ("manipulation angle over the target (deg)", ("manipulation_angle_min_deg", "manipulation_angle_max_deg"),
         1, " - ", f"{a_lo:g}-{a_hi:g}", (a_lo, a_hi)),
        ("azimuth imbalance (deg)", ("azimuth_imbalance_deg",), 1, "", "0: equal azimuths (Hanna 1997)", None),
        ("instrument elevation at the centre (deg)", ("psm1_elevation_deg", "psm2_elevation_deg"), 1, " / ",
         "60 with a 60-deg manipulation angle (Hanna 1997)", None),
        ("optical axis off the instruments' arc (deg)", ("camera_off_arc_deg",), 1, "", "0: camera between them",
         None),
        ("common reach", ("common_reach",), 3, "", "1", (1.0, 1.0)),
        ("camera coverage", ("camera_coverage",), 3, "", "1", (1.0, 1.0)),
    )


#: The columns the clinical checks read (the same whatever the run's bands).
CLINICAL_COLUMNS = tuple(f for _, fields, *_ in clinical_checks() for f in fields)


#: What reading a run's config again from its rows' metadata can raise (an older run's fields, a missing key).
STORED_ERRORS = (ValueError, OSError, KeyError)


def stored_config(meta: dict) -> PortPlaceConfig:
    """The run's config as its rows' metadata keep it (its files are not read and hashed again)."""
    return PortPlaceConfig.model_validate(json.loads(meta["config"]), context={"stored": True})


def _config_or_none(meta: dict) -> PortPlaceConfig | None:
    """``stored_config``, or None where it cannot be read again (the checks then say the defaults)."""
    try:
        return stored_config(meta)
    except STORED_ERRORS:
        return None


def within_band(values, band) -> str:
    """"yes", "OUTSIDE" (any value out of the band) or "" (the literature gives no band)."""
    if band is None:
        return ""
    return "yes" if all(band[0] <= v <= band[1] for v in values) else "OUTSIDE"


#: What every answer leaves out (docs/port_placement.md, "What the model leaves out"), said in the closing report.
NOT_MODELLED = ("the Xi's setup joints, each PSM's own docking turn (the rows dock both PSMs at one turn, mirrored by "
                "their ports' sides, a roll about the shaft on the Classic, a yaw off psi* on the Si: "
                "robot.docking_roll_deg, or each of robot.docking_rolls_deg enumerated; the report tries each PSM's "
                "own on cheaper layouts as advice, never as the answer), tissue "
                "and the body wall's thickness (a port is a point), the assistant's port, the table's pedestal and "
                "the staff; the bedside (rails, the patient's arms and legs) is boxes of assumed size (bedside.py); "
                "the setup joints' and the ECM's link radii are assumptions, the PSMs' are capsules about their meshes (docs/port_placement.md, what the model leaves out)")


def summary(parts) -> Summary:
    """Feasible count, each reason's count, the best feasible design by cost with its clinical checks."""
    from surgopt.kinematics.port.reasons import DOCKING, REASONS

    n = parts.num_rows
    by_bit = dict.fromkeys(REASONS, 0)
    feasible = only_docking = 0
    for t in parts.only(["infeasible"]):  # one pass over one column: every count at once
        bad = t["infeasible"].to_numpy()
        feasible += int(np.count_nonzero(bad == 0))
        only_docking += int(np.count_nonzero(bad == DOCKING))
        for bit in by_bit:
            by_bit[bit] += int(np.count_nonzero(bad & bit))
    meta = {k.decode(): v.decode() for k, v in (parts.schema.metadata or {}).items()}
    cfg = _config_or_none(meta)  # once: every part of the report reads the run's config from here
    if meta.get("rows_stored") == "feasible":  # the infeasible designs were counted out, their reasons not kept
        headline = {"designs": int(meta["designs_enumerated"]) if "designs_enumerated" in meta else "not known",
                    "rows_stored": "feasible only", "feasible": feasible}
        counts = {"feasible": feasible}
        if "designs_enumerated" in meta:
            counts["infeasible (rows not stored)"] = int(meta["designs_enumerated"]) - feasible
    else:
        counts = {"feasible": feasible, "infeasible": n - feasible}
        counts.update({f"infeasible: {why}": by_bit[bit] for bit, why in REASONS.items()})
        headline = {"designs": n, "feasible": feasible}
    best = least_cost_layouts(parts, max(5, SCREEN_LAYOUTS))
    rows = best.to_pylist()
    screen = screen_of(parts, meta, rows)
    rolled = rolled_of(screen)
    first = rows[0] if rows else None
    best = best.slice(0, 5)
    tables = []
    if rolled is not None:  # a cheaper layout the screen clears with its PSMs rolled: advice, not the answer
        headline["cheaper_if_rolled"] = cheaper_if_rolled_words(*rolled, cfg)
    if first is not None:  # the answer is the rows' best feasible layout, docked as its row is (#54 item 2, #56 2)
        b = first
        headline.update({"best_design_id": b["design_id"], "best_cost": b["cost"]})
        checks = [[label + (" (all three instruments)" if fields == ("common_reach",) and "psm3_reach" in b else ""),
                   joiner.join(f"{b[f]:.{digits}f}" for f in fields), clinical,
                   within_band([b[f] for f in fields], band)]
                  for label, fields, digits, joiner, clinical, band in clinical_checks(cfg)]
        tables.append(("best layout: clinical checks", ["quantity", "value", "clinical number", "within"], checks))
        if cfg is not None and cfg.robot.docking_rolls_deg:  # the roll a dimension of the rows (#54 item 2)
            headline["docking_roll"] = docking_words(cfg, b)
        if "image_right_psm" in b:  # which hand drives which arm (#54 item 4)
            headline["hands"] = pairing_words(int(b["image_right_psm"]))
        mark = json.loads(meta["landmark"]) if "landmark" in meta else None
        skin = cfg is not None and mark is not None  # the tape's distances need the patient (#57 item 2)
        ports = [[arm, str(b[f"{arm}_site"]), f"{b[f'{arm}_x_mm']:.0f}", f"{b[f'{arm}_y_mm']:.0f}",
                  f"{b[f'{arm}_z_mm']:.0f}"] + ([from_landmark(b[f"{arm}_x_mm"], b[f"{arm}_y_mm"], mark[1:])]
                                                if mark else [])
                 + ([skin_words(cfg.patient, mark[1:], b[f"{arm}_x_mm"], b[f"{arm}_y_mm"])] if skin else [])
                 for arm in ("psm1", "psm2", "psm3", "ecm") if f"{arm}_site" in b]
        wall = wall_column(cfg, b)
        if wall is not None:  # a CT's wall: its thickness at each port, toward the target (#57 item 1)
            ports = [r + [w] for r, w in zip(ports, wall)]
        tables.append((f"best layout: ports ({FRAME_TEXT})", ["arm", "site", "x_mm", "y_mm", "z_mm"]
                       + ([f"from the {mark[0]} (mm, top view)"] if mark else [])
                       + ([f"from the {mark[0]} along the skin (across, then along)"] if skin else [])
                       + (["wall_mm (skin to peritoneum, toward the target)"] if wall is not None else []), ports))
        lines = landmark_lines_table(cfg) if skin else None
        if lines is not None:  # the lines a team draws between landmarks, measured along the skin (#57 item 2)
            tables.append(lines)
        if "cart_pose" in b:  # after the screen: the best layout's clearances and rolls are then known
            bound = cart_bound_words(parts, b, cfg)
            if bound:
                headline["cart_on_bound"] = bound
            tables += docking_tables(b, meta)
            if meta.get("rows_stored") != "feasible":
                tables += undocked_table(parts, meta)
            if screen is not None:
                headline["links_clear"], table, _ = screen
                tables.append(table)
            whole = whole_target_words(parts, meta, b)
            if whole:
                headline["links_whole_target"] = whole
    if best.num_rows:
        cols = ["design_id", "cost", "common_reach", "dexterity_mean", "manipulation_angle_mean_deg",
                "azimuth_imbalance_deg", "camera_coverage"]
        repeats = best.schema.metadata.get(b"repeats_collapsed", b"0").decode() if best.schema.metadata else "0"
        at_roll = " (their links clear at the run's docking roll)" if "best_at_run_roll" in headline else ""
        tables.append(("best feasible designs by cost" + at_roll + (f" ({repeats} repeats of a listed layout "
                                                                   f"collapsed)" if repeats != "0" else ""), cols,
                       [[f"{r[c]:.4g}" if isinstance(r[c], float) else str(r[c]) for c in cols] for r in best.to_pylist()]))
        if mark:
            arms = [a for a in ("psm1", "psm2", "psm3", "ecm") if f"{a}_x_mm" in b]
            tables.append((f"best feasible designs: ports from the {mark[0]} (mm, top view: the patient's left or "
                           f"right, cranial or caudal)", ["design_id", *arms],
                           [[str(r["design_id"]), *(from_landmark(r[f"{a}_x_mm"], r[f"{a}_y_mm"], mark[1:])
                                                    for a in arms)] for r in best.to_pylist()]))
    if first is None:  # the answer is why: each check's count, and why the cart docks none of the rest
        headline["best"] = ("none: no design is feasible (the reasons below)" if meta.get("rows_stored") != "feasible"
                            else "none: no design is feasible (this run stored feasible rows only, so it kept no "
                                 "reasons: run with rows_stored = 'all', on a coarser grid if need be, to see them)")
        failing = [[k.removeprefix("infeasible: "), f"{v:,}"] for k, v in counts.items()
                   if k.startswith("infeasible: ") and v]
        if "cart_pose" in parts.schema.names and meta.get("rows_stored") != "feasible":
            failing.append(["every check but the cart's docking passes", f"{only_docking:,}"])
            tables += undocked_table(parts, meta)  # (with the links deciding, those failing on them alone too)
        if failing:
            tables.insert(0, ("why no design is feasible: the designs failing each check (one may fail several)",
                              ["check", "designs"], failing))
        if screen is not None:  # the layouts failing only on their links, none of which a roll cleared
            headline["links_clear"], table, _ = screen
            tables.append(table)
    if "cart" in meta:
        headline["cart"] = meta["cart"]
    if cfg is not None and "external_link_pair" in parts.schema.names:  # what the links clear beside the table
        from surgopt.studies.port_place.bedside import bedside_words

        headline["bedside"] = bedside_words(cfg)
    if cfg is not None and any(o.obstacle for o in cfg.patient.organs.values()):  # the shafts' obstacles (#57 item 1)
        from surgopt.studies.port_place.organs import organs_words
        from surgopt.studies.port_place.rolls import first_docking
        from surgopt.studies.port_place.model import model_of

        headline["organs"] = organs_words(model_of(first_docking(cfg)))
    headline["not_modelled"] = NOT_MODELLED
    if "cart_pose" in parts.schema.names and meta.get("rows_stored") != "feasible":
        counts["infeasible only for docking (feasible without the cart)"] = only_docking
    return Summary(headline, counts, tables)


def landmark_lines_table(cfg):
    """(#57 item 2) The lines between the patient's landmarks (``geometry.landmark_lines``) with their lengths along
    the skin and in the top view (cm), as a team marks them before placing ports; None without any line."""
    from surgopt.studies.port_place.geometry import landmark_lines, landmarks_mm, skin_line_mm

    marks = landmarks_mm(cfg.patient)
    rows = []
    for a, b in landmark_lines(cfg.patient):
        _, along = skin_line_mm(cfg.patient, marks[a], marks[b])
        top = float(np.hypot(marks[b][0] - marks[a][0], marks[b][1] - marks[a][1]))
        rows.append([f"{a} - {b}", f"{along / 10:.1f}", f"{top / 10:.1f}"])
    if not rows:
        return None
    return ("the patient's landmarks: the lines between them (drawn straight in the top view, on the skin)",
            ["line", "along the skin (cm)", "top view (cm)"], rows)


def wall_column(cfg, row: dict) -> list[str] | None:
    """With a wall's shell for the patient (``patient.mesh_is = "wall"``): each port's wall thickness (mm) toward the
    target's centre (``geometry.wall_thickness_mm``), in the ports table's order; else None."""
    if cfg is None or cfg.patient.shape != "mesh" or cfg.patient.mesh_is != "wall":
        return None
    from surgopt.studies.port_place.geometry import wall_thickness_mm

    arms = [a for a in ("psm1", "psm2", "psm3", "ecm") if f"{a}_site" in row]
    ports = np.array([[row[f"{a}_{c}_mm"] for c in "xyz"] for a in arms])
    return [f"{w:.1f}" if np.isfinite(w) else "-" for w in wall_thickness_mm(ports, cfg.target.centre_mm, cfg.patient)]


#: The feasible layouts after the answer (by cost) the closing report checks over the whole target when the
#: answer's links overlap there (each ~1 s).
WHOLE_TARGET_SCREEN = 5


def whole_target_words(parts, meta: dict, answer: dict) -> str | None:
    """(#54 item 3) What the answer's links do over every target point (``clashes.whole_target_clearances``),
    in words: clear by how much; or, in a run stored before the rows measured their feasible layouts so (no
    ``links_whole_target_mm``) or without a floor, the overlap the rows' sample missed, its pair and where, and the
    first of the next WHOLE_TARGET_SCREEN feasible layouts by cost whose links clear over the whole target."""
    from surgopt.studies.port_place.clashes import least, links_modelled, whole_target_clearances
    from surgopt.studies.port_place.columns import WHOLE_TARGET_COLUMN
    from surgopt.studies.port_place.link_tables import POSE_POINTS

    cfg = _config_or_none(meta)
    if cfg is None or not links_modelled(cfg) or cfg.constraints.link_least_mm is None:
        return None
    floor = cfg.constraints.link_least_mm
    worst = least(whole_target_clearances(model_for(cfg, answer), answer))
    if worst is None:
        return None
    points = worst.check.split("(")[-1].rstrip(")")
    if worst.clearance_mm >= floor:
        decided = ("every feasible layout is measured so: the link tables sample "
                   f"{POSE_POINTS} of them, then each layout feasible there is measured again over every point"
                   if answer.get(WHOLE_TARGET_COLUMN) is not None else f"the rows check {POSE_POINTS} of them")
        return (f"clear by {worst.clearance_mm:.0f} mm between arms over every one of the {points} ({worst.link_a} / "
                f"{worst.link_b}; {decided})")
    words = (f"OVERLAP: over the whole target ({points}) the answer's links overlap by {-worst.clearance_mm:.0f} mm "
             f"({worst.link_a} / {worst.link_b}; {worst.where}), which the rows' check of {POSE_POINTS} points "
             f"passed")
    for row in least_cost_layouts(parts, WHOLE_TARGET_SCREEN + 1).to_pylist()[1:]:
        other = least(whole_target_clearances(model_for(cfg, row), row))
        if other is not None and other.clearance_mm >= floor:
            return words + (f"; design {row['design_id']} (cost {row['cost']:.4g}), the next feasible layout by cost "
                            f"whose links clear over the whole target (by {other.clearance_mm:.0f} mm)")
    return words + f"; none of the next {WHOLE_TARGET_SCREEN} feasible layouts by cost clears over the whole target"


def suj_margin_words(cfg, arm) -> tuple[str, str]:
    """A docked arm's least margin to its setup joints' ranges, the revolute joints' (deg, and which) and the
    column's (mm) apart: one column of rad and m mixed read as one number (issue 56 item 10)."""
    if not arm.joints:
        return "-", "-"
    suj = PLATFORMS[cfg.cart.model].suj(arm.arm)
    margins = [min(v - lo, hi - v) for v, (lo, hi) in zip(arm.joints, suj.ranges)]
    names = [link.name for link in suj.links]
    least, name = min(zip(margins[1:], names[1:]))
    return f"{math.degrees(least):.1f} ({name})", f"{margins[0] * 1000:.0f}"


def docking_tables(best: dict, meta: dict) -> list:
    """The best layout's cart pose and each arm's setup joints there (solved again from the row's ports and
    pose, and the run's config in the rows' metadata), docked as the dvrk export docks it (``layout.layout_of``:
    where the links overlap at the run's own docking and a roll of each PSM about its shaft clears them, so),
    and the links' clearances so docked."""
    from surgopt.studies.port_place.clashes import turn_words
    from surgopt.studies.port_place.layout import layout_of

    try:
        cfg = stored_config(meta)
    except STORED_ERRORS as exc:
        return [("best layout: the cart", ["note"], [[f"the run's config cannot be read again ({exc}); the cart "
                                                       f"pose is in the row's cart_* columns"]])]
    model = model_for(cfg, best)  # (with rolls enumerated: its roll's)
    layout = layout_of(model, best)  # as the export docks it
    docked, rolls, clearances = layout.docked, layout.rolls, layout.clearances
    turned = {arm: deg for arm, deg in rolls.items() if deg}
    pose = [[f"{best['cart_x_mm']:.0f}", f"{best['cart_y_mm']:.0f}", f"{best['cart_heading_deg']:.1f}",
             str(best["cart_pose"]) if cfg.cart.pose != "search" else
             f"searched: {best['cart_around_deg']:.1f} deg around, {best['cart_distance_mm']:.0f} mm"]]
    rows = [[a.arm, a.site, " ".join(f"{v:.4f}" for v in a.joints) if a.joints else "-", *suj_margin_words(cfg, a),
             a.note or (f"ECM yaw {math.degrees(a.ecm[0]):.1f}, pitch {math.degrees(a.ecm[1]):.1f} deg" if a.ecm
                        else f"docking {turn_words(cfg)[1]} {turned[a.arm]:+.0f} deg ({turn_words(cfg)[0]})"
                        if a.arm in turned
                        else "")] for a in docked]
    from surgopt.studies.port_place.clashes import whole_target_clearances

    whole = [] if turned else whole_target_clearances(model, best)  # (#54 item 3) at the row's own docking
    clear = [[c.check, f"{c.clearance_mm:.0f}", c.link_a, c.link_b, c.where]
             for c in clearances + whole]
    return [(f"best layout: the {PLATFORMS[cfg.cart.model].title} cart (origin on the floor, patient frame; heading from +y toward +x)",
             ["x_mm", "y_mm", "heading_deg", "pose (of the grid, or searched)"], pose),
            ("best layout: setup joints (column m, then rad, the dVRK's simulated_position order)"
             + (" as `export --format dvrk` docks it: each PSM's docking turned so that the links clear" if turned
                else ""),
             ["arm", "port", "suj_joints", "least joint margin_deg", "column margin_mm", "note"], rows),
            (f"best layout: least clearance outside the body ({LINK_MODEL_WORDS}; negative: the links overlap; "
             + in_feasible(cfg) + ")", ["between", "clearance_mm", "link", "against", "where"], clear)]


#: The layouts of least cost among those feasible without the cart whose docking the closing report explains.
UNDOCKED_OF_BEST = 1000
UNDOCKED_WHY = ("the ECM's setup joints reach its port at no cart pose",
                "PSM1's and PSM2's setup joints take the pair's two ports at no cart pose, either way round",
                "PSM3's setup joints reach its port at no cart pose",
                "every arm docks at some cart pose of the grid, never all at one",
                "every arm docks at some cart pose, but at each the arms' links overlap each other, the patient or "
                "the table (min_link_clearance_mm)")


def undocked_table(parts, meta: dict) -> list:
    """How many of the UNDOCKED_OF_BEST layouts of least cost that are feasible without the cart (every reason
    but docking passes) the cart cannot dock, and why (``why_undocked``): the closing report's answer to "which
    of the previous best layouts are not dockable"."""
    from surgopt.kinematics.port.reasons import DOCKING, OUTSIDE
    from surgopt.studies.port_place.model import model_of

    arms = [a for a in ("psm1", "psm2", "psm3", "ecm") if f"{a}_site" in parts.schema.names]
    cols = {c: [] for c in ["cost", "design_id", "infeasible", *(f"{a}_site" for a in arms)]}
    links = "external_link_pair" in parts.schema.names  # the links decide: a clash is the cart's failure too
    cart_only = (0, DOCKING, OUTSIDE) if links else (0, DOCKING)
    for t in parts.only(list(cols)):
        keep = np.isin(t["infeasible"].to_numpy(), cart_only)
        for c in cols:
            cols[c].append(t[c].to_numpy()[keep])
    got = {c: np.concatenate(v) if v else np.zeros(0) for c, v in cols.items()}
    best = np.lexsort((got["design_id"], got["cost"]))[:UNDOCKED_OF_BEST]
    undocked = best[got["infeasible"][best] != 0]
    try:
        cfg = stored_config(meta)
    except STORED_ERRORS:
        return []
    if cfg.cart.pose == "search":  # each trial docked at its own pose, not at the grid's
        return []
    sites = np.column_stack([got[f"{a}_site"][undocked] for a in arms]).astype(np.int64)
    ids = got["design_id"][undocked]
    undocked_why = np.empty(len(ids), np.int64)
    block_of = ids // per_roll(cfg)
    for block in np.unique(block_of):  # each docking's block by its own docking's dock tables
        at = np.flatnonzero(block_of == block)
        undocked_why[at] = why_undocked(model_of(at_docking(cfg, dockings(cfg)[block])).dock, sites[at])
    why = np.where(got["infeasible"][undocked] == OUTSIDE, len(UNDOCKED_WHY) - 1, undocked_why)
    rows = [[w, f"{int(np.sum(why == k)):,}"] for k, w in enumerate(UNDOCKED_WHY) if np.any(why == k)]
    return [(f"the {len(best):,} layouts of least cost feasible without the cart: {len(undocked):,} the "
             f"{PLATFORMS[cfg.cart.model].title} cart's setup joints cannot dock at any pose of its grid"
             + (" with the arms' links clear" if links else "") + ", because", ["why", "layouts"], rows)]


def why_undocked(dock, sites: np.ndarray) -> np.ndarray:
    """For layouts the cart docks at no pose (``sites``: each arm's site, PSM1, PSM2[, PSM3], ECM), why, as an
    index into UNDOCKED_WHY, from the best solutions' margins at each pose (``DockTables.margin``, >= 0 where
    an arm docks): the first that holds of the ECM docking nowhere, the working pair's PSMs taking its two ports
    at no pose either way round, PSM3 docking nowhere, else no pose common to all."""
    some = (dock.margin >= 0.0).any(axis=2)  # (arms, sites): the arm docks there at some pose
    camera = (dock.camera_margin >= 0.0).any(axis=1)
    a, b, k = sites[:, 0], sites[:, 1], sites[:, -1]
    pair = (some[0, a] & some[1, b]) | (some[0, b] & some[1, a])
    third = some[2, sites[:, 2]] if sites.shape[1] == 4 else np.ones(len(sites), bool)
    return np.select([~camera[k], ~pair, ~third], [0, 1, 2], default=3)


#: The best distinct feasible layouts whose links the closing report checks for clearance outside the body (each
#: ~0.2 s: its setup joints solved again, its arms' capsules docked and over the target, against each other, the
#: patient and the table; ``clashes.layout_clearances``).
SCREEN_LAYOUTS = 10
ROLL_TEXT = "a 15-degree grid over +-90"


def cart_bound_words(parts, best: dict, cfg) -> str:
    """Where the answer's cart pose lies on a bound of the run's grid of cart poses (its nearest or farthest ring,
    an end of its arc, an outermost heading offset), in words with how many feasible layouts dock on that bound
    too; "" where it lies inside the grid, or the cart's pose was given or searched (issue 54 item 5: the grid's
    bounds are the config's; a bound the answer sits on is one a wider grid might beat)."""
    from surgopt.studies.port_place.tables import grid_place_of_pose

    if cfg is None or cfg.cart.pose != "grid" or best.get("cart_pose", -1) < 0:
        return ""
    places = grid_place_of_pose(cfg)
    at = places[best["cart_pose"]]
    poses = [t.filter(t["feasible"])["cart_pose"].to_numpy() for t in parts.only(["cart_pose", "feasible"])]
    poses = np.concatenate(poses) if poses else np.zeros(0, np.int64)
    poses = poses[poses >= 0].astype(np.int64)
    said = []
    for c, field, low, high in ((1, "distance_mm", "nearest ring", "farthest ring"), (0, "around_deg", "arc's end",
                                "arc's end"), (2, "yaw_offsets_deg", "outermost heading offset",
                                               "outermost heading offset")):
        lo, hi = places[:, c].min(), places[:, c].max()
        for value, name in ((lo, low), (hi, high)):
            if lo < hi and abs(at[c] - value) < 1e-9:
                n = int(np.count_nonzero(np.abs(places[poses, c] - value) < 1e-9))
                said.append(f"on the grid's {name} ({value:g}, cart.{field}; {n:,} of the {len(poses):,} feasible "
                            f"layouts dock there)")
    if not said:
        return ""
    return ("the answer's cart pose lies " + "; and ".join(said) + ": a pose beyond it may do better. The grid's "
            "bounds are the config's (the cart's base, from its mesh, is kept cart.clear_of_table_mm from the table; "
            "the grid's rings and arc are not the robot's): widen them to see")


def screen_of(parts, meta: dict, best: list[dict]):
    """``clearance_screen`` of the best feasible layouts ``best`` (by cost), with the links in feasible the cheaper
    ones that fail only on them first (``with_cheaper_overlapping``); None without the cart."""
    if "cart_pose" not in parts.schema.names:
        return None
    if links_of(json.loads(meta.get("config", "{}"))):
        best = with_cheaper_overlapping(parts, best)
    return clearance_screen(best, meta) if best else None


def cheaper_if_rolled_words(row: dict, rolled, cfg=None) -> str:
    """The screen's cheaper layout that clears only rolled (``rolled_of``), in words: not a row, so not the
    answer; what it would take to make it one."""
    turned = ", ".join(f"{a} {d:+.0f} deg" for a, d in rolled.rolls.items() if d)
    return (f"design {row['design_id']} (cost {rolled.cost:.4f} so docked) is not a feasible row: its links overlap "
            f"at the run's docking roll; with its PSMs' docking turned ({turned}) they would clear by "
            f"{rolled.least.clearance_mm:.0f} mm, checked for this one layout only (not as the rows are: every "
            f"check at every pose). Not the answer: to weigh such dockings as rows, run with robot.docking_roll = "
            f"'search' (or another docking_roll_deg)" + ("" if cfg is None else _below_table(cfg, row, rolled)))


def rolled_of(screen) -> tuple | None:
    """(row, ``RollsThatClear``) of the headline's best layout when it is one whose row is not feasible: it fails
    only on its links at the run's docking roll, is cheaper than every feasible row, and clears with its PSMs
    rolled (``screen_of``); else None (the best feasible row is the best)."""
    chosen = screen[2] if screen is not None else None
    return chosen if chosen is not None and not chosen[0]["feasible"] else None


def with_cheaper_overlapping(parts, feasible: list[dict]) -> list[dict]:
    """With the links in feasible: the layouts cheaper than the best feasible one that fail only on the links
    (reason 16: they dock, and their links overlap at the run's docking roll at every pose) before the feasible
    ones, by cost, for the screen to try with each PSM's roll (``clearance_screen``)."""
    from surgopt.kinematics.port.reasons import OUTSIDE

    cheaper = [r for r in least_cost_layouts(parts, SCREEN_LAYOUTS, False, only_reasons=OUTSIDE).to_pylist()
               if not feasible or (r["cost"], r["design_id"]) < (feasible[0]["cost"], feasible[0]["design_id"])]
    return sorted(cheaper + feasible, key=lambda r: (r["cost"], r["design_id"]))


def clearance_screen(rows: list[dict], meta: dict):
    """The best layouts (``rows``, distinct, by cost) screened for their links' clearance outside the body, which
    feasible may leave out (issue 40; the rows' feasible has them at the run's docking roll only): (the
    headline's word, the table, (the row, its ``RollsThatClear``) of the first cheaper layout that clears only
    with its PSMs rolled, else None), or None when the run's config cannot be read again. A layout whose links
    overlap at the run's docking roll is tried with each PSM's own roll (``clashes.rolls_that_clear``: full
    reach and the setup joints' ranges kept). The word names the first layout that clears docked as its row is
    (the answer's check); a rolled one is advice (``cheaper_if_rolled_words``), never the answer."""
    from surgopt.studies.port_place.clashes import layout_clearances, least, rolls_that_clear, turn_words

    try:
        cfg = stored_config(meta)
    except STORED_ERRORS:
        return None
    out, clear, chosen = [], None, None
    cheaper, feasible = [r for r in rows if not r["feasible"]], [r for r in rows if r["feasible"]]
    # the cheaper layouts that fail only on their links, until one clears rolled (advice), then the feasible rows
    # until one clears docked as its row is (the answer's check): each phase at most SCREEN_LAYOUTS
    for r in cheaper[:SCREEN_LAYOUTS] + feasible[:SCREEN_LAYOUTS]:
        if chosen is not None and not r["feasible"]:
            continue
        model = model_for(cfg, r)  # (with rolls enumerated: its roll's)
        c = least(layout_clearances(model, r))
        if c is None:
            continue
        rolled = rolls_that_clear(model, r) if c.clearance_mm < 0 else None
        if rolled is None:
            with_rolls = "-"
        elif rolled.least is None:
            with_rolls = f"none of {rolled.tried} that reach and dock"
        else:
            with_rolls = (", ".join(f"{a} {d:+.0f}" for a, d in rolled.rolls.items()) + f": {rolled.least.clearance_mm:.0f} "
                          f"mm ({rolled.least.link_a} / {rolled.least.link_b}); cost {rolled.cost:.4g}")
        out.append([str(r["design_id"]), f"{r['cost']:.4g}", f"{c.clearance_mm:.0f}", c.check,
                    f"{c.link_a} / {c.link_b}", with_rolls])
        if clear is None and c.clearance_mm >= 0:
            clear = (f"design {r['design_id']} (the best {'feasible ' if r['feasible'] else ''}layout whose links "
                     f"clear; {{n}} screened)")
        elif clear is None and chosen is None and rolled is not None and rolled.least is not None:
            chosen = (r, rolled)  # advice beside the answer (``cheaper_if_rolled_words``)
        if clear is not None:  # what the headline needs: the best layout that clears as its row docks it
            break
    if not out:
        return None
    n = len(out)
    if clear is not None:
        word = clear.replace("{n}", str(n))
    else:
        worst = max(float(x[2]) for x in out)
        kind = "feasible layouts" if all(r["feasible"] for r in rows[:n]) else "layouts failing only on their links"
        word = (f"none of the {n} best {kind}, docked as its row is: their links overlap outside the body by "
                f"{-worst:.0f} mm or more (link clearance: {in_feasible(cfg)})"
                + ("" if chosen is None else f"; design {chosen[0]['design_id']} clears with its PSMs' docking "
                   f"{turn_words(cfg)[1]} (cheaper_if_rolled)"))
    which = ("the best feasible layouts" if all(r["feasible"] for r in rows[:n]) else
             "the best layouts (the feasible ones and, as the links are in feasible, those cheaper that fail only on "
             "them at the run's roll)")
    title = (f"{which}, {n} screened by cost until one clears (at most {SCREEN_LAYOUTS} of each): their "
             f"links' least clearance outside the body ({LINK_MODEL_WORDS}; negative: they overlap; "
             f"{in_feasible(cfg)})"
             + f", and each PSM's docking {turn_words(cfg)[0]} (deg, {ROLL_TEXT}) at which they clear")
    return word, (title, ["design_id", "cost", "least_clearance_mm", "between", "links", "with rolls"], out), chosen


def _below_table(cfg, row: dict, rolled) -> str:
    """``clashes.below_table_note`` of a layout docked as the roll search (``rolled``, ``RollsThatClear``) found."""
    from surgopt.studies.port_place.clashes import below_table_note

    return below_table_note(cfg, row, rolled.arms)


def layout_columns(names) -> list[str]:
    """The columns that make two rows the same layout: each arm's site, and a search's docking and stance (a
    search evaluates a layout again when its optimiser asks again; its rows repeat one layout)."""
    return [c for c in names if c.endswith("_site") or "_docking_" in c or "_stance_" in c]


def first_of_each_layout(t, key: list[str]):
    """``t`` (ordered) with each layout's first row only: (the rows, the (cost, design_id) of the rows dropped)."""
    if not key or t.num_rows < 2:
        return t, np.zeros((0, 2))
    import pyarrow as pa

    keys = np.stack([t[c].to_numpy().astype(np.float64) for c in key], axis=1)
    _, first = np.unique(keys, axis=0, return_index=True)
    first = np.sort(first)
    dropped = np.setdiff1d(np.arange(t.num_rows), first)
    return t.take(pa.array(first)), np.stack([t["cost"].to_numpy()[dropped],
                                              t["design_id"].to_numpy()[dropped]], axis=1)


def least_cost_layouts(parts, k: int, feasible: bool = True, columns: list[str] | None = None,
                       only_reasons: int | None = None):
    """The k layouts of least cost (ties by design id) among the feasible (or the infeasible) ones (with
    ``only_reasons``, the infeasible whose ``infeasible`` mask is exactly that), read part by
    part, each layout once (``first_of_each_layout``: a search's repeats collapsed, their count among the rows
    ranked up to the last listed in the table's metadata, ``repeats_collapsed``); only ``columns`` (with feasible,
    cost, design_id and the layout's) when given: the closing report and the HTML page."""
    import pyarrow as pa
    import pyarrow.compute as pc

    key = layout_columns(parts.schema.names)
    if columns is not None:
        columns = sorted({*columns, "feasible", "cost", "design_id", "infeasible", *key} & set(parts.schema.names))
    kept, dropped = [], []
    for t in parts.only(columns):
        t = t.filter(t["feasible"] if feasible else pc.invert(t["feasible"]) if only_reasons is None
                     else pc.equal(t["infeasible"], only_reasons))
        if t.num_rows:
            order = np.lexsort((t["design_id"].to_numpy(), t["cost"].to_numpy()))
            window = 4 * k + 16  # the best rows first; more only while repeats leave fewer than k layouts
            while True:
                top, gone = first_of_each_layout(t.take(pa.array(order[:window])), key)
                if top.num_rows >= k or window >= len(order):
                    break
                window *= 4
            kept.append(top.slice(0, k))
            dropped.append(gone)
    if not kept:
        return parts.schema.empty_table() if columns is None else parts.schema.empty_table().select(columns)
    t = pa.concat_tables(kept)
    t = t.take(pa.array(np.lexsort((t["design_id"].to_numpy(), t["cost"].to_numpy()))))
    t, gone = first_of_each_layout(t, key)
    t = t.slice(0, k)
    gone = np.concatenate([*dropped, gone])
    last = (t["cost"][-1].as_py(), t["design_id"][-1].as_py())
    repeats = int(np.count_nonzero((gone[:, 0] < last[0]) | ((gone[:, 0] == last[0]) & (gone[:, 1] <= last[1]))))
    return t.replace_schema_metadata({**(t.schema.metadata or {}), b"repeats_collapsed": str(repeats).encode()})
