"""The dVRK's Classic ECM (endoscope camera manipulator): an RCM arm holding the endoscope.

Source: jhu-dvrk/sawIntuitiveResearchKit share/kinematic/ and share/tool/ as transcribed in
../shared/robots/dvrk-kinematics.md (radians and metres as there; ``robots/dvrk/__init__.py`` has the convention).
Rows: yaw, pitch, insertion (limits in rad, rad, m; the insertion offset in m), then the roll row whose d
brings the reaching point to the wrist (an instrument) or the scope's tip.
"""
from __future__ import annotations

from surgopt.robots.dvrk import ECM_SAFE_INSERTION_M, RcmArm, revolute, yaw_pitch_insertion

MODEL = RcmArm(
    "dvrk_ecm_classic",
    yaw_pitch_insertion((-1.5708, 1.5708), (-0.76794, 1.1344), (0.0, 0.255), -0.3822)
    + (revolute(0.0, 0.0, 0.3829, 0.0, -1.552, 1.552, "roll"),),
    "ECM.json",
    min_insertion_m=ECM_SAFE_INSERTION_M)
