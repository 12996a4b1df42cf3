"""Port-place's carts as classes: every branch on which cart a config models is a method here (issue 53).

``cart_for(cfg)`` gives the config's cart: ``NoCart`` (docking assumed), or the class of its platform's family of
setup joints (``Platform.suj_family``, ``robots/dvrk/platforms.py``): ``ClassicCart`` (a column and five revolute
joints: the docking frame's roll about the shaft is free; S2, S4) or ``SiCart`` (a column, planar joints and two
fixed links: one orientation per yaw, psi*; S3, S5-S7). ``FAMILIES`` is the one map from a family to its class. A
platform of an existing family is data alone (``PLATFORMS``); a new family is one class here.

Also here, because every cart class uses them: the patient's frame in the cart's world frame at a floor pose
(``patient_in_cart``), a frame turned about its shaft (``rolled``) and the Si's frames at psi* (``si_frames``).
"""
from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from surgopt.robots.chain import rot_x, rot_y, rot_z
from surgopt.robots.dvrk.platforms import PLATFORMS, Platform, platform_of

class PsmDocking(NamedTuple):
    """One PSM's setup joints at one base frame (``ClassicCart.psm_docking``): the best solution's joints (m for the
    column, rad; empty when none is within the ranges), its least range margin (None then), the joint of that
    margin, and why none is within (empty when one is)."""

    joints: tuple
    margin: float | None
    tightest: str
    reason: str


#: The lateral direction the neutral docking frame's x is taken from (patient frame: the patient's left).
LATERAL = np.array([1.0, 0.0, 0.0])


def rolled(rot: np.ndarray, roll_rad: np.ndarray) -> np.ndarray:
    """rot[i] Rz(roll_i): each base frame turned about its own z (the neutral shaft's line), its x toward its y
    for a positive roll."""
    c, s = np.cos(roll_rad)[:, None], np.sin(roll_rad)[:, None]
    out = np.array(rot, dtype=np.float64, copy=True)
    out[:, :, 0] = c * rot[:, :, 0] + s * rot[:, :, 1]
    out[:, :, 1] = c * rot[:, :, 1] - s * rot[:, :, 0]
    return out


def patient_in_cart(cart, x_mm: float, y_mm: float, heading_deg: float) -> np.ndarray:
    """(4, 4) The patient's frame in the cart's world frame (m), the cart's origin at (x, y) on the floor of the
    patient's untilted frame F, heading ``heading_deg`` (its +y toward F's +y turned toward +x), the patient tilted
    in F about the table top under the frame's origin: T_cart_patient = T_F_cart^-1 T_F_patient with
    T_F_patient = Rx(-trendelenburg) Ry(-lateral tilt) (head down, left side up) and T_F_cart =
    [Rz(-heading), (x, y, the cart's world above the floor - table height)]
    (``Platform.world_above_floor_m``; 0 with no cart). ``cart``: the config's [cart]."""
    platform = platform_of(cart.model)
    f_cart = np.eye(4)
    f_cart[:3, :3] = rot_z(-math.radians(heading_deg))[:3, :3]
    f_cart[:3, 3] = (x_mm / 1000, y_mm / 1000, (platform.world_above_floor_m if platform else 0.0)
                     - cart.table_height_mm / 1000)
    f_patient = np.eye(4)
    f_patient[:3, :3] = (rot_x(-math.radians(cart.trendelenburg_deg))
                         @ rot_y(-math.radians(cart.lateral_tilt_deg)))[:3, :3]
    return np.linalg.inv(f_cart) @ f_patient


def row_patient_in_cart(cfg, row) -> np.ndarray:
    """(4, 4) ``patient_in_cart`` at a row's own cart pose (``cart_x_mm``, ``cart_y_mm``, ``cart_heading_deg``):
    the one place a view turns a row's columns into the cart's pose."""
    return patient_in_cart(cfg.cart, row["cart_x_mm"], row["cart_y_mm"], row["cart_heading_deg"])


def si_frames(cfg, suj, sites: np.ndarray, aims: np.ndarray, turn_rad: float = 0.0) -> np.ndarray:
    """(n, 3, 3) Each port's docking rotation on the Si cart, in the patient's frame: the orientation its setup
    joints give at psi*, the yaw that leaves the arm's own yaw and pitch the least to absorb to point the shaft
    along ``aims`` (n, 3, unit, patient frame; ``si_docking.si_frame``, S5-S6). Independent of the cart's pose on
    the floor (turning the cart turns psi* with it), so one frame per port serves every pose of the grid. The Si's
    PSM1 and PSM2 give the same frames (their bases differ by a half turn about the vertical). ``turn_rad``: each
    yawed that much off psi* (the report's search for clear links, ``clashes.turned_frames``)."""
    from surgopt.kinematics.port.si_docking import si_frame

    p = patient_in_cart(cfg.cart, 0.0, 0.0, 0.0)[:3, :3]
    return np.array([p.T @ si_frame(suj, p @ a, turn_rad) for a in aims]).reshape(len(sites), 3, 3)


