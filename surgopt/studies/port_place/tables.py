"""port-place's tables, built from the prepared model (``model.py``: ``prepare``, ``PortModel``): the per-port and
per-pair tables of a docking (``port_tables``: reach and isotropy per site and point, the pairs' angles, the camera's
views, the links' tables with the cart), the cart's dock tables (which setup joints dock which arm at which site and
cart pose, ``dock_tables``), and one layout's docked arms (``docked_arms``: its setup joints solved by the same batch
solvers the dock tables use, for the views through ``layout.py``).

One module of ~560 lines: the per-port tables and the cart's dock tables are built together (a dock table reads the
model's rolled docking frames; the grid's tables read the dock tables), and the docked arms of one layout are
solved the way the tables were.

Equations: the docking frame (shaft through the target's centre, the frame's x as near the patient's lateral
axis as the shaft allows) is ``kinematics.port.place.docking_frames``; reach is the RCM inverse of
``rcm_point`` within ``ArmLimits`` (docs/port_placement.md, "Reach"); the pair tables are
``kinematics.port.place.pair_tables`` (manipulation angle, Hanna et al. 1997); the wrist margin below is the
approach cone's test of ``instrument_tables``.
"""
from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from surgopt.robots.dvrk.platforms import PLATFORMS, platform_of, role_of

from surgopt.robots import dvrk
from surgopt.robots.dvrk.suj import INSTRUMENT_SUJS
from surgopt.studies.port_place.carts import (LATERAL, cart_for, given_turns_rad, patient_in_cart,  # noqa: F401
                                              roll_sides, rolled, row_patient_in_cart, si_frames)
from surgopt.studies.port_place.arms import (RcmCamera, RcmInstruments, arm_limits,  # noqa: F401 (theirs)
                                             camera_held, instrument_limits, instrument_reach, instruments_held,
                                             reach_offsets_m)
from surgopt.studies.port_place.config import PortPlaceConfig, Target, camera_arm_of, instrument_of

#: Every ``model`` argument below is the prepared model (``model.PortModel``, built by ``model.prepare``).

#: The patient's lateral axis (x): each docking frame's x is turned as near it as the shaft allows.


#: The rolls about the shaft a 'most_reach' docking tries at each port (deg).
ROLL_CHOICES_DEG = (0.0, 15.0, 30.0, 45.0, 60.0, 75.0, 90.0)


def instrument_rolls_rad(model, sites: np.ndarray, rot: np.ndarray) -> np.ndarray:
    """Each port's docking roll (rad, signed by ``roll_sides``): ``robot.docking_roll_deg`` (on the patient's right
    ``docking_roll_right_deg`` when given), or with
    ``docking_roll = 'most_reach'`` the one of ``ROLL_CHOICES_DEG`` whose frame reaches the most target points
    (``instrument_tables``; ties: the choice nearest docking_roll_deg, then the smaller)."""
    r = model.cfg.robot
    side = roll_sides(sites)
    if r.docking_roll in ("given", "search") or not model.instruments.rolls:  # a search's trials give their own
        return given_turns_rad(model.cfg, sites)  # on the Si, the yaw off psi* (``carts.SiCart``)
    choices = np.array(ROLL_CHOICES_DEG)
    counts = np.stack([instrument_reach(model, sites, rolled(rot, np.radians(c) * side))[0].sum(axis=1)
                       for c in choices], axis=1)
    order = np.argsort(np.abs(choices - r.docking_roll_deg), kind="stable")
    return np.radians(choices[order[np.argmax(counts[:, order], axis=1)]]) * side


def in_degrees(rolls_rad: np.ndarray) -> np.ndarray:
    """Docking rolls as the rows and the export give them: deg to 1e-9 (30, not 29.99..96), never -0."""
    return np.round(np.degrees(rolls_rad), 9) + 0.0


def instrument_frames(model, sites: np.ndarray, rot: np.ndarray, rolls_rad=None) -> np.ndarray:
    """The instrument arms' docking frames at ``sites``: the frames ``rot`` turned by each port's roll
    (``rolls_rad``, else ``instrument_rolls_rad``), or the cart's own (``carts``: the Si's at psi*)."""
    rolls = instrument_rolls_rad(model, sites, rot) if rolls_rad is None else rolls_rad
    return cart_for(model.cfg).instrument_frames(model, sites, rot, rolls)


