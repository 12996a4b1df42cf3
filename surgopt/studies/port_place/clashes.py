"""A docked layout's clearances outside the body (issue 40): each arm's setup-joint links and its own links
(``robots/dvrk/links.py``) as capsules in the patient's frame, docked and at the joint values that reach each
target point, placed as the rows place them (``link_tables.placed_arm``), checked between arms, against the patient
and against the bedside (``kinematics.port.capsules``).

Between two arms the least is over every pair of their poses (each instrument at any of its target points, the
other at any of its own: they move independently), the ECM held where it docks. Against the patient and the
table, every link but those that pass through the port (the shafts) at every pose, at points along the link at
most ``SPACING_M`` apart (the least over-reads by at most half that, and on a dome by the surface samples' gap);
the bedside as boxes in the patient frame, tilted with the table (``bedside.py``: the table's slab, its rails, the
patient's arms and legs).
The answer is also checked over every target point (``whole_target_clearances``, #54 item 3).

One module of ~450 lines: one layout's clearances as the report, the figures and the export ask for them (the
arms placed per pose, between arms, against the patient and the bedside, over the whole target, the docking roll
that clears), all sharing ``ArmPoses`` and one memo of answers; the rows' tables are ``link_tables``.
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np

from surgopt.robots.dvrk.platforms import PLATFORMS, role_of

from surgopt.studies.port_place.carts import cart_for
from surgopt.studies.port_place.link_tables import PATIENT_CAP_MM, pose_points

class Clearance(NamedTuple):
    """One least clearance: what against what, the value (mm, negative: they overlap), which links, and where
    (the pose of each arm: "docked" or the target point it reaches, mm in the patient frame)."""

    check: str
    clearance_mm: float
    link_a: str
    link_b: str
    where: str


class ArmPoses(NamedTuple):
    """One docked arm: its name, capsules at each pose (p, n, 2, 3), radii, link names, which links pass the
    port, and each pose's label (``PoseLabels``, or ("docked",) for an arm held docked)."""

    arm: str
    segments: np.ndarray
    radii: np.ndarray
    names: tuple
    through_port: np.ndarray
    poses: object


def _point_label(p_mm: np.ndarray) -> str:
    return f"target point ({p_mm[0]:.0f}, {p_mm[1]:.0f}, {p_mm[2]:.0f}) mm"


class PoseLabels:
    """Each pose's label, "docked" then "target point (x, y, z) mm" for each of ``points_m``, worded when read (the
    rows ask ~900 poses of each feasible layout and read the labels of one or two)."""

    def __init__(self, points_m: np.ndarray):
        self.points_m = points_m

    def __len__(self) -> int:
        return 1 + len(self.points_m)

    def __getitem__(self, k: int) -> str:
        return "docked" if k == 0 else _point_label(self.points_m[k - 1] * 1000)


def arm_poses(model, arm, patient: np.ndarray, targets_m: np.ndarray) -> ArmPoses:
    """A docked arm's capsules (``tables.DockedArm``: its setup joints', fixed, and its own, moving) docked and at
    each target point of ``targets_m`` (a PSM; the ECM held at its docked aim), in the patient's frame (``patient``:
    the patient's frame in the cart's world), placed as the rows place them (``link_tables.placed_arm``)."""
    from surgopt.studies.port_place.link_tables import placed_arm

    placed = placed_arm(model, arm.arm, arm.joints, arm.base, arm.ecm, np.linalg.inv(patient), targets_m)
    labels = ("docked",) if arm.arm == "ECM" else PoseLabels(np.asarray(targets_m, float).reshape(-1, 3))
    return ArmPoses(arm.arm, placed.segments, placed.radii, placed.names, placed.through_port, labels)


def between(a: ArmPoses, b: ArmPoses) -> tuple[Clearance, Clearance]:
    """The least clearance between two arms docked, and over every pair of their poses."""
    from surgopt.kinematics.port.capsules import least_over_poses, least_pair_clearance

    c0, i0, j0 = least_pair_clearance(a.segments[0], a.radii, b.segments[0], b.radii)
    docked = Clearance(f"{a.arm} and {b.arm}, docked", c0 * 1000, a.names[i0], b.names[j0], "docked")
    c, pa, pb, i, j = least_over_poses(a.segments, a.radii, b.segments, b.radii)
    moving = Clearance(f"{a.arm} and {b.arm}, over the target", c * 1000, a.names[i], b.names[j],
                       f"{a.arm} {a.poses[pa]}; {b.arm} {b.poses[pb]}")
    return docked, moving