def roll_sides(sites: np.ndarray) -> np.ndarray:
    """+1 for a port on the patient's left (x >= 0), -1 on the right: a docking turn's sense, mirrored about the
    midline."""
    return np.where(sites[:, 0] >= 0.0, 1.0, -1.0)


def given_turns_rad(cfg, sites: np.ndarray) -> np.ndarray:
    """Each port's docking turn as the config gives it (rad, signed by ``roll_sides``): ``robot.docking_roll_deg``,
    on the patient's right ``docking_roll_right_deg`` when given: a roll about the neutral shaft on the Classic, a
    yaw of the setup joints off psi* on the Si (#54)."""
    r = cfg.robot
    side = roll_sides(sites)
    right = r.docking_roll_deg if r.docking_roll_right_deg is None else r.docking_roll_right_deg
    return np.radians(np.where(side > 0, r.docking_roll_deg, right)) * side


def _turned_si_frames(cfg, suj, sites: np.ndarray, aims: np.ndarray, turns_rad: np.ndarray) -> np.ndarray:
    """``si_frames`` of each port at its own turn off psi* (a few distinct turns: one call each)."""
    out = np.empty((len(sites), 3, 3))
    for t in np.unique(turns_rad):
        at = turns_rad == t
        out[at] = si_frames(cfg, suj, sites[at], aims[at], float(t))
    return out


def _unit_aims(centre_m: np.ndarray, sites: np.ndarray) -> np.ndarray:
    aims = centre_m - sites
    return aims / np.linalg.norm(aims, axis=1)[:, None]


def _neutral(cfg, site: np.ndarray) -> np.ndarray:
    from surgopt.kinematics.port import place as K

    return K.docking_frames(site[None], np.asarray(cfg.target.centre_mm, float) / 1000, LATERAL)


class NoCart:
    """No cart: docking assumed (``cart.model = "none"``); each PSM's docking frame rolled as the config says."""

    platform: Platform | None = None
    docks = False
    roll_is_free = True
    #: (what a PSM's docking turn is, its participle): the roll about its neutral shaft
    turn = ("roll about the shaft", "rolled")
    own_docking = "the run's docking frames (robot.docking_roll)"

    def instrument_frames(self, model, sites: np.ndarray, rot: np.ndarray, rolls_rad: np.ndarray) -> np.ndarray:
        """The instrument arms' docking frames at ``sites``: ``rot`` turned by each port's roll."""
        return rolled(rot, rolls_rad)

    def third_frames(self, model, sites: np.ndarray) -> np.ndarray | None:
        """The third instrument's frames where they are not PSM1's and PSM2's (None: they are)."""
        return None

    def turned_frames(self, cfg, site: np.ndarray, role: str, turns_rad: np.ndarray) -> np.ndarray:
        """(R, 3, 3) PSM ``role``'s docking frames at ``site`` turned by each of ``turns_rad`` (``turn``)."""
        return rolled(np.repeat(_neutral(cfg, site), len(turns_rad), axis=0), turns_rad)

    def docked_roll_deg(self, turn_deg: float) -> float:
        """A DockedArm's roll about its shaft when docked at ``turn_deg`` of ``turn``."""
        return float(turn_deg)

    def turned_how(self, rolls: dict) -> str:
        """How the report's screen docked the PSMs it turned (``rolls``: role -> deg)."""
        return "each PSM's docking frame turned about its neutral shaft by docking_roll_deg (x toward y)"

    def check(self, cfg) -> None:
        """What this cart refuses of a config, as a ValueError "field: why" (nothing here)."""


