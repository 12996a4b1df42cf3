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

The config models are in ``port_place_config``, the geometry they imply (patient, sites, target) in
``port_place_geometry``, the design kernels in ``kinematics.port_designs``, a serial arm's tables in
``port_place_serial``. One module of ~790 lines: the memoised tables, the rows and their columns, the design's
dimensions (ports, docking, stance) that both the rows and the search read, the evaluator, the estimate and the
summary are one declaration, read together; split, the study's declaration and its search would import each
other.
"""
from __future__ import annotations

import json
import math

import numpy as np

from surgopt.robots import dvrk
from surgopt.studies.port_place import HELP  # the command's help, read by the CLI without importing this module
from surgopt.studies import Estimate, Study, Summary, figures_in, html_views_in, peak_bytes
from surgopt.parts import concat_rows
from surgopt.studies.port_place.config import OBJECTIVE, PortPlaceConfig, camera_arm_of, instrument_of
from surgopt.studies.port_place.geometry import FRAME_TEXT, from_landmark, sites_mm, target_points_mm
from surgopt.studies.port_place.tables import LATERAL, model_of, port_tables

NAME = "port-place"
KERNEL_VERSION = "port-place-1"
DEFAULT_CONFIG = "port_place_dvrk.toml"
CONFIG_HELP = "TOML or YAML config ([patient], [target], [robot], [constraints], [objective]); default: the dVRK example."

def n_designs(n_sites: int, instruments: int = 2) -> int:
    """Designs of ``n_sites`` candidates (``port_designs.design_columns``'s enumeration): an unordered working
    pair of instruments, then (three instruments) the third's port, then the camera's, all distinct:
    C(n, 2) (n - 2), times (n - 3) with a third instrument."""
    d = n_sites * (n_sites - 1) // 2 * max(0, n_sites - 2)
    return d * max(0, n_sites - 3) if instruments == 3 else d


def n_total(cfg: PortPlaceConfig) -> int:
    return n_designs(len(sites_mm(cfg)), cfg.robot.instrument_count)


def instruments_of(config=None) -> int:
    """The instrument arms of a config: validated, as stored (a dict), or none (2)."""
    if isinstance(config, dict):
        return int(config.get("robot", {}).get("instrument_count", 2))
    return 2 if config is None else config.robot.instrument_count


def arms_of(config=None) -> tuple[str, ...]:
    """The arms' column prefixes, instruments first, the camera last: psm1, psm2, (psm3,) ecm."""
    return tuple(f"psm{a + 1}" for a in range(instruments_of(config))) + ("ecm",)


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


FLOAT_COLUMNS = ("psm1_reach", "psm2_reach", "common_reach", "dexterity_mean", "manipulation_angle_mean_deg",
                 "manipulation_angle_min_deg", "manipulation_angle_max_deg", "manipulation_angle_share_45_75",
                 "manipulation_angle_centre_deg", "azimuth_imbalance_deg", "camera_coverage",
                 "shaft_clearance_mm", "external_clearance_mm", "camera_off_arc_deg")
ANGLE_COLUMNS = {4, 5, 6, 8, 9, 13}
#: With a third instrument, after FLOAT_COLUMNS (``port_designs.THIRD_COLUMNS``).
THIRD_COLUMNS = ("psm3_reach", "psm3_dexterity_mean")


def float_columns(config=None) -> tuple[str, ...]:
    return FLOAT_COLUMNS + (THIRD_COLUMNS if instruments_of(config) == 3 else ())


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
               *[pa.field(c, pa.float64()) for c in docking_columns(config)],
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
                   f"{bit} {why}" for bit, why in _reasons().items())})]
    return pa.schema(fields, metadata=_stored_metadata(config))


#: The cart's columns (with ``cart.model`` other than "none"): the first pose of its grid at which every arm
#: docks (-1: none), that pose's origin on the floor and heading (the patient's floor frame).
CART_COLUMNS = ("cart_pose", "cart_x_mm", "cart_y_mm", "cart_heading_deg")


def cart_of(config) -> str:
    """The cart a config models: validated, as stored (a dict), or none ("none")."""
    if isinstance(config, dict):
        return (config.get("cart") or {}).get("model", "none")
    return "none" if config is None else config.cart.model


def cart_search_columns(config) -> tuple[str, ...]:
    """A search's cart dimensions (``cart.pose = "search"``; ``tables.searched_pose_box``), else none."""
    from surgopt.studies.port_place.tables import searched_pose_box

    if config is None or cart_of(config) == "none":
        return ()
    cart = (config.get("cart") or {}) if isinstance(config, dict) else config.cart
    if (cart.get("pose") if isinstance(cart, dict) else cart.pose) != "search":
        return ()
    if isinstance(cart, dict):
        from surgopt.studies.port_place.config import Cart

        cart = Cart.model_validate(cart)
    return tuple(searched_pose_box(cart))


def links_of(config) -> bool:
    """Whether the arms' links decide feasible (``tables.links_decide``) in a config, validated or as stored."""
    if cart_of(config) == "none":
        return False
    if isinstance(config, dict):
        return (config.get("constraints") or {}).get("min_link_clearance_mm") is not None
    from surgopt.studies.port_place.tables import links_decide

    return links_decide(config)


#: ``external_clearance_mm`` when the links decide (``constraints.min_link_clearance_mm``).
LINK_MEANING = {"meaning": "the least clearance of the arms' links outside the body (setup joints' and arms' "
                           "own, capsules of assumed radii; docked and over the target) to each other, the "
                           "patient's body and the table, at the row's cart pose; between arms resolved up to 100 "
                           "mm above min_link_clearance_mm (reads as that beyond; the patient's body up to 150 mm), "
                           "below it the first overlap found (an upper bound); NaN: no pose docks, or the layout "
                           "fails on a count of its own and was not checked"}