def against_patient(cfg, a: ArmPoses) -> Clearance:
    """(C3) The least clearance of the arm's links (not the shafts) to the patient's body at any pose, measured as
    the rows measure it (``link_tables.to_patient_body``)."""
    from surgopt.studies.port_place.link_tables import to_patient_body

    c = to_patient_body(cfg, a.segments, a.radii, a.through_port)
    pose, link = np.unravel_index(int(np.argmin(c)), c.shape)
    d_mm = (c[pose, link] + a.radii[link]) * 1000
    note = " (inside the body)" if d_mm <= 1e-9 else (f" (at least: nothing within {PATIENT_CAP_MM:.0f} mm)"
                                                      if d_mm >= PATIENT_CAP_MM - 1e-9 else "")
    return Clearance(f"{a.arm} and the patient", float(c[pose, link] * 1000), a.names[link], "patient's body",
                     f"{a.arm} {a.poses[pose]}{note}")


def against_bedside(cfg, a: ArmPoses) -> Clearance:
    """(C2) The least clearance of the arm's links to the bedside (the table's slab, its rails, the patient's arms
    and legs: ``bedside.bedside_boxes``, in the patient's frame) at any pose, and which, measured as the rows
    measure it (``link_tables.to_bedside``: each link exact by golden-section search)."""
    from surgopt.studies.port_place.bedside import BEDSIDE
    from surgopt.studies.port_place.link_tables import to_bedside

    c, which = to_bedside(cfg, a.segments, a.radii)
    pose, link = np.unravel_index(int(np.argmin(c)), c.shape)
    return Clearance(f"{a.arm} and the bedside", float(c[pose, link] * 1000), a.names[link],
                     BEDSIDE[which[pose, link]], f"{a.arm} {a.poses[pose]}")


#: Answers (a layout's clearances, or its roll search) a process keeps: the closing report screens up to
#: ``report.SCREEN_LAYOUTS`` (10) layouts, two answers each, and then its tables, the figure and the export ask again
#: for the best layout's (~0.5-1.5 s each time otherwise).
MEMO_ENTRIES = 32
_memo: dict = {}


def memoised(what: str, cfg, row: dict, compute):
    """``compute()`` once per (what, the config, the row's values) in this process, the MEMO_ENTRIES latest kept:
    every answer memoised is a pure function of the config and the row (the layout, its clearances, rolls)."""
    key = (what, cfg.model_dump_json(), tuple(sorted((k, repr(v)) for k, v in row.items())))
    if key not in _memo:
        while len(_memo) >= MEMO_ENTRIES:
            _memo.pop(next(iter(_memo)))
        _memo[key] = compute()
    return _memo[key]


def links_modelled(cfg) -> bool:
    """Whether the arms' links are modelled on a config's cart (validated or as stored: every platform of
    ``PLATFORMS`` has its arms' links): where not (no cart), no clearance outside the body is measured, none is
    reported."""
    from surgopt.studies.port_place.config import cart_of

    return cart_of(cfg) in PLATFORMS


def in_feasible(cfg) -> str:
    """What of the links' clearance feasible holds (a validated config): between arms with
    ``constraints.min_link_clearance_mm``, or that it is not asked for."""
    from surgopt.studies.port_place.tables import links_decide

    if links_decide(cfg):
        return f"in feasible, at least {cfg.constraints.link_least_mm:g} mm"
    return "not part of feasible (constraints.min_link_clearance_mm = 'off')"


def layout_clearances(model, row: dict, docked=None) -> list[Clearance]:
    """Every least clearance of a layout's row on the cart (its ports and cart pose): each pair of docked arms
    (docked and over the target), each arm against the patient and the bedside. Arms that do not dock are left
    out (their setup joints have no solution to place links at). ``docked``: the arms docked otherwise than the
    row's own docking (rolled); without it the answer is kept for the process (``memoised``)."""
    from surgopt.studies.port_place.tables import docked_arms, row_patient_in_cart

    cfg = model.cfg
    if not links_modelled(cfg):
        return []
    if docked is None:
        return list(memoised("clearances", cfg, row, lambda: layout_clearances(model, row, docked_arms(model, row))))
    patient = row_patient_in_cart(cfg, row)
    points = pose_points(model)[0]
    arms = [arm_poses(model, a, patient, points) for a in docked if a.joints]
    out = []
    for i in range(len(arms)):
        for j in range(i + 1, len(arms)):
            out += between(arms[i], arms[j])
    out += [against_patient(cfg, a) for a in arms]
    out += [against_bedside(cfg, a) for a in arms]
    return out


