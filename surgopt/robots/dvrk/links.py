"""The dVRK Classic and Si arms' links outside the body, as capsules (a segment and a radius) for the clash check of
issue 40: where the links are is data (sourced), how thick they are is an assumption (labelled).

Where the links are: the Classic PSM's skeleton as the dVRK's own robot description writes it,
jhu-dvrk/dvrk-ros ``dvrk_model/model/psm.base.urdf.xacro`` (commit be3910ac): each frame's parent, origin (xyz m,
roll-pitch-yaw rad, URDF's fixed-axis convention R = Rz(yaw) Ry(pitch) Rx(roll)) and the joint it turns about its
z with (yaw q1, pitch q2 times the parallelogram's mimic multiplier +-1, or insertion q3 along z). The frame
``base`` is the PSM's base frame, whose origin is the RCM: at (q1, q2) the carriage-to-wrist line of this
skeleton is the shaft u(q1, q2) of the DH model (``kinematics.port.place.shaft_direction``,
tests/test_capsules.py checks it), so both descriptions agree where they overlap. The ECM's arm beyond its
setup joints is not in that file; it is modelled as its scope's carriage, a line behind the RCM (below).

How thick they are: the PSMs' own links (Classic and Si) are capsules fitted to the arms' own meshes
(jhu-dvrk/dvrk_model, ``dvrk.link_envelopes``, written by tools/fit_link_envelopes.py: each contains its mesh,
tests/test_link_envelopes.py). What has no mesh placed on this skeleton stays an *assumption*, labelled as such:
the setup joints' links 50 mm radius, the link from the SUJ's tip to the arm 45 mm, the Si instrument's housing
40 mm (its mesh is empty in that repository), the ECM's carriage and camera 40 mm; the shaft outside the port 4 mm
and the ECM's scope 6 mm are the instruments' own 8 mm and 12 mm (data). Read each radius as the link's half width.
"""
from __future__ import annotations

import math
from typing import NamedTuple


class LinkFrame(NamedTuple):
    """One frame of the arm's skeleton: T_parent_frame = Trans(xyz) RPY(rpy) then the joint, a turn about ``axis``
    (z unless given) by ``multiplier * (q[joint] + offset_rad)`` (revolute) or a slide along it (``prismatic``);
    joint -1: fixed."""

    name: str
    parent: str
    xyz_m: tuple
    rpy_rad: tuple
    joint: int  # 0 yaw, 1 pitch, 2 insertion, -1 none
    multiplier: float = 1.0
    prismatic: bool = False
    axis: tuple = (0.0, 0.0, 1.0)
    offset_rad: float = 0.0  # the file's joint zero less the DH model's (added to q before the multiplier)


class Capsule(NamedTuple):
    """A link as the segment between two points (each in a frame of the skeleton, m) and a radius (m)."""

    name: str
    frame_a: str
    point_a_m: tuple
    frame_b: str
    point_b_m: tuple
    radius_m: float
    source: str


HALF_PI = math.pi / 2

#: The link model in a few words, for the reports and the export beside every clearance.
LINK_MODEL_WORDS = ("capsules: the PSMs' own links fitted to the dVRK's meshes, the setup joints', the ECM's and the "
                    "mounts' radii assumed")

