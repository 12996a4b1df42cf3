"""How port-place's arms hold their tools (issue 53): each way is a class, chosen once from the config's robot by
``instruments_held`` / ``camera_held``; every difference between an RCM arm and a serial arm keeping the RCM in
software is a method or an attribute here, and no other module of port-place reads which kind a config has.

- ``RcmInstruments``: each instrument on an RCM arm (a dVRK PSM, or an RCM arm from a file, ``robot.instrument_arm``
  / ``instrument_file``). The mechanism keeps the RCM; reach is its inverse within the arm's ``ArmLimits`` (eq. P1,
  docs/port_placement.md "Reach"); it docks in a frame that a search may tilt (yaw, pitch) and a run may roll.
- ``SerialInstruments``: a serial arm holding each instrument and keeping the RCM at the port in software
  (``robot.instrument_serial``; its tables in ``serial_arms``): reach is the arm's own IK by continuation over the
  target; a search turns its base about the port (yaw only); it has no docking frame to roll.
- ``RcmCamera`` / ``SerialCamera``: the endoscope likewise (``robot.camera_arm`` / ``camera_file``, or
  ``robot.camera_serial``, placed by the arm's IK at the tip the scope needs).

The arms' limits and kernels' inputs built from a config live here too (``arm_limits``, ``instrument_limits``,
``serial_kernel``, ``walk_order``). Adding an arm kind is one class here (and its config field).
"""
from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from surgopt.studies.port_place.config import PortPlaceConfig, Target, camera_arm_of, instrument_of
from surgopt.studies.port_place.geometry import target_points_mm

#: An RCM instrument's per-port tables: ~60 ns per site x target point (its closed-form inverse).
NS_PER_SITE_POINT = 60.0
#: A serial instrument arm's per-port tables: ~3.4 us per site x target point (generic Newton IK by continuation,
#: benchmarks/bench_port_place.py: 0.55 s for 164 x 915 at 91 % reached).
NS_PER_SITE_POINT_SERIAL = 4000.0


class SerialKernel(NamedTuple):
    """A serial arm's inputs to ``kinematics.port.serial``, read once from its DH table or URDF: the chain's
    arrays, the IK's seed and restarts, the tool's length past the flange (m). Its RCM (``rcm_in_base_m``) is
    read from the arm itself, since a search moves it (``stance``)."""

    chain: tuple
    seed: np.ndarray
    restarts: np.ndarray
    tool_m: float


class Reached(NamedTuple):
    """The instruments' reach[site, point] and dexterity[site, point] at some ports, and, for a serial arm, its
    clearance outside the body per pair of sites (m) and its ``SerialTables`` (None for an RCM arm: the shafts'
    lines decide outside, ``kinematics.port.place.external_clearances``)."""

    reach: np.ndarray
    dexterity: np.ndarray
    outside_m: np.ndarray | None
    serial: object | None


def serial_kernel(arm) -> SerialKernel:
    """A ``SerialInstrumentArm``'s chain arrays, seed and restarts (``kinematics.serial_chain``)."""
    from surgopt.kinematics.serial_chain import default_restarts, kernel_arrays

    chain, _, seed = arm.chain()
    seed = np.asarray(seed, np.float64)
    return SerialKernel(kernel_arrays(chain), seed, default_restarts(seed), float(arm.tool_past_flange_m))


def walk_order(target: Target, centre_m: np.ndarray) -> tuple:
    """Prim's order over the target's points from the one nearest the centre (``serial.prim_order``): the
    continuation a serial arm's IK walks."""
    from surgopt.kinematics.port.serial import prim_order

    pts = target_points_mm(target) / 1000
    root = int(np.argmin(np.linalg.norm(pts - centre_m, axis=1)))
    return prim_order(pts, root)


def arm_limits(arm):
    """The kernel's ``ArmLimits`` of an arm (``dvrk.RcmArm`` or ``rcm_arm.RcmLimits``; a spherical mechanism with
    its axes)."""
    from surgopt.kinematics.port.place import ArmLimits

    axes = getattr(arm, "yaw_axis", None)
    spherical = (True, *arm.yaw_axis, *arm.pitch_axis) if axes is not None else ()
    return ArmLimits(*arm.yaw_limits_rad, *arm.pitch_limits_rad, *arm.insertion_limits_m, arm.along_shaft_m,
                     *spherical)


