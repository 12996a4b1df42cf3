"""The arms' links outside the body in every row (issue 40): for each pair of arms, at each pair of their sites and
each cart pose at which both dock, the least clearance between their links (``clashes``' capsules: the setup
joints' links and each arm's own), docked and over the target, factored as the issue asks:

- per site, each PSM's own links at the poses that reach the target (``own_moving``: its docked frame at the port
  does not depend on the cart's pose, so neither do they), bounded per link by a capsule (``capsules.swept_capsules``);
- per (arm, site, pose), its setup joints' links from the dock tables' best solution (``suj_static``), and the
  ECM held docked (its setup joints and its own links, ``ecm_static``);
- per (site pair), the two PSMs' own links over every pair of their poses (``capsules.moving_pairs``), once
  for every cart pose; per (site pair, pose) the rest (``capsules.pair_clearances``);
- per (arm, site, pose), each arm against the patient's body and the bedside (``arm_surroundings``: a PSM's own
  links once per site).

All in the patient's frame (the cart's pose moves the setup joints only). The tables are dense over (site, site,
pose) where both arms dock (NaN elsewhere), with each least's link pair, and packed as the design kernel's 64-pose
words of where the clearance is at least ``constraints.min_link_clearance_mm``. One layout's clearances
(``clashes``, for the views) place its links with the same functions (``placed_arm``); the tables are held to them,
computed directly over every pair of poses, and the placement to the reference kinematics, in
tests/test_link_tables.py.

One module of ~450 lines: each arm's links placed (static, moving), the pairs' and the surroundings' tables and
their packing are one computation read together, for either cart; its kernels are ``kinematics.port.capsules``'.
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np

# the setup joints' links checked: after the column and the arm's carriage on it, which are the cart's
# (``clashes.arm_poses``)
from surgopt.kinematics.port.capsules import LINK_CODE, PAIR_CODE
from surgopt.robots.dvrk.links import SUJ_ON_COLUMN as FIRST_SUJ_LINK, through_port
from surgopt.robots.dvrk.platforms import PLATFORMS
from surgopt.studies.port_place.bedside import BEDSIDE
from surgopt.studies.port_place.geometry import TABLE_THREADS

#: The arm pairs whose links are checked, in the order of the rows' ``external_link_pair`` code (PAIR_CODE * pair +
#: LINK_CODE * link of the first + link of the second: ``kinematics.port.capsules``).
ARM_PAIRS = (("PSM1", "PSM2"), ("PSM1", "ECM"), ("PSM2", "ECM"), ("PSM1", "PSM3"), ("PSM2", "PSM3"),
             ("PSM3", "ECM"))
#: Points along a link at most this far apart (m) where its clearance to the patient is measured.
SPACING_M = 0.01
#: Against the patient, clearances are resolved up to this (mm); a link farther off reads as this much.
PATIENT_CAP_MM = 150.0
#: Clearances are resolved up to this much above the config's least (m): a pair farther apart reads as that much
#: ("at least"); below the least, the search stops at the first overlap it finds (an upper bound: the layout
#: fails there whatever the exact least).
CAP_M = 0.1


class LinkTables(NamedTuple):
    """``value[pair]`` (sites, sites, poses) float32: the least clearance (m) between the pair's two arms (the
    first at the first index's site); ``code[pair]`` int16: its link pair (16 * first's link + second's); ``words``
    (sites, sites, pose words) uint64: where it is at least the config's least; ``names`` per arm its links."""

    value: dict
    code: dict
    words: dict
    names: dict
    # each arm (PSM1, PSM2, PSM3, ECM) against its surroundings (the patient's body, the table) at (site, pose):
    # the least clearance (m; NaN where it does not dock), LINK_CODE * link + (0 patient, 1 table), and the words
    arm_value: np.ndarray | None = None
    arm_code: np.ndarray | None = None
    arm_words: np.ndarray | None = None


#: The tables' kernels (each ``nogil``) run on ``geometry.TABLE_THREADS``; batches of fewer tasks than this
#: run inline (a task of ``capsules.pair_clearances`` takes microseconds; of ``moving_pairs``, ~0.5-1 ms: see its
#: call).
INLINE_TASKS = 4096