#: The Classic PSM's skeleton (psm.base.urdf.xacro): the yaw link turns about the base's -y through the RCM; the
#: parallelogram's back and front pivots sit on it 0.5185 and 0.4285 m from the RCM; its bottom and top links
#: turn back by -q2 (mimic -1), the lower long link (0.520 m) forward again; the carriage ("tool_main") slides
#: along the shaft, 0.4318 m behind the RCM at q3 = 0.
PSM_CLASSIC_FRAMES = (
    LinkFrame("yaw", "base", (0.0, 0.0, 0.0), (0.0, -HALF_PI, HALF_PI), 0),
    LinkFrame("pitch", "yaw", (0.0, 0.0, 0.0), (-HALF_PI, -HALF_PI, 0.0), 1),
    LinkFrame("back", "yaw", (0.0, 0.0295, 0.5185), (-HALF_PI, -HALF_PI, 0.0), 1),
    LinkFrame("front", "yaw", (0.0, 0.0295, 0.4285), (-HALF_PI, -HALF_PI, 0.0), 1),
    LinkFrame("bottom", "back", (0.04178, 0.15007, -0.0137), (0.0, 0.0, 0.0), 1, -1.0),
    LinkFrame("top", "back", (0.04209, 0.18695, -0.02412), (0.0, 0.0, 0.0), 1, -1.0),
    LinkFrame("insertion", "bottom", (-0.520, 0.0, -0.0155), (0.0, 0.0, 0.0), 1),
    LinkFrame("carriage", "pitch", (0.0, 0.4318, 0.0), (HALF_PI, 0.0, 0.0), 2, 1.0, True),
)

URDF = "jhu-dvrk/dvrk-ros psm.base.urdf.xacro"
ASSUMED = "radius assumed"


def mesh_capsules(skeleton: str) -> tuple:
    """The PSM's links as fitted to its own meshes (``dvrk.link_envelopes``, issue 54), each named with its mesh
    and how loose its fit is (the capsules' volume over the mesh's convex hull)."""
    from surgopt.robots.dvrk import link_envelopes as E

    fits = [e for e in E.ENVELOPES if e.skeleton == skeleton]
    loose = {}
    for e in fits:
        loose[e.mesh] = loose.get(e.mesh, 0.0) + e.capsule_volume_l / e.hull_volume_l
    return tuple(Capsule(e.name, e.frame, e.point_a_m, e.frame, e.point_b_m, e.radius_m,
                         f"{E.REPOSITORY}@{E.COMMIT} {e.mesh}: fitted, x{loose[e.mesh]:.1f} its hull's volume")
                 for e in fits)


#: "mount": the SUJ's tip (the base frame's point where SUJ_tip_to_tool_origin starts, ``dvrk.suj``) is added
#: by the code as frame "mount"; the capsule between it and the yaw link closes the arm to its setup joints (its
#: radius an assumption). The arm's own links are its meshes' fitted capsules (``mesh_capsules``): the mount's
#: housing, the yaw link, the parallelogram's four links, the insertion stage and the instrument's housing; the
#: shaft outside the port is the instrument's 8 mm.
PSM_CLASSIC_CAPSULES = (
    Capsule("mount", "mount", (0.0, 0.0, 0.0), "back", (0.0, 0.0, 0.0), 0.045, f"{URDF}, suj-simulated.json; "
            f"{ASSUMED}"),
    *mesh_capsules("PSM_CLASSIC"),
    Capsule("shaft outside the port", "carriage", (0.0, 0.0, 0.0), "base", (0.0, 0.0, 0.0), 0.004,
            "dvrk-kinematics.md: 8 mm shaft"),
)

#: The ECM's yaw and pitch are the PSM's (their DH rows 1 and 2 are the same), so its skeleton is the first two
#: frames; the scope runs behind the RCM along the pitch frame's +y.
ECM_CLASSIC_FRAMES = PSM_CLASSIC_FRAMES[:2]

#: The ECM beyond its setup joints: its carriage and camera as one line behind the RCM along the scope, from
#: the port to 0.3822 m (its insertion offset at q3 = 0) plus 0.1 m of camera head (an assumption throughout).
ECM_CLASSIC_CAPSULES = (
    Capsule("mount", "mount", (0.0, 0.0, 0.0), "pitch", (0.0, 0.4822, 0.0), 0.04, f"suj-simulated.json; "
            f"{ASSUMED}"),
    Capsule("scope outside the port", "base", (0.0, 0.0, 0.0), "pitch", (0.0, 0.2822, 0.0), 0.006,
            "dvrk-kinematics.md: 12 mm camera port"),
    Capsule("carriage and camera", "pitch", (0.0, 0.2822, 0.0), "pitch", (0.0, 0.4822, 0.0), 0.04,
            f"ECM.json insertion offset; {ASSUMED}"),
)

