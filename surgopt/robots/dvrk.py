"""da Vinci Research Kit arms: the PSM (instrument arm) and the ECM (endoscope arm), both RCM mechanisms.

Source: jhu-dvrk/sawIntuitiveResearchKit (commit 9e535e6, April 2026), share/kinematic/ (PSM.json,
PSM_Si.json, ECM.json, ECM_Si.json), share/tool/ (LARGE_NEEDLE_DRIVER_400006.json, ..._420006.json), as
transcribed in ../shared/robots/dvrk-kinematics.md. Modified DH (Craig): link i is
Rx(alpha_i) Tx(A_i) Rz(theta_i) Tz(D_i); a revolute joint adds q + offset to theta, the prismatic joint
q + offset to D. The base frame's origin is the remote centre of motion (the port). Lengths in m, angles
in rad.

The first three rows (yaw, pitch, insertion) are the same mechanism in every arm here; the forward
kinematics of that mechanism is, in the base frame,

    p = (q3 + along_shaft_m) * u(q1, q2),   u = (sin q1 cos q2, -sin q2, -cos q1 cos q2),

where ``along_shaft_m`` is the insertion offset plus the next row's D (the instrument's roll row for a
PSM: -0.4318 + 0.4162 = -0.0156 m, the point the wrist pitch axis passes through; the ECM's roll row:
-0.3822 + 0.3829 = +0.0007 m, the scope's tip). ``tests/reference.py`` multiplies the 4x4 DH matrices
out independently and the tests hold the closed form to it.

Known disagreements (../shared/robots/dvrk-kinematics.md): the AMBF description's Classic RCM-to-tool
offset is -0.4389 (not -0.4318); some descriptions give the Classic yaw +-270 deg (here +-91 deg).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

HALF_PI = math.pi / 2


@dataclass(frozen=True)
class DhRowMdh:
    """One modified-DH row: alpha (rad), A (m), D (m), prismatic or not, offset (rad or m), limits."""

    alpha_rad: float
    a_m: float
    d_m: float
    prismatic: bool
    offset: float
    lower: float
    upper: float


@dataclass(frozen=True)
class RcmArm:
    """An RCM arm: its DH rows from the base (the RCM) through the row after insertion, and what the
    study needs of them: the limits of yaw, pitch and insertion and the shaft offset of the point that
    reaches (the wrist of an instrument, the tip of a scope)."""

    name: str
    rows: tuple[DhRowMdh, ...]
    source: str
    #: how far the instrument's wrist turns the jaws off the shaft (0: a scope, no wrist)
    wrist_bend_rad: float = 0.0

    @property
    def yaw_limits_rad(self) -> tuple[float, float]:
        return self.rows[0].lower, self.rows[0].upper

    @property
    def pitch_limits_rad(self) -> tuple[float, float]:
        return self.rows[1].lower, self.rows[1].upper

    @property
    def insertion_limits_m(self) -> tuple[float, float]:
        return self.rows[2].lower, self.rows[2].upper

    @property
    def along_shaft_m(self) -> float:
        """Distance from the RCM, along the shaft, of the reaching point at zero insertion (q3 = 0)."""
        return self.rows[2].offset + self.rows[3].d_m


def _yaw_pitch_insertion(yaw: tuple[float, float], pitch: tuple[float, float], insertion: tuple[float, float],
                         insertion_offset_m: float) -> tuple[DhRowMdh, ...]:
    return (DhRowMdh(HALF_PI, 0.0, 0.0, False, HALF_PI, *yaw),
            DhRowMdh(-HALF_PI, 0.0, 0.0, False, -HALF_PI, *pitch),
            DhRowMdh(HALF_PI, 0.0, 0.0, True, insertion_offset_m, *insertion))


#: The Large Needle Driver's roll row (D: Classic 0.4162, Si 0.4670) and wrist rows (the wrist pitch and yaw
#: rows' limits +-80 deg; the 0.0091 m of the yaw row's A is the distance from the wrist pitch axis).
LND_ROLL_LIMITS_RAD = (-4.53786, 4.53786)
LND_WRIST_LIMITS_RAD = (-1.39626, 1.39626)
LND_WRIST_LINK_M = 0.0091
#: How far the Large Needle Driver's jaws can point away from its shaft: a cone of the wrist rows' +-80 deg
#: (pitch and yaw each reach 80 deg; together they reach farther on the diagonals, so the cone is the
#: conservative reading of the two limits).
LND_WRIST_BEND_RAD = min(-LND_WRIST_LIMITS_RAD[0], LND_WRIST_LIMITS_RAD[1])

PSM_CLASSIC = RcmArm(
    "dvrk_psm_classic",
    _yaw_pitch_insertion((-1.588, 1.588), (-0.925025, 0.925025), (0.0, 0.240), -0.4318)
    + (DhRowMdh(0.0, 0.0, 0.4162, False, 0.0, *LND_ROLL_LIMITS_RAD),),
    "PSM.json + LARGE_NEEDLE_DRIVER_400006.json", LND_WRIST_BEND_RAD)
PSM_SI = RcmArm(
    "dvrk_psm_si",
    _yaw_pitch_insertion((-2.964, 2.964), (-1.265, 1.301), (0.0, 0.290), -0.4826)
    + (DhRowMdh(0.0, 0.0, 0.4670, False, 0.0, *LND_ROLL_LIMITS_RAD),),
    "PSM_Si.json + LARGE_NEEDLE_DRIVER_420006.json", LND_WRIST_BEND_RAD)
ECM_CLASSIC = RcmArm(
    "dvrk_ecm_classic",
    _yaw_pitch_insertion((-1.5708, 1.5708), (-0.76794, 1.1344), (0.0, 0.255), -0.3822)
    + (DhRowMdh(0.0, 0.0, 0.3829, False, 0.0, -1.552, 1.552),),
    "ECM.json")
ECM_SI = RcmArm(
    "dvrk_ecm_si",
    _yaw_pitch_insertion((-2.964, 2.964), (-1.1, 1.04), (0.001, 0.259), -0.3822)
    + (DhRowMdh(0.0, 0.0, 0.3829, False, 0.0, -1.54, 1.54),),
    "ECM_Si.json (its D rows as the Classic's: the file's values for rows 3-4 are the same)")

INSTRUMENT_ARMS = {a.name: a for a in (PSM_CLASSIC, PSM_SI)}
CAMERA_ARMS = {a.name: a for a in (ECM_CLASSIC, ECM_SI)}

#: Instrument shaft diameter (robotic ports are 8 mm; the camera port 12 mm).
INSTRUMENT_SHAFT_DIAMETER_MM = 8.0
ENDOSCOPE_DIAMETER_MM = 12.0
#: How far behind the RCM the instrument's back end (and the arm carrying it) sits at zero insertion:
#: the RCM-to-tool-origin offset of the Classic PSM, 0.4318 m. Used as the length of the outside segment
#: in the arms' external clearance.
OUTSIDE_LENGTH_M = 0.4318