def third_frames(model, sites: np.ndarray) -> np.ndarray | None:
    """The third instrument's docking frames at ``sites`` where they are not PSM1's and PSM2's (the cart's:
    the Si PSM3 hangs 15 deg off the vertical, they 45); else None."""
    return cart_for(model.cfg).third_frames(model, sites)


def approach(target: Target, wrist_bend_rad: float):
    """The target's approach cone for the kernel (``place.Approach``): a point is reached only where the
    shaft's direction from the port lies within (wrist bend - half-angle) of the approach direction, so that the
    wrist can point the jaws along every direction of the cone; any direction when none is given."""
    from surgopt.kinematics.port.place import Approach

    if target.approach_direction is None:
        return Approach(0.0, 0.0, -1.0, -2.0)  # a cosine below -1: every shaft direction passes
    d = np.asarray(target.approach_direction, float)
    d = d / np.linalg.norm(d)
    return Approach(*d, math.cos(wrist_bend_rad - math.radians(target.approach_half_angle_deg)))


def camera_of(cfg: PortPlaceConfig):
    """The endoscope for the kernels (``place.Camera``), its mechanism's ranges as the config's arm holds it
    (a serial arm's open: its own IK decides, ``arms.SerialCamera``)."""
    from surgopt.kinematics.port.place import Camera

    r = cfg.robot
    limits = camera_held(cfg).limits(cfg)
    return Camera(limits, math.radians(r.camera_fov_deg) / 2,
                  r.camera_standoff_mm / 1000, r.camera_range_mm[0] / 1000, r.camera_range_mm[1] / 1000,
                  math.radians(r.camera_scope_angle_deg), r.camera_scope_view == "down")


def criteria(cfg: PortPlaceConfig):
    """The kernels' ``Criteria``: the constraints and the objective's weights, in radians and metres."""
    from surgopt.kinematics.port.place import Criteria

    k, o = cfg.constraints, cfg.objective
    lo, hi = (math.radians(v) for v in k.manipulation_angle_deg)
    return Criteria(k.dexterity_length_m, lo, hi, math.radians(60.0), k.tip_zone_mm / 1000,
                    (k.shaft_diameter_mm + k.min_shaft_clearance_mm) / 1000, k.min_external_clearance_mm / 1000,
                    outside_length_m(cfg), k.min_port_spacing_mm / 1000, o.reach, o.angle, o.azimuth, o.camera,
                    o.dexterity)


def outside_length_m(cfg: PortPlaceConfig) -> float:
    """The outside segment of the instruments' external clearance: the instrument arm's own
    (``RcmArm.outside_length_m``; issue 53: the Classic's 0.4318 m was applied to the Si PSM, whose row gives
    0.4826 m), or the Classic's for a serial arm (its links are measured themselves)."""
    return instruments_held(cfg).outside_length_m(cfg)


def wrist_margin_deg(model, sites: np.ndarray) -> np.ndarray:
    """Per port (``sites``, m): how far the instrument's wrist could still turn the jaws at the worst target point,
    wrist bend - cone half-angle - the angle between the shaft (port to point) and the approach direction, least
    over the target's points (deg; negative: the cone is out of the wrist's reach there by that much). Without an
    approach direction no point asks anything of the wrist: the margin is its whole bend."""
    bend = math.degrees(instrument_of(model.cfg).wrist_bend_rad)
    t = model.cfg.target
    if t.approach_direction is None:
        return np.full(len(sites), bend)
    a = np.asarray(t.approach_direction, float) / np.linalg.norm(t.approach_direction)
    shafts = model.targets_m[None, :, :] - sites[:, None, :]
    cos = np.clip(shafts @ a / np.linalg.norm(shafts, axis=2), -1.0, 1.0)
    return bend - t.approach_half_angle_deg - np.degrees(np.arccos(cos)).max(axis=1)