def cart_fields(config) -> list:
    import pyarrow as pa

    if cart_of(config) == "none":
        return []
    links = [pa.field("external_link_pair", pa.int64(), metadata={
        "meaning": "the two links of external_clearance_mm: 256 x arm pair (0 PSM1-PSM2, 1 PSM1-ECM, 2 PSM2-ECM, "
                   "3 PSM1-PSM3, 4 PSM2-PSM3, 5 PSM3-ECM) + 16 x the first arm's link + the second's, or 256 x (6 + "
                   "arm: PSM1, PSM2, PSM3, ECM) + 16 x its link + (0 the patient's body, 1 the table); each arm's "
                   "links its setup joints' 3-6, then its own (link_tables.pair_name decodes it); -1: none"})] \
        if links_of(config) else []
    margins = [pa.field(f"{arm}_suj_{what}", pa.float64(), metadata={
        "meaning": f"the {arm.upper()} setup joints' least margin to their ranges at the row's cart pose, "
                   + ("over the revolute joints (deg)" if what.endswith("deg") else "of the column (mm)")
                   + "; negative never (the best solution within the ranges); NaN: no pose docks"})
        for arm in arms_of(config) for what in ("margin_deg", "column_margin_mm")]
    joints = [pa.field(name, pa.float64(), metadata={
        "meaning": f"the {arm.upper()} setup joint {joint} at the row's cart pose ("
                   + ("the column's height, mm" if name.endswith("_mm") else "deg")
                   + "; the dVRK's simulated_position in m and rad is export --format dvrk's); the solution with "
                     "the largest least margin; NaN: no pose docks"})
        for arm, names in suj_joint_columns(config).items() for joint, name in names]
    return [pa.field("cart_pose", pa.int64(), metadata={"meaning": "the first pose of the cart's grid at which "
                                                                    "every arm's setup joints dock (-1: none)"}),
            *[pa.field(c, pa.float64()) for c in CART_COLUMNS[1:]], *links, *margins, *joints]


def suj_joint_columns(config) -> dict[str, tuple[tuple[str, str], ...]]:
    """Per arm (its column prefix), its setup joints' names in the cart's data and their row columns, in the
    order of the dVRK's ``simulated_position``: the column (prismatic, mm) first, then the revolute joints (deg)."""
    from surgopt.robots.dvrk_suj import CARTS, INSTRUMENT_SUJS

    cart = CARTS[cart_of(config)]
    out = {}
    for a, arm in enumerate(arms_of(config)):
        suj = cart["ECM" if arm == "ecm" else INSTRUMENT_SUJS[a]]
        out[arm] = tuple((row.name, f"{arm}_suj_{row.name}_{'mm' if row.prismatic else 'deg'}") for row in suj.links)
    return out


def _stored_metadata(config) -> dict | None:
    """With the cart: what its docking is solved from (``cart_metadata``); with only feasible rows stored: how
    many designs were enumerated (what the summary counts the infeasible from), when the config can be read
    again (a stored mesh config whose file moved cannot)."""
    meta = {**(cart_metadata(config) or {}), **landmark_metadata(config)} or None
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
    import json

    if config is None:
        return None
    if cart_of(config) == "none":  # what the closing report says of the cart: none, and why
        return {"cart": no_cart_note(config)}
    return {"config": json.dumps(config if isinstance(config, dict) else config.model_dump(mode="json"))}


def _feasible_metadata(config) -> dict:
    try:
        cfg = (config if isinstance(config, PortPlaceConfig)  # as stored: its files not read and hashed again
               else PortPlaceConfig.model_validate(config, context={"stored": True}))
        return {"rows_stored": "feasible", "designs_enumerated": str(n_total(cfg))}
    except (ValueError, OSError):
        return {"rows_stored": "feasible"}


def _reasons():
    from surgopt.kinematics.port_reasons import REASONS

    return REASONS


#: What each reason a design fails takes off its score, so that feasible designs rank first.
INFEASIBLE_PENALTY = 100.0


def compute_task(cfg, chunk: int, index: int) -> dict:
    """Designs [index*chunk, (index+1)*chunk) of the enumeration, every port docked toward the target's centre
    (only the feasible ones' rows when ``rows_stored`` is 'feasible')."""
    from surgopt.kinematics.port_designs import design_columns

    model = model_of(cfg)
    sites, (t, _, _), crit = model.sites_m, model.grid, model.criteria
    start = index * chunk
    stop = min(n_designs(len(sites), cfg.robot.instrument_count), start + chunk)
    ids, f, bad, cost, design_ids, dock = design_columns(t, crit, start, stop, cfg.robot.instrument_count,
                                                         cfg.rows_stored == "feasible")
    return design_rows(cfg, sites, t, ids, ids, f, bad, cost, design_ids,
                       np.zeros((len(design_ids), len(docking_columns(cfg)))), dock=dock,
                       floor=model.dock.poses.floor if cfg.cart.model != "none" else None,
                       dock_tables=model.dock if cfg.cart.model != "none" else None)


