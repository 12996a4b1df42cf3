"""Study ``port-place``: where the ports go for a multi-arm RCM robot on a patient (dVRK: two or three PSMs +
the ECM).

Beyond the three papers (issue #29; ../shared/robots/dvrk-kinematics.md). A design is one port for each
instrument arm (two, or three: the working pair and a third arm) and one for the camera arm, each chosen from
candidate sites sampled on the insufflated abdominal wall; each arm is docked with its neutral shaft through
the target's centre. Per design: each instrument's reach of the target (RCM inverse kinematics within the
joint limits), the common reach, the instruments' dexterity (isotropy with a stated characteristic length),
the working pair's manipulation angle (Hanna et al. 1997: 45-75 deg, 60 best), their azimuth imbalance about
the optical axis, the camera's coverage of the target, the port spacing and the shafts' clearance inside and
the arms' outside, a cost and the reasons a design is infeasible. Every assignment of the working pair's
ports (unordered: the PSMs are the same arm), the third's when there is one, and a distinct camera port is
evaluated; docs/port_placement.md has the model, its sources and assumptions.

This module is the study's declaration (``STUDY``): its name, default config, the rows' schema and metadata, the
task entry (``compute_task``), the estimate, the search space it hands the plans and its exports. What it declares
lives beside it (issue 53): the config models in ``config``, the geometry they imply (patient, sites, target) in
``geometry``, the prepared model in ``model``, the per-port, per-pair and dock tables in ``tables`` and
``link_tables``, the design evaluator in ``designs`` (kernel: ``kinematics.port.designs``), the rows' column
vocabulary in ``columns``, one row re-solved for the views in ``layout``, the closing report in ``report`` (named
here by module, imported when a report is made). One module of ~530 lines: the schema, the estimate and the task
entry are read together (the estimate counts what the schema stores and the tasks build).
"""
from __future__ import annotations

import math

import numpy as np

from surgopt.robots.dvrk.platforms import AUTO_PLATFORM, PLATFORMS, role_of
from surgopt.studies.port_place.arms import instruments_held
from surgopt.studies.port_place.carts import has_cart
from surgopt.studies.port_place import HELP  # the command's help, read by the CLI without importing this module
from surgopt.studies import Estimate, Study, figures_in, html_views_in, peak_bytes, summary_in
from surgopt.studies.port_place.config import OBJECTIVE, PortPlaceConfig, instrument_of
from surgopt.studies.port_place.geometry import sites_mm, target_points_mm
from surgopt.studies.port_place.columns import (CART_COLUMNS, DOCKING_COLUMNS, FLOAT_COLUMNS,  # noqa: F401 (theirs)
                                                SITE_COLUMNS, THIRD_COLUMNS, aim_columns, arms_of,
                                                cart_search_columns, docking_columns, float_columns,
                                                instruments_of, links_of, roll_columns, stance_columns,
                                                suj_joint_columns, WHOLE_TARGET_COLUMN)
from surgopt.studies.port_place.designs import (design_dims, design_rows, evaluate_designs,  # noqa: F401 (theirs)
                                                nearest_sites, reasons, searched_docking)
from surgopt.studies.port_place.model import model_of
from surgopt.studies.port_place.rolls import dockings, n_designs, per_roll  # noqa: F401 (n_designs: theirs)

NAME = "port-place"
KERNEL_VERSION = "port-place-1"
DEFAULT_CONFIG = "port_place_dvrk.toml"
CONFIG_HELP = "TOML or YAML config ([patient], [target], [robot], [constraints], [objective]); default: the dVRK example."

def n_total(cfg: PortPlaceConfig) -> int:
    """Every design of the enumeration: the sites' designs at each docking (``rolls.dockings``)."""
    return per_roll(cfg) * len(dockings(cfg))


def design_identity(config=None) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """What a layout is across runs whose candidate sites differ (a marked region, another spacing): each arm's
    port, x, y, z (mm, patient frame); design_id and the site indices only number the run's own enumeration
    (``surgopt diff`` joins on the ports, issue 42 item 1)."""
    arms = arms_of(config)
    return (tuple(f"{arm}_{c}_mm" for arm in arms for c in "xyz"),
            ("design_id", *(f"{arm}_site" for arm in arms), "cart_pose"))