def port_tables(model, sites: np.ndarray, rot: np.ndarray, outside=None, base_yaw_rad=None, dock=None,
                rolls_rad=None):
    """(``PortTables``, reach, isotropy) of ports ``sites`` (m) docked in frames ``rot``; ``outside``: the arms'
    external clearances when the docking is not the default (``external_clearances``); ``base_yaw_rad``: a serial
    instrument arm's base turned further at each port (a search's free docking); ``dock``: the cart's
    ``DockTables`` of these sites (None: no cart, every arm docks); ``rolls_rad``: each port's roll about its
    shaft (a search's, ``docking_roll = 'search'``; else the config's, ``instrument_rolls_rad``)."""
    from surgopt.kinematics.port import designs as D
    from surgopt.kinematics.port import place as K

    cfg, targets, centre, crit, camera = model.cfg, model.targets_m, model.centre_m, model.criteria, model.camera
    rolls = instrument_rolls_rad(model, sites, rot) if rolls_rad is None else rolls_rad  # the instruments'
    # frames (``instrument_frames``), once
    frames = instrument_frames(model, sites, rot, rolls)
    reach, dex, outside_held, serial = model.instruments.reach(model, sites, frames, base_yaw_rad)
    if outside_held is not None:  # a serial arm: its links' clearance outside
        outside = outside_held
    coverage = K.camera_coverage(sites, rot, targets, centre, camera)
    views = K.camera_views(sites, rot, centre, camera)  # the scope's tip and view at each port (eq. P10)
    held = model.endoscope.hold(model, sites, views)  # a serial arm's: placed by its IK
    if held is not None:
        coverage = np.where(held.placed, coverage, 0.0)
    pairs = list(K.pair_tables(sites, reach, dex, targets, centre, crit))
    if outside is not None:
        pairs[-1] = outside
    outside_camera = camera_clearances(sites, rot, pairs[-1], serial, held)
    if camera.scope_angle_rad == 0.0:  # the optical axis: port to centre
        azimuth, side = K.camera_pair_tables(sites, centre, LATERAL)
    else:  # along the angled scope's view, through the centre
        azimuth, side = K.camera_pair_tables(sites, centre, LATERAL, views[1])
    spacing = np.linalg.norm(sites[:, None, :] - sites[None, :, :], axis=2)
    tables = D.PortTables(reach.sum(axis=1).astype(np.int64), coverage, *pairs, spacing, azimuth, side,
                          len(targets), D.reach_bits(reach), D.site_dexterity(reach, dex),
                          wrist_margin_deg(model, sites), outside_camera,
                          *((dock.bits, dock.camera) if dock is not None else no_cart(len(sites))),
                          roll_deg=in_degrees(rolls), **camera_tip_tables(sites, centre, views, held))
    third = third_frames(model, sites)
    if third is not None:  # the third instrument's reach in frames of its own (the Si PSM3)
        reach3, dex3 = instrument_reach(model, sites, third)
        tables = tables._replace(third_reach_count=reach3.sum(axis=1).astype(np.int64),
                                 third_reach_bits=D.reach_bits(reach3), third_dex_site=D.site_dexterity(reach3, dex3))
    if links_decide(cfg) and dock is not None and dock.joints is not None:
        tables = with_links(model, tables, sites, frames, dock, third)
    return tables, reach, dex


def camera_tip_tables(sites: np.ndarray, centre: np.ndarray, views, held=None) -> dict:
    """Per port: the endoscope's tip (``camera_views``) as its depth past the RCM along the shaft and its distance
    to the target's centre, mm, the tip itself (m) and its view axis; NaN where the scope cannot be placed (or a
    serial arm cannot hold it, ``held``)."""
    tips, axes, ok = views
    if held is not None:
        ok = ok & held.placed
    depth = np.where(ok, np.linalg.norm(tips - sites, axis=1) * 1000, np.nan)
    return {"camera_tip_depth_mm": depth,
            "camera_tip_to_centre_mm": np.where(ok, np.linalg.norm(centre - tips, axis=1) * 1000, np.nan),
            "camera_tip_m": np.where(ok[:, None], tips, np.nan), "camera_axis": np.where(ok[:, None], axes, np.nan)}


def camera_tips(model, sites: np.ndarray) -> dict:
    """``camera_tip_tables`` of ports ``sites`` (m) docked as the grid docks the camera: what a view of one
    layout (its export) reads, from the kernel the rows use."""
    from surgopt.kinematics.port import place as K

    frames = K.docking_frames(sites, model.centre_m, LATERAL)
    return camera_tip_tables(sites, model.centre_m, K.camera_views(sites, frames, model.centre_m, model.camera))


def links_decide(cfg: PortPlaceConfig) -> bool:
    """Whether the arms' links outside the body are in the rows' feasible: with the cart and
    ``constraints.min_link_clearance_mm`` not 'off' (a run stored before it was the default: None)."""
    return cart_for(cfg).docks and cfg.constraints.link_least_mm is not None