def design_rows(cfg, sites, t, ids, site_ids, f, bad, cost, design_ids, docking_deg, aim_mm=None,
                stance_m=None, dock=None, floor=None, cart_searched=None, dock_tables=None) -> dict:
    """The rows of designs: ``ids`` (a column per arm, ``arms_of``) index ``sites`` and ``t`` (the tables they
    were combined from), ``site_ids`` are the candidate sites' numbers reported; ``docking_deg`` (yaw, pitch of
    each instrument) per design. With the cart (``floor``: its poses, ``tables.CartPoses.floor``), ``dock``
    (cart pose, swapped) per design: where PSM1 docks on the pair's second port, PSM1's and PSM2's columns
    are swapped, so that psm1_* is the arm on PSM1's setup joints; ``dock_tables`` (``tables.DockTables`` of the
    sites ``ids`` index) give each arm's setup joints' range margins at the row's pose."""
    arms = arms_of(cfg)
    if floor is not None:
        swap = dock[:, 1] == 1
        ids, site_ids, f = ids.copy(), site_ids.copy(), f.copy()
        for a in (ids, site_ids, f):
            a[swap, 0], a[swap, 1] = a[swap, 1], a[swap, 0].copy()
    cols = {"design_id": design_ids}
    cols.update({f"{arm}_site": site_ids[:, a] for a, arm in enumerate(arms)})
    for a, arm in enumerate(arms):
        for c, axis in enumerate("xyz"):
            cols[f"{arm}_{axis}_mm"] = sites[ids[:, a], c] * 1000
    for c, name in enumerate(float_columns(cfg)):
        v = f[:, c]
        cols[name] = np.degrees(v) if c in ANGLE_COLUMNS else (v * 1000 if name.endswith("_mm") else v)
    centre = np.asarray(cfg.target.centre_mm) / 1000
    d = np.linalg.norm(sites - centre, axis=1) * 1000
    spacing = np.full(len(ids), np.inf)
    for a in range(len(arms)):
        for b in range(a + 1, len(arms)):
            spacing = np.minimum(spacing, t.spacing[ids[:, a], ids[:, b]])
    cols["min_port_spacing_mm"] = spacing * 1000
    cols["psm_to_target_mm"] = d[ids[:, :-1]].max(axis=1) if len(ids) else np.zeros(0)
    rise = np.degrees(np.arcsin((sites[:, 2] - centre[2]) * 1000 / d))  # each site's elevation over the centre
    for a, arm in enumerate(arms[:-1]):
        cols[f"{arm}_elevation_deg"] = rise[ids[:, a]]
        cols[f"{arm}_wrist_margin_deg"] = t.wrist_margin_deg[ids[:, a]]
    for c, name in enumerate(docking_columns(cfg)):
        cols[name] = np.asarray(docking_deg[:, c], dtype=np.float64)
    for c, name in enumerate(aim_columns(cfg)):  # the sites themselves, unless a surface search aimed elsewhere
        cols[name] = sites[ids[:, c // 2], c % 2] * 1000 if aim_mm is None else np.asarray(aim_mm[:, c], float)
    for c, name in enumerate(stance_columns(cfg)):  # 0 on the grid: the configured stance
        cols[name] = np.zeros(len(ids)) if stance_m is None else np.asarray(stance_m[:, c], float)
    if floor is not None:
        pose = dock[:, 0]
        cols["cart_pose"] = pose
        where = np.where(pose[:, None] >= 0, floor[np.maximum(pose, 0)], np.nan)
        for c, name in enumerate(CART_COLUMNS[1:]):
            cols[name] = where[:, c]
        if links_of(cfg):
            cols["external_link_pair"] = dock[:, 2]
        if dock_tables is not None and dock_tables.joints is not None:
            from surgopt.studies.port_place.tables import suj_margins

            revolute, column = suj_margins(cfg, dock_tables)
            at = np.maximum(pose, 0)
            for a, arm in enumerate(arms):
                suj = 3 if arm == "ecm" else a  # the arm on PSM1's, PSM2's, PSM3's setup joints, or the ECM's
                for name, table in ((f"{arm}_suj_margin_deg", revolute), (f"{arm}_suj_column_margin_mm", column)):
                    cols[name] = np.where(pose >= 0, table[suj, ids[:, a], at], np.nan)
            joints = np.concatenate([dock_tables.joints[:len(arms) - 1], dock_tables.camera_joints[None]])
            for a, (arm, names) in enumerate(suj_joint_columns(cfg).items()):
                q = joints[a, ids[:, a], at]  # (designs, joints): m and rad; NaN where the arm does not dock there
                for j, (_, name) in enumerate(names):
                    value = q[:, j] * 1000 if name.endswith("_mm") else np.degrees(q[:, j])
                    cols[name] = np.where(pose >= 0, value, np.nan)
    for c, name in enumerate(cart_search_columns(cfg)):  # the searched pose, docked there or not
        cols[name] = np.asarray(cart_searched[:, c], float)
    cols["cost"] = cost
    failed = sum((bad >> bit) & 1 for bit in range(len(_reasons())))
    cols["score"] = -cost - INFEASIBLE_PENALTY * failed
    cols["feasible"] = bad == 0
    cols["infeasible"] = bad
    return cols


def docking_columns(config=None) -> tuple[str, ...]:
    """Free docking (a search's dimensions): each instrument's base turned off the target's centre, yaw and
    pitch (0: the default docking); for a serial arm the yaw is its base's turn about the port, added to
    ``base_yaw_deg``, and the pitch stays 0."""
    return tuple(f"{arm}_docking_{angle}_deg" for arm in arms_of(config)[:-1] for angle in ("yaw", "pitch"))


def aim_columns(config=None) -> tuple[str, ...]:
    """A surface search's dimensions (``search_ports = "surface"``): each port's top-view point, x and y (mm)."""
    ports = (config.get("search_ports", "sites") if isinstance(config, dict)
             else "sites" if config is None else config.search_ports)
    return tuple(f"{arm}_aim_{c}_mm" for arm in arms_of(config) for c in "xy") if ports == "surface" else ()


SERIAL_ROLES = ("instrument", "camera")


def stance_columns(config=None) -> tuple[str, ...]:
    """A search's serial-arm stances: for each serial arm (the instruments' one, the camera's) whose
    ``stance_range_m`` > 0, its RCM moved out from its base and up, off ``rcm_in_base_m`` (m)."""
    robot = (config.get("robot", {}) if isinstance(config, dict)
             else {} if config is None else config.robot.model_dump())
    return tuple(f"{role}_stance_{d}_m" for role in SERIAL_ROLES
                 if (robot.get(f"{role}_serial") or {}).get("stance_range_m", 0.0) > 0 for d in ("out", "up"))


def with_stance(cfg: PortPlaceConfig, moves: dict) -> PortPlaceConfig:
    """``cfg`` with each serial arm's RCM moved (``moves``: {role: (out, up) m}): out along its horizontal
    direction from the base (kept 0.05 m or more from the base's axis), up along z."""
    update = {}
    for role, (out, up) in moves.items():
        arm = getattr(cfg.robot, f"{role}_serial")
        x, y, z = arm.rcm_in_base_m
        h = math.hypot(x, y)
        scale = max(h + out, 0.05) / h
        update[f"{role}_serial"] = arm.model_copy(update={"rcm_in_base_m": [x * scale, y * scale, z + up]})
    return cfg.model_copy(update={"robot": cfg.robot.model_copy(update=update)})


def design_dims(cfg: PortPlaceConfig) -> dict:
    """The dimensions a design of this config has, in order, with their domains: every arm's port (a site, or a
    top-view point with ``search_ports = "surface"``), each instrument's docking when ``robot.docking_range_deg``
    > 0 (a serial arm's yaw only), each serial arm's stance when its ``stance_range_m`` > 0."""
    sites = sites_mm(cfg)
    if cfg.search_ports == "surface":  # a box around the candidate sites, top view
        lo, hi = sites[:, :2].min(axis=0), sites[:, :2].max(axis=0)
        dims = {c: (float(lo[i % 2]), float(hi[i % 2])) for i, c in enumerate(aim_columns(cfg))}
    else:
        dims = {f"{arm}_site": list(range(len(sites))) for arm in arms_of(cfg)}
    r = cfg.robot.docking_range_deg
    if r > 0:  # a serial arm turns its base about the port (yaw) only
        free = docking_columns(cfg)[::2] if cfg.robot.instrument_serial is not None else docking_columns(cfg)
        dims.update({c: (-r, r) for c in free})
    for c in stance_columns(cfg):
        reach = getattr(cfg.robot, f"{c.split('_')[0]}_serial").stance_range_m
        dims[c] = (-reach, reach)
    if cart_search_columns(cfg):
        from surgopt.studies.port_place.tables import searched_pose_box

        dims.update(searched_pose_box(cfg.cart))
    return dims


def nearest_sites(sites_xy_mm: np.ndarray, aims_mm: np.ndarray) -> np.ndarray:
    """The candidate site nearest each top-view point (rows of ``aims_mm``, (x, y) mm): its index."""
    d = ((aims_mm[:, None, :] - sites_xy_mm[None, :, :]) ** 2).sum(axis=2)
    return d.argmin(axis=1)


#: The two-instrument study's docking and site columns.
DOCKING_COLUMNS = docking_columns()
SITE_COLUMNS = tuple(f"{arm}_site" for arm in arms_of())


def search_plan(cfg):
    """A search's space: every arm's port (categorical: any candidate site; or, with ``search_ports = "surface"``,
    a top-view point within the candidate sites' box, continuous) and, when ``robot.docking_range_deg`` > 0, each
    instrument's docking yaw and pitch within +- that range."""
    from surgopt.plans.search import SearchPlan, objectives_of, optimiser_of

    spec = optimiser_of(cfg)
    if spec is None:
        return None
    return SearchPlan(spec, design_dims(cfg), objectives_of(spec, OBJECTIVE))


def evaluate_designs(cfg, x: np.ndarray, ids: np.ndarray, source: str) -> dict:
    """Rows of any designs (rows of ``x``: every arm's site number, ``arms_of``, or with ``search_ports =
    "surface"`` every arm's top-view point (x, y mm, taken to the nearest candidate site), then each instrument's
    docking yaw and pitch in deg when free), each from its own ports docked as given: the per-port and per-pair tables
    of those ports (``port_tables``), combined as the enumeration combines them (its design 0 is the ports in
    this order), with the cart's dock tables of those ports when the run has a cart. A design whose ports coincide
    is infeasible (zero spacing and clearance)."""
    from surgopt.kinematics import port_place as K
    from surgopt.kinematics.port_designs import design_columns

    ports = len(arms_of(cfg))
    x = np.asarray(x, dtype=np.float64).reshape(len(ids), -1)
    model = model_of(cfg)  # its grid's tables are not built: a design builds the tables of its own ports
    all_sites, crit, centre = model.sites_m, model.criteria, model.centre_m
    serial = cfg.robot.instrument_serial is not None
    names = list(design_dims(cfg))
    if x.shape[1] == ports:  # site numbers alone: the configured docking and stance
        names = [f"{arm}_site" for arm in arms_of(cfg)]
    elif x.shape[1] != len(names):
        raise ValueError(f"a design of this config has {len(names)} values ({', '.join(names)}), not {x.shape[1]}")
    col = {n: j for j, n in enumerate(names)}
    surface = f"{arms_of(cfg)[0]}_aim_x_mm" in col
    stances = [c for c in stance_columns(cfg) if c in col]
    port_cols = [col[c] for c in (aim_columns(cfg) if surface else [f"{arm}_site" for arm in arms_of(cfg)])]
    docking_cols = [col.get(c) for c in docking_columns(cfg)]  # None: not free, 0
    cart = cfg.cart.model != "none"  # the grid's dock tables (every site, every cart pose), each design's sites
    searched = cart_search_columns(cfg)  # or, searched, each design's own pose's (of sites alone: the box's middle)
    out = []
    for r in range(x.shape[0]):
        v = x[r]
        site_ids = (nearest_sites(all_sites[:, :2] * 1000, v[port_cols].reshape(ports, 2)) if surface
                    else v[port_cols].astype(np.int64))
        docking = np.array([0.0 if j is None else v[j] for j in docking_cols])
        stance = np.array([v[col[c]] for c in stances])
        cfg_r = with_stance(cfg, {c.split("_")[0]: (stance[k], stance[k + 1]) for k, c in enumerate(stances)
                                  if c.endswith("_out_m")}) if stances else cfg
        sites = all_sites[site_ids]
        pose = searched_values(cfg.cart, {c: v[col[c]] for c in searched if c in col}) if searched else None
        model_r = model.with_config(cfg_r) if stances else model
        if serial:  # the RCM mechanism (the camera) docked as in the grid, each serial base turned by its yaw
            t, _, _ = port_tables(model_r, sites, K.docking_frames(sites, centre, LATERAL),
                                  base_yaw_rad=np.radians([*docking[0::2], 0.0]))
        else:
            rot = K.tilted_frames(K.docking_frames(sites, centre, LATERAL), np.radians([*docking[0::2], 0.0]),
                                  np.radians([*docking[1::2], 0.0]))
            outside = K.external_clearances(sites, np.ascontiguousarray(rot[:, :, 2]), dvrk.OUTSIDE_LENGTH_M)
            tables = (None if not cart else cart_of_sites(model.dock, site_ids) if pose is None
                      else searched_dock(model, site_ids, pose))
            t, _, _ = port_tables(model_r, sites, rot, outside, dock=tables)
        local, f, bad, cost, _, dock = design_columns(t, crit, 0, 1, ports - 1)
        out.append(design_rows(cfg, sites, t, local, site_ids[None, :], f, bad, cost,
                               np.asarray(ids[r:r + 1], dtype=np.int64), docking[None, :],
                               v[None, port_cols] if surface else None,
                               stance[None, :] if stances else None,
                               dock=dock if cart else None, floor=tables.poses.floor if cart else None,
                               dock_tables=tables if cart else None,
                               cart_searched=np.array([[pose[c] for c in searched]]) if searched else None))
    return concat_rows(out)


def searched_dock(model, site_ids: np.ndarray, pose: dict):
    """The dock tables of a design's own ports at its own searched cart pose (``pose``: the pose's dimensions,
    ``tables.searched_values``): one pose, at which no arm docks (nothing solved) when the cart's origin would
    stand within ``clear_of_table_mm`` of the table."""
    from surgopt.kinematics.port_designs import pack_bits
    from surgopt.studies.port_place.tables import DockTables, dock_at, floor_pose, off_table, poses_of

    cfg = model.cfg
    floor = np.array([floor_pose(cfg, *pose.values())])
    poses = poses_of(cfg.cart, floor)
    if off_table(cfg.cart, floor[:, 0], floor[:, 1])[0]:
        return dock_at(model, site_ids, poses)
    n = len(site_ids)
    margin, camera = np.full((3, n, 1), -np.inf), np.full((n, 1), -np.inf)
    return DockTables(pack_bits(margin >= 0.0), pack_bits(camera >= 0.0), margin, camera, poses,
                      np.full((3, n, 1, 6), np.nan), np.full((n, 1, 6), np.nan), np.full((n, 1, 2), np.nan))


def searched_values(cart, given: dict) -> dict:
    """A searched cart pose's three dimensions in ``floor_pose``'s order: those ``given``, the others (not
    searched, or a design of sites alone) at the middle of their range."""
    from surgopt.studies.port_place.tables import searched_middle

    return {**searched_middle(cart), **given}


def cart_of_sites(dock, site_ids: np.ndarray):
    """The cart's dock tables (``tables.DockTables``, every candidate site) of a design's own ports, in its order."""
    pick = {"joints": (slice(None), site_ids), "camera_joints": (site_ids,), "camera_aim": (site_ids,)}
    return dock._replace(bits=dock.bits[:, site_ids], camera=dock.camera[site_ids], margin=dock.margin[:, site_ids],
                         camera_margin=dock.camera_margin[site_ids],
                         **{k: getattr(dock, k)[at] for k, at in pick.items() if getattr(dock, k) is not None})


def warm_up(cfg) -> None:
    """The per-port tables (their kernels), then the design kernel as the config's tasks call it: the grid's
    chunks (``compute_task``), or a search's one design at a time (``evaluate_designs``)."""
    from surgopt.kinematics.port_designs import design_columns
    from surgopt.plans.search import optimiser_of

    model = model_of(cfg)
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
    model = model_of(cfg)
    t = model.grid.tables
    best = int(t.reach_count.max())
    if best < t.n_points:
        from surgopt.studies.port_place.serial_arms import refused_ports_note

        arm = ("" if cfg.robot.instrument_serial is None else
               f"; stand the arm elsewhere (robot.instrument_serial.rcm_in_base_m, base_yaw_deg: rcm-grid finds where "
               f"an arm keeps an RCM best){refused_ports_note(model, model.sites_m)}")
        raise ValueError(f"target: no candidate port's instrument ({instrument_of(cfg).name}, docked toward the "
                         f"target's centre) reaches the whole target: {best:,} of its {t.n_points:,} points at best, "
                         f"so every layout would fail on reach; move or shrink the target, ease its approach cone, "
                         f"or widen patient.port_region / constraints.port_to_target_mm{arm}")
    if cfg.robot.camera_serial is not None and not t.coverage.any():
        raise ValueError(f"robot.camera_serial: the arm ({camera_arm_of(cfg).name}) holds the endoscope where it "
                         f"must be at no candidate port, so no layout has a camera; stand it elsewhere "
                         f"(rcm_in_base_m, base_yaw_deg) or give it a longer tool")


#: Cost model: ~60 ns to combine one design and turn it into columns on one core (~70 ns with a third
#: instrument), plus the tables (~60 ns per site x target point by the closed forms, ~0.3 us per instrument
#: pair x target point);
#: a row is ~190 bytes (~230 with a third instrument).
NS_PER_DESIGN = 60.0
NS_PER_DESIGN_3 = 70.0
ROW_BYTES, ROW_BYTES_3 = 190, 230
#: The cart's columns in a row: cart_pose (int64) and the pose's x, y and heading (float64).
CART_ROW_BYTES = 32
#: Each arm's setup-joint margins and its six setup joints in a row (float64 each).
SUJ_MARGIN_ROW_BYTES = 16
SUJ_JOINTS_ROW_BYTES = 6 * 8
IN_FLIGHT_TASKS = 4
NS_PER_SITE_POINT = 60.0
#: A serial instrument arm's per-port tables: ~3.4 us per site x target point (generic Newton IK by continuation,
#: benchmarks/bench_port_place.py: 0.55 s for 164 x 915 at 91 % reached).
NS_PER_SITE_POINT_SERIAL = 4000.0
NS_PER_PAIR_POINT = 300.0


#: One Classic PSM setup joint's inverse kinematics (``kinematics.suj_batch.classic_psm_margins``, jitted): ~3.4 us
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
#: The ECM's setup joints at one site and cart pose (``kinematics.suj_batch.ecm_margins``' grid of 36 x 36 x 12,
#: jitted): ~125 us measured (3.1 s for the default's 164 x 150; numpy over a pose's sites: ~300 us).
NS_PER_ECM_DOCK = 130_000.0


#: A searched design (its three ports' tables of its own): ~0.43 ms at 915 target points (measured, one core).
NS_PER_SEARCHED_DESIGN_POINT = 470.0


#: The share of designs assumed feasible when only the feasible rows are stored (their storing time in the
#: estimate): an assumption, measured on the defaults: 1.8 % with three PSMs (6,142,464 of 348,612,012, the wrist
#: reaching at any depth), 3.6 % with two (77,336 of 2,165,292).
FEASIBLE_SHARE_ASSUMED = 0.02

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


def estimate(cfg) -> Estimate:
    from surgopt.plans.search import optimiser_of

    n = len(sites_mm(cfg))
    m = len(target_points_mm(cfg.target))
    spec = optimiser_of(cfg)
    if spec is not None:
        return Estimate(spec.trials, f"{spec.method} trials", spec.trials,
                        spec.trials * m * NS_PER_SEARCHED_DESIGN_POINT * 1e-9, peak_bytes(spec.trials, 220))
    arms = cfg.robot.instrument_count
    d = n_designs(n, arms)
    per_design = NS_PER_DESIGN if arms == 2 else NS_PER_DESIGN_3
    per_site_point = NS_PER_SITE_POINT if cfg.robot.instrument_serial is None else NS_PER_SITE_POINT_SERIAL
    seconds = (d * per_design + n * m * per_site_point + n * n / 2 * m * NS_PER_PAIR_POINT) * 1e-9
    if cfg.cart.model != "none":  # each instrument arm's setup joints at each site and cart pose
        from surgopt.studies.port_place.tables import cart_poses

        poses = len(cart_poses(cfg).floor)
        seconds += n * poses * (arms * NS_PER_SUJ_SOLVE + NS_PER_ECM_DOCK) * 1e-9
        if links_of(cfg):  # the links' clearance tables, each arm pair's (site, site, pose) entries
            seconds += link_pairs(arms) * n * n * poses * NS_PER_LINK_ENTRY * 1e-9
    row = (ROW_BYTES if arms == 2 else ROW_BYTES_3) + (
        CART_ROW_BYTES + (arms + 1) * (SUJ_MARGIN_ROW_BYTES + SUJ_JOINTS_ROW_BYTES) if cfg.cart.model != "none" else 0)
    working = n * n * 8 * 12 + n * m * 9 + LIBRARY_BYTES + (CART_LIBRARY_BYTES if cfg.cart.model != "none" else 0)
    if cfg.cart.model != "none":  # the dock tables: each arm's margins, best joints and the ECM's aim per (site, pose)
        working += n * poses * DOCK_ENTRY_BYTES
    if links_of(cfg):  # float32 values, int16 pairs and the float work arrays of each arm pair's dense tables
        working += link_pairs(arms) * n * n * poses * LINK_ENTRY_BYTES
    if cfg.rows_stored == "feasible":  # at most every design feasible: 8 bytes of each stored row in the parent
        # and, in flight, tasks of feasible rows only (2 per worker, ~4 on this scale of machine)
        return Estimate(d, "port designs (feasible rows stored)", d, seconds,
                        peak_bytes(d, 0, working_bytes=working + IN_FLIGHT_TASKS * auto_chunk(cfg) * row),
                        stored_rows=int(d * FEASIBLE_SHARE_ASSUMED))
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
    cart = [*CART_COLUMNS, *(f"{arm}_{c}_mm" for arm in arms for c in "xyz")] if cart_of(config) != "none" else []
    return ["design_id", *(f"{arm}_site" for arm in arms), "cost", "feasible", "infeasible", *cart]


def feasible_mask(table):
    return table["feasible"].to_numpy(zero_copy_only=False)


#: A layout's clinical checks beside their literature values: (quantity, row fields, decimals, how the fields'
#: values are joined, the clinical number and its source). The closing report and the HTML page read it.
#: The best layout's checks against the literature: (quantity, columns, digits, joiner, the clinical number, its
#: band (lo, hi) where the literature gives one: a value outside it is marked).
CLINICAL_CHECKS = (
    ("port spacing (mm)", ("min_port_spacing_mm",), 0, "", ">= 80 (assumption: 8 cm)", (80.0, math.inf)),
    ("instrument port to target centre, 3-D (mm)", ("psm_to_target_mm",), 0, "",
     "<= 180 (J Endourol 2004: port to pubis)", (0.0, 180.0)),
    ("manipulation angle at the centre (deg)", ("manipulation_angle_centre_deg",), 1, "",
     "45-75, 60 best (Hanna 1997)", (45.0, 75.0)),
    ("manipulation angle over the target (deg)", ("manipulation_angle_min_deg", "manipulation_angle_max_deg"), 1,
     " - ", "45-75", (45.0, 75.0)),
    ("azimuth imbalance (deg)", ("azimuth_imbalance_deg",), 1, "", "0: equal azimuths (Hanna 1997)", None),
    ("instrument elevation at the centre (deg)", ("psm1_elevation_deg", "psm2_elevation_deg"), 1, " / ",
     "60 with a 60-deg manipulation angle (Hanna 1997)", None),
    ("optical axis off the instruments' arc (deg)", ("camera_off_arc_deg",), 1, "", "0: camera between them", None),
    ("common reach", ("common_reach",), 3, "", "1", (1.0, 1.0)),
    ("camera coverage", ("camera_coverage",), 3, "", "1", (1.0, 1.0)),
)


def within_band(values, band) -> str:
    """"yes", "OUTSIDE" (any value out of the band) or "" (the literature gives no band)."""
    if band is None:
        return ""
    return "yes" if all(band[0] <= v <= band[1] for v in values) else "OUTSIDE"


#: What every answer leaves out (docs/port_placement.md, "What the model leaves out"), said in the closing report.
NOT_MODELLED = ("the Si cart's and the Xi's setup joints, tissue and the body wall's thickness (a port is a point), "
                "the assistant's port, the table's rails and arm boards and the patient's arms; every link radius is "
                "an assumption (docs/port_placement.md, what the model leaves out)")


def summary(parts) -> Summary:
    """Feasible count, each reason's count, the best feasible design by cost with its clinical checks."""
    from surgopt.kinematics.port_reasons import REASONS

    from surgopt.kinematics.port_reasons import DOCKING

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
    screened = best.to_pylist()
    if screened and "cart_pose" in parts.schema.names and links_of(json.loads(meta.get("config", "{}"))):
        screened = with_cheaper_overlapping(parts, screened)
    best = best.slice(0, 5)
    tables = []
    if best.num_rows:
        b = best.to_pylist()[0]
        headline.update({"best_design_id": b["design_id"], "best_cost": b["cost"]})
        checks = [[label + (" (all three instruments)" if fields == ("common_reach",) and "psm3_reach" in b else ""),
                   joiner.join(f"{b[f]:.{digits}f}" for f in fields), clinical,
                   within_band([b[f] for f in fields], band)]
                  for label, fields, digits, joiner, clinical, band in CLINICAL_CHECKS]
        tables.append(("best layout: clinical checks", ["quantity", "value", "clinical number", "within"], checks))
        mark = json.loads(meta["landmark"]) if "landmark" in meta else None
        ports = [[arm, str(b[f"{arm}_site"]), f"{b[f'{arm}_x_mm']:.0f}", f"{b[f'{arm}_y_mm']:.0f}",
                  f"{b[f'{arm}_z_mm']:.0f}"] + ([from_landmark(b[f"{arm}_x_mm"], b[f"{arm}_y_mm"], mark[1:])]
                                                if mark else [])
                 for arm in ("psm1", "psm2", "psm3", "ecm") if f"{arm}_site" in b]
        tables.append((f"best layout: ports ({FRAME_TEXT})", ["arm", "site", "x_mm", "y_mm", "z_mm"]
                       + ([f"from the {mark[0]} (mm, top view)"] if mark else []), ports))
        if "cart_pose" in b:  # the screen first: the best layout's clearances and rolls are then known
            screen = clearance_screen(screened, meta)
            tables += docking_tables(b, meta)
            if meta.get("rows_stored") != "feasible":
                tables += undocked_table(parts, meta)
            if screen is not None:
                headline["links_clear"], table = screen
                tables.append(table)
        cols = ["design_id", "cost", "common_reach", "dexterity_mean", "manipulation_angle_mean_deg",
                "azimuth_imbalance_deg", "camera_coverage"]
        repeats = best.schema.metadata.get(b"repeats_collapsed", b"0").decode() if best.schema.metadata else "0"
        tables.append(("best feasible designs by cost" + (f" ({repeats} repeats of a listed layout collapsed)"
                                                          if repeats != "0" else ""), cols,
                       [[f"{r[c]:.4g}" if isinstance(r[c], float) else str(r[c]) for c in cols] for r in best.to_pylist()]))
        if mark:
            arms = [a for a in ("psm1", "psm2", "psm3", "ecm") if f"{a}_x_mm" in b]
            tables.append((f"best feasible designs: ports from the {mark[0]} (mm, top view: the patient's left or "
                           f"right, cranial or caudal)", ["design_id", *arms],
                           [[str(r["design_id"]), *(from_landmark(r[f"{a}_x_mm"], r[f"{a}_y_mm"], mark[1:])
                                                    for a in arms)] for r in best.to_pylist()]))
    else:
        headline["best"] = "none: no design is feasible (see the reasons' counts)"
    if "cart" in meta:
        headline["cart"] = meta["cart"]
    headline["not_modelled"] = NOT_MODELLED
    if "cart_pose" in parts.schema.names and meta.get("rows_stored") != "feasible":
        counts["infeasible only for docking (feasible without the cart)"] = only_docking
    return Summary(headline, counts, tables)


def no_cart_note(config) -> str:
    """What a run without the cart says of it (validated or as stored): docking assumed, and why the cart is not
    in (the arms it cannot carry, or cart.model = "none")."""
    from surgopt.studies.port_place.config import cart_does_not_carry

    try:
        cfg = (config if isinstance(config, PortPlaceConfig)
               else PortPlaceConfig.model_validate(config, context={"stored": True}))
    except (ValueError, OSError):
        return "none: docking assumed"
    why = cart_does_not_carry(cfg)
    return f"none: docking assumed ({'the Classic cart carries the Classic PSMs and ECM, ' + why if why else 'cart.model = none'})"


def ports_export(cfg, row: dict) -> str:
    """``surgopt export KEY --design ID --format ports`` (``export.ports_csv``)."""
    from surgopt.studies.port_place.export import ports_csv

    return ports_csv(cfg, row)


def dvrk_export(cfg, row: dict) -> str:
    """``surgopt export KEY --design ID --format dvrk`` (``export.dvrk_setup``)."""
    from surgopt.studies.port_place.export import dvrk_setup

    return dvrk_setup(cfg, row)


def docking_tables(best: dict, meta: dict) -> list:
    """The best layout's cart pose and each arm's setup joints there (solved again from the row's ports and
    pose, and the run's config in the rows' metadata), docked as the dvrk export docks it (``docking_that_clears``:
    where the links overlap at the run's own docking and a roll of each PSM about its shaft clears them, so),
    and the links' clearances so docked."""
    import json

    from surgopt.studies.port_place.clashes import docking_that_clears

    try:  # as stored: its files are not read and hashed again
        cfg = PortPlaceConfig.model_validate(json.loads(meta["config"]), context={"stored": True})
    except (ValueError, OSError, KeyError) as exc:
        return [("best layout: the cart", ["note"], [[f"the run's config cannot be read again ({exc}); the cart "
                                                       f"pose is in the row's cart_* columns"]])]
    docked, rolls, _, clearances = docking_that_clears(cfg, best)  # as the export docks it
    turned = {arm: deg for arm, deg in rolls.items() if deg}
    pose = [[f"{best['cart_x_mm']:.0f}", f"{best['cart_y_mm']:.0f}", f"{best['cart_heading_deg']:.1f}",
             str(best["cart_pose"]) if cfg.cart.pose != "search" else
             f"searched: {best['cart_around_deg']:.1f} deg around, {best['cart_distance_mm']:.0f} mm"]]
    rows = [[a.arm, a.site, " ".join(f"{v:.4f}" for v in a.joints) if a.joints else "-",
             "-" if a.margin is None else f"{a.margin:.3f}" + (f" ({a.tightest})" if a.tightest else ""),
             a.note or (f"ECM yaw {math.degrees(a.ecm[0]):.1f}, pitch {math.degrees(a.ecm[1]):.1f} deg" if a.ecm
                        else f"docking rolled {turned[a.arm]:+.0f} deg about the shaft" if a.arm in turned
                        else "")] for a in docked]
    clear = [[c.check, f"{c.clearance_mm:.0f}", c.link_a, c.link_b, c.where]
             for c in clearances]
    return [(f"best layout: the {cfg.cart.model} cart (origin on the floor, patient frame; heading from +y toward +x)",
             ["x_mm", "y_mm", "heading_deg", "pose (of the grid, or searched)"], pose),
            ("best layout: setup joints (column m, then rad, the dVRK's simulated_position order)"
             + (" as `export --format dvrk` docks it: each PSM's docking turned so that the links clear" if turned
                else ""),
             ["arm", "port", "suj_joints", "least range margin", "note"], rows),
            ("best layout: least clearance outside the body (capsules, radii assumed; negative: the links overlap; "
             + in_feasible(cfg) + ")", ["between", "clearance_mm", "link", "against", "where"], clear)]


def in_feasible(cfg) -> str:
    """What of the links' clearance feasible holds: between arms with ``constraints.min_link_clearance_mm``."""
    if links_of(cfg):
        return f"in feasible, at least {cfg.constraints.min_link_clearance_mm:g} mm"
    return "not yet part of feasible"


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
    from surgopt.kinematics.port_reasons import DOCKING, OUTSIDE
    from surgopt.studies.port_place.tables import model_of

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
    try:  # as stored: its files are not read and hashed again
        cfg = PortPlaceConfig.model_validate(json.loads(meta["config"]), context={"stored": True})
    except (ValueError, OSError, KeyError):
        return []
    if cfg.cart.pose == "search":  # each trial docked at its own pose, not at the grid's
        return []
    sites = np.column_stack([got[f"{a}_site"][undocked] for a in arms]).astype(np.int64)
    why = np.where(got["infeasible"][undocked] == OUTSIDE, len(UNDOCKED_WHY) - 1, why_undocked(model_of(cfg).dock,
                                                                                                sites))
    rows = [[w, f"{int(np.sum(why == k)):,}"] for k, w in enumerate(UNDOCKED_WHY) if np.any(why == k)]
    return [(f"the {len(best):,} layouts of least cost feasible without the cart: {len(undocked):,} the "
             f"{cfg.cart.model} cart's setup joints cannot dock at any pose of its grid"
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
ROLL_TEXT = "a 15-degree grid over +-90 about the neutral shaft"


def with_cheaper_overlapping(parts, feasible: list[dict]) -> list[dict]:
    """With the links in feasible: the layouts cheaper than the best feasible one that fail only on the links
    (reason 16: they dock, and their links overlap at the run's docking roll at every pose) before the feasible
    ones, by cost, for the screen to try with each PSM's roll (``clearance_screen``)."""
    from surgopt.kinematics.port_reasons import OUTSIDE

    cheaper = [r for r in least_cost_layouts(parts, SCREEN_LAYOUTS, False, only_reasons=OUTSIDE).to_pylist()
               if (r["cost"], r["design_id"]) < (feasible[0]["cost"], feasible[0]["design_id"])]
    return sorted(cheaper + feasible, key=lambda r: (r["cost"], r["design_id"]))


def clearance_screen(rows: list[dict], meta: dict):
    """The best layouts (``rows``, distinct, by cost) screened for their links' clearance outside the body, which
    feasible does not yet include (issue 40): (the headline's word, the table), or None when the run's config
    cannot be read again. A layout whose links overlap at the run's docking roll is tried with each PSM's own
    roll (``clashes.rolls_that_clear``: full reach and the setup joints' ranges kept). The headline names the
    first layout that clears, at the run's roll or with rolls; else how much the least of them overlaps."""
    from surgopt.studies.port_place.clashes import layout_clearances, least, rolls_that_clear

    try:  # as stored: its files are not read and hashed again
        cfg = PortPlaceConfig.model_validate(json.loads(meta["config"]), context={"stored": True})
    except (ValueError, OSError, KeyError):
        return None
    out, clear = [], None
    for r in rows[:SCREEN_LAYOUTS]:
        c = least(layout_clearances(cfg, r))
        if c is None:
            continue
        rolled = rolls_that_clear(cfg, r) if c.clearance_mm < 0 else None
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
        elif clear is None and rolled is not None and rolled.least is not None:
            turned = ", ".join(f"{a} {d:+.0f}" for a, d in rolled.rolls.items() if d)
            clear = (f"design {r['design_id']} with its PSMs' docking rolled ({turned} deg about the shaft): least "
                     f"clearance {rolled.least.clearance_mm:.0f} mm ({rolled.least.link_a} / {rolled.least.link_b}); "
                     f"so docked its cost is {rolled.cost:.4f} (at the run's roll {r['cost']:.4f}: of the cost only "
                     f"the dexterity depends on the roll)"
                     + ("" if r["feasible"] else "; its row fails on its links at the run's roll (reason 16), and it "
                        "is cheaper than every feasible layout")
                     + "; `surgopt export --format dvrk` docks it so" + _below_table(cfg, r, rolled))
        if clear is not None:  # what the headline needs: the best layout that clears (each costs ~0.5-2 s)
            break
    if not out:
        return None
    n = len(out)
    if clear is not None:
        word = clear.replace("{n}", str(n))
    else:
        worst = max(float(x[2]) for x in out)
        word = (f"none of the {n} best feasible layouts, at the run's docking roll or each PSM's own: their links "
                f"overlap outside the body by {-worst:.0f} mm or more (link clearance: {in_feasible(cfg)})")
    which = ("the best feasible layouts" if all(r["feasible"] for r in rows[:n]) else
             "the best layouts (the feasible ones and, as the links are in feasible, those cheaper that fail only on "
             "them at the run's roll)")
    title = (f"{which}, {n} screened by cost until one clears (at most {SCREEN_LAYOUTS}): their "
             f"links' least clearance outside the body (capsules, radii "
             f"assumed; negative: they overlap; {in_feasible(cfg)}), and each PSM's docking roll (deg, "
             f"{ROLL_TEXT}) at which they clear")
    return word, (title, ["design_id", "cost", "least_clearance_mm", "between", "links", "with rolls"], out)


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


STUDY = Study(
    name=NAME, kernel_version=KERNEL_VERSION, config_model=PortPlaceConfig, default_config=DEFAULT_CONFIG,
    help=HELP, config_help=CONFIG_HELP, schema=schema, key_columns=("design_id",), objective=OBJECTIVE,
    auto_chunk=auto_chunk, n_tasks=n_tasks, warm_up=warm_up, compute_task=compute_task, summary=summary,
    feasible_mask=feasible_mask, feasible_columns=("feasible",), figures=figures_in("surgopt.studies.port_place.figures"), estimate=estimate, search_plan=search_plan,
    html_views=html_views_in("surgopt.studies.port_place.html"), reported_objective=("cost", "minimize"),
    exports={"dvrk": dvrk_export, "ports": ports_export},
    warm_variants=(('robot.instrument_serial={model = "pa10_7c", rcm_in_base_m = [0.65, 0.0, 0.5]}',
                    "constraints.min_external_clearance_mm=150.0"),),
    evaluate=evaluate_designs, figure_columns=figure_columns, preflight=preflight, top_columns=top_columns,
    design_identity=design_identity)