class ClassicCart(NoCart):
    """A cart of the Classic's family: a prismatic column and five revolute joints per arm (S1); each PSM's setup
    joints solved in closed form for its docking frame at any roll (S2), the ECM's with its own yaw and pitch
    aiming the scope (S4)."""

    docks = True
    #: Why no setup joint values dock a PSM, in words (``psm_docking``).
    out_of_reach = "beyond the setup joints' reach, or a tilt their wrist cannot give"

    def __init__(self, platform: Platform):
        self.platform = platform

    def psm_docking(self, role: str, base: np.ndarray) -> "PsmDocking":
        """One PSM's setup joints for its base frame ``base`` (4x4) in the cart's world frame, by the rows' own solver
        (``psm_solutions``: the batch S2, the Si's S3 and S7; issue 53, one implementation in production): the best
        solution's joints, its least range margin and that joint, or why none is within the ranges."""
        suj = self.platform.suj(role)
        margin, q = self.psm_solutions(role, np.asarray(base, float)[None])
        least, q = float(margin[0]), q[0, :suj.n_joints]
        if not math.isfinite(least):
            return PsmDocking((), None, "", f"{suj.cart} {suj.arm} SUJ: no joint values put the arm's base there "
                                            f"({self.out_of_reach})")
        k = int(np.argmin([min(v - lo, hi - v) for v, (lo, hi) in zip(q, suj.ranges)]))
        name = suj.links[k].name
        if least >= 0.0:
            return PsmDocking(tuple(float(v) for v in q), least, name, "")
        unit, scale = ("m", 1.0) if name == "column" else ("deg", 180 / math.pi)
        lo, hi = suj.ranges[k]
        return PsmDocking((), None, name, f"{suj.cart} {suj.arm} SUJ {name} = {q[k] * scale:.4g} {unit}, outside its "
                                          f"range [{lo * scale:.4g}, {hi * scale:.4g}] {unit} (the nearest solution)")

    def psm_solutions(self, role: str, bases: np.ndarray, third_bases=None) -> tuple[np.ndarray, np.ndarray]:
        """(least margin, joints (n, 6)) of the best solution for each of ``bases`` (n, 4, 4) of PSM ``role``
        (``suj_batch``, S2 jitted); ``third_bases``: PSM3's own bases where its frames are its own (unused)."""
        from surgopt.kinematics.port.suj_batch import classic_psm_solutions, suj_arrays

        return classic_psm_solutions(suj_arrays(self.platform.suj(role)), bases)

    def camera_dock(self, cfg, arm, patients: np.ndarray, sites_m: np.ndarray, shafts: np.ndarray):
        """The ECM's setup joints at ports ``sites_m`` for each patient pose in ``patients`` (m, 4, 4), its own yaw
        and pitch aiming the scope along ``shafts`` (``suj_batch.ecm_margins``, S4): (margin, joints, yaw and
        pitch), per pose then port."""
        from surgopt.kinematics.port.suj import ECM_GRID_STEPS
        from surgopt.kinematics.port.suj_batch import ecm_arrays, ecm_margins

        origins = np.concatenate([sites_m @ p[:3, :3].T + p[:3, 3] for p in patients])
        aims = np.concatenate([shafts @ p[:3, :3].T for p in patients])
        s = ecm_arrays(self.platform.suj("ECM"), arm.yaw_limits_rad, arm.pitch_limits_rad)
        return ecm_margins(s, np.ascontiguousarray(origins), np.ascontiguousarray(aims), *ECM_GRID_STEPS)