def with_links(model, tables, sites: np.ndarray, rot: np.ndarray, dock, third_rot=None):
    """The design kernel's tables with the arms' link clearance tables (``link_tables``) of these sites
    (``third_rot``: the third PSM's frames where they are its own, ``third_frames``)."""
    from surgopt.studies.port_place.link_tables import link_tables, wanted_of

    got = link_tables(model, sites, rot, dock, wanted_of(tables, model.criteria), third_rot)
    pairs = sorted(got.value)
    return tables._replace(link_words=np.stack([got.words[p] for p in pairs]),
                           link_value=np.stack([got.value[p] for p in pairs]),
                           link_code=np.stack([got.code[p] for p in pairs]), arm_words=got.arm_words,
                           arm_value=got.arm_value, arm_code=got.arm_code)


def no_cart(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Dock bits with no cart: one pose, at which every arm docks at every site."""
    ones = np.ones((n, 1), np.uint64)
    return np.stack([ones] * 3), ones


def camera_clearances(sites: np.ndarray, rot: np.ndarray, outside: np.ndarray, serial=None, held=None):
    """[instrument port, camera port]: the two arms' clearance outside the body, each arm its shaft line behind
    its port (``outside``, the instruments' pair table, i < j), or a serial arm's centre line (``serial``: the
    instruments' ``SerialTables``, ``held``: the camera's ``SerialCamera``)."""
    from surgopt.kinematics.port import serial as S

    if serial is None and held is None:
        return outside + outside.T
    if serial is not None and held is not None:
        return S.polyline_clearances(serial.links, held.links)
    axes = np.ascontiguousarray(rot[:, :, 2])
    if held is None:
        return S.link_camera_clearances(serial.links, sites, axes, dvrk.OUTSIDE_LENGTH_M)
    return S.link_camera_clearances(held.links, sites, axes, dvrk.OUTSIDE_LENGTH_M).T


# ---- the patient cart (issue 40): where it stands, and which of its setup joints dock which arm at which port


class CartPoses(NamedTuple):
    """The cart's poses a config explores: ``floor`` (m, 3): its origin (x, y mm, the patient's floor frame) and
    heading (deg, from +y toward +x) each; ``patient`` (m, 4, 4): the patient's frame in the cart's world frame
    there (metres), the table's height and tilts applied."""

    floor: np.ndarray
    patient: np.ndarray



def footprint_corners_mm(cart, floor: np.ndarray) -> np.ndarray:
    """(n, 4, 2) The corners of the cart's base on the floor (mm, the patient's floor frame) at each pose of ``floor``
    (n, 3: x, y mm, heading deg from +y toward +x): its platform's ``footprint_m`` turned by the heading."""
    (x0, y0), (x1, y1) = platform_of(cart.model).footprint_m
    local = np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]]) * 1000
    h = np.radians(np.asarray(floor, float)[:, 2])
    c, s = np.cos(h), np.sin(h)
    # the cart's +y is the heading's direction (``patient_in_cart``: its frame is Rz(-heading) on the floor)
    x = floor[:, None, 0] + c[:, None] * local[None, :, 0] + s[:, None] * local[None, :, 1]
    y = floor[:, None, 1] - s[:, None] * local[None, :, 0] + c[:, None] * local[None, :, 1]
    return np.stack([x, y], axis=2)


