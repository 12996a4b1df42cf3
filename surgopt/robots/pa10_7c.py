"""Mitsubishi PA10-7C: DH table, link lengths, joint limits, maximum joint speeds.

Sources
-------
[MHI]  General Purpose Robot PA10 Series (PA10-7CE) Instruction Manual for
       Installation, Maintenance and Safety, Mitsubishi Heavy Industries
       (ref. [2] of Locke & Patel 2007). Values as commonly cited from it:
       rated speeds S1, S2 57 deg/s (1 rad/s); S3, E1 114 deg/s (2 rad/s);
       E2, W1, W2 360 deg/s (2 pi rad/s); joint ranges S1 +-177, S2 +-91,
       S3 +-174, E1 +-137, E2 +-255, W1 +-165, W2 +-255 deg. The manual itself
       could not be consulted here; the indirect check is that these speeds
       as the scaling matrix Q reproduce Locke & Patel's Table I to four
       digits in 11 of 15 rows (docs/reproduction.md), and that other speed
       sets do visibly worse.
[KIN]  Public PA10 kinematic models disagree on the link lengths:
       d1, d3, d5, d7 = 0.317 / 0.45 / 0.48 / 0.07 m versus
       0.315 / 0.45 / 0.50 / 0.08 m. The first set reproduces Table I and is
       the default; the second is one config field away.
[LP07] R. C. O. Locke, R. V. Patel, "Optimal remote center-of-motion location
       for robotics-assisted minimally-invasive surgery", ICRA 2007: tool
       (end-effector + instrument) length 587 mm, S3 and W2 held at zero.

Standard (distal) DH, joints S1, S2, S3, E1, E2, W1, W2, angles zero with the
arm pointing straight up:

    joint  d       a   alpha
    S1     d1      0   -90 deg
    S2     0       0   +90 deg
    S3     d3      0   -90 deg
    E1     0       0   +90 deg
    E2     d5      0   -90 deg
    W1     0       0   +90 deg
    W2     d7      0     0
"""
from __future__ import annotations

import math

JOINT_NAMES = ("S1", "S2", "S3", "E1", "E2", "W1", "W2")
#: Joints moved in the RCM study (S3 = W2 = 0, [LP07] Sec. III-A).
ACTIVE_JOINTS = ("S1", "S2", "E1", "E2", "W1")

#: Standard DH alpha of each joint (deg); a = 0 for every joint, d from the link lengths below
#: (d1 on S1, d3 on S3, d5 on E2, d7 on W2, zero elsewhere). Read by tests/reference.py.
DH_ALPHA_DEG = (-90.0, 90.0, -90.0, 90.0, -90.0, 90.0, 0.0)
#: Which link length (index into LINKS_BIELEFELD_M) is each joint's DH d, or None for d = 0.
DH_D_LINK = (0, None, 1, None, 2, None, 3)

#: Link lengths (m) [KIN]: (d1, d3, d5, d7). The other published set, (0.315, 0.45, 0.50, 0.08),
#: is one config field away (robot.link_d*_m); docs/reproduction.md compares the two.
LINKS_BIELEFELD_M = (0.317, 0.45, 0.48, 0.07)

#: Joint ranges (deg) [MHI].
JOINT_LIMIT_DEG = {"S1": 177.0, "S2": 91.0, "S3": 174.0, "E1": 137.0,
                   "E2": 255.0, "W1": 165.0, "W2": 255.0}

#: Rated maximum joint speeds (rad/s) [MHI].
MAX_JOINT_SPEED_RAD_S = {"S1": 1.0, "S2": 1.0, "S3": 2.0, "E1": 2.0,
                         "E2": 2 * math.pi, "W1": 2 * math.pi, "W2": 2 * math.pi}

#: End-effector + surgical tool length (m) [LP07] Sec. III-B.
TOOL_LENGTH_M = 0.587


def dh_rows(links_m=LINKS_BIELEFELD_M, limits_deg=None, speeds_rad_s=None):
    """The standard DH table above as ``DhRow``s for the generic chain (a = 0, theta offsets 0)."""
    from surgopt.robots.chain import DhRow

    limits_deg = {**JOINT_LIMIT_DEG, **(limits_deg or {})}
    speeds_rad_s = {**MAX_JOINT_SPEED_RAD_S, **(speeds_rad_s or {})}
    return tuple(DhRow.deg(0.0, alpha, 0.0 if link is None else links_m[link], 0.0, -limits_deg[n], limits_deg[n],
                       speeds_rad_s[n], n)
                 for n, alpha, link in zip(JOINT_NAMES, DH_ALPHA_DEG, DH_D_LINK))


def _model():
    from surgopt.robots.models import ArmModel

    return ArmModel(
        name="pa10_7c", title="Mitsubishi PA10-7C", convention="standard", dh=dh_rows(),
        locked_joints_deg={"S3": 0.0, "W2": 0.0},
        lock_reason="S3 and W2 held at zero as in Locke & Patel Sec. III-A",
        seed_deg=dict(SEED_DEG), tool_length_m=TOOL_LENGTH_M, z_reference="shoulder", spin_joint="W2")


#: A configuration on the closed-form kernel's branch (elbow up, wrist W1 > 0): the generic kernel's seed.
SEED_DEG = {"S1": 0.0, "S2": 30.0, "E1": 90.0, "E2": 0.0, "W1": 60.0}
#: Elbow-down seed (``robot.elbow = "down"`` through the generic kernel).
SEED_ELBOW_DOWN_DEG = {"S1": 0.0, "S2": -30.0, "E1": -90.0, "E2": 0.0, "W1": 60.0}
MODEL = _model()