class SiCart(ClassicCart):
    """A cart of the Si's family: a column, three (PSM3: four) planar joints and two fixed links per arm (S3): one
    docking orientation per yaw of the planar chain, taken at psi* (S5, S6), the arm's own yaw and pitch absorbing
    the rest; no roll about the shaft to choose. Its PSM3 hangs 15 deg off the vertical (S7), the others 45."""

    roll_is_free = False
    turn = ("yaw off psi*", "yawed")
    out_of_reach = "beyond the setup joints' reach, or off the orientations the Si's setup joints give"
    own_docking = "the Si's docking frames (each PSM at psi*, S6)"

    def instrument_frames(self, model, sites, rot, rolls_rad):
        """PSM1's and PSM2's frames at psi* (the same for both; ``si_frames``), each yawed off it by its port's
        docking turn (``rolls_rad``: the config's, ``given_turns_rad``; 0 at psi*)."""
        return _turned_si_frames(model.cfg, self.platform.suj("PSM1"), sites, _unit_aims(model.centre_m, sites),
                                 np.asarray(rolls_rad, float) if rolls_rad is not None
                                 else given_turns_rad(model.cfg, sites))

    def third_frames(self, model, sites):
        """PSM3's own frames at psi* (it hangs 15 deg off the vertical) with three instruments, yawed off it by the
        config's docking turn as the others are."""
        if model.cfg.robot.instrument_count != 3:
            return None
        return _turned_si_frames(model.cfg, self.platform.suj("PSM3"), sites, _unit_aims(model.centre_m, sites),
                                 given_turns_rad(model.cfg, sites))

    def turned_frames(self, cfg, site, role, turns_rad):
        """The Si's frames at psi* + each turn, by the arm's own setup joints."""
        centre = np.asarray(cfg.target.centre_mm, float) / 1000
        aim = (centre - site) / np.linalg.norm(centre - site)
        return np.concatenate([si_frames(cfg, self.platform.suj(role), site[None], aim[None], t) for t in turns_rad])

    def docked_roll_deg(self, turn_deg):
        return 0.0  # the turn is a yaw of the planar chain, not a roll about the shaft

    def turned_how(self, rolls):
        return ("each PSM's Si setup joints yawed off psi* by " + ", ".join(f"{a} {d:+.0f} deg" for a, d in rolls.items())
                + " (its own yaw and pitch absorbing the rest)")

    def psm_solutions(self, role, bases, third_bases=None):
        """S3, S7 batched: the column and three (PSM3: four) planar joints, the rest NaN."""
        from surgopt.kinematics.port.si_docking import si_solutions

        got, q = si_solutions(self.platform.suj(role), bases if third_bases is None else third_bases)
        return got, np.concatenate([q, np.full((len(q), 6 - q.shape[1]), np.nan)], axis=1)

    def camera_dock(self, cfg, arm, patients, sites_m, shafts):
        """Each port's ECM base at psi* (``si_frames``), the ECM's own yaw and pitch that point the scope along its
        shaft (``si_docking.own_joints``, the same at every cart pose) within the ECM's ranges, and its setup
        joints at each pose (S3, ``si_docking.si_solutions``). The margin, as the Classic's (S4): the least of the
        setup joints' and the own yaw's and pitch's margins (rad; the column's in m)."""
        from surgopt.kinematics.port.si_docking import own_joints, si_solutions

        suj = self.platform.suj("ECM")
        n, m = len(sites_m), len(patients)
        rot = si_frames(cfg, suj, sites_m, shafts)
        own = np.array([own_joints(r, a)[:2] for r, a in zip(rot, shafts)]).reshape(n, 2)
        (ylo, yhi), (plo, phi) = arm.yaw_limits_rad, arm.pitch_limits_rad
        own_margin = np.minimum.reduce([own[:, 0] - ylo, yhi - own[:, 0], own[:, 1] - plo, phi - own[:, 1]])
        bases = np.zeros((n, 4, 4))
        bases[:, :3, :3], bases[:, :3, 3], bases[:, 3, 3] = rot, sites_m, 1.0
        in_cart = np.einsum("pij,njk->pnik", patients, bases).reshape(m * n, 4, 4)  # per pose, then port
        margin, q = si_solutions(suj, in_cart)
        margin = np.minimum(margin, np.tile(own_margin, m))
        return margin, np.concatenate([q, np.full((m * n, 2), np.nan)], axis=1), np.tile(own, (m, 1))

    def check(self, cfg):
        """Its setup joints fix each arm's roll about its shaft; the docking turn is a yaw of the planar chain off
        psi* (#54), given (docking_roll_deg, docking_roll_right_deg) or enumerated (docking_rolls_deg): a roll
        chosen per port or searched is refused by name."""
        if cfg.robot.docking_roll != "given":
            raise ValueError("robot.docking_roll: on the Si the docking turn is a yaw of the setup joints off psi* "
                             "(no roll about the shaft to choose): docking_roll = 'given', with docking_roll_deg "
                             "(or docking_rolls_deg to enumerate several) the yaw in deg")


#: Each family of setup joints (``Platform.suj_family``) and the class that docks its arms.
FAMILIES = {"classic": ClassicCart, "si": SiCart}
NO_CART = NoCart()


def cart_named(model: str) -> NoCart:
    """The cart a ``cart.model`` names (``NO_CART`` for "none"): its platform's family's class on its platform,
    read from the registry when asked (a few attributes: nothing to keep)."""
    if model == "none":
        return NO_CART
    platform = PLATFORMS[model]
    return FAMILIES[platform.suj_family](platform)


def cart_for(cfg) -> NoCart:
    """The cart a validated config models."""
    return cart_named(cfg.cart.model)


def cart_of(config) -> str:
    """The ``cart.model`` a config names: validated, as stored (a dict), or none ("none")."""
    if isinstance(config, dict):
        return (config.get("cart") or {}).get("model", "none")
    return "none" if config is None else config.cart.model


def has_cart(config) -> bool:
    """Whether a config (validated, as stored, or None) docks its arms by a cart's setup joints."""
    return cart_named(cart_of(config)).docks