def _to_box(points: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """The distance of each point (..., 2) to the axis-aligned rectangle [lo, hi] (0 inside)."""
    d = np.maximum(np.maximum(lo - points, points - hi), 0.0)
    return np.hypot(d[..., 0], d[..., 1])


def footprint_gap_mm(cart, floor: np.ndarray) -> np.ndarray:
    """(n,) The least distance on the floor (mm) between the cart's base (``footprint_corners_mm``) and the table
    top's outline (|x| <= table_half_width_mm, y within table_y_mm) at each pose; 0 where they overlap (separating
    axes: the table's two and the base's two). Two disjoint convex outlines are nearest at a corner of one."""
    corners = footprint_corners_mm(cart, floor)
    lo = np.array([-cart.table_half_width_mm, cart.table_y_mm[0]])
    hi = np.array([cart.table_half_width_mm, cart.table_y_mm[1]])
    table = np.array([[lo[0], lo[1]], [hi[0], lo[1]], [hi[0], hi[1]], [lo[0], hi[1]]])
    gap = _to_box(corners, lo, hi).min(axis=1)  # the base's corners to the table
    # the table's corners to the base, in the base's own frame (an axis-aligned rectangle there)
    (x0, y0), (x1, y1) = platform_of(cart.model).footprint_m
    h = np.radians(np.asarray(floor, float)[:, 2])
    c, s = np.cos(h), np.sin(h)
    dx, dy = table[None, :, 0] - floor[:, None, 0], table[None, :, 1] - floor[:, None, 1]
    local = np.stack([c[:, None] * dx - s[:, None] * dy, s[:, None] * dx + c[:, None] * dy], axis=2)
    gap = np.minimum(gap, _to_box(local, np.array([x0, y0]) * 1000, np.array([x1, y1]) * 1000).min(axis=1))
    # overlap: no separating axis among the four
    axes = np.stack([np.broadcast_to([1.0, 0.0], (len(h), 2)), np.broadcast_to([0.0, 1.0], (len(h), 2)),
                     np.stack([c, -s], axis=1), np.stack([s, c], axis=1)], axis=1)  # (n, 4, 2)
    a = np.einsum("nkd,nvd->nkv", axes, corners)
    b = np.einsum("nkd,vd->nkv", axes, table)
    separated = (a.max(axis=2) < b.min(axis=2)) | (b.max(axis=2) < a.min(axis=2))
    return np.where(separated.any(axis=1), gap, 0.0)


def off_table(cart, floor: np.ndarray) -> np.ndarray:
    """Whether the cart at each pose of ``floor`` (n, 3: x, y mm, heading deg) stands with its base at least
    ``clear_of_table_mm`` from the table top's outline on the floor (``footprint_gap_mm``; issue 54: the base from
    its own mesh, not its origin; the base is not let under the table, whose pedestal is not modelled)."""
    return footprint_gap_mm(cart, np.asarray(floor, float).reshape(-1, 3)) >= cart.clear_of_table_mm


def floor_pose(cfg: PortPlaceConfig, around_deg: float, distance_mm: float, offset_deg: float) -> list[float]:
    """[x, y, heading] of the cart on the arc around the target: ``around_deg`` from the patient's feet toward
    their left, ``distance_mm`` from the target's centre (horizontal), facing the centre turned by ``offset_deg``."""
    cx, cy = cfg.target.centre_mm[0], cfg.target.centre_mm[1]
    x, y = cx + distance_mm * math.sin(math.radians(around_deg)), cy - distance_mm * math.cos(math.radians(around_deg))
    facing = math.degrees(math.atan2(cx - x, cy - y))  # from +y toward +x
    return [x, y, facing + offset_deg]


def searched_pose_box(cart) -> dict:
    """A [search]'s cart dimensions (``cart.pose = "search"``): each of around_deg, distance_mm and the range of
    yaw_offsets_deg that spans more than a point, with its bounds."""
    box = {"cart_around_deg": tuple(cart.around_deg), "cart_distance_mm": tuple(cart.distance_mm),
           "cart_yaw_offset_deg": (min(cart.yaw_offsets_deg), max(cart.yaw_offsets_deg))}
    return {k: (float(lo), float(hi)) for k, (lo, hi) in box.items() if hi > lo}


def searched_middle(cart) -> dict:
    """The middle of a searched cart pose's three ranges, in ``floor_pose``'s order (around, distance, offset)."""
    return {"cart_around_deg": sum(cart.around_deg) / 2, "cart_distance_mm": sum(cart.distance_mm) / 2,
            "cart_yaw_offset_deg": (min(cart.yaw_offsets_deg) + max(cart.yaw_offsets_deg)) / 2}


def cart_poses(cfg: PortPlaceConfig) -> CartPoses:
    """The given pose, or the grid's poses that stand clear of the table (in the grid's order: around, then
    distance, then heading offset); a searched pose (``pose = "search"``): the search box's middle (each trial
    docks at its own, ``dock_at``)."""
    cart = cfg.cart
    if cart.pose == "given":
        floor = np.array([[cart.x_mm, cart.y_mm, cart.heading_deg]])
    elif cart.pose == "search":
        floor = np.array([floor_pose(cfg, *searched_middle(cart).values())])
    else:
        floor = grid_on_floor(cfg)[1]
    return poses_of(cart, floor)


def grid_places(cfg: PortPlaceConfig) -> np.ndarray:
    """(P, 3) The grid's places before the table's clearance is applied: around (deg), distance (mm), heading offset
    (deg), in the grid's order (``cart_poses``)."""
    cart = cfg.cart
    around = np.arange(cart.around_deg[0], cart.around_deg[1] + 1e-9, cart.around_step_deg)
    distance = np.arange(cart.distance_mm[0], cart.distance_mm[1] + 1e-9, cart.distance_step_mm)
    return np.array([(a, d, off) for a in around for d in distance for off in cart.yaw_offsets_deg], float)


def grid_on_floor(cfg: PortPlaceConfig) -> tuple[np.ndarray, np.ndarray]:
    """(places, floor poses) of the grid's places that stand clear of the table, in ``cart_poses``' order: each
    place's (around deg, distance mm, heading offset deg) and its floor pose (x, y mm, heading deg)."""
    grid = grid_places(cfg)
    floor = np.array([floor_pose(cfg, *g) for g in grid])
    clear = off_table(cfg.cart, floor)
    return grid[clear], floor[clear]


def grid_place_of_pose(cfg: PortPlaceConfig) -> np.ndarray:
    """(poses, 3) Each grid pose's (around deg, distance mm, heading offset deg), as ``cart_poses`` numbers them."""
    return grid_on_floor(cfg)[0]


def poses_of(cart, floor: np.ndarray) -> CartPoses:
    """``CartPoses`` of floor poses (m, 3: x, y mm, heading deg)."""
    return CartPoses(floor, np.array([patient_in_cart(cart, *f) for f in floor]).reshape(-1, 4, 4))




class DockTables(NamedTuple):
    """Which setup joint docks which arm at which site: ``bits`` (arms, sites, words) uint64, bit p of a site's
    words set when that arm's SUJ has a solution within its ranges at cart pose p (PSM1, PSM2, PSM3); ``camera``
    (sites, words): the ECM's; ``margin`` (arms, sites, poses) and ``camera_margin`` (sites, poses): the best
    solution's least range margin there (rad or m; -inf: none in reach); the poses."""

    bits: np.ndarray
    camera: np.ndarray
    margin: np.ndarray
    camera_margin: np.ndarray
    poses: CartPoses
    joints: np.ndarray | None = None  # (arms, sites, poses, 6): that best solution's joints (NaN: none)
    camera_joints: np.ndarray | None = None  # (sites, poses, 6): the ECM's
    camera_aim: np.ndarray | None = None  # (sites, poses, 2): the ECM's own yaw and pitch there (rad)


def base_pose(rot: np.ndarray, site_m: np.ndarray) -> np.ndarray:
    """(4, 4) An arm's base frame in the patient's frame: its docking rotation at its port."""
    t = np.eye(4)
    t[:3, :3], t[:3, 3] = rot, site_m
    return t


def dock_tables(model) -> DockTables:
    """Every arm's setup joints at every site and cart pose, as bits and margins: each instrument arm's best
    solution's least margin (``kinematics.port.suj_batch``, S2 jitted over every (site, pose); its docking frame the
    rolled one, ``PortModel.instrument_rot``) and the ECM's (``camera_dock``); with no cart, one pose at which
    everything docks."""
    cfg = model.cfg
    n = len(model.sites_m)
    if not cart_for(cfg).docks:
        bits, camera = no_cart(n)
        return DockTables(bits, camera, np.zeros((3, n, 1)), np.zeros((n, 1)), CartPoses(np.zeros((1, 3)),
                                                                                        np.eye(4)[None]))
    return dock_at(model, np.arange(n), cart_poses(cfg))


def dock_at(model, site_ids: np.ndarray, poses: CartPoses, rot=None) -> DockTables:
    """``dock_tables`` of some candidate sites (``site_ids``, in that order: a design's own ports) at some cart
    poses (a searched pose: one); ``rot``: the instruments' frames at those sites when not the model's (a
    search's rolls)."""
    from surgopt.kinematics.port.designs import pack_bits

    m, n = len(poses.floor), len(site_ids)
    margin, joints = psm_docks(model, site_ids, poses, rot)
    camera, camera_joints, aim = camera_dock(model.cfg, poses.patient, model.sites_m[site_ids])
    camera = camera.reshape(m, n).T
    return DockTables(pack_bits(margin >= 0.0), pack_bits(camera >= 0.0), margin, camera, poses,
                      np.where((margin >= 0.0)[..., None], joints, np.nan),
                      np.where((camera >= 0.0)[..., None], camera_joints.reshape(m, n, 6).transpose(1, 0, 2), np.nan),
                      aim.reshape(m, n, 2).transpose(1, 0, 2))


def psm_docks(model, site_ids: np.ndarray, poses: CartPoses, rot=None) -> tuple[np.ndarray, np.ndarray]:
    """Each instrument arm's setup joints at each of ``site_ids`` and ``poses``, docked in the model's frames there
    or ``rot`` (one per site): (the best solution's least margin (3, n, m), -inf where none; its joints (3, n, m,
    6), the Si's four or five then NaN)."""
    cfg = model.cfg
    cart = cart_for(cfg)
    arms = INSTRUMENT_SUJS[:cfg.robot.instrument_count]
    n, m = len(site_ids), len(poses.floor)
    sites = model.sites_m[site_ids]
    margin = np.full((3, n, m), -np.inf)
    joints = np.full((3, n, m, 6), np.nan)

    def in_cart(frames):
        bases = np.zeros((n, 4, 4))
        bases[:, :3, :3], bases[:, :3, 3], bases[:, 3, 3] = frames, sites, 1.0
        return np.ascontiguousarray(np.einsum("pij,njk->npik", poses.patient, bases).reshape(n * m, 4, 4))

    frames = model.instrument_rot[site_ids] if rot is None else rot
    shared = in_cart(frames)
    for a, arm in enumerate(arms):  # the best solution's least margin (suj_answer's first), every site and pose
        own = a == 2 and model.third_rot is not None
        third = in_cart(model.third_rot[site_ids]) if own else None
        got, q = cart.psm_solutions(arm, shared, third)
        margin[a], joints[a] = got.reshape(n, m), q.reshape(n, m, 6)
        if cfg.cart.mount_below_table_top == "refuse":  # the mount's height does not depend on the cart's pose
            low = mount_heights_m(cfg, arm, model.third_rot[site_ids] if own else frames, sites) < 0.0
            margin[a, low], joints[a, low] = -np.inf, np.nan
    return margin, joints


def mount_heights_m(cfg: PortPlaceConfig, arm: str, frames: np.ndarray, sites_m: np.ndarray) -> np.ndarray:
    """(n,) The height over the table top (the patient frame's z, m) of PSM ``arm``'s mount (its setup joints' last
    frame, where its own links begin) when its base (the RCM) is docked in ``frames`` (n, 3, 3) at ``sites_m`` (n,
    3): the base times the inverse of SUJ_tip_to_tool_origin, whatever the cart's pose (the base is fixed in the
    patient's frame)."""
    back = np.linalg.inv(np.asarray(PLATFORMS[cfg.cart.model].suj(arm).tip_to_tool, float))[:3, 3]
    return sites_m[:, 2] + frames[:, 2, :] @ back


def redocked(model, dock: DockTables, site_ids: np.ndarray, rot: np.ndarray) -> DockTables:
    """``dock`` (the dock tables of ``site_ids``) with the instruments' setup joints solved again in frames ``rot``
    (a search's rolls, one per site); the ECM's, which do not depend on them, kept."""
    from surgopt.kinematics.port.designs import pack_bits

    margin, joints = psm_docks(model, site_ids, dock.poses, rot)
    return dock._replace(bits=pack_bits(margin >= 0.0), margin=margin,
                         joints=np.where((margin >= 0.0)[..., None], joints, np.nan))


def suj_margins(cfg: PortPlaceConfig, dock: DockTables) -> tuple[np.ndarray, np.ndarray]:
    """(revolute deg, column mm), each (4, sites, poses): the least margin to their ranges of PSM1's, PSM2's,
    PSM3's and the ECM's setup joints at the best solution the dock tables kept (NaN where the arm does not
    dock): the revolute joints' in degrees and the column's in millimetres apart, not one number of two units."""

    joints = np.concatenate([dock.joints, dock.camera_joints[None]])  # (4, n, m, 6)
    sujs = [PLATFORMS[cfg.cart.model].suj(a) for a in (*INSTRUMENT_SUJS, "ECM")]
    ranges = np.stack([np.asarray(s.ranges + ((-np.inf, np.inf),) * (6 - len(s.ranges)), float) for s in sujs])
    lo, hi = ranges[:, None, None, :, 0], ranges[:, None, None, :, 1]
    margin = np.minimum(joints - lo, hi - joints)
    jointed = np.arange(6) < np.array([len(s.links) for s in sujs])[:, None]  # (4, 6): the Si has four joints
    margin = np.where(jointed[:, None, None, :], margin, np.inf)
    return np.degrees(margin[..., 1:].min(axis=-1)), margin[..., 0] * 1000


def camera_shafts(camera, centre_m: np.ndarray, sites_m: np.ndarray) -> np.ndarray:
    """(n, 3) The endoscope's shaft direction at each port (patient frame): toward the target's centre, or an
    angled scope's shaft (``camera_views``' tip)."""
    from surgopt.kinematics.port import place as K

    if camera.scope_angle_rad == 0.0:
        d = centre_m - sites_m
    else:
        tips, _, _ = K.camera_views(sites_m, K.docking_frames(sites_m, centre_m, LATERAL), centre_m, camera)
        d = tips - sites_m
    return d / np.linalg.norm(d, axis=1)[:, None]


def camera_dock(cfg: PortPlaceConfig, patient: np.ndarray, sites_m: np.ndarray):
    """The ECM's setup joints at ports ``sites_m`` (n, 3) with the patient at ``patient`` (4, 4, or (m, 4, 4):
    each cart pose) in the cart's world frame (``kinematics.port.suj_batch.ecm_margins``, S4: its own yaw and pitch
    aim the scope's shaft): (margin, SUJ joints, ECM yaw and pitch) per port (per pose, then port)."""
    arm = camera_arm_of(cfg)
    centre = np.asarray(cfg.target.centre_mm, float) / 1000
    patients = patient.reshape(-1, 4, 4)
    shafts = camera_shafts(camera_of(cfg), centre, sites_m)
    return cart_for(cfg).camera_dock(cfg, arm, patients, sites_m, shafts)


class DockedArm(NamedTuple):
    """One arm of a layout on the cart: its SUJ's joints (m, rad; empty when none within the ranges), their least
    range margin, and a note (why none, or what is not checked)."""

    arm: str
    site: str
    joints: tuple
    margin: float | None  # rad, or m for the column
    tightest: str  # the joint of that margin
    note: str
    port_m: tuple
    base: np.ndarray | None  # the arm's base (RCM) frame in the cart's world frame
    ecm: tuple  # the ECM's yaw and pitch aiming the scope (empty for an instrument arm)
    roll_deg: float | None = None  # an instrument arm's docking roll about its neutral shaft (deg, x toward y)


def docked_arms(model, row: dict) -> list[DockedArm]:
    """Each arm of a layout's row (its ports, ``psm1_x_mm`` ..., and its cart pose, ``cart_x_mm`` ...) docked by
    the cart's setup joints: the best solution within the ranges (the largest least margin); the ECM's with its
    own yaw and pitch aiming the scope (``camera_dock``), in ``ecm``."""
    from surgopt.kinematics.port import place as K
    from surgopt.kinematics.port import suj as S

    cfg = model.cfg
    cart = cart_for(cfg)
    centre = np.asarray(cfg.target.centre_mm, float) / 1000
    patient = row_patient_in_cart(cfg, row)
    out = []
    for arm in ("psm1", "psm2", "psm3", "ecm"):
        if f"{arm}_site" not in row:
            continue
        site = np.array([row[f"{arm}_{c}_mm"] for c in "xyz"]) / 1000
        if arm == "ecm":
            margin, joints, aim = camera_dock(cfg, patient, site[None])
            if margin[0] >= 0:
                suj = cart.platform.suj("ECM")
                joints = joints[:, :len(suj.links)]
                base = S.forward(suj, joints[0])
                out.append(DockedArm("ECM", str(row["ecm_site"]), tuple(float(v) for v in joints[0]),
                                     float(margin[0]), "", "", tuple(site), base, tuple(float(v) for v in aim[0])))
            else:
                out.append(DockedArm("ECM", str(row["ecm_site"]), (), None, "", "no grid point of the ECM's setup "
                                     "joints docks it", tuple(site), None, ()))
            continue
        neutral = K.docking_frames(site[None], centre, LATERAL)
        roll = (np.radians([row[f"{arm}_roll_deg"]]) if cfg.robot.docking_roll == "search"  # the trial's
                else instrument_rolls_rad(model, site[None], neutral))  # as the tables (``instrument_frames``)
        third = third_frames(model, site[None]) if arm == "psm3" else None  # the Si PSM3's frame is its own
        frame = instrument_frames(model, site[None], neutral, roll)[0] if third is None else third[0]
        base = patient @ base_pose(frame, site)
        got = cart.psm_docking(role_of(arm), base)
        out.append(DockedArm(role_of(arm), str(row[f"{arm}_site"]), got.joints, got.margin,
                             got.tightest if got.joints else "", got.reason, tuple(site), base, (),
                             float(in_degrees(roll)[0])))
    return out
