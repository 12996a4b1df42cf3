"""One stored layout, re-solved once, for every view (issue 53: "the views import no kernel and never rebuild a
pose themselves: they read a ``Layout``").

A layout's row holds its ports, its cart pose and every number the rows computed; the views (the closing report,
the figures, the page, the robot files) also need what the rows do not store: each arm's setup joints and base
frame, the links' clearances and their pairs. ``layout_of`` solves them once per (config, row) in a process, docked
as the robot files dock them (``clashes.docking_that_clears``: the run's own docking, or where the links overlap
there, a roll of each PSM that clears them, said so), and the helpers below give the views what they draw or write
from it (a setup joint chain's frames, an arm's joints at the target's centre) so that no view calls a kernel.
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np

from surgopt.robots.dvrk.platforms import PLATFORMS


class Layout(NamedTuple):
    """A row re-solved on its cart: the patient's frame in the cart's world frame (4x4, m; None without a cart),
    each arm docked (``tables.DockedArm``, PSMs then the ECM), each PSM's roll off the run's own docking where it
    was turned (deg), what docking that is in words, and the links' least clearances so docked (``clashes``)."""

    row: dict
    patient_in_cart: np.ndarray | None
    docked: list
    rolls: dict
    docking: str
    clearances: list

    def frames_of(self) -> dict:
        """Each docked arm's base (RCM) frame in the cart's world frame (4x4, m), by arm name."""
        return {a.arm: a.base for a in self.docked if a.base is not None and a.joints}


def layout_of(model, row: dict) -> Layout:
    """``row`` (a layout of a run with a cart) on its prepared model (``model.PortModel``) docked as the robot files
    dock it, solved once per (config, row) in a process (``clashes.memoised``): every view of one layout reads the
    same solve."""
    from surgopt.studies.port_place.clashes import docking_that_clears, memoised
    from surgopt.studies.port_place.tables import row_patient_in_cart

    def solve() -> Layout:
        docked, rolls, docking, clearances = docking_that_clears(model, row)
        return Layout(dict(row), row_patient_in_cart(model.cfg, row), docked, rolls, docking, clearances)

    return memoised("layout", model.cfg, row, solve)


def setup_joint_frames(cfg, arm) -> np.ndarray:
    """(links + 2, 4, 4) The frames of a docked arm's setup joints (``tables.DockedArm``) in the cart's world frame:
    its world-to-SUJ frame, each link, the tool origin (S1, ``kinematics/port/suj.frames``)."""
    from surgopt.kinematics.port import suj as S

    return S.frames(PLATFORMS[cfg.cart.model].suj(arm.arm), arm.joints)


def mount_point_m(cfg, arm) -> np.ndarray:
    """A docked arm's mount (the setup joints' last frame, where its own links begin) in the cart's world frame (m)."""
    return setup_joint_frames(cfg, arm)[-2, :3, 3]


def arm_joints_at_centre(limits, base_in_patient: np.ndarray, centre_m: np.ndarray) -> list[float]:
    """An instrument arm's yaw, pitch (rad) and insertion (m) that put its reaching point (the tip or the wrist,
    as the run's ``ArmLimits`` say) on the target's centre (``kinematics.port.place.rcm_inverse``, eq. P2, in its
    base frame)."""
    from surgopt.kinematics.port.place import rcm_inverse

    p = base_in_patient[:3, :3].T @ (centre_m - base_in_patient[:3, 3])
    return [float(v) for v in rcm_inverse(p, limits.along_shaft_m)]


def docked_lines_mm(model, row: dict) -> dict | None:
    """(#56 item 4) The cart and its arms as a layout's row docks them, for a scene in the patient's frame (mm):
    ``arms``: per docked arm, its role and one polyline (rows of x, y, z; None between pieces) of its setup joints'
    frames (``setup_joint_frames``) and its own links' capsule axes (``clashes.arm_poses``, as the rows place them);
    ``cart``: the outline of the cart's base on the floor (``Platform.footprint_m``) and its column from the floor
    to its origin. None without a cart. The run's own docking (``tables.docked_arms``), as the row was decided."""
    from surgopt.studies.port_place.carts import has_cart
    from surgopt.studies.port_place.clashes import arm_poses
    from surgopt.studies.port_place.tables import docked_arms, row_patient_in_cart

    cfg = model.cfg
    if not has_cart(cfg):
        return None
    patient = row_patient_in_cart(cfg, row)
    to_patient = np.linalg.inv(patient)
    in_patient = lambda p: p @ to_patient[:3, :3].T + to_patient[:3, 3]  # noqa: E731 - cart world (m) -> patient (m)
    arms = []
    for arm in docked_arms(model, row):
        if not arm.joints:
            continue
        pieces = [in_patient(setup_joint_frames(cfg, arm)[:-1, :3, 3])]
        links = arm_poses(model, arm, patient, model.targets_m[:0])
        pieces += [links.segments[0, i] for i, n in enumerate(links.names) if "setup joint" not in n]
        arms.append([arm.arm, _polyline_mm(pieces)])
    platform = PLATFORMS[cfg.cart.model]
    (x0, y0), (x1, y1) = platform.footprint_m
    floor = -platform.world_above_floor_m
    base = np.array([[x0, y0, floor], [x1, y0, floor], [x1, y1, floor], [x0, y1, floor], [x0, y0, floor]])
    column = np.array([[0.0, 0.0, floor], [0.0, 0.0, 0.0]])
    return {"arms": arms, "cart": _polyline_mm([in_patient(base), in_patient(column)])}


def _polyline_mm(pieces) -> list:
    """Pieces of polylines (each (k, 3), m) as one list of [x, y, z] mm rounded to 0.1 mm, None between pieces."""
    out = []
    for p in pieces:
        if out:
            out.append(None)
        out += [[round(float(v) * 1000, 1) for v in q] for q in np.asarray(p, float)]
    return out


def layout_isotropy(model, row: dict) -> np.ndarray:
    """(target points,) The instruments' smaller isotropy (eq. P5) at each target point, docked as the layout's
    row says (its docking yaw and pitch, eq. P3, then its rolls: a searched trial's own frames), NaN where one of
    them does not reach it: what the figures and the page colour a searched layout's target by."""
    from surgopt.kinematics.port import place as K
    from surgopt.studies.port_place.arms import instrument_reach
    from surgopt.studies.port_place.carts import LATERAL, rolled
    from surgopt.studies.port_place.columns import arms_of

    arms = arms_of(model.cfg)[:-1]
    sites = np.array([[row[f"{a}_{c}_mm"] for c in "xyz"] for a in arms]) / 1000
    turn = {angle: np.radians([row.get(f"{a}_docking_{angle}_deg", 0.0) for a in arms]) for angle in ("yaw", "pitch")}
    rot = K.tilted_frames(K.docking_frames(sites, model.centre_m, LATERAL), turn["yaw"], turn["pitch"])
    frames = rolled(rot, np.radians([row[f"{a}_roll_deg"] for a in arms]))
    reach, dex = instrument_reach(model, sites, frames)
    return np.where(reach.all(axis=0), dex.min(axis=0), np.nan)