def reach_offsets_m(cfg: PortPlaceConfig, arm) -> tuple[float, float]:
    """(tip past the wrist, least wrist depth), m: the config's ``robot.tip_beyond_wrist_mm`` and
    ``robot.min_wrist_depth_mm``, or, where they are not given, the arm's own (``dvrk.RcmArm``: the Large Needle
    Driver's 9.1 mm, the PSM controller's 45 mm; 0 for an arm from a file)."""
    r = cfg.robot
    tip = getattr(arm, "tip_beyond_wrist_m", 0.0) if r.tip_beyond_wrist_mm is None else r.tip_beyond_wrist_mm / 1000
    depth = (getattr(arm, "min_wrist_depth_m", 0.0) if r.min_wrist_depth_mm is None
             else r.min_wrist_depth_mm / 1000)
    return tip, depth


def instrument_limits(cfg: PortPlaceConfig, arm):
    """The instrument's ``ArmLimits`` with the config's reaching point and least wrist depth: the reaching point
    moved from the wrist to the tip (along_shaft_m + tip: the point rcm_point puts on a target point, eq. P1), and
    insertion's lower limit raised so that the wrist, at q3 + the wrist's own offset from the RCM, lies at least
    the least depth inside (q3 >= depth - offset)."""
    limits = arm_limits(arm)
    tip, depth = reach_offsets_m(cfg, arm)
    wrist = limits.along_shaft_m
    return limits._replace(along_shaft_m=wrist + tip, insertion_lo=max(limits.insertion_lo, depth - wrist))


