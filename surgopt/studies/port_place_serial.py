"""port-place's instruments on serial arms that keep the RCM in software (``[robot.instrument_serial]``): each
candidate port's reach and dexterity, and the arms' clearance outside the body, from ``kinematics.port_serial``.

A port is refused for the arm (it reaches nothing there) when the arm's base would stand inside the patient's
body, or when its links, at the docked pose, pass through the body or nearer its wall than their radius
(``link_radius_mm``; the centre lines sampled at ``LINK_SAMPLES`` points a segment)."""
from __future__ import annotations

from functools import lru_cache
from typing import NamedTuple

import numpy as np

from surgopt.studies.port_place_config import PortPlaceConfig, body_distance_mm, inside_body, target_points_mm
from surgopt.studies.rcm_arm_config import SerialInstrumentArm

#: Points sampled along each link segment for the inside-the-body check.
LINK_SAMPLES = 9


class SerialTables(NamedTuple):
    """reach[site, point], dexterity[site, point] (sigma_min / sigma_max of the RCM metric), the arms' least
    centre-line distance outside the body per pair of sites (m), the joints at each (site, point) (NaN where
    unreached), each site's base frame and link centre lines at the docked pose, and why a site was refused
    (0: usable; 1: base inside the body; 2: links through the body, or nearer it than their radius, at the
    docked pose)."""

    reach: np.ndarray
    dexterity: np.ndarray
    outside_m: np.ndarray
    joints: np.ndarray
    base_rot: np.ndarray
    base_pos: np.ndarray
    links: np.ndarray
    refused: np.ndarray


BASE_INSIDE, LINKS_INSIDE = 1, 2


@lru_cache(maxsize=4)
def arm_kernel(arm_json: str):
    """(chain arrays, seed, restarts, rcm (m), tool length past the flange (m)) of a serial instrument arm, once
    per process."""
    from surgopt.kinematics.serial_chain import default_restarts, kernel_arrays

    arm = SerialInstrumentArm.model_validate_json(arm_json, context={"stored": True})
    chain, _, seed = arm.chain()
    seed = np.asarray(seed, np.float64)
    return (kernel_arrays(chain), seed, default_restarts(seed), np.asarray(arm.rcm_in_base_m, np.float64),
            float(arm.tool_past_flange_m))


@lru_cache(maxsize=4)
def walk_order(target_json: str, centre: tuple):
    """Prim's order over the target points from the one nearest the centre (``port_serial.prim_order``), once per
    target."""
    from surgopt.kinematics.port_serial import prim_order
    from surgopt.studies.port_place_config import Target

    pts = target_points_mm(Target.model_validate_json(target_json)) / 1000
    root = int(np.argmin(np.linalg.norm(pts - np.asarray(centre), axis=1)))
    return prim_order(pts, root)


def _stand(cfg: PortPlaceConfig, arm, sites: np.ndarray, extra_yaw_rad=None):
    """(the arm's kernel inputs (``arm_kernel``), base rotations, base origins, refused) of a serial ``arm`` standing
    at ports ``sites`` (m), turned by ``base_yaw_deg`` and ``extra_yaw_rad``: BASE_INSIDE where its base would
    stand inside the body."""
    from surgopt.kinematics import port_serial as S

    kernel = arm_kernel(arm.model_dump_json())
    centre = np.asarray(cfg.target.centre_mm, float) / 1000
    yaw = np.radians(arm.base_yaw_deg) + (0.0 if extra_yaw_rad is None else np.asarray(extra_yaw_rad, float))
    rot, pos = S.serial_base_frames(sites, centre, kernel[3], yaw)
    return kernel, rot, pos, np.where(inside_body(pos * 1000, cfg.patient), BASE_INSIDE, 0)


def _docked(cfg: PortPlaceConfig, arm, kernel, joints: np.ndarray, rot, pos, refused: np.ndarray):
    """(centre lines, through) of the arm at its docked ``joints`` (n, 5; NaN: none): where its links come through
    or near the wall (``_links_inside``) the port is refused (``refused`` set to LINKS_INSIDE) and its line NaN."""
    from surgopt.kinematics import port_serial as S

    chain, _, _, rcm, tool_m = kernel
    links = S.link_polylines(chain, np.ascontiguousarray(joints), tool_m, rcm, rot, pos)
    through = _links_inside(links, cfg, arm.link_radius_mm)
    refused[through & (refused == 0)] = LINKS_INSIDE
    links[through] = np.nan
    return links, through


