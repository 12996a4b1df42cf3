"""The dVRK's Si PSM with the Si Large Needle Driver: an RCM arm holding an instrument.

Source: jhu-dvrk/sawIntuitiveResearchKit share/kinematic/ and share/tool/ as transcribed in
../shared/robots/dvrk-kinematics.md (radians and metres as there; ``robots/dvrk/__init__.py`` has the convention).
Rows: yaw, pitch, insertion (limits in rad, rad, m; the insertion offset in m), then the roll row whose d
brings the reaching point to the wrist (an instrument) or the scope's tip.
"""
from __future__ import annotations

from surgopt.robots.dvrk import (LND_ROLL_LIMITS_RAD, LND_WRIST_BEND_RAD, LND_WRIST_LINK_M, PSM_SAFE_DISTANCE_FROM_RCM_M,
                                 RcmArm, revolute, yaw_pitch_insertion)

MODEL = RcmArm(
    "dvrk_psm_si",
    yaw_pitch_insertion((-2.964, 2.964), (-1.265, 1.301), (0.0, 0.290), -0.4826)
    + (revolute(0.0, 0.0, 0.4670, 0.0, *LND_ROLL_LIMITS_RAD, "roll"),),
    "PSM_Si.json + LARGE_NEEDLE_DRIVER_420006.json", LND_WRIST_BEND_RAD, LND_WRIST_LINK_M,
    PSM_SAFE_DISTANCE_FROM_RCM_M)