#: Designs per task: ~1 s of combining and a few MB of rows; with only the feasible rows stored, a task's
#: memory is its feasible rows' and it can be ten times larger (fewer parts for the parent to write).
CHUNK = 200_000
CHUNK_FEASIBLE = 2_000_000


def auto_chunk(cfg) -> int:
    from surgopt.studies import chunk_for_seconds

    most = CHUNK_FEASIBLE if cfg.rows_stored == "feasible" else CHUNK
    per_design = NS_PER_DESIGN if cfg.robot.instrument_count == 2 else NS_PER_DESIGN_3
    return min(most, chunk_for_seconds(n_total(cfg), per_design * 1e-9))


def n_tasks(cfg, chunk: int) -> int:
    return max(1, math.ceil(n_total(cfg) / chunk))


def schema(config=None):
    """The rows' schema: with three instruments, PSM3's site, position, reach and isotropy too; the common
    reach is then all three's, the shaft clearance the least of the three pairs', and the angles stay the
    working pair's (PSM1, PSM2)."""
    import pyarrow as pa

    arms = arms_of(config)
    fields = [pa.field("design_id", pa.int64()), *[pa.field(f"{arm}_site", pa.int64()) for arm in arms]]
    fields += [pa.field(f"{arm}_{c}_mm", pa.float64()) for arm in arms for c in "xyz"]
    fields += [pa.field(c, pa.float64(), metadata=LINK_MEANING if c == "external_clearance_mm" and links_of(config)
                        else None) for c in float_columns(config)]
    fields += [pa.field("min_port_spacing_mm", pa.float64()), pa.field("psm_to_target_mm", pa.float64()),
               *[pa.field(f"{arm}_elevation_deg", pa.float64(), metadata={
                   "meaning": "the instrument's shaft (port to target centre) above the horizontal: Hanna et al. "
                              "1997's elevation angle"}) for arm in arms[:-1]],
               *[pa.field(f"{arm}_wrist_margin_deg", pa.float64(), metadata={
                   "meaning": "the wrist's bend left at the worst target point for the approach cone (its whole "
                              "bend when no approach is asked; negative: short by that much)"}) for arm in arms[:-1]],
               pa.field("ecm_tip_depth_mm", pa.float64(), metadata={
                   "meaning": "the endoscope's tip past the RCM (the port) along its shaft, as held: inserted to "
                              "stop camera_standoff_mm before the target's centre, never less than its least "
                              "insertion (the dVRK ECM's 50 mm); NaN where the scope cannot be placed"}),
               pa.field("ecm_tip_to_target_mm", pa.float64(), metadata={
                   "meaning": "the endoscope's tip to the target's centre, as held (the standoff the port's "
                              "distance allows); the camera's coverage is seen from there"}),
               pa.field("image_right_psm", pa.int64(), metadata={
                   "meaning": "1 or 2: the working pair's PSM whose port lies to the camera image's right (the "
                              "image level, its up the patient's front): the surgeon's right hand (MTMR) should "
                              "drive it, else the hands are crossed; 0: neither (no camera image, or the two "
                              "enter it along one line; studies/port_place/hands.py)"}),
               *[pa.field(c, pa.float64()) for c in docking_columns(config)],
               *[pa.field(c, pa.float64(), metadata={"meaning": "the instrument arm's docking frame turned about "
                                                                 "its neutral shaft (deg, x toward y): "
                                                                 "robot.docking_roll_deg by the port's side, or the "
                                                                 "port's most_reach choice"})
                 for c in roll_columns(config)],
               *[pa.field(c, pa.float64(), metadata={"meaning": "the top-view point a surface search placed the "
                                                                 "port at, taken to the nearest candidate site"})
                 for c in aim_columns(config)],
               *[pa.field(c, pa.float64(), metadata={"meaning": "a search's move of the serial arm's RCM off "
                                                                 "rcm_in_base_m: out from its base, or up (m)"})
                 for c in stance_columns(config)],
               *cart_fields(config),
               *[pa.field(c, pa.float64(), metadata={"meaning": "a search's cart pose (cart.pose = 'search'): on "
                                                                 "the arc around the target, from the feet (deg), "
                                                                 "its distance (mm), off facing it (deg)"})
                 for c in cart_search_columns(config)],
               pa.field("cost", pa.float64()),
               pa.field("score", pa.float64(), metadata={"meaning": "what summarize ranks by (higher is better): "
                                                                     "-cost, less 100 per reason a design fails"}),
               pa.field("feasible", pa.bool_()),
               pa.field("infeasible", pa.int64(), metadata={"meaning": "bit mask: " + "; ".join(
                   f"{bit} {why}" for bit, why in reasons().items())})]
    return pa.schema(fields, metadata=_stored_metadata(config))


