"""The dVRK's Si ECM: an RCM arm holding the endoscope.

Source: jhu-dvrk/sawIntuitiveResearchKit share/kinematic/ and share/tool/ as transcribed in
../shared/robots/dvrk-kinematics.md (radians and metres as there; ``robots/dvrk/__init__.py`` has the convention).
Rows: yaw, pitch, insertion (limits in rad, rad, m; the insertion offset in m), then the roll row whose d
brings the reaching point to the wrist (an instrument) or the scope's tip.
"""
from __future__ import annotations

from surgopt.robots.dvrk import ECM_SAFE_INSERTION_M, RcmArm, revolute, yaw_pitch_insertion

MODEL = RcmArm(
    "dvrk_ecm_si",
    yaw_pitch_insertion((-2.964, 2.964), (-1.1, 1.04), (0.001, 0.259), -0.3822)
    + (revolute(0.0, 0.0, 0.3829, 0.0, -1.54, 1.54, "roll"),),
    "ECM_Si.json (its D rows as the Classic's: the file's values for rows 3-4 are the same)",
    min_insertion_m=ECM_SAFE_INSERTION_M)