#: The whole target's points are checked in this many groups of neighbours (each bounded by its own swept capsules).
WHOLE_TARGET_GROUPS = 64


def whole_target_clearances(model, row: dict) -> list[Clearance]:
    """(#54 item 3) Between each pair of a layout's docked arms (docked as its row is), the least clearance over
    **every** target point (each PSM at any of them and docked, the other at any of its own; the ECM held docked),
    exact: ``least_fixed_and_moving`` over all pose pairs, pruned only by lower bounds. The rows' link tables
    sample ``link_tables.POSE_POINTS`` of them and the rows then decide their feasible layouts with this
    (``designs.decided_over_the_whole_target``). Kept for the process (``memoised``)."""
    if not links_modelled(model.cfg):
        return []
    return list(memoised("whole target", model.cfg, row, lambda: over_the_whole_target(model, row)))


def whole_target_points(model) -> tuple[np.ndarray, np.ndarray]:
    """Every target point, ordered into WHOLE_TARGET_GROUPS groups of neighbours (``link_tables.grouped``,
    spread first), and the groups' offsets among an arm's poses (docked first)."""
    from surgopt.studies.port_place.link_tables import grouped, spread_points

    start = int(np.argmin(np.linalg.norm(model.targets_m - model.centre_m, axis=1)))
    seeds = spread_points(model.targets_m, WHOLE_TARGET_GROUPS, start)[0]  # spread first, then every other point
    first = np.concatenate([seeds, np.setdiff1d(np.arange(len(model.targets_m)), seeds)])
    return grouped(model.targets_m[first], min(WHOLE_TARGET_GROUPS, len(model.targets_m)))


def fixed_links(segments: np.ndarray) -> np.ndarray:
    """(links,) bool: the links an arm holds still over all its poses (its setup joints', the ECM's), the same
    segment at every pose."""
    return np.all(segments == segments[:1], axis=(0, 2, 3))


def fixed_and_moving(arm: ArmPoses, groups: np.ndarray) -> list:
    """An arm's links as the pruned least takes them: its fixed links (``fixed_links``) at one pose, and the others
    at every pose in ``groups`` (an arm held docked: all fixed), each with its swept capsules: [(the links' indices,
    their pose groups, segments, radii, swept capsules)]."""
    from surgopt.kinematics.port.capsules import swept_capsules

    held = np.array([0, 1], np.int64)
    still = fixed_links(arm.segments)
    links = [(np.flatnonzero(still), held, arm.segments[:1])]
    if len(arm.poses) > 1 and not still.all():
        links.append((np.flatnonzero(~still), groups, arm.segments))
    out = []
    for i, g, seg in links:
        if len(i):
            s, r = np.ascontiguousarray(seg[:, i]), arm.radii[i]
            out.append((i, g, s, r, swept_capsules(s, r, g)))
    return out


def least_fixed_and_moving(a: list, b: list, best: float = np.inf,
                           floor: float = -np.inf) -> tuple[float, int, int, int, int]:
    """``capsules.least_between`` of two arms over every pair of their poses, each arm as ``fixed_and_moving``
    gives it (its fixed links taken once, not at every pose): (clearance m, link of a, link of b, pose of a, pose of
    b), -1s when nothing is below ``best``; with a ``floor``, stopped at the first below it."""
    from surgopt.kinematics.port.capsules import least_between

    out = (best, -1, -1, -1, -1)
    for ia, ga, sa, ra, ca in a:
        for ib, gb, sb, rb, cb in b:
            v, i, j, p, q = least_between(sa, ra, ca, ga, sb, rb, cb, gb, out[0], floor)
            if i >= 0:
                out = (v, int(ia[i]), int(ib[j]), p, q)
                if v < floor:
                    return out
    return out