def instrument_reach(model, sites: np.ndarray, frames: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """[site, point] (reach, isotropy) of an RCM arm's instrument at ports ``sites`` (m) docked in ``frames``: eq.
    P1's inverse within the limits, the approach cone, eq. P5 (``instrument_tables``), and no shaft through an organ
    (``organs.clear_reach``). Every RCM instrument's reach is taken here."""
    from surgopt.kinematics.port import place as K
    from surgopt.studies.port_place.organs import clear_reach

    reach, dex = K.instrument_tables(sites, frames, model.targets_m, model.limits, model.criteria.dexterity_length_m,
                                     model.cone)
    return clear_reach(model, sites, reach, dex)


def approach_mask(sites: np.ndarray, targets: np.ndarray, cone) -> np.ndarray:
    """[site, point]: whether the shaft from the port to the point lies within the approach cone's reach of the
    wrist (``instrument_tables``' test, for arms whose reach is computed elsewhere)."""
    d = targets[None, :, :] - sites[:, None, :]
    return d @ np.array([cone.dx, cone.dy, cone.dz]) >= cone.cos_min * np.linalg.norm(d, axis=2)


# ---- the instruments


class RcmInstruments:
    """Each instrument on an RCM arm: the mechanism keeps the RCM at the port."""

    #: A search's free docking turns the arm's docking frame by these angles (``study.docking_columns``).
    docking_angles = ("yaw", "pitch")
    #: Whether the docking frame can be rolled about the shaft (``robot.docking_roll``; the rows' roll columns).
    rolls = True
    ns_per_site_point = NS_PER_SITE_POINT

    @classmethod
    def prepare(cls, cfg: PortPlaceConfig, centre_m: np.ndarray) -> "RcmInstruments":
        return cls()

    def limits(self, cfg: PortPlaceConfig):
        """The kernels' ``ArmLimits`` of the instrument with the config's tip and least wrist depth."""
        return instrument_limits(cfg, instrument_of(cfg))

    def reach(self, model, sites: np.ndarray, frames: np.ndarray, base_yaw_rad=None) -> Reached:
        """Reach and isotropy of each port's instrument docked in ``frames`` (``instrument_tables``: eq. P1's
        inverse within the limits, the approach cone, eq. P5)."""
        reach, dex = instrument_reach(model, sites, frames)
        return Reached(reach, dex, None, None)

    def turned(self, frames: np.ndarray, docking_deg: np.ndarray) -> tuple[np.ndarray, None]:
        """(frames, base yaws) of ports docked with a search's ``docking_deg`` (yaw, pitch per instrument, then
        the camera's 0, 0): the docking frames tilted (``tilted_frames``); no base to turn."""
        from surgopt.kinematics.port import place as K

        return K.tilted_frames(frames, np.radians([*docking_deg[0::2], 0.0]),
                               np.radians([*docking_deg[1::2], 0.0])), None

    @classmethod
    def docks_in_own_frames(cls, cfg: PortPlaceConfig) -> bool:
        """Whether a run's trials dock each instrument in frames of their own (a search's yaw and pitch, or its
        rolls), not the grid's at its sites."""
        return cfg.robot.docking_roll == "search" or cfg.robot.docking_range_deg > 0

    def docked_lines(self, model, sites: np.ndarray) -> None:
        """The arm's centre lines at its docked pose, drawn beside the ports: an RCM arm is drawn by its cart
        (or not at all)."""
        return None

    def refused_note(self, model) -> str:
        """What a config could change when no port's instrument reaches the whole target (beyond the target)."""
        return ""

    @classmethod
    def outside_length_m(cls, cfg: PortPlaceConfig) -> float:
        """The outside segment of the instruments' external clearance (the shaft behind the port): the RCM arm's
        own (``RcmArm.outside_length_m``: the Classic PSM's 0.4318 m, the Si's 0.4826 m)."""
        return instrument_of(cfg).outside_length_m


class SerialInstruments(RcmInstruments):
    """Each instrument on a serial arm keeping the RCM at the port in software (``serial_arms``)."""

    docking_angles = ("yaw",)
    rolls = False
    ns_per_site_point = NS_PER_SITE_POINT_SERIAL

    def __init__(self, kernel: SerialKernel, walk: tuple):
        self.kernel, self.walk = kernel, walk

    @classmethod
    def prepare(cls, cfg: PortPlaceConfig, centre_m: np.ndarray) -> "SerialInstruments":
        return cls(serial_kernel(cfg.robot.instrument_serial), walk_order(cfg.target, centre_m))

    def limits(self, cfg: PortPlaceConfig) -> None:
        return None  # the arm's own IK decides

    def reach(self, model, sites: np.ndarray, frames: np.ndarray, base_yaw_rad=None) -> Reached:
        """The serial arm's tables at the ports (``serial_arms.serial_tables``), its base turned by
        ``base_yaw_rad``; reach within the approach cone, and its links' clearance outside."""
        from surgopt.studies.port_place.serial_arms import serial_tables

        from surgopt.studies.port_place.organs import clear_reach

        serial = serial_tables(model, sites, base_yaw_rad)
        reach = serial.reach & approach_mask(sites, model.targets_m, model.cone)
        reach, dex = clear_reach(model, sites, reach, np.where(reach, serial.dexterity, 0.0))  # the organs
        return Reached(reach, dex, serial.outside_m, serial)

    def turned(self, frames: np.ndarray, docking_deg: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The default docking frames (the camera's RCM mechanism), each serial base turned by its yaw."""
        return frames, np.radians([*docking_deg[0::2], 0.0])

    @classmethod
    def docks_in_own_frames(cls, cfg: PortPlaceConfig) -> bool:
        return False

    def docked_lines(self, model, sites: np.ndarray) -> np.ndarray:
        """(ports, joints, 3) m: the arm's centre line (base, joints, flange, port) at its docked pose at each
        port (``serial_tables``)."""
        from surgopt.studies.port_place.serial_arms import serial_tables

        return serial_tables(model, sites).links

    def refused_note(self, model) -> str:
        from surgopt.studies.port_place.serial_arms import refused_ports_note

        return (f"; stand the arm elsewhere (robot.instrument_serial.rcm_in_base_m, base_yaw_deg: rcm-grid finds "
                f"where an arm keeps an RCM best){refused_ports_note(model, model.sites_m)}")

    @classmethod
    def outside_length_m(cls, cfg: PortPlaceConfig) -> float:
        """A serial arm's links are measured themselves (``docked_lines``); its shafts' outside segment is the
        Classic PSM's (``dvrk.OUTSIDE_LENGTH_M``), as the external-clearance check has always taken it."""
        from surgopt.robots import dvrk

        return dvrk.OUTSIDE_LENGTH_M


def instruments_held(config=None) -> type[RcmInstruments]:
    """How a config's instruments are held (its class): a config, a stored config (a dict) or none (a dVRK PSM)."""
    return SerialInstruments if _robot_field(config, "instrument_serial") is not None else RcmInstruments


# ---- the endoscope


class RcmCamera:
    """The endoscope on an RCM arm (the dVRK ECM, or one from a file)."""

    @classmethod
    def prepare(cls, cfg: PortPlaceConfig) -> "RcmCamera":
        return cls()

    @classmethod
    def limits(cls, cfg: PortPlaceConfig):
        """The camera mechanism's ``ArmLimits``, its insertion's lower limit raised to the least insertion (the
        config's ``robot.camera_min_insertion_mm``, else the arm's own: the dVRK ECM's 50 mm, ``dvrk.
        ECM_SAFE_INSERTION_M``), so that the scope's tip is out of the cannula, inside the body."""
        arm = camera_arm_of(cfg)
        limits = arm_limits(arm)
        given = cfg.robot.camera_min_insertion_mm
        least = getattr(arm, "min_insertion_m", 0.0) if given is None else given / 1000
        return limits._replace(insertion_lo=max(limits.insertion_lo, least))

    def hold(self, model, sites: np.ndarray, views) -> None:
        """Where the arm holds the scope at each port, when it must be solved (``SerialCamera``): the RCM
        mechanism's range is the kernel's."""
        return None

    def docked_lines(self, model, sites: np.ndarray) -> None:
        return None

    def check(self, model, tables) -> None:
        """Refuse a config in which no port can hold the camera (nothing to refuse: the grid's coverage says)."""


class SerialCamera(RcmCamera):
    """The endoscope held by a serial arm keeping its RCM at the port in software."""

    def __init__(self, kernel: SerialKernel):
        self.kernel = kernel

    @classmethod
    def prepare(cls, cfg: PortPlaceConfig) -> "SerialCamera":
        return cls(serial_kernel(cfg.robot.camera_serial))

    @classmethod
    def limits(cls, cfg: PortPlaceConfig):
        """Open ranges: the arm's own IK decides where it can hold the scope (``hold``)."""
        from surgopt.kinematics.port.place import ArmLimits

        return ArmLimits(-math.pi, math.pi, -math.pi / 2, math.pi / 2, 0.0, 10.0, 0.0)

    def hold(self, model, sites: np.ndarray, views):
        from surgopt.studies.port_place.serial_arms import serial_camera_tables

        return serial_camera_tables(model, sites, views[0], views[2])

    def docked_lines(self, model, sites: np.ndarray) -> np.ndarray:
        """(ports, joints, 3) m: the arm's centre line at each port docked as the grid docks it (NaN where it
        cannot hold the scope)."""
        from surgopt.kinematics.port import place as K
        from surgopt.studies.port_place.carts import LATERAL

        frames = K.docking_frames(sites, model.centre_m, LATERAL)
        return self.hold(model, sites, K.camera_views(sites, frames, model.centre_m, model.camera)).links

    def check(self, model, tables) -> None:
        if not tables.coverage.any():
            raise ValueError(f"robot.camera_serial: the arm ({camera_arm_of(model.cfg).name}) holds the endoscope "
                             f"where it must be at no candidate port, so no layout has a camera; stand it elsewhere "
                             f"(rcm_in_base_m, base_yaw_deg) or give it a longer tool")


def camera_held(config=None) -> type[RcmCamera]:
    """How a config's endoscope is held (its class), as ``instruments_held``."""
    return SerialCamera if _robot_field(config, "camera_serial") is not None else RcmCamera


def _robot_field(config, name: str):
    """``config.robot.<name>`` of a validated config, a stored one (a dict) or none (None)."""
    if config is None:
        return None
    if isinstance(config, dict):
        return (config.get("robot") or {}).get(name)
    return getattr(config.robot, name)