#: The Si PSM's skeleton (jhu-dvrk/dvrk_model urdf/Si/PSM_base.urdf.xacro): the arm's base 0.843 m from the RCM
#: (its mount: the Si's SUJ tip is 0.834 m from it), the yaw about the RCM frame's -y, the pitch and its
#: parallelogram's two mimic links (-1, +1), the adaptor (the carriage) sliding along the shaft 0.4826 m behind the
#: RCM at q3 = 0. The file's pitch zero is PSM_Si.json's less SI_PITCH_OFFSET_RAD = 0.16292 rad (9.3 deg): with it
#: the adaptor's insertion axis is the DH shaft u(q1, q2) to 1.2e-5 over yaw +-1.2, pitch +-1.0 rad, passing within
#: 3.9 mm of the RCM (the parallelogram's rounded numbers); ``tests/test_capsules.py`` holds this.
SI_PITCH_OFFSET_RAD = 0.16292
SI_URDF = "jhu-dvrk/dvrk_model urdf/Si/PSM_base.urdf.xacro"
PSM_SI_FRAMES = (
    LinkFrame("arm base", "base", (0.0, -0.84316314, 0.0), (0.0, 0.0, HALF_PI), -1),
    LinkFrame("yaw", "arm base", (0.158, 0.0, 0.0), (0.0, 0.0, 0.0), 0, axis=(-1.0, 0.0, 0.0)),
    LinkFrame("pitch", "yaw", (0.2987, 0.0, -0.071222), (0.0, -1.1345, -3.1416), 1, axis=(0.0, -1.0, 0.0),
              offset_rad=-SI_PITCH_OFFSET_RAD),
    LinkFrame("pitch 2", "pitch", (0.2032, 0.0, 0.0), (0.0, -0.90761, -3.1416), 1, -1.0, axis=(0.0, 1.0, 0.0),
              offset_rad=-SI_PITCH_OFFSET_RAD),
    LinkFrame("pitch 3", "pitch 2", (0.35966, 0.0, 0.16013), (0.0, -0.063963, 0.0), 1, axis=(0.0, 1.0, 0.0),
              offset_rad=-SI_PITCH_OFFSET_RAD),
    LinkFrame("carriage", "pitch 3", (0.11523752, 0.0, 0.31095531), (math.pi, 0.0, -math.pi), 2, 1.0, True),
)

#: The Si PSM's links outside the body: the mount (assumed, as the Classic's), its meshes' fitted capsules (the arm
#: base, the yaw and pitch links, the parallelogram, the insertion stage), the instrument's housing (the Si housing's
#: mesh is empty in the dVRK's repository: the Classic's length and radius, assumed) and the shaft.
PSM_SI_CAPSULES = (
    Capsule("mount", "mount", (0.0, 0.0, 0.0), "arm base", (0.0, 0.0, 0.0), 0.045, f"{SI_URDF}, suj-si-simulated"
            f".json; {ASSUMED}"),
    *mesh_capsules("PSM_SI"),
    Capsule("instrument housing", "carriage", (0.0, 0.0, 0.0), "carriage", (0.0, 0.0, -0.08), 0.04,
            f"{SI_URDF}; length and {ASSUMED}"),
    Capsule("shaft outside the port", "carriage", (0.0, 0.0, 0.0), "base", (0.0, 0.0, 0.0), 0.004,
            "dvrk-kinematics.md: 8 mm shaft"),
)

#: The setup joints' links: the segments between successive frames of ``kinematics.port.suj.frames``; the first two
#: (the cart's column and the arm's carriage on it) are part of the cart and not checked between arms.
SUJ_RADIUS_M = 0.05


def through_port(capsules) -> list[bool]:
    """Which of an arm's capsules pass through its port (they end at the base frame, the RCM): the shaft or the
    scope outside the port, left out of the check against the patient's body."""
    return ["base" in (c.frame_a, c.frame_b) for c in capsules]
SUJ_ON_COLUMN = 2