#: ``external_clearance_mm`` when the links decide (``constraints.min_link_clearance_mm``).
LINK_MEANING = {"meaning": "the least clearance of the arms' links outside the body (setup joints' and arms' "
                           "own, capsules of assumed radii; docked and over the target) to each other, the "
                           "patient's body and the table, at the row's cart pose; between arms resolved up to 100 "
                           "mm above min_link_clearance_mm (reads as that beyond; the patient's body up to 150 mm), "
                           "below it the first overlap found (an upper bound); NaN: no pose docks, or the layout "
                           "fails on a count of its own and was not checked"}


def cart_fields(config) -> list:
    import pyarrow as pa

    from surgopt.kinematics.port.capsules import LINK_CODE, PAIR_CODE

    if not has_cart(config):
        return []
    links = [pa.field("external_link_pair", pa.int64(), metadata={
        "meaning": f"the two links of external_clearance_mm: {PAIR_CODE} x arm pair (0 PSM1-PSM2, 1 PSM1-ECM, 2 "
                   f"PSM2-ECM, 3 PSM1-PSM3, 4 PSM2-PSM3, 5 PSM3-ECM) + {LINK_CODE} x the first arm's link + the "
                   f"second's, or {PAIR_CODE} x (6 + arm: PSM1, PSM2, PSM3, ECM) + {LINK_CODE} x its link + (0 the "
                   "patient's body, 1 + the bedside's box in bedside.BEDSIDE: 1 the table); each arm's "
                   "links its setup joints' 3-6, then its own (link_tables.pair_name decodes it); -1: none"}),
             pa.field(WHOLE_TARGET_COLUMN, pa.float64(), metadata={
                 "meaning": "the least clearance between the layout's arms over every target point (each PSM at any "
                            "of them, the other at any of its own; exact, clashes.whole_target_clearances), measured "
                            "for the layouts feasible on the sampled points; below min_link_clearance_mm the layout "
                            "is infeasible for its links (#54 item 3); NaN: not measured (the layout fails "
                            "elsewhere)"})] \
        if links_of(config) else []
    margins = [pa.field(f"{arm}_suj_{what}", pa.float64(), metadata={
        "meaning": f"the {role_of(arm)} setup joints' least margin to their ranges at the row's cart pose, "
                   + ("over the revolute joints (deg)" if what.endswith("deg") else "of the column (mm)")
                   + "; negative never (the best solution within the ranges); NaN: no pose docks"})
        for arm in arms_of(config) for what in ("margin_deg", "column_margin_mm")]
    joints = [pa.field(name, pa.float64(), metadata={
        "meaning": f"the {role_of(arm)} setup joint {joint} at the row's cart pose ("
                   + ("the column's height, mm" if name.endswith("_mm") else "deg")
                   + "; the dVRK's simulated_position in m and rad is export --format dvrk's); the solution with "
                     "the largest least margin; NaN: no pose docks"})
        for arm, names in suj_joint_columns(config).items() for joint, name in names]
    return [pa.field("cart_pose", pa.int64(), metadata={"meaning": "the first pose of the cart's grid at which "
                                                                    "every arm's setup joints dock (-1: none)"}),
            *[pa.field(c, pa.float64()) for c in CART_COLUMNS[1:]], *links, *margins, *joints]


def _stored_metadata(config) -> dict | None:
    """With the cart: what its docking is solved from (``cart_metadata``); with only feasible rows stored: how
    many designs were enumerated (what the summary counts the infeasible from), when the config can be read
    again (a stored mesh config whose file moved cannot)."""
    meta = {**(cart_metadata(config) or {}), **landmark_metadata(config)} or None
    given = (config.get("given_layout") if isinstance(config, dict)
             else getattr(config, "given_layout", None) if config is not None else None)
    if given is not None and "config" not in (meta or {}):  # the closing report scores it from the config
        meta = {**(meta or {}), "config": config_json(config)}
    stored = config.get("rows_stored") if isinstance(config, dict) else getattr(config, "rows_stored", "all")
    if stored != "feasible":
        return meta
    return {**(meta or {}), **_feasible_metadata(config)}