def in_threads(kernel, aligned: tuple, *rest, inline: int = INLINE_TASKS) -> tuple:
    """``kernel(*aligned, *rest)`` over ``TABLE_THREADS`` slices of the row-aligned arrays ``aligned`` (fewer
    than ``inline`` rows: one call), the outputs (row-aligned arrays) joined in order: the same answer as one
    call."""
    n = len(aligned[0])
    if TABLE_THREADS == 1 or n < inline:
        return kernel(*aligned, *rest)
    from concurrent.futures import ThreadPoolExecutor

    cuts = np.linspace(0, n, TABLE_THREADS + 1).astype(int)
    with ThreadPoolExecutor(TABLE_THREADS) as pool:
        outs = list(pool.map(lambda k: kernel(*(a[cuts[k]:cuts[k + 1]] for a in aligned), *rest),
                             range(TABLE_THREADS)))
    return tuple(np.concatenate(parts) for parts in zip(*outs))


def suj_link_count(cart: str, arm: str) -> int:
    """How many of an arm's setup-joint links the tables check: its chain's rows (jointed, then the Si's fixed
    ones) from ``FIRST_SUJ_LINK`` on (the Classic's 4; the Si's 4, its PSM3's 5)."""

    suj = PLATFORMS[cart].suj(arm)
    return len(suj.links) + len(suj.fixed) - FIRST_SUJ_LINK


def link_names(arm: str, cart: str = "classic") -> tuple[str, ...]:
    """An arm's links in the tables' numbering: its setup joints' (fixed), then its own."""
    n_suj = suj_link_count(cart, arm)
    names = (tuple(f"{arm} setup joint link {k + 1}" for k in range(FIRST_SUJ_LINK, FIRST_SUJ_LINK + n_suj))
             + tuple(f"{arm} {c.name}" for c in PLATFORMS[cart].own_links(arm)[1]))
    if len(names) > LINK_CODE:  # a platform's data, not a user's input: the code could not name its links
        raise ValueError(f"{arm} on the {cart} cart has {len(names)} links; a clearance's code names at most "
                         f"{LINK_CODE} (kinematics.port.capsules.LINK_CODE)")
    return names


#: The arms checked against their surroundings, in the order of the rows' codes PAIR_CODE * (6 + arm) + LINK_CODE * link +
#: what (``SURROUNDINGS``).
ARMS = ("PSM1", "PSM2", "PSM3", "ECM")
SURROUNDINGS = ("patient's body", *BEDSIDE)


def pair_name(code: int, cart: str = "classic") -> str:
    """A row's ``external_link_pair`` code as "PSM1 setup joint link 6 / PSM2 mount" or "PSM2 mount / table"
    ("" for -1)."""
    if code < 0:
        return ""
    pair, link, other = code // PAIR_CODE, (code % PAIR_CODE) // LINK_CODE, code % LINK_CODE
    if pair >= len(ARM_PAIRS):
        return f"{link_names(ARMS[pair - len(ARM_PAIRS)], cart)[link]} / {SURROUNDINGS[other]}"
    a, b = ARM_PAIRS[pair]
    return f"{link_names(a, cart)[link]} / {link_names(b, cart)[other]}"


