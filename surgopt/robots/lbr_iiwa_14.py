"""KUKA LBR iiwa 14 R820: standard DH table, joint ranges and rated speeds.

Sources
-------
[KUKA] KUKA, "LBR iiwa" brochure / specification (LBR iiwa 7 R800, LBR iiwa 14 R820): joint ranges
       A1 +-170, A2 +-120, A3 +-170, A4 +-120, A5 +-170, A6 +-120, A7 +-175 deg; maximum speeds
       85, 85, 100, 75, 130, 135, 135 deg/s (the table Drake's iiwa_description README quotes from
       the brochure). Link lengths d1 = 0.36 (base to A2), d3 = 0.42 (A2 to A4), d5 = 0.40 (A4 to
       A6), d7 = 0.126 m (A6 to the media flange), every a = 0.
[DH]   Standard DH alphas (-90, 90, 90, -90, -90, 90, 0) deg as in the public LBR iiwa models
       (e.g. the Sunrise toolbox's modified table, alpha_{i-1} = (0, -90, 90, 90, -90, -90, 90));
       tests check the two tables give the same flange pose.

Locked: A7 (it only spins the tool, as on the UR5e) and A3, the redundant upper-arm rotation, at 0
(the PA10 study's S3 = 0, Locke & Patel Sec. III-A): with A3 = 0 the iiwa is the PA10's kinematic
twin with other link lengths.
"""
from __future__ import annotations

from surgopt.robots.chain import DhRow
from surgopt.robots.models import PAPER_WORKSPACE, ArmModel

#: name, alpha (deg), d (m), range (+-deg), speed (deg/s) [KUKA], [DH]
_TABLE = (("A1", -90.0, 0.36, 170.0, 85.0), ("A2", 90.0, 0.0, 120.0, 85.0), ("A3", 90.0, 0.42, 170.0, 100.0),
          ("A4", -90.0, 0.0, 120.0, 75.0), ("A5", -90.0, 0.40, 170.0, 130.0), ("A6", 90.0, 0.0, 120.0, 135.0),
          ("A7", 0.0, 0.126, 175.0, 135.0))
#: The modified-DH form of the same arm (alpha_{i-1}, d_i), for the tests' cross-check [DH].
MODIFIED_ALPHA_DEG = (0.0, -90.0, 90.0, 90.0, -90.0, -90.0, 90.0)

DEG_S = 3.141592653589793 / 180.0

MODEL = ArmModel(
    name="lbr_iiwa_14", title="KUKA LBR iiwa 14 R820", convention="standard",
    dh=tuple(DhRow.deg(0.0, alpha, d, 0.0, -rng, rng, v * DEG_S, name) for name, alpha, d, rng, v in _TABLE),
    locked_joints_deg={"A3": 0.0, "A7": 0.0},
    lock_reason="A7 only spins the tool; A3 (redundant upper-arm rotation) held at 0 like the PA10's S3",
    seed_deg={"A1": 0.0, "A2": 22.0, "A4": -111.0, "A5": 0.0, "A6": 47.0},
    tool_length_m=0.30, spin_joint="A7",
    workspace=PAPER_WORKSPACE, grid=dict(x_min_m=0.1, x_max_m=0.8, x_count=36, z_min_m=-0.2, z_max_m=0.6, z_count=41),
)