def landmark_metadata(config) -> dict:
    """The landmark the closing report measures ports from (``geometry.reference_landmark``), as JSON [name, x, y]
    in the rows' schema metadata (nothing when the config cannot be read again)."""
    import json

    from surgopt.studies.port_place.geometry import reference_landmark

    if config is None:
        return {}
    try:
        cfg = (config if isinstance(config, PortPlaceConfig)
               else PortPlaceConfig.model_validate(config, context={"stored": True}))
    except (ValueError, OSError):
        return {}
    name, (x, y) = reference_landmark(cfg.patient)
    return {"landmark": json.dumps([name, x, y])}


def cart_metadata(config) -> dict | None:
    """With the cart: the run's config (as stored) in the rows' schema metadata, so that the summary can solve the
    best layout's setup joints again from its row; without: why there is no cart (``no_cart_note``)."""
    if config is None:
        return None
    if not has_cart(config):  # what the closing report says of the cart: none, and why
        return {"cart": no_cart_note(config)}
    return {"config": config_json(config)}


def config_json(config) -> str:
    """The run's config as the rows' metadata keep it (``report.stored_config`` reads it back)."""
    import json

    return json.dumps(config if isinstance(config, dict) else config.model_dump(mode="json"))


def _feasible_metadata(config) -> dict:
    try:
        cfg = (config if isinstance(config, PortPlaceConfig)  # as stored: its files not read and hashed again
               else PortPlaceConfig.model_validate(config, context={"stored": True}))
        return {"rows_stored": "feasible", "designs_enumerated": str(n_total(cfg))}
    except (ValueError, OSError):
        return {"rows_stored": "feasible"}


def compute_task(cfg, chunk: int, index: int) -> dict:
    """Designs [index*chunk, (index+1)*chunk) of the enumeration, every port docked toward the target's centre
    (only the feasible ones' rows when ``rows_stored`` is 'feasible'), each roll's block at its own roll
    (``rolls.blocks``)."""
    from surgopt.parts import concat_rows
    from surgopt.studies.port_place.rolls import blocks

    start = index * chunk
    if len(dockings(cfg)) == 1:  # one docking: its model's sites bound the task (no sites computed again)
        return block_rows(cfg, start, start + chunk)
    parts = [block_rows(block, lo, hi, offset) for block, lo, hi, offset in blocks(cfg, start, start + chunk)]
    return parts[0] if len(parts) == 1 else concat_rows(parts)


def block_rows(cfg, start: int, stop: int, offset: int = 0) -> dict:
    """The rows of designs ``start`` .. ``stop`` - 1 of one docking roll's enumeration (``cfg`` at that roll),
    numbered from ``offset``."""
    from surgopt.kinematics.port.designs import design_columns

    model = model_of(cfg)
    sites, (t, _, _), crit = model.sites_m, model.grid, model.criteria
    stop = min(n_designs(len(sites), cfg.robot.instrument_count), stop)
    ids, f, bad, cost, design_ids, dock = design_columns(t, crit, start, stop, cfg.robot.instrument_count,
                                                         cfg.rows_stored == "feasible")
    return design_rows(cfg, sites, t, ids, ids, f, bad, cost, design_ids + offset,
                       np.zeros((len(design_ids), len(docking_columns(cfg)))), dock=dock,
                       floor=model.dock.poses.floor if has_cart(cfg) else None,
                       dock_tables=model.dock if has_cart(cfg) else None)


def search_plan(cfg):
    """A search's space: every arm's port (categorical: any candidate site; or, with ``search_ports = "surface"``,
    a top-view point within the candidate sites' box, continuous) and, when ``robot.docking_range_deg`` > 0, each
    instrument's docking yaw and pitch within +- that range."""
    from surgopt.plans.search import SearchPlan, objectives_of, optimiser_of

    spec = optimiser_of(cfg)
    if spec is None:
        return None
    return SearchPlan(spec, design_dims(cfg), objectives_of(spec, OBJECTIVE))