def to_bedside(cfg, segs: np.ndarray, radii: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(C2) Each link's clearance (m) to the bedside (``bedside.bedside_boxes``: the table's slab, its rails, the
    patient's arms and legs; each box exact by golden-section search) for each item of ``segs`` (K, L, 2, 3),
    patient frame, and the nearest box's index in ``bedside.BEDSIDE``: ((K, L), (K, L))."""
    from surgopt.kinematics.port.capsules import segments_box_distance
    from surgopt.studies.port_place.bedside import BEDSIDE, bedside_boxes

    k, n = segs.shape[:2]
    flat = np.ascontiguousarray(segs.reshape(-1, 2, 3))
    value, which = np.full(len(flat), np.inf), np.zeros(len(flat), np.int64)
    for box in bedside_boxes(cfg):
        d = segments_box_distance(flat, box.lo, box.hi)
        nearer = d < value
        value, which = np.where(nearer, d, value), np.where(nearer, BEDSIDE.index(box.name), which)
    return value.reshape(k, n) - radii[None], which.reshape(k, n)


def to_patient_body(cfg, segs: np.ndarray, radii: np.ndarray, through: np.ndarray) -> np.ndarray:
    """(C3) (K, L) Each link's clearance (m) to the patient's body for each item of ``segs`` (K, L, 2, 3), patient
    frame: the least over points along the link at most ``SPACING_M`` apart, the body distance resolved to
    ``PATIENT_CAP_MM`` (0 inside the body); inf for the links that pass the port (``through``)."""
    from surgopt.kinematics.port.capsules import along_many
    from surgopt.studies.port_place.geometry import body_box_mm, body_distance_mm, inside_body

    k, n = segs.shape[:2]
    flat = np.ascontiguousarray(segs.reshape(-1, 2, 3))
    link = np.tile(np.arange(n), k)
    keep = np.flatnonzero(~through[link])
    out = np.full(len(flat), np.inf)
    if not len(keep):
        return out.reshape(k, n)
    pts, owner = along_many(np.ascontiguousarray(flat[keep]), SPACING_M)
    local_mm = pts * 1000
    d = np.full(len(pts), PATIENT_CAP_MM)
    lo_mm, hi_mm = body_box_mm(cfg.patient)
    near = np.flatnonzero(np.all((local_mm >= lo_mm - PATIENT_CAP_MM) & (local_mm <= hi_mm + PATIENT_CAP_MM), axis=1))
    d[near] = np.where(inside_body(local_mm[near], cfg.patient), 0.0,
                       body_distance_mm(local_mm[near], cfg.patient, PATIENT_CAP_MM, many=True))
    np.minimum.at(out, keep[owner], d / 1000 - radii[link[keep[owner]]])
    return out.reshape(k, n)


def surroundings(cfg, segs: np.ndarray, radii: np.ndarray, through: np.ndarray, valid: np.ndarray):
    """(C2, C3) Per item of ``segs`` (K, L, 2, 3), patient frame, where ``valid``: the least clearance (m) of its
    links to the patient's body (``to_patient_body``) and to the bedside (``to_bedside``), and its code LINK_CODE *
    link + (0 the patient, 1 + the box's index in ``bedside.BEDSIDE``: ``SURROUNDINGS``): (value (K,), code (K,)),
    NaN and -1 elsewhere. One layout's checks (``clashes``) read the same two functions."""
    n_item, n_link = segs.shape[:2]
    value, code = np.full(n_item, np.nan), np.full(n_item, -1, np.int64)
    idx = np.flatnonzero(valid)
    if not len(idx):
        return value, code
    bedside, which = to_bedside(cfg, segs[idx], radii)
    both = np.stack([to_patient_body(cfg, segs[idx], radii, through), bedside], axis=2).reshape(len(idx), n_link * 2)
    best = np.argmin(both, axis=1)
    value[idx] = both[np.arange(len(idx)), best]
    on_bedside = best % 2 == 1
    code[idx] = LINK_CODE * (best // 2) + np.where(on_bedside, 1 + which[np.arange(len(idx)), best // 2], 0)
    return value, code


#: The arms' poses: docked, and reaching each of at most this many target points, spread by farthest-point
#: sampling from the centre (the target's extremes come first; ``spread_points`` gives the covering radius).
POSE_POINTS = 64


def spread_points(points: np.ndarray, k: int, start: int = 0) -> tuple[np.ndarray, float]:
    """Farthest-point sampling: k indices (all when fewer), each next the point farthest from those chosen, and
    the covering radius (m): every point lies within it of a chosen one."""
    if len(points) <= k:
        return np.arange(len(points)), 0.0
    chosen = [start]
    d = np.linalg.norm(points - points[start], axis=1)
    for _ in range(k - 1):
        i = int(np.argmax(d))
        chosen.append(i)
        d = np.minimum(d, np.linalg.norm(points - points[i], axis=1))
    return np.array(chosen), float(d.max())


#: The target points are checked in this many groups of neighbours (each bounded by its own swept capsules).
POSE_GROUPS = 8


def pose_points(model) -> tuple[np.ndarray, np.ndarray]:
    """The target points each PSM reaches in the check (``spread_points`` from the centre's nearest),
    ordered into ``POSE_GROUPS`` groups of neighbours (each point with the nearest of the first POSE_GROUPS, the
    target's extremes), and the groups' offsets among the arm's poses (the docked pose first, a group of its
    own): (points (k, 3), offsets (G + 2,))."""
    start = int(np.argmin(np.linalg.norm(model.targets_m - model.centre_m, axis=1)))
    return grouped(model.targets_m[spread_points(model.targets_m, POSE_POINTS, start)[0]], POSE_GROUPS)


def grouped(points: np.ndarray, n_groups: int) -> tuple[np.ndarray, np.ndarray]:
    """``points`` (farthest-point ordered: the first ``n_groups`` are spread) ordered into groups of neighbours,
    each point with the nearest of the first n_groups, and the groups' offsets among an arm's poses (the docked pose
    first, a group of its own): (points (k, 3), offsets (n_groups + 2,))."""
    seeds = points[:n_groups]
    group = np.argmin(np.linalg.norm(points[:, None, :] - seeds[None, :, :], axis=2), axis=1)
    order = np.argsort(group, kind="stable")
    counts = np.bincount(group, minlength=len(seeds))
    return points[order], np.concatenate([[0, 1], 1 + np.cumsum(counts)]).astype(np.int64)


def own_moving(model, sites: np.ndarray, rot: np.ndarray, arm: str = "PSM1", points: np.ndarray | None = None
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(segments (n, P, L, 2, 3) m in the patient frame, radii (L,), the poses' groups (``pose_points``)): a
    PSM's own links (its cart's, ``Platform.own_links``) docked at each port in its docking frame ``rot`` (n, 3, 3), with
    the mount where its setup joints' tip is (SUJ_tip_to_tool_origin), docked (yaw = pitch = 0, the tip at the
    centre's depth) and reaching each of ``pose_points`` (eq. P2), or of ``points`` (m, patient frame; groups
    then None): the one placement of a PSM's links, for the rows and for one layout (``placed_arm``)."""
    from surgopt.kinematics.port import capsules as C

    along = model.limits.along_shaft_m
    points, groups = pose_points(model) if points is None else (np.asarray(points, float).reshape(-1, 3), None)
    n, k = len(sites), len(points) + 1
    base = np.zeros((n, 4, 4))
    base[:, :3, :3], base[:, :3, 3], base[:, 3, 3] = rot, sites, 1.0
    cart = model.cfg.cart.model
    mount = base @ np.linalg.inv(np.asarray(PLATFORMS[cart].suj(arm).tip_to_tool, float))
    skeleton, capsules = PLATFORMS[cart].own_links(arm)
    local = np.einsum("npi,nij->npj", points[None, :, :] - sites[:, None, :], rot)  # (n, P-1, 3), base frame
    rho = np.linalg.norm(local, axis=2)
    q = np.empty((n, k, 3))
    q[:, 0] = (0.0, 0.0, 0.0)
    q[:, 0, 2] = np.linalg.norm(model.centre_m - sites, axis=1) - along
    q[:, 1:, 1] = -np.arcsin(np.clip(local[:, :, 1] / rho, -1.0, 1.0))
    q[:, 1:, 0] = np.arctan2(local[:, :, 0], -local[:, :, 2])
    q[:, 1:, 2] = rho - along
    frames = C.skeleton_batch(skeleton, q.reshape(-1, 3), np.repeat(base, k, axis=0), np.repeat(mount, k, axis=0))
    segs = C.capsules_batch(capsules, frames).reshape(n, k, -1, 2, 3)
    return segs, np.array([c.radius_m for c in capsules]), groups


def _chain(suj):
    """A SUJ's base and modified-DH rows (its jointed links, then its fixed ones: the Si's two) and how many are
    jointed, as ``suj_batch.link_segments`` reads them."""
    rows = tuple(suj.links) + tuple(suj.fixed)
    return (np.asarray(suj.world_to_suj, float), np.array([r.alpha_rad for r in rows]),
            np.array([r.a_m for r in rows]), np.array([r.d_m for r in rows]),
            np.array([r.theta_offset_rad for r in rows]), np.array([bool(r.prismatic) for r in rows]),
            len(suj.links))


def to_patient(dock) -> np.ndarray:
    """(poses, 4, 4) The cart's world frame in the patient's frame at each pose."""
    return np.linalg.inv(dock.poses.patient)


def suj_static(cfg, arm: str, joints: np.ndarray, dock) -> np.ndarray:
    """(n, m, S, 2, 3) An arm's setup-joint links (``FIRST_SUJ_LINK`` on, ``suj_link_count``) at its joints (n, m,
    6: the jointed first; NaN where it does not dock) in the patient's frame."""
    from surgopt.kinematics.port.suj_batch import link_segments

    n, m = joints.shape[:2]
    frame = np.broadcast_to(to_patient(dock)[None], (n, m, 4, 4)).reshape(-1, 4, 4)
    segs = link_segments(*_chain(PLATFORMS[cfg.cart.model].suj(arm)),
                         np.ascontiguousarray(joints.reshape(-1, joints.shape[-1])), np.ascontiguousarray(frame),
                         FIRST_SUJ_LINK)
    return segs.reshape(n, m, -1, 2, 3)


def ecm_static(cfg, dock) -> np.ndarray:
    """(n, m, S + 3, 2, 3) The ECM docked at each site and pose: its setup joints' links and its own
    (``Platform.own_links``: at the yaw and pitch that aim the scope, insertion 0), in the patient's frame (NaN where it
    does not dock)."""
    from surgopt.kinematics.port import capsules as C
    from surgopt.kinematics.port.suj_batch import chain_ends

    suj = PLATFORMS[cfg.cart.model].suj("ECM")
    joints = dock.camera_joints
    n, m = joints.shape[:2]
    flat = np.ascontiguousarray(joints.reshape(-1, 6))
    mount = chain_ends(*_chain(suj), flat)
    base = mount @ np.asarray(suj.tip_to_tool, float)
    aim = dock.camera_aim.reshape(-1, 2)
    q = np.zeros((len(flat), 3))
    q[:, :2] = np.nan_to_num(aim)
    skeleton, capsules = PLATFORMS[cfg.cart.model].own_links("ECM")
    own = C.capsules_batch(capsules, C.skeleton_batch(skeleton, q, base, mount))  # cart frame
    frame = np.broadcast_to(to_patient(dock)[None], (n, m, 4, 4)).reshape(-1, 4, 4)
    own = np.einsum("kij,klej->klei", frame[:, :3, :3], own) + frame[:, None, None, :3, 3]
    return np.concatenate([suj_static(cfg, "ECM", joints, dock).reshape(n * m, -1, 2, 3), own],
                          axis=1).reshape(n, m, -1, 2, 3)


class PlacedArm(NamedTuple):
    """One docked arm's links as capsules in the patient's frame (``placed_arm``): segments at each pose (p, L, 2,
    3: docked, then at each target point asked for; the ECM docked only), radii (L,), names (``link_names``),
    which pass the port (the shafts, not checked against the body)."""

    segments: np.ndarray
    radii: np.ndarray
    names: tuple
    through_port: np.ndarray


def placed_arm(model, arm: str, joints, base: np.ndarray, ecm_aim, to_patient: np.ndarray,
               points: np.ndarray) -> PlacedArm:
    """One docked arm (``arm``: "PSM1" ... "ECM"; its setup joints ``joints``, m and rad; its base (RCM) frame
    ``base`` in the cart's world frame; the ECM's yaw and pitch ``ecm_aim``) placed as the rows place it: its
    setup-joint links by ``suj_batch.link_segments`` (``suj_static``'s), a PSM's own links docked and reaching
    each of ``points`` (m, patient frame; ``own_moving``), the ECM's at its aim (``ecm_static``'s), all in the
    patient's frame (``to_patient``: the cart's world frame there, 4x4). Issue 53: one placement of the links,
    for the rows' tables and for one layout's clearances (``clashes``)."""
    from surgopt.kinematics.port import capsules as C
    from surgopt.kinematics.port.suj_batch import chain_ends, link_segments

    cart = model.cfg.cart.model
    suj = PLATFORMS[cart].suj(arm)
    q = np.full((1, 6), np.nan)
    q[0, :len(joints)] = joints
    chain = _chain(suj)
    setup = link_segments(*chain, q, np.ascontiguousarray(to_patient[None]), FIRST_SUJ_LINK)[0]  # (S, 2, 3)
    skeleton, capsules = PLATFORMS[cart].own_links(arm)
    if arm == "ECM":
        mount = chain_ends(*chain, np.ascontiguousarray(q))
        at = C.capsules_batch(capsules, C.skeleton_batch(skeleton, np.array([[ecm_aim[0], ecm_aim[1], 0.0]]),
                                                          mount @ np.asarray(suj.tip_to_tool, float), mount))
        own = (at @ to_patient[:3, :3].T + to_patient[:3, 3])  # (1, L, 2, 3)
    else:
        in_patient = to_patient @ base
        own = own_moving(model, in_patient[None, :3, 3], in_patient[None, :3, :3], arm, points)[0][0]
    segments = np.concatenate([np.broadcast_to(setup, (len(own),) + setup.shape), own], axis=1)
    radii = np.concatenate([suj_radii(cart, arm), [c.radius_m for c in capsules]])
    through = np.array([False] * len(setup) + through_port(capsules))
    return PlacedArm(segments, radii, link_names(arm, cart), through)


def suj_radii(cart: str, arm: str) -> np.ndarray:
    """An arm's setup-joint links' radii (m)."""
    from surgopt.robots.dvrk.links import SUJ_RADIUS_M

    return np.full(suj_link_count(cart, arm), SUJ_RADIUS_M)


def ecm_radii(cart: str) -> np.ndarray:
    """The ECM's links' radii (m) as ``ecm_static`` lists them."""
    return np.concatenate([suj_radii(cart, "ECM"), [c.radius_m for c in PLATFORMS[cart].own_links("ECM")[1]]])


class Wanted(NamedTuple):
    """Which entries a design can need (the others fail on a count of their own, whatever their links): ``pair``
    (n, n) the working pair's two ports pass every per-pair check (reach, angle, shafts inside, spacing);
    ``third`` (n,) a port PSM3 can take (it reaches every point); ``camera`` (n,) one the ECM can take (it sees
    every point); ``spaced`` (n, n) ports far enough apart."""

    pair: np.ndarray
    third: np.ndarray
    camera: np.ndarray
    spaced: np.ndarray


def wanted_of(t, crit) -> Wanted:
    """``Wanted`` from a design kernel's ``PortTables`` (the checks ``design_columns`` makes, per pair)."""
    count, ang, inside = (a + a.T for a in (t.count, t.ang_centre, t.inside))  # the kernel fills i < j
    spaced = t.spacing >= crit.min_spacing_m
    pair = ((count == t.n_points) & (ang >= crit.angle_lo_rad) & (ang <= crit.angle_hi_rad)
            & (inside >= crit.min_shaft_gap_m) & spaced)
    np.fill_diagonal(pair, False)
    third = t.third_reach_count if len(t.third_reach_count) else t.reach_count  # the Si PSM3's own, when given
    return Wanted(pair, third == t.n_points, t.coverage >= 1.0, spaced)


def link_tables(model, sites: np.ndarray, rot: np.ndarray, dock, wanted: Wanted,
                third_rot: np.ndarray | None = None) -> LinkTables:
    """Every pair of arms' least link clearance at every pair of ``sites`` (m, the tables' sites) and cart pose of
    ``dock`` (its ``joints``) where both dock and a design can need it (``wanted``; elsewhere NaN, and the words
    set: the links do not decide there); ``rot``: the instrument arms' docking frames there, ``third_rot`` the
    third's where they are its own (the Si's PSM3, ``tables.third_frames``)."""
    from surgopt.kinematics.port import capsules as C
    from surgopt.kinematics.port.designs import pack_bits
    from surgopt.robots.dvrk.suj import INSTRUMENT_SUJS

    cfg = model.cfg
    cart = cfg.cart.model
    n, m = len(sites), dock.margin.shape[2]
    psms = INSTRUMENT_SUJS[:cfg.robot.instrument_count]
    own, r_own, groups = own_moving(model, sites, rot)

    def balls_of(segs):
        return (np.stack([C.swept_capsules(segs[i], r_own, groups) for i in range(n)]) if n
                else np.zeros((0, len(r_own), len(groups) - 1, C.SWEPT)))

    moving = {a: own for a in psms}
    if third_rot is not None and "PSM3" in psms:
        moving["PSM3"] = own_moving(model, sites, third_rot, "PSM3")[0]
    balls = {a: balls_of(own) for a in psms[:1]}
    balls.update({a: balls["PSM1"] if moving[a] is own else balls_of(moving[a]) for a in psms[1:]})
    static = {a: suj_static(cfg, a, dock.joints[k], dock) for k, a in enumerate(psms)}
    docks = {a: dock.margin[k] >= 0.0 for k, a in enumerate(psms)}
    static["ECM"], docks["ECM"] = ecm_static(cfg, dock), dock.camera_margin >= 0.0
    r_static = {a: ecm_radii(cart) if a == "ECM" else suj_radii(cart, a) for a in static}
    none = np.zeros((n, 1, 0, 2, 3))
    no_balls = np.zeros((n, 0, len(groups) - 1, C.SWEPT))
    least = cfg.constraints.link_least_mm / 1000
    cap = least + CAP_M
    value, code, words = {}, {}, {}
    arm_value, arm_code = arm_surroundings(cfg, moving, r_own, static, docks)
    used = wanted.pair.any(axis=1)  # a port of some working pair that passes
    need = {"PSM1": used, "PSM2": used, "PSM3": wanted.third, "ECM": wanted.camera}
    for pair, (x, y) in enumerate(ARM_PAIRS):
        if x not in static or y not in static:
            continue
        asked = wanted.pair if y == "PSM2" else need[x][:, None] & need[y][None, :] & wanted.spaced
        np.fill_diagonal(asked, False)  # two arms on one port: never a layout
        both = docks[x][:, None, :] & docks[y][None, :, :] & asked[:, :, None]
        tasks = np.argwhere(both)
        start, start_code = np.full(len(tasks), cap), np.full(len(tasks), -1, np.int64)
        if y != "ECM" and len(tasks):  # two PSMs: their own links over every pair of poses, per site pair
            start, la, lb = moving_starts(tasks, n, moving[x], balls[x], moving[y], balls[y], r_own, groups, cap,
                                          least)
            fx, fy = len(r_static[x]), len(r_static[y])
            start_code = np.where(la >= 0, LINK_CODE * (la + fx) + lb + fy, -1)
        moving_y, r_my, balls_y = (none, np.zeros(0), no_balls) if y == "ECM" else (moving[y], r_own, balls[y])
        v, c = in_threads(_pairs, (tasks, start, start_code), static[x], moving[x], r_static[x], r_own, balls[x],
                          static[y], moving_y, r_static[y], r_my, balls_y, groups, least)
        dense = np.full((n, n, m), np.nan, np.float32)
        dense_code = np.full((n, n, m), -1, np.int16)
        dense[tasks[:, 0], tasks[:, 1], tasks[:, 2]] = v
        dense_code[tasks[:, 0], tasks[:, 1], tasks[:, 2]] = c
        value[pair], code[pair] = dense, dense_code
        words[pair] = pack_bits(np.where(both, dense >= least, True))
    arm_words = pack_bits(np.where(np.isnan(arm_value), True, arm_value >= least))
    return LinkTables(value, code, words, {a: link_names(a, cart) for a in static}, arm_value.astype(np.float32),
                      arm_code.astype(np.int16), arm_words)


def moving_starts(tasks, n, moving_x, balls_x, moving_y, balls_y, radii, groups, cap, least):
    """Two PSMs' own links over every pair of their poses (``capsules.moving_pairs``), once per site pair of
    ``tasks`` (T, 3: site of X, site of Y, cart pose), whatever the pose: (least (T,), X's link, Y's link). Two arms
    in the same frames (``moving_x is moving_y``) are one problem per unordered pair."""
    from surgopt.kinematics.port import capsules as C

    if moving_x is moving_y:
        lo, hi = np.minimum(tasks[:, 0], tasks[:, 1]), np.maximum(tasks[:, 0], tasks[:, 1])
        uniq, back = np.unique(lo * n + hi, return_inverse=True)
    else:
        uniq, back = np.unique(tasks[:, 0] * n + tasks[:, 1], return_inverse=True)
    got, links = in_threads(C.moving_pairs, (np.stack([uniq // n, uniq % n], axis=1),), moving_x, balls_x,
                            moving_y, balls_y, radii, groups, cap, least, inline=2 * TABLE_THREADS)  # ~1 ms a task
    la, lb = links[back, 0], links[back, 1]
    if moving_x is moving_y:
        flip = tasks[:, 0] > tasks[:, 1]
        la, lb = np.where(flip, lb, la), np.where(flip, la, lb)
    return got[back], la, lb


def arm_surroundings(cfg, moving, r_own, static, docks):
    """Each arm against the patient and the bedside at each (site, pose) where it docks (``surroundings``): a PSM's
    own links (``moving``, per PSM) once per site over its poses (its docked frame does not depend on the cart),
    the least of those and its setup joints' at the pose; the ECM held docked. (value (4, n, m) m, NaN where it
    does not dock; code (4, n, m): LINK_CODE * link + what, the links numbered as ``link_names``.)"""
    cart = cfg.cart.model
    n, m = static["ECM"].shape[:2]
    value, code = np.full((4, n, m), np.nan), np.full((4, n, m), -1, np.int64)
    through_own = np.array(through_port(PLATFORMS[cart].own_links("PSM1")[1]))
    measured = {}  # per set of own links (PSM1's and PSM2's are one on either cart)
    for a, arm in enumerate(ARMS):
        if arm not in static:
            continue
        n_suj = suj_link_count(cart, arm)
        segs = static[arm].reshape(n * m, -1, 2, 3)
        radii = ecm_radii(cart) if arm == "ECM" else suj_radii(cart, arm)
        through = np.array([False] * n_suj + (through_port(PLATFORMS[cart].own_links("ECM")[1]) if arm == "ECM" else []))
        v, c = surroundings(cfg, segs, radii, through, docks[arm].reshape(-1))
        v, c = v.reshape(n, m), c.reshape(n, m)
        if arm != "ECM":  # the arm's own links, wherever its setup joints dock
            own = moving[arm]
            if id(own) not in measured:
                k = own.shape[1]
                measured[id(own)] = surroundings(cfg, own.reshape(n, -1, 2, 3), np.tile(r_own, k),
                                                 np.tile(through_own, k), np.ones(n, bool))
            own_v, own_c = measured[id(own)]
            own_c = np.where(own_c >= 0, LINK_CODE * (n_suj + (own_c // LINK_CODE) % len(r_own)) + own_c % LINK_CODE,
                             -1)
            worse = own_v[:, None] < v
            v, c = np.where(worse, own_v[:, None], v), np.where(worse, own_c[:, None], c)
        value[a], code[a] = v, c
    return value, code


def _pairs(tasks, start, start_code, *rest):
    """``capsules.pair_clearances`` with its row-aligned arguments first (``in_threads``)."""
    from surgopt.kinematics.port.capsules import pair_clearances

    static_x, moving_x, r_sx, r_mx, balls_mx, static_y, moving_y, r_sy, r_my, balls_my, groups, floor = rest
    return pair_clearances(tasks, static_x, moving_x, r_sx, r_mx, balls_mx, static_y, moving_y, r_sy, r_my, balls_my,
                           groups, start, start_code, floor)