def serial_tables(cfg: PortPlaceConfig, sites: np.ndarray, extra_yaw_rad=None) -> SerialTables:
    """The serial instrument arm's tables at ports ``sites`` (m), each base turned by ``base_yaw_deg`` and, when
    given, by ``extra_yaw_rad`` at each site (a search's free docking)."""
    from surgopt.kinematics import port_serial as S

    arm = cfg.robot.instrument_serial
    kernel, rot, pos, refused = _stand(cfg, arm, sites, extra_yaw_rad)
    chain, seed, restarts, rcm, tool_m = kernel
    targets = target_points_mm(cfg.target) / 1000
    centre = np.asarray(cfg.target.centre_mm, float) / 1000
    order, parent = walk_order(cfg.target.model_dump_json(), tuple(centre))
    joints = np.empty((len(sites), len(targets), 5))
    reach, dex = S.serial_instrument_tables(chain, seed, restarts, rcm, tool_m, rot, pos, targets, order, parent,
                                            refused == 0, joints)
    near = np.where(reach, np.linalg.norm(targets - centre, axis=1)[None, :], np.inf).argmin(axis=1)
    docked = joints[np.arange(len(sites)), near]  # NaN where a site reaches nothing
    links, through = _docked(cfg, arm, kernel, docked, rot, pos, refused)
    reach[through] = False
    dex[through] = 0.0
    return SerialTables(reach, dex, S.link_clearances(links), joints, rot, pos, links, refused)


def _links_inside(links: np.ndarray, cfg: PortPlaceConfig, radius: float) -> np.ndarray:
    """Per site: whether any sampled point of its arm's link centre lines, base to flange, lies inside the body
    or nearer its wall than ``radius`` (mm: the arm's ``link_radius_mm``; the last segment, flange to port, is the
    tool entering the body)."""
    s = np.linspace(0.0, 1.0, LINK_SAMPLES)[None, None, :, None]
    links = links[:, :-1]
    samples = links[:, :-1, None, :] * (1 - s) + links[:, 1:, None, :] * s  # (n, segments, samples, 3)
    flat = samples.reshape(-1, 3) * 1000
    ok = np.isfinite(flat[:, 0])
    hit = np.zeros(len(flat), bool)
    hit[ok] = inside_body(flat[ok], cfg.patient)
    if radius > 0:
        out = ok & ~hit
        hit[out] = body_distance_mm(flat[out], cfg.patient, radius) < radius
    return hit.reshape(len(links), -1).any(axis=1)


class SerialCamera(NamedTuple):
    """Per port: whether the serial arm holds the endoscope's tip where the scope must be (``camera_views``' tip,
    its shaft through the port), its joints there, its base frame and centre line, and why a port was refused
    (as ``SerialTables.refused``)."""

    placed: np.ndarray
    joints: np.ndarray
    base_rot: np.ndarray
    base_pos: np.ndarray
    links: np.ndarray
    refused: np.ndarray


def serial_camera_tables(cfg: PortPlaceConfig, sites: np.ndarray, tips: np.ndarray, ok: np.ndarray) -> SerialCamera:
    """The serial endoscope arm at ports ``sites`` (m): at each port whose scope can be placed (``ok``), the arm's
    IK with the tip at ``tips`` and the tool line through the port, on the seeded branch (one target point a
    port: the anchor is the point itself), within the limits and with the RCM on the tool; refused where its
    base would stand inside the body or its links, there, come nearer the wall than ``link_radius_mm``."""
    from surgopt.kinematics import port_serial as S

    arm = cfg.robot.camera_serial
    kernel, rot, pos, refused = _stand(cfg, arm, sites)
    chain, seed, restarts, rcm, tool_m = kernel
    joints = np.full((len(sites), 5), np.nan)
    one = np.zeros(1, np.int64)
    for i in np.flatnonzero(ok & (refused == 0)):
        q = np.empty((1, 1, 5))
        S.serial_instrument_tables(chain, seed, restarts, rcm, tool_m, rot[i:i + 1], pos[i:i + 1],
                                   np.ascontiguousarray(tips[i:i + 1]), one, one - 1, np.ones(1, bool), q)
        joints[i] = q[0, 0]
    links, through = _docked(cfg, arm, kernel, joints, rot, pos, refused)
    placed = np.isfinite(joints[:, 0]) & ~through
    return SerialCamera(placed, joints, rot, pos, links, refused)


def camera_lines(cfg: PortPlaceConfig, sites: np.ndarray) -> np.ndarray:
    """The serial endoscope arm's centre lines (m) at ports ``sites`` docked as the grid docks them (NaN where it
    cannot hold the scope): what the figures draw."""
    from surgopt.kinematics import port_place as K
    from surgopt.studies.port_place import LATERAL, camera_of

    centre = np.asarray(cfg.target.centre_mm, float) / 1000
    tips, _, ok = K.camera_views(sites, K.docking_frames(sites, centre, LATERAL), centre, camera_of(cfg))
    return serial_camera_tables(cfg, sites, tips, ok).links


def refused_ports_note(cfg: PortPlaceConfig, sites: np.ndarray) -> str:
    """How many of the ports ``sites`` (m) the arm cannot stand at (its base inside the body, its links through
    the wall), as a clause for a message; empty when none."""
    refused = serial_tables(cfg, sites).refused
    base, links = int((refused == BASE_INSIDE).sum()), int((refused == LINKS_INSIDE).sum())
    if not base + links:
        return ""
    return (f" ({base} of the {len(refused)} ports put the arm's base inside the body, {links} its links through or "
            f"within link_radius_mm of the wall)")