def warm_up(cfg) -> None:
    """The per-port tables (their kernels), then the design kernel as the config's tasks call it: the grid's
    chunks (``compute_task``), or a search's one design at a time (``evaluate_designs``)."""
    from surgopt.kinematics.port.designs import design_columns
    from surgopt.plans.search import optimiser_of
    from surgopt.studies.port_place.rolls import first_docking

    cfg = first_docking(cfg)  # the first block's: the others build their own tables
    model = model_of(cfg)
    if optimiser_of(cfg) is None:
        reach, _ = model.site_reach
        if reach.sum(axis=1).max() < reach.shape[1]:
            return  # no port reaches the whole target: ``preflight`` refuses it next, no table built for nothing
    t, crit = model.grid.tables, model.criteria
    if optimiser_of(cfg) is None:
        design_columns(t, crit, 0, 1, cfg.robot.instrument_count, cfg.rows_stored == "feasible")
    else:
        design_columns(t, crit, 0, 1, cfg.robot.instrument_count)


def preflight(cfg) -> None:
    """Refuse (a ValueError naming the field) a target that no candidate port's instrument reaches whole, docked
    toward its centre: every layout of the grid would fail on reach. (A search docks as it explores: not checked.)"""
    from surgopt.plans.search import optimiser_of

    if optimiser_of(cfg) is not None:
        return
    from surgopt.studies.port_place.rolls import first_docking

    model = model_of(first_docking(cfg))  # (with rolls enumerated: at the first docking)
    reach, _ = model.site_reach  # the instruments' reach alone: a refused target builds no cart or link tables
    best, n_points = int(reach.sum(axis=1).max()), reach.shape[1]
    if best < n_points:
        arm = model.instruments.refused_note(model)
        raise ValueError(f"target: no candidate port's instrument ({instrument_of(cfg).name}, docked toward the "
                         f"target's centre) reaches the whole target: {best:,} of its {n_points:,} points at best, "
                         f"so every layout would fail on reach; move or shrink the target, ease its approach cone, "
                         f"or widen patient.port_region / constraints.port_to_target_mm{arm}")
    model.endoscope.check(model, model.grid.tables)


#: Cost model: ~60 ns to combine one design and turn it into columns on one core (~70 ns with a third
#: instrument), plus the tables (~60 ns per site x target point by the closed forms, ~0.3 us per instrument
#: pair x target point);
#: a row is ~214 bytes (~254 with a third instrument).
NS_PER_DESIGN = 60.0
NS_PER_DESIGN_3 = 70.0
ROW_BYTES, ROW_BYTES_3 = 214, 254
#: The cart's columns in a row: cart_pose (int64) and the pose's x, y and heading (float64).
CART_ROW_BYTES = 32
#: Each arm's setup-joint margins and its six setup joints in a row (float64 each).
SUJ_MARGIN_ROW_BYTES = 16
SUJ_JOINTS_ROW_BYTES = 6 * 8
IN_FLIGHT_TASKS = 4
NS_PER_PAIR_POINT = 300.0


#: One Classic PSM setup joint's inverse kinematics (``kinematics.port.suj_batch.classic_psm_margins``, jitted): ~3.4 us
#: measured (benchmarks/bench_cart.py; plain Python's classic_psm_ik: ~118 us).
NS_PER_SUJ_SOLVE = 4_000.0
#: The links' clearance tables (``link_tables``), per (arm pair, site, site, cart pose) entry of the dense tables
#: (most are not computed: an arm does not dock there, or no design can need it): 15.6 s for the default's 3 x
#: 164^2 x 150 entries on one core of the development machine (~1.3 us), rounded up.
NS_PER_LINK_ENTRY = 1_500.0
#: Bytes per dense entry while the link tables are built and kept: float32 value, int16 pair, the bool and float
#: work arrays (the words are 1/64 of a bit per entry).
LINK_ENTRY_BYTES = 16


def link_pairs(instruments: int) -> int:
    """The arm pairs whose links are checked: PSM1-PSM2 and each PSM with the ECM, and PSM3 with the others."""
    return 3 if instruments == 2 else 6
#: The ECM's setup joints at one site and cart pose (``kinematics.port.suj_batch.ecm_margins``' grid of 36 x 36 x 12,
#: jitted): ~125 us measured (3.1 s for the default's 164 x 150; numpy over a pose's sites: ~300 us).
NS_PER_ECM_DOCK = 130_000.0


#: A searched design (its three ports' tables of its own): ~0.43 ms at 915 target points (measured, one core).
NS_PER_SEARCHED_DESIGN_POINT = 470.0


