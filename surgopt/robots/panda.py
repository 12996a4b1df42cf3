"""Franka Emika Panda (FR3's predecessor): modified (Craig) DH table, joint ranges and rated speeds.

Sources
-------
[FE]   Franka Emika, "Robot and interface specifications" / "Control parameters"
       (frankaemika.github.io/docs/control_parameters.html): modified DH a, d, alpha;
       joint ranges (rad) +-2.8973, +-1.7628, +-2.8973, [-3.0718, -0.0698], +-2.8973,
       [-0.0175, 3.7525], +-2.8973; maximum joint speeds 2.1750 rad/s (joints 1-4) and
       2.6100 rad/s (joints 5-7). The same table is Robotics Toolbox's ``models/DH/Panda.py``.
       The flange is d = 0.107 m beyond joint 7's frame (the last row's d).

Locked: joint 7 (it only spins the tool about its own axis, as on the UR5e) and joint 3, the
redundant upper-arm rotation, at 0: the PA10 study's choice for its own S3 (Locke & Patel Sec. III-A).
"""
from __future__ import annotations

import math

from surgopt.robots.chain import DhRow
from surgopt.robots.models import PAPER_WORKSPACE, ArmModel

#: name, a (m), alpha (deg), d (m), lower (rad), upper (rad), speed (rad/s) [FE]
_TABLE = (("joint1", 0.0, 0.0, 0.333, -2.8973, 2.8973, 2.1750),
          ("joint2", 0.0, -90.0, 0.0, -1.7628, 1.7628, 2.1750),
          ("joint3", 0.0, 90.0, 0.316, -2.8973, 2.8973, 2.1750),
          ("joint4", 0.0825, 90.0, 0.0, -3.0718, -0.0698, 2.1750),
          ("joint5", -0.0825, -90.0, 0.384, -2.8973, 2.8973, 2.6100),
          ("joint6", 0.0, 90.0, 0.0, -0.0175, 3.7525, 2.6100),
          ("joint7", 0.088, 90.0, 0.107, -2.8973, 2.8973, 2.6100))

MODEL = ArmModel(
    name="panda", title="Franka Emika Panda", convention="modified",
    dh=tuple(DhRow(a, math.radians(alpha), d, 0.0, lo, hi, v, name)  # the ranges as [FE] gives them (rad)
             for name, a, alpha, d, lo, hi, v in _TABLE),
    locked_joints_deg={"joint3": 0.0, "joint7": 0.0},
    lock_reason="joint7 only spins the tool; joint3 (redundant upper-arm rotation) held at 0 like the PA10's S3",
    seed_deg={"joint1": 0.0, "joint2": -10.0, "joint4": -143.0, "joint5": 0.0, "joint6": 133.0},
    tool_length_m=0.30, spin_joint="joint7",
    workspace=PAPER_WORKSPACE, grid=dict(x_min_m=0.1, x_max_m=0.7, x_count=31, z_min_m=-0.1, z_max_m=0.7, z_count=41),
)