def over_the_whole_target(model, row: dict) -> list[Clearance]:
    """``whole_target_clearances`` computed (not kept: the rows ask it of each feasible layout, from threads)."""
    from surgopt.studies.port_place.tables import docked_arms, row_patient_in_cart

    points, groups = model.whole_target
    patient = row_patient_in_cart(model.cfg, row)
    arms = [arm_poses(model, a, patient, points) for a in docked_arms(model, row) if a.joints]
    parts = [fixed_and_moving(a, groups) for a in arms]
    out = []
    for x in range(len(arms)):
        for y in range(x + 1, len(arms)):
            a, b = arms[x], arms[y]
            v, i, j, p, s = least_fixed_and_moving(parts[x], parts[y])
            out.append(Clearance(f"{a.arm} and {b.arm}, over the whole target ({len(points):,} points)", v * 1000,
                                 a.names[i], b.names[j], f"{a.arm} {a.poses[p]}; {b.arm} {b.poses[s]}"))
    return out


def least(clearances: list[Clearance]) -> Clearance | None:
    return min(clearances, key=lambda c: c.clearance_mm) if clearances else None


#: Docking rolls (deg) each PSM may take about its neutral shaft when a layout's links do not clear at the run's
#: own roll (the docking frame's x turned toward its y; issue 40's "docking roll searched per arm").
ROLL_GRID_DEG = tuple(range(-90, 91, 15))
#: Roll combinations whose docked links clear that are then checked over the target too: this many of least cost,
#: then this many that clear docked by the most.
ROLL_FULL_CHECKS = 4
#: Costs of two roll combinations within this are a tie (broken by the docked clearance).
COST_TIE = 1e-9


def turn_words(cfg) -> tuple[str, str]:
    """(what a PSM's docking turn is, its participle): on the Classic the roll about the neutral shaft; on the Si,
    whose setup joints fix the roll, the yaw of its planar chain off psi* (S5, S6), the arm's own yaw and pitch
    absorbing more."""
    return cart_for(cfg).turn


def turned_frames(cfg, site: np.ndarray, arm: str, turns_rad: np.ndarray) -> np.ndarray:
    """(R, 3, 3) PSM ``arm``'s docking frames at ``site`` (m, patient frame) turned by each of ``turns_rad``
    (``turn_words``): the default frame rolled about its shaft (Classic), or the Si's at psi* + the turn, by its
    arm's own setup joints (``tables.si_frames``)."""
    return cart_for(cfg).turned_frames(cfg, site, role_of(arm), turns_rad)


def rolled_reach(model, row: dict, arm: str) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """PSM ``arm``'s (``psm1`` ...) port of a layout's row docked at each turn of ROLL_GRID_DEG (``turn_words``:
    a roll about its neutral shaft, or on the Si a yaw off psi*): (its frames (R, 3, 3), full reach (R,), the
    isotropy at each target point (R, points; eq. P5, 0 where it does not reach), the port (3,) m), by the
    kernel's own tables in the turned frames."""
    from surgopt.studies.port_place.arms import instrument_reach

    site = np.array([row[f"{arm}_{c}_mm"] for c in "xyz"]) / 1000
    rolls = np.radians(np.array(ROLL_GRID_DEG, float))
    frames = turned_frames(model.cfg, site, arm, rolls)
    reach, dex = instrument_reach(model, np.repeat(site[None], len(rolls), axis=0), frames)
    return frames, reach.all(axis=1), dex, site


def rolled_docks(model, row: dict, arm: str, patient: np.ndarray, reached=None) -> list[tuple[float, object]]:
    """(turn in deg, ``tables.DockedArm``) for each turn of ROLL_GRID_DEG at which PSM ``arm`` (``psm1`` ...)
    still reaches every target point from its port (``rolled_reach``, or ``reached``: its answer already had)
    and its setup joints dock the turned frame within their ranges (S2; the Si's S3, S7) with their mount above the
    table top (unless ``cart.mount_below_table_top = 'allow'``, ``tables.mount_heights_m``). A DockedArm's
    ``roll_deg`` is the Classic's roll; on the Si, 0 (the turn is a yaw, in the returned degrees)."""
    from surgopt.studies.port_place.tables import DockedArm, base_pose

    from surgopt.studies.port_place.tables import mount_heights_m

    cfg = model.cfg
    frames, full, _, site = rolled_reach(model, row, arm) if reached is None else reached
    low = (mount_heights_m(cfg, role_of(arm), np.asarray(frames), np.repeat(np.asarray(site)[None], len(frames), 0))
           < 0.0) & (cfg.cart.mount_below_table_top == "refuse")
    out = []
    for deg, rot, ok, below in zip(ROLL_GRID_DEG, frames, full, low):
        if not ok or below:  # it loses a target point, or its mount would stand below the table top
            continue
        base = patient @ base_pose(rot, site)
        got = cart_for(cfg).psm_docking(role_of(arm), base)
        if got.joints:
            out.append((float(deg), DockedArm(role_of(arm), str(row[f"{arm}_site"]), got.joints, got.margin,
                                              got.tightest, "", tuple(site), base, (),
                                              cart_for(cfg).docked_roll_deg(deg))))
    return out