#: The share of designs assumed feasible when only the feasible rows are stored (their storing time in the
#: estimate): an assumption, measured on the defaults: 1.8 % with three PSMs (6,142,464 of 348,612,012, the wrist
#: reaching at any depth), 3.6 % with two (77,336 of 2,165,292).
FEASIBLE_SHARE_ASSUMED = 0.02
#: The share of designs the memory estimate allows for when only the feasible rows are stored: 10 %, ~3x the
#: largest measured (3.6 %), so that a looser config still fits; the bound (every design feasible) is shown beside
#: it. A task allocates its chunk's row arrays without touching them (np.empty): only the rows it writes, the
#: feasible ones, become resident (3 PSMs + ECM with the links: 0.69 GB measured, where the bound was 7.5 GB).
FEASIBLE_SHARE_MEMORY = 0.10

#: Resident memory port-place's own libraries and tables add to the base process (trimesh, scipy's spatial index,
#: the sites' frames) and, on a first run, LLVM's while it compiles the kernels: measured peaks 440 MB (default,
#: warm), 452 MB (PA10 arms, warm) and 548 MB (default, compiling in a fresh CI clone) against a model of 349 MB
#: without it (issue 43: the estimate was 1.26-1.36x below the peak, on the wrong side of a budget).
LIBRARY_BYTES = 220 * 2 ** 20
#: What the cart adds: the setup joints' and the capsules' kernels and, on a first run, LLVM compiling them (the
#: default with the cart, measured: 526 MB warm, 608 MB compiling, 650 MB compiling in the test suite beside other
#: compiles, against 577 MB estimated without this); 30 MB more since the design kernel holds the links' branches
#: and the rows each arm's setup-joint margins (issue 40: 700 MB measured in the suite against 698 MB estimated
#: with 120 MB here before the margins, whose rows added 28 MB to the warm peak, 505 -> 533 MB).
CART_LIBRARY_BYTES = 150 * 2 ** 20
#: The dock tables per (site, cart pose): 3 PSMs' and the ECM's margins (float64) and best joints (6 float64),
#: the ECM's aim (2), with the solver's copies of the joints (x2).
DOCK_ENTRY_BYTES = (4 + 2 * 4 * 6 + 2) * 8
#: What a mesh patient adds (#57 item 0): the mesh, the k-d tree over it subdivided for the links' distances,
#: trimesh's ray and containment caches and the report's exact queries, and the time its ray casts take. Measured
#: (this machine, warm): the 10,494-face dome with the cart 969 MB against 938 MB estimated without this (the
#: closed-form dome: 845 MB), 22 s against 14 s; OpenHELP's 31,934-face wall 749 MB and 24 s against 852 MB and
#: 9.6 s. Each a measured constant, not a model of the mesh's size.
MESH_BYTES = 128 * 2 ** 20
MESH_SECONDS = 12.0
#: What the organs add (``organs.py``): each organ's voxels and mesh, the shafts' samples per site (measured on
#: OpenHELP's nine obstacles: 66 MB and 4.8 s more than the same run without them).
ORGANS_BYTES = 96 * 2 ** 20
SECONDS_PER_ORGAN = 0.8


