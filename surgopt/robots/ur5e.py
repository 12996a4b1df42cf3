"""Universal Robots UR5e: standard DH table, joint ranges and rated speeds.

Sources
-------
[UR]   Universal Robots, "DH parameters for calculations of kinematics and dynamics" (support
       article; also Robotics Toolbox for Python, ``models/DH/UR5e.py``): a2 = -0.425, a3 = -0.3922,
       d1 = 0.1625, d4 = 0.1333, d5 = 0.0997, d6 = 0.0996 m; alpha = (90, 0, 0, 90, -90, 0) deg.
       (Robotics Toolbox prints a3 = -0.39225, the UR5 value; the UR5e article gives -0.3922.)
[UR-TS] UR5e technical specifications: every joint +-360 deg, every joint 180 deg/s (pi rad/s).

Locked: wrist_3. With the tool along the flange's z axis, wrist 3 only spins the tool about its own
axis: it moves neither the tip nor the tool line, so its column of the RCM Jacobian is zero.
"""
from __future__ import annotations

import math

from surgopt.robots.chain import DhRow
from surgopt.robots.models import PAPER_WORKSPACE, ArmModel

SPEED_RAD_S = math.pi  # [UR-TS]
RANGE_DEG = 360.0  # [UR-TS]

#: name, a (m), alpha (deg), d (m) [UR]
_TABLE = (("shoulder_pan", 0.0, 90.0, 0.1625), ("shoulder_lift", -0.425, 0.0, 0.0), ("elbow", -0.3922, 0.0, 0.0),
          ("wrist_1", 0.0, 90.0, 0.1333), ("wrist_2", 0.0, -90.0, 0.0997), ("wrist_3", 0.0, 0.0, 0.0996))

MODEL = ArmModel(
    name="ur5e", title="Universal Robots UR5e", convention="standard",
    dh=tuple(DhRow.deg(a, alpha, d, 0.0, -RANGE_DEG, RANGE_DEG, SPEED_RAD_S, name) for name, a, alpha, d in _TABLE),
    locked_joints_deg={"wrist_3": 0.0},
    lock_reason="wrist_3 only spins the tool about its own axis",
    seed_deg={"shoulder_pan": 163.0, "shoulder_lift": -95.0, "elbow": 115.0, "wrist_1": -110.0, "wrist_2": -90.0},
    tool_length_m=0.30, spin_joint="wrist_3",
    workspace=PAPER_WORKSPACE, grid=dict(x_min_m=0.0, x_max_m=0.8, x_count=41, z_min_m=-0.9, z_max_m=0.5, z_count=71),
)