def rolled_cost(cfg, row: dict, dex: dict) -> tuple[float, float]:
    """(dexterity_mean, cost) of a layout's row with its PSMs docked at other rolls, ``dex`` each PSM's isotropy
    at every target point so docked (by ``psm1`` ...; full reach, as a roll is only taken with it): the pair's
    dexterity is the mean over the points of the smaller of PSM1's and PSM2's (eq. P5), PSM3's its own mean, and
    the cost (P11) the row's with those dexterity terms replaced (the other terms do not depend on the roll)."""
    w = cfg.objective.dexterity
    pair = float(np.mean(np.minimum(dex["psm1"], dex["psm2"])))
    cost = row["cost"] + w * (row["dexterity_mean"] - pair)
    if "psm3" in dex:
        cost += w * (row["psm3_dexterity_mean"] - float(np.mean(dex["psm3"])))
    return pair, cost


class RollsThatClear(NamedTuple):
    """Per-PSM docking rolls (deg, by arm) at which a layout's every clearance outside the body is >= 0, the least
    of them and all of them (``layout_clearances`` so docked); ``tried``: the roll combinations whose arms all
    reach and dock."""

    rolls: dict
    least: Clearance | None
    tried: int
    clearances: tuple = ()
    arms: tuple = ()  # ``tables.DockedArm`` of each arm so docked (the PSMs rolled, then the ECM)
    dexterity: float | None = None  # the layout's dexterity_mean so docked (``rolled_cost``)
    cost: float | None = None  # and its cost


def rolls_that_clear(model, row: dict) -> RollsThatClear:
    """``_rolls_that_clear``, kept for the process (``memoised``)."""
    return memoised("rolls", model.cfg, row, lambda: _rolls_that_clear(model, row))


def _rolls_that_clear(model, row: dict) -> RollsThatClear:
    """A layout's PSMs docked at every combination of ROLL_GRID_DEG (each PSM's own roll; the ECM as it docks):
    each combination's docked arms' least clearance to each other (fast: one pose each) and its cost so docked
    (``rolled_cost``: the dexterity changes with the roll). Of those that clear docked, the ROLL_FULL_CHECKS of
    least cost are checked in full (``layout_clearances``: over the target, the patient, the table), cheapest
    first (ties within COST_TIE: the most docked clearance first), then the ROLL_FULL_CHECKS that clear docked by
    the most; the first whose least clearance is >= 0, or ``least`` None."""
    import itertools

    from surgopt.kinematics.port.capsules import least_pair_clearance
    from surgopt.studies.port_place.tables import docked_arms, row_patient_in_cart

    cfg = model.cfg
    patient = row_patient_in_cart(cfg, row)
    ecm = [a for a in docked_arms(model, row) if a.arm == "ECM" and a.joints]
    psms = [a for a in ("psm1", "psm2", "psm3") if f"{a}_site" in row]
    reached = {a: rolled_reach(model, row, a) for a in psms}
    options = {a: rolled_docks(model, row, a, patient, reached[a]) for a in psms}
    isotropy = {a: dict(zip(ROLL_GRID_DEG, reached[a][2])) for a in psms}
    none = np.zeros((0, 3))
    docked_pose = {(a, deg): arm_poses(model, d, patient, none) for a in psms for deg, d in options[a]}
    ecm_pose = arm_poses(model, ecm[0], patient, none) if ecm else None

    def pair(p, q):
        return least_pair_clearance(p.segments[0], p.radii, q.segments[0], q.radii)[0]

    with_ecm = {k: pair(p, ecm_pose) if ecm_pose is not None else np.inf for k, p in docked_pose.items()}
    between_psms = {}  # each (arm, roll) pair once, however many combinations share it

    def psms_pair(x, y):
        if (x, y) not in between_psms:
            between_psms[x, y] = pair(docked_pose[x], docked_pose[y])
        return between_psms[x, y]

    combos = []
    for choice in itertools.product(*([(a, deg) for deg, _ in options[a]] for a in psms)):
        c = min([with_ecm[k] for k in choice] + [psms_pair(x, y) for x, y in itertools.combinations(choice, 2)])
        dexterity, cost = rolled_cost(cfg, row, {a: isotropy[a][int(deg)] for a, deg in choice})
        combos.append((c, cost, dexterity, choice))
    docked_clear = [t for t in combos if t[0] >= 0]
    # costs equal to COST_TIE (the default's: the roll moves no isotropy there) taken by docked clearance, not
    # by rounding
    cheapest = sorted(docked_clear, key=lambda t: (round(t[1] / COST_TIE), -t[0]))[:ROLL_FULL_CHECKS]
    clearest = [t for t in sorted(docked_clear, key=lambda t: -t[0]) if t not in cheapest][:ROLL_FULL_CHECKS]
    for c, cost, dexterity, choice in cheapest + clearest:
        arms = [dict(options[a])[deg] for a, deg in choice] + ecm
        found = layout_clearances(model, row, arms)
        worst = least(found)
        if worst is not None and worst.clearance_mm >= 0:  # the first that clears, cheapest first
            return RollsThatClear({role_of(a): deg for a, deg in choice}, worst, len(combos), tuple(found),
                                  tuple(arms), dexterity, cost)
    return RollsThatClear({}, None, len(combos))