def estimate(cfg) -> Estimate:
    from surgopt.plans.search import optimiser_of

    n = len(sites_mm(cfg))
    m = len(target_points_mm(cfg.target))
    spec = optimiser_of(cfg)
    if spec is not None:
        return Estimate(spec.trials, f"{spec.method} trials", spec.trials,
                        spec.trials * m * NS_PER_SEARCHED_DESIGN_POINT * 1e-9, peak_bytes(spec.trials, 220))
    arms = cfg.robot.instrument_count
    rolls = len(dockings(cfg))  # each docking its own tables and designs; two dockings' models held at a time
    d = n_designs(n, arms) * rolls
    per_design = NS_PER_DESIGN if arms == 2 else NS_PER_DESIGN_3
    per_site_point = instruments_held(cfg).ns_per_site_point
    seconds = (d * per_design + rolls * (n * m * per_site_point + n * n / 2 * m * NS_PER_PAIR_POINT)) * 1e-9
    if has_cart(cfg):  # each instrument arm's setup joints at each site and cart pose
        from surgopt.studies.port_place.tables import cart_poses

        poses = len(cart_poses(cfg).floor)
        seconds += rolls * n * poses * (arms * NS_PER_SUJ_SOLVE + NS_PER_ECM_DOCK) * 1e-9
        if links_of(cfg):  # the links' clearance tables, each arm pair's (site, site, pose) entries
            seconds += rolls * link_pairs(arms) * n * n * poses * NS_PER_LINK_ENTRY * 1e-9
    obstacles = sum(o.obstacle for o in cfg.patient.organs.values())
    if cfg.patient.shape == "mesh":
        seconds += MESH_SECONDS
    seconds += obstacles * SECONDS_PER_ORGAN
    row = (ROW_BYTES if arms == 2 else ROW_BYTES_3) + 8 * len(roll_columns(cfg)) + (
        CART_ROW_BYTES + (arms + 1) * (SUJ_MARGIN_ROW_BYTES + SUJ_JOINTS_ROW_BYTES) if has_cart(cfg) else 0)
    working = n * n * 8 * 12 + n * m * 9 + LIBRARY_BYTES + (CART_LIBRARY_BYTES if has_cart(cfg) else 0)
    working += (MESH_BYTES if cfg.patient.shape == "mesh" else 0) + (ORGANS_BYTES if obstacles else 0)
    if has_cart(cfg):  # the dock tables: each arm's margins, best joints and the ECM's aim per (site, pose)
        working += n * poses * DOCK_ENTRY_BYTES
    if links_of(cfg):  # float32 values, int16 pairs and the float work arrays of each arm pair's dense tables
        working += link_pairs(arms) * n * n * poses * LINK_ENTRY_BYTES
    if rolls > 1:  # the rolls' models: HELD_MODELS kept (``model.model_of``) and, across a block's boundary, one
        # dropped from the cache that a thread still reads, with the next one's build temporaries beside them; the
        # libraries once (measured on the default: 845 MB at one roll against 938 estimated; at three rolls 1,597 MB,
        # against 1,514 with only the models held counted, so the build's temporaries as one model more)
        from surgopt.studies.port_place.model import HELD_MODELS

        models = min(rolls, HELD_MODELS + 1)
        working += models * (working - LIBRARY_BYTES - (CART_LIBRARY_BYTES if has_cart(cfg) else 0))
    if cfg.rows_stored == "feasible":  # 8 bytes of each stored row in the parent and, in flight, tasks holding
        # their feasible rows only (2 per worker, ~4 on this scale of machine): at FEASIBLE_SHARE_MEMORY of the
        # designs, and the bound were every design feasible (what the dry run shows beside it)
        def at(share):
            return peak_bytes(int(d * share), 0, working_bytes=working + int(IN_FLIGHT_TASKS * auto_chunk(cfg) * row
                                                                              * share))

        return Estimate(d, "port designs (feasible rows stored)", d, seconds, at(FEASIBLE_SHARE_MEMORY),
                        stored_rows=int(d * FEASIBLE_SHARE_ASSUMED), peak_bytes_bound=at(1.0))
    return Estimate(d, "port designs", d, seconds, peak_bytes(d, row, working_bytes=working),
                    smaller="store only the feasible designs' rows (rows_stored=feasible), or make it smaller")


def top_columns(config) -> list[str]:
    """What summarize's top table shows: the ports, the cost, and the numbers a surgeon compares layouts by."""
    return ["design_id", *(f"{arm}_site" for arm in arms_of(config)), "cost", "feasible", "common_reach",
            "dexterity_mean", "manipulation_angle_centre_deg", "azimuth_imbalance_deg", "camera_coverage",
            "min_port_spacing_mm", "shaft_clearance_mm", "external_clearance_mm"]


def figure_columns(config) -> list[str]:
    """What the grid's figures read: the ports, the cost and the feasibility (not the ~40 other columns); with the
    cart, its pose and the ports' positions (the cart figure solves the setup joints again from them)."""
    arms = arms_of(config)
    cart = [*CART_COLUMNS, *(f"{arm}_{c}_mm" for arm in arms for c in "xyz")] if has_cart(config) else []
    # with the links in feasible, the figures draw the report's best layout: its PSMs' rolls searched, whose cost
    # so docked reads the row's dexterity (``clashes.rolled_cost``)
    rolled = ["dexterity_mean", *(["psm3_dexterity_mean"] if "psm3" in arms else [])] if links_of(config) else []
    return ["design_id", *(f"{arm}_site" for arm in arms), "cost", "feasible", "infeasible", *cart, *rolled]


