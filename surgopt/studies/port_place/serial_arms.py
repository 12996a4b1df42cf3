"""port-place's instruments on serial arms that keep the RCM in software (``[robot.instrument_serial]``): each
candidate port's reach and dexterity, and the arms' clearance outside the body, from ``kinematics.port.serial``.

A port is refused for the arm (it reaches nothing there) when the arm's base would stand inside the patient's
body, or when its links, at the docked pose, pass through the body or nearer its wall than their radius
(``link_radius_mm``; the centre lines sampled at ``LINK_SAMPLES`` points a segment)."""
from __future__ import annotations

from typing import NamedTuple

import numpy as np

from surgopt.studies.port_place.geometry import body_distance_mm, inside_body

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


def _stand(model, arm, sites: np.ndarray, extra_yaw_rad=None):
    """(rcm in the base (m), base rotations, base origins, refused) of a serial ``arm`` standing at ports ``sites``
    (m), turned by ``base_yaw_deg`` and ``extra_yaw_rad``: BASE_INSIDE where its base would stand inside the
    body."""
    from surgopt.kinematics.port import serial as S

    rcm = np.asarray(arm.rcm_in_base_m, np.float64)
    yaw = np.radians(arm.base_yaw_deg) + (0.0 if extra_yaw_rad is None else np.asarray(extra_yaw_rad, float))
    rot, pos = S.serial_base_frames(sites, model.centre_m, rcm, yaw)
    return rcm, rot, pos, np.where(inside_body(pos * 1000, model.cfg.patient), BASE_INSIDE, 0)


def _docked(model, arm, kernel, rcm, joints: np.ndarray, rot, pos, refused: np.ndarray):
    """(centre lines, through) of the arm at its docked ``joints`` (n, 5; NaN: none): where its links come through
    or near the wall (``_links_inside``) the port is refused (``refused`` set to LINKS_INSIDE) and its line NaN."""
    from surgopt.kinematics.port import serial as S

    links = S.link_polylines(kernel.chain, np.ascontiguousarray(joints), kernel.tool_m, rcm, rot, pos)
    through = _links_inside(links, model.cfg, arm.link_radius_mm)
    refused[through & (refused == 0)] = LINKS_INSIDE
    links[through] = np.nan
    return links, through


def serial_tables(model, sites: np.ndarray, extra_yaw_rad=None) -> SerialTables:
    """The serial instrument arm's tables at ports ``sites`` (m), each base turned by ``base_yaw_deg`` and, when
    given, by ``extra_yaw_rad`` at each site (a search's free docking); ``model``: the config's ``PortModel``."""
    from surgopt.kinematics.port import serial as S

    arm, k = model.cfg.robot.instrument_serial, model.instruments.kernel
    rcm, rot, pos, refused = _stand(model, arm, sites, extra_yaw_rad)
    targets, centre = model.targets_m, model.centre_m
    order, parent = model.instruments.walk
    joints = np.empty((len(sites), len(targets), 5))
    reach, dex = S.serial_instrument_tables(k.chain, k.seed, k.restarts, rcm, k.tool_m, rot, pos, targets, order,
                                            parent, refused == 0, joints)
    near = np.where(reach, np.linalg.norm(targets - centre, axis=1)[None, :], np.inf).argmin(axis=1)
    docked = joints[np.arange(len(sites)), near]  # NaN where a site reaches nothing
    links, through = _docked(model, arm, k, rcm, docked, rot, pos, refused)
    reach[through] = False
    dex[through] = 0.0
    return SerialTables(reach, dex, S.link_clearances(links), joints, rot, pos, links, refused)


def _links_inside(links: np.ndarray, cfg, radius: float) -> np.ndarray:
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


def serial_camera_tables(model, sites: np.ndarray, tips: np.ndarray, ok: np.ndarray) -> SerialCamera:
    """The serial endoscope arm at ports ``sites`` (m): at each port whose scope can be placed (``ok``), the arm's
    IK with the tip at ``tips`` and the tool line through the port, on the seeded branch (one target point a
    port: the anchor is the point itself), within the limits and with the RCM on the tool; refused where its
    base would stand inside the body or its links, there, come nearer the wall than ``link_radius_mm``."""
    from surgopt.kinematics.port import serial as S

    arm, k = model.cfg.robot.camera_serial, model.endoscope.kernel
    rcm, rot, pos, refused = _stand(model, arm, sites)
    joints = np.full((len(sites), 5), np.nan)
    one = np.zeros(1, np.int64)
    for i in np.flatnonzero(ok & (refused == 0)):
        q = np.empty((1, 1, 5))
        S.serial_instrument_tables(k.chain, k.seed, k.restarts, rcm, k.tool_m, rot[i:i + 1], pos[i:i + 1],
                                   np.ascontiguousarray(tips[i:i + 1]), one, one - 1, np.ones(1, bool), q)
        joints[i] = q[0, 0]
    links, through = _docked(model, arm, k, rcm, joints, rot, pos, refused)
    placed = np.isfinite(joints[:, 0]) & ~through
    return SerialCamera(placed, joints, rot, pos, links, refused)


def refused_ports_note(model, sites: np.ndarray) -> str:
    """How many of the ports ``sites`` (m) the arm cannot stand at (its base inside the body, its links through
    the wall), as a clause for a message; empty when none."""
    refused = serial_tables(model, sites).refused
    base, links = int((refused == BASE_INSIDE).sum()), int((refused == LINKS_INSIDE).sum())
    if not base + links:
        return ""
    return (f" ({base} of the {len(refused)} ports put the arm's base inside the body, {links} its links through or "
            f"within link_radius_mm of the wall)")