def mounts_below_table_top(cfg, row: dict, docked) -> dict:
    """Each docked arm whose mount (the setup joints' last frame, where the arm's own links begin) lies below the
    table top: its depth there (mm). Clear of the bedside the model has (``bedside.py``), such an arm still rises from
    beside the table, where the model's boxes are only assumed sizes: a docking to check."""
    from surgopt.kinematics.port import suj as S
    from surgopt.studies.port_place.tables import row_patient_in_cart

    patient = row_patient_in_cart(cfg, row)
    out = {}
    for a in docked:
        if a.joints:
            mount = S.frames(PLATFORMS[cfg.cart.model].suj(a.arm), a.joints)[-2, :3, 3]
            z = float((mount - patient[:3, 3]) @ patient[:3, 2]) * 1000  # height over the table top
            if z < 0:
                out[a.arm] = -z
    return out


def docking_that_clears(model, row: dict):
    """(the arms as docked, each PSM's docking roll about its shaft in deg where it was turned, what was done,
    the links' clearances so docked): the run's own docking when the layout's links clear outside the body; else,
    when some combination of each PSM's roll clears them (``clashes.rolls_that_clear``: full reach and the setup
    joints' ranges kept), the PSMs docked so, so that the file a robot loads does not dock arms whose links
    overlap."""
    from surgopt.studies.port_place.tables import docked_arms

    cfg = model.cfg
    docked = docked_arms(model, row)
    clearances = layout_clearances(model, row)
    worst = least(clearances)
    own = cart_for(cfg).own_docking
    turn, _ = turn_words(cfg)
    if worst is None or worst.clearance_mm >= 0:
        return docked, {}, own, clearances
    found = rolls_that_clear(model, row)
    if found.least is None:
        return docked, {}, (f"{own}; their links overlap outside the body by {-worst.clearance_mm:.0f} mm "
                            f"({worst.link_a} / {worst.link_b}) and no {turn} of each PSM (of {found.tried} that "
                            f"reach and dock) clears them"), clearances
    turned = {a.arm: a for a in found.arms if a.arm in found.rolls}  # as the roll search docked them
    arms = [turned.get(a.arm, a) for a in docked]
    how = cart_for(cfg).turned_how(found.rolls)
    return (arms, found.rolls,
            f"{how} so that the links clear outside the body (least {found.least.clearance_mm:.0f} mm: "
            f"{found.least.link_a} / {found.least.link_b}); at the run's own docking they overlap by {-worst.clearance_mm:.0f} mm "
            f"({worst.link_a} / {worst.link_b}); the run's rows are at its own docking (cost {row['cost']:.4f}), so "
            f"docked its dexterity_mean is {found.dexterity:.4f} and its cost {found.cost:.4f}"
            + below_table_note(cfg, row, arms), list(found.clearances))


def below_table_note(cfg, row: dict, docked) -> str:
    """"; PSM2's mount 58 mm below the table top, ..." for arms docked from below the table top."""
    low = mounts_below_table_top(cfg, row, docked)
    if not low:
        return ""
    return ("; " + ", ".join(f"{a}'s mount {d:.0f} mm below the table top" for a, d in low.items())
            + " (beside the table: clear of the bedside's boxes, whose sizes are assumptions; check that side)")
