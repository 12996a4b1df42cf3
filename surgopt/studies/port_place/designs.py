"""port-place's design evaluator (issue 53: ``tables.py`` / ``designs.py``, apart from the study's declaration): the
rows of designs combined by the design kernel (``design_rows``, for the grid's chunks and a search's trials alike),
and any designs evaluated alone from their own ports (``evaluate_designs``: a search's path, each design docked as
given: its sites or top-view points, its docking turns, a serial arm's stance, its rolls, its searched cart pose).

Kernels: ``kinematics/port/designs.design_columns`` (P11), the float columns by named index
(``kinematics/port/columns.py``); the tables it combines are ``tables.py``'s, built from the prepared model
(``model.py``).
"""
from __future__ import annotations

import math

import numpy as np

from surgopt.kinematics.port.columns import COLUMNS, REACH_1, REACH_2, index as column_index, stored_value
from surgopt.parts import concat_rows
from surgopt.studies.port_place.arms import instruments_held
from surgopt.studies.port_place.carts import has_cart
from surgopt.studies.port_place.columns import (CART_COLUMNS, ROLL_RANGE_DEG, aim_columns, arms_of,
                                                cart_search_columns, docking_columns, float_columns,
                                                free_docking_columns, links_of, roll_columns, searched_roll_columns,
                                                stance_columns, suj_joint_columns, WHOLE_TARGET_COLUMN)
from surgopt.studies.port_place.config import PortPlaceConfig
from surgopt.studies.port_place.geometry import sites_mm
from surgopt.studies.port_place.hands import image_right_psm
from surgopt.studies.port_place.model import model_of
from surgopt.studies.port_place.tables import LATERAL, outside_length_m, port_tables, redocked, rolled


def reasons():
    from surgopt.kinematics.port.reasons import REASONS

    return REASONS


#: What each reason a design fails takes off its score, so that feasible designs rank first.
INFEASIBLE_PENALTY = 100.0


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
        for a in (ids, site_ids):
            a[swap, 0], a[swap, 1] = a[swap, 1], a[swap, 0].copy()
        f[swap, REACH_1], f[swap, REACH_2] = f[swap, REACH_2], f[swap, REACH_1].copy()
    cols = {"design_id": design_ids}
    cols.update({f"{arm}_site": site_ids[:, a] for a, arm in enumerate(arms)})
    for a, arm in enumerate(arms):
        for c, axis in enumerate("xyz"):
            cols[f"{arm}_{axis}_mm"] = sites[ids[:, a], c] * 1000
    for name in (*float_columns(cfg), "min_port_spacing_mm"):  # each in its stored unit, by its kernel index
        c = column_index(name)
        cols[name] = stored_value(COLUMNS[c], f[:, c])
    centre = np.asarray(cfg.target.centre_mm) / 1000
    d = np.linalg.norm(sites - centre, axis=1) * 1000
    cols["psm_to_target_mm"] = d[ids[:, :-1]].max(axis=1) if len(ids) else np.zeros(0)
    rise = np.degrees(np.arcsin((sites[:, 2] - centre[2]) * 1000 / d))  # each site's elevation over the centre
    for a, arm in enumerate(arms[:-1]):
        cols[f"{arm}_elevation_deg"] = rise[ids[:, a]]
        cols[f"{arm}_wrist_margin_deg"] = t.wrist_margin_deg[ids[:, a]]
    cols["ecm_tip_depth_mm"] = t.camera_tip_depth_mm[ids[:, -1]]
    cols["ecm_tip_to_target_mm"] = t.camera_tip_to_centre_mm[ids[:, -1]]
    cols["image_right_psm"] = image_right_psm(sites[ids[:, 0]], sites[ids[:, 1]], t.camera_tip_m[ids[:, -1]],
                                              t.camera_axis[ids[:, -1]])
    for c, name in enumerate(docking_columns(cfg)):
        cols[name] = np.asarray(docking_deg[:, c], dtype=np.float64)
    for a, name in enumerate(roll_columns(cfg)):  # the rolls the tables docked each port at
        cols[name] = t.roll_deg[ids[:, a]]
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
    if links_of(cfg):
        cols[WHOLE_TARGET_COLUMN], bad = decided_over_the_whole_target(cfg, cols, bad)
    cols["cost"] = cost
    failed = sum((bad >> bit) & 1 for bit in range(len(reasons())))
    cols["score"] = -cost - INFEASIBLE_PENALTY * failed
    cols["feasible"] = bad == 0
    cols["infeasible"] = bad
    return cols