def feasible_mask(table):
    return table["feasible"].to_numpy(zero_copy_only=False)


def no_cart_note(config) -> str:
    """What a run without the cart says of it (validated or as stored): docking assumed, and why the cart is not
    in (the arms it cannot carry, or cart.model = "none")."""
    from surgopt.studies.port_place.config import cart_does_not_carry

    try:
        cfg = (config if isinstance(config, PortPlaceConfig)
               else PortPlaceConfig.model_validate(config, context={"stored": True}))
    except (ValueError, OSError):
        return "none: docking assumed"
    why = cart_does_not_carry(cfg, AUTO_PLATFORM)
    other = next((p for p in PLATFORMS.values() if p.name != AUTO_PLATFORM and not cart_does_not_carry(cfg, p.name)), None)
    if why and other:  # another platform's arms: its cart is asked for by name
        return (f"none: docking assumed (the {other.title} PSMs and ECM: cart.model = '{other.name}' docks them on "
                f"the {other.title} cart)")
    auto = PLATFORMS[AUTO_PLATFORM].title
    return f"none: docking assumed ({f'the {auto} cart carries the {auto} PSMs and ECM, ' + why if why else 'cart.model = none'})"


def ports_export(cfg, row: dict) -> str:
    """``surgopt export KEY --design ID --format ports`` (``export.ports_csv``)."""
    from surgopt.studies.port_place.export import ports_csv

    return ports_csv(cfg, row)


def suj_fixed_export(cfg, row: dict) -> str:
    """``surgopt export KEY --design ID --format dvrk-suj-fixed`` (``export.suj_fixed``)."""
    from surgopt.studies.port_place.export import suj_fixed

    return suj_fixed(cfg, row)


def console_export(cfg, row: dict) -> str:
    """``surgopt export KEY --design ID --format dvrk-console`` (``export.dvrk_console``: the console that loads the
    SUJ_Fixed file)."""
    from surgopt.studies.port_place.export import dvrk_console

    return dvrk_console(cfg, row)


def slicer_export(cfg, row: dict) -> str:
    """``surgopt export KEY --design ID --format slicer`` (``export.slicer_markups``: a 3D Slicer markups file)."""
    from surgopt.studies.port_place.export import slicer_markups

    return slicer_markups(cfg, row)


def dvrk_export(cfg, row: dict) -> str:
    """``surgopt export KEY --design ID --format dvrk`` (``export.dvrk_setup``)."""
    from surgopt.studies.port_place.export import dvrk_setup

    return dvrk_setup(cfg, row)


def given_config_report(cfg, parts):
    """(#57 item 3) A surgeon's own layout (``[given_layout]``, left out of the run's key) scored against the run's
    rows: ({"given_layout": words}, [its table]), or None without one (``given.given_report``)."""
    if cfg.given_layout is None:
        return None
    from surgopt.studies.port_place.given import given_report

    words, tables = given_report(parts, cfg)
    return {"given_layout": words}, tables


STUDY = Study(
    name=NAME, kernel_version=KERNEL_VERSION, config_model=PortPlaceConfig, default_config=DEFAULT_CONFIG,
    help=HELP, config_help=CONFIG_HELP, schema=schema, key_columns=("design_id",), objective=OBJECTIVE,
    auto_chunk=auto_chunk, n_tasks=n_tasks, warm_up=warm_up, compute_task=compute_task, summary=summary_in("surgopt.studies.port_place.report"),
    feasible_mask=feasible_mask, feasible_columns=("feasible",), figures=figures_in("surgopt.studies.port_place.figures"), estimate=estimate, search_plan=search_plan,
    html_views=html_views_in("surgopt.studies.port_place.html"), reported_objective=("cost", "minimize"),
    exports={"dvrk": dvrk_export, "dvrk-suj-fixed": suj_fixed_export, "ports": ports_export,
             "dvrk-console": console_export, "slicer": slicer_export},
    warm_variants=(('robot.instrument_serial={model = "pa10_7c", rcm_in_base_m = [0.65, 0.0, 0.5]}',
                    "constraints.min_external_clearance_mm=150.0"),),
    warm_up_builds="the per-port tables (with the cart: its setup joints at every site and pose, the arms' links)",
    evaluate=evaluate_designs, figure_columns=figure_columns, preflight=preflight, top_columns=top_columns,
    design_identity=design_identity, config_report=given_config_report)