def decided_over_the_whole_target(cfg, cols: dict, bad: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(#54 item 3) The link tables sample ``link_tables.POSE_POINTS`` target points; each layout feasible on them
    is measured again over every target point, docked as its row is (``clashes.whole_target_clearances``: the
    least between each pair of its arms, exact), and fails on its links (``reasons.OUTSIDE``) when that is below
    ``constraints.min_link_clearance_mm``: (the least over the whole target (mm, NaN where not measured), the
    reasons updated). ~20 ms a layout on the default's 915 points."""
    from surgopt.kinematics.port.reasons import OUTSIDE
    from surgopt.studies.port_place.clashes import least, over_the_whole_target

    value = np.full(len(bad), np.nan)
    floor = cfg.constraints.link_least_mm
    if floor is None:
        return value, bad
    bad = np.array(bad, copy=True)
    model = model_of(cfg)
    for r in np.flatnonzero(bad == 0):
        row = {name: column[r] for name, column in cols.items()}
        worst = least(over_the_whole_target(model, row))
        value[r] = worst.clearance_mm if worst is not None else np.nan
        if worst is not None and worst.clearance_mm < floor:
            bad[r] |= OUTSIDE
    return value, bad


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
    > 0 (a serial arm's yaw only), each serial arm's stance when its ``stance_range_m`` > 0, each PSM's docking
    roll with ``robot.docking_roll = 'search'``, the cart's pose when searched."""
    sites = sites_mm(cfg)
    if cfg.search_ports == "surface":  # a box around the candidate sites, top view
        lo, hi = sites[:, :2].min(axis=0), sites[:, :2].max(axis=0)
        dims = {c: (float(lo[i % 2]), float(hi[i % 2])) for i, c in enumerate(aim_columns(cfg))}
    else:
        dims = {f"{arm}_site": list(range(len(sites))) for arm in arms_of(cfg)}
    r = cfg.robot.docking_range_deg
    if r > 0:  # a serial arm turns its base about the port (yaw) only
        dims.update({c: (-r, r) for c in free_docking_columns(cfg)})
    for c in stance_columns(cfg):
        reach = getattr(cfg.robot, f"{c.split('_')[0]}_serial").stance_range_m
        dims[c] = (-reach, reach)
    dims.update({c: ROLL_RANGE_DEG for c in searched_roll_columns(cfg)})
    if cart_search_columns(cfg):
        from surgopt.studies.port_place.tables import searched_pose_box

        dims.update(searched_pose_box(cfg.cart))
    return dims


def nearest_sites(sites_xy_mm: np.ndarray, aims_mm: np.ndarray) -> np.ndarray:
    """The candidate site nearest each top-view point (rows of ``aims_mm``, (x, y) mm): its index."""
    d = ((aims_mm[:, None, :] - sites_xy_mm[None, :, :]) ** 2).sum(axis=2)
    return d.argmin(axis=1)


def evaluate_designs(cfg, x: np.ndarray, ids: np.ndarray, source: str) -> dict:
    """Rows of any designs (rows of ``x``: every arm's site number, ``arms_of``, or with ``search_ports =
    "surface"`` every arm's top-view point (x, y mm, taken to the nearest candidate site), then each instrument's
    docking yaw and pitch in deg when free), each from its own ports docked as given: the per-port and per-pair tables
    of those ports (``port_tables``), combined as the enumeration combines them (its design 0 is the ports in
    this order), with the cart's dock tables of those ports when the run has a cart. A design whose ports coincide
    is infeasible (zero spacing and clearance)."""
    from surgopt.kinematics.port import place as K
    from surgopt.kinematics.port.designs import design_columns

    ports = len(arms_of(cfg))
    x = np.asarray(x, dtype=np.float64).reshape(len(ids), -1)
    model = model_of(cfg)  # its grid's tables are not built: a design builds the tables of its own ports
    all_sites, crit, centre = model.sites_m, model.criteria, model.centre_m
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
    roll_cols = [col[c] for c in searched_roll_columns(cfg) if c in col]  # a trial's rolls (deg, per PSM)
    cart = has_cart(cfg)  # the grid's dock tables (every site, every cart pose), each design's sites
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
        # the docking frames tilted by the design's yaw and pitch (an RCM arm), or each serial base turned by its yaw
        rot, base_yaw = model.instruments.turned(K.docking_frames(sites, centre, LATERAL), docking)
        outside = K.external_clearances(sites, np.ascontiguousarray(rot[:, :, 2]), outside_length_m(cfg))
        rolls = np.radians([*v[roll_cols], 0.0]) if roll_cols else None  # each port's, the ECM's 0
        frames = rolled(rot, rolls) if roll_cols else None
        tables = (None if not cart else searched_dock(model, site_ids, pose, frames) if pose is not None
                  else cart_of_sites(model.dock, site_ids) if frames is None
                  else redocked(model, cart_of_sites(model.dock, site_ids), site_ids, frames))
        t, _, _ = port_tables(model_r, sites, rot, outside, base_yaw_rad=base_yaw, dock=tables, rolls_rad=rolls)
        local, f, bad, cost, _, dock = design_columns(t, crit, 0, 1, ports - 1)
        out.append(design_rows(cfg, sites, t, local, site_ids[None, :], f, bad, cost,
                               np.asarray(ids[r:r + 1], dtype=np.int64), docking[None, :],
                               v[None, port_cols] if surface else None,
                               stance[None, :] if stances else None,
                               dock=dock if cart else None, floor=tables.poses.floor if cart else None,
                               dock_tables=tables if cart else None,
                               cart_searched=np.array([[pose[c] for c in searched]]) if searched else None))
    return concat_rows(out)


def evaluate_at_ports(cfg: PortPlaceConfig, ports_mm: np.ndarray, design_id: int = -1) -> dict:
    """(#58, the engine's first part) The row of one layout whose ports are any points (``ports_mm``, (arms, 3),
    ``arms_of``'s order, patient frame): the grid's own tables built for those ports alone, as if they were the
    candidate sites (a ``PortModel`` whose sites are the ports: their per-port and per-pair tables, their cart's dock
    tables at every pose of the grid and their links), combined by the design kernel as design 0 of that grid. At
    candidate sites it is the enumeration's row (tested, every column but the site numbers, here -1). What a
    perturbed layout (a port moved on the skin) is evaluated with; ~0.1 s a layout. Docked at the config's own
    docking turn (one docking: a list of rolls is refused, ``model.prepare``)."""
    import dataclasses

    from surgopt.kinematics.port import place as K
    from surgopt.kinematics.port.designs import design_columns
    from surgopt.studies.port_place.tables import dock_tables

    arms = arms_of(cfg)
    ports = np.asarray(ports_mm, float).reshape(len(arms), 3) / 1000
    model = model_of(cfg)
    own = dataclasses.replace(model, sites_m=ports, rot=K.docking_frames(ports, model.centre_m, LATERAL))
    rot, base_yaw = model.instruments.turned(own.rot, np.zeros(2 * (len(arms) - 1)))
    outside = K.external_clearances(ports, np.ascontiguousarray(rot[:, :, 2]), outside_length_m(cfg))
    cart = has_cart(cfg)
    dock = dock_tables(own) if cart else None
    t, _, _ = port_tables(own, ports, rot, outside, base_yaw_rad=base_yaw, dock=dock)
    local, f, bad, cost, _, docked = design_columns(t, model.criteria, 0, 1, len(arms) - 1)
    return design_rows(cfg, ports, t, local, np.full((1, len(arms)), -1, np.int64), f, bad, cost,
                       np.array([design_id], np.int64), np.zeros((1, 2 * (len(arms) - 1))),
                       dock=docked if cart else None, floor=dock.poses.floor if cart else None,
                       dock_tables=dock if cart else None)


def searched_docking(cfg: PortPlaceConfig) -> bool:
    """Whether a run's trials dock each RCM instrument in frames of their own (a [search]'s docking yaw and pitch,
    ``robot.docking_range_deg`` > 0, or its rolls, ``docking_roll = 'search'``), not the grid's at its sites."""
    return instruments_held(cfg).docks_in_own_frames(cfg)


def searched_dock(model, site_ids: np.ndarray, pose: dict, rot=None):
    """The dock tables of a design's own ports at its own searched cart pose (``pose``: the pose's dimensions,
    ``tables.searched_values``): one pose, at which no arm docks (nothing solved) when the cart's origin would
    stand within ``clear_of_table_mm`` of the table; ``rot``: the instruments' frames at the ports when not the
    model's (a search's rolls)."""
    from surgopt.kinematics.port.designs import pack_bits
    from surgopt.studies.port_place.tables import DockTables, dock_at, floor_pose, off_table, poses_of

    cfg = model.cfg
    floor = np.array([floor_pose(cfg, *pose.values())])
    poses = poses_of(cfg.cart, floor)
    if off_table(cfg.cart, floor)[0]:
        return dock_at(model, site_ids, poses, rot)
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
