"""da Vinci Research Kit arms: what the PSM (instrument arm) and the ECM (endoscope arm), both RCM mechanisms,
share: the ``RcmArm`` type, their yaw / pitch / insertion rows, the Large Needle Driver's wrist, the shaft
diameters. The arms themselves are model files in this package (``psm_classic.py``, ``psm_si.py``, ``ecm_classic.py``,
``ecm_si.py``) in the one registry of shipped arms (``robots.models.ARMS``, kind "rcm").

Source: jhu-dvrk/sawIntuitiveResearchKit (commit 9e535e6, April 2026), share/kinematic/ (PSM.json,
PSM_Si.json, ECM.json, ECM_Si.json), share/tool/ (LARGE_NEEDLE_DRIVER_400006.json, ..._420006.json), as
transcribed in ../shared/robots/dvrk-kinematics.md. Modified DH (Craig): link i is
Rx(alpha_i) Tx(A_i) Rz(theta_i) Tz(D_i); a revolute joint adds q + offset to theta, the prismatic joint
q + offset to D. The base frame's origin is the remote centre of motion (the port). The rows are
``chain.DhRow``s (the one DH row type), in the JSON files' own radians and metres.

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

from surgopt.robots.chain import DhRow

HALF_PI = math.pi / 2


@dataclass(frozen=True)
class RcmArm:
    """An RCM arm: its DH rows from the base (the RCM) through the row after insertion, and what the
    study needs of them: the limits of yaw, pitch and insertion and the shaft offset of the point that
    reaches (the wrist of an instrument, the tip of a scope)."""

    name: str
    rows: tuple[DhRow, ...]  # modified DH
    source: str
    #: how far the instrument's wrist turns the jaws off the shaft (0: a scope, no wrist)
    wrist_bend_rad: float = 0.0
    #: the jaws' tip past the wrist point along a straight wrist (an instrument's last link; 0: a scope's tip)
    tip_beyond_wrist_m: float = 0.0
    #: the least distance of the wrist from the RCM the arm's controller accepts (0: none stated)
    min_wrist_depth_m: float = 0.0
    #: the least insertion (q3) the arm's controller accepts for Cartesian control (0: none stated; the ECM's 50 mm)
    min_insertion_m: float = 0.0

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
    def outside_length_m(self) -> float:
        """How far behind the RCM the arm's carriage (the instrument's back end) sits at zero insertion: the
        insertion row's offset (its d; the Classic PSM's 0.4318 m, the Si's 0.4826 m), the outside segment of the
        arms' external clearance; the Classic PSM's OUTSIDE_LENGTH_M for an arm whose row has none (an assumption)."""
        return abs(self.rows[2].d_m) or OUTSIDE_LENGTH_M

    @property
    def along_shaft_m(self) -> float:
        """Distance from the RCM, along the shaft, of the reaching point at zero insertion (q3 = 0): the
        insertion row's offset (its d) plus the next row's d."""
        return self.rows[2].d_m + self.rows[3].d_m


def revolute(alpha_rad: float, a_m: float, d_m: float, offset_rad: float, lower_rad: float, upper_rad: float,
             name: str) -> DhRow:
    """A revolute modified-DH row in the dVRK JSON's order (alpha, A, D, offset, limits; radians and metres)."""
    return DhRow(a_m, alpha_rad, d_m, offset_rad, lower_rad, upper_rad, name=name)


def yaw_pitch_insertion(yaw_rad: tuple[float, float], pitch_rad: tuple[float, float],
                        insertion_m: tuple[float, float], insertion_offset_m: float) -> tuple[DhRow, ...]:
    """The first three rows of every dVRK arm: yaw, pitch (both about the RCM), insertion along the shaft
    (a prismatic row whose d is its offset)."""
    return (revolute(HALF_PI, 0.0, 0.0, HALF_PI, *yaw_rad, "yaw"),
            revolute(-HALF_PI, 0.0, 0.0, -HALF_PI, *pitch_rad, "pitch"),
            DhRow(0.0, HALF_PI, insertion_offset_m, 0.0, *insertion_m, name="insertion",
                  prismatic=True))


#: The Large Needle Driver's roll row (D: Classic 0.4162, Si 0.4670) and wrist rows (the wrist pitch and yaw
#: rows' limits +-80 deg; the 0.0091 m of the yaw row's A is the distance from the wrist pitch axis).
LND_ROLL_LIMITS_RAD = (-4.53786, 4.53786)
LND_WRIST_LIMITS_RAD = (-1.39626, 1.39626)
LND_WRIST_LINK_M = 0.0091
#: The dVRK's PSM controller: Cartesian control is refused while the first joint at the end of the instrument's
#: shaft (the wrist) is within 45 mm of the RCM (``SafeDistanceFromRCM``), and the cannula's tip is ~25 mm from
#: the RCM (``EngageDepthCannula``): jhu-dvrk/sawIntuitiveResearchKit, core/components/include/
#: sawIntuitiveResearchKit/mtsIntuitiveResearchKit.h, namespace PSM.
PSM_SAFE_DISTANCE_FROM_RCM_M = 0.045
PSM_CANNULA_ENGAGE_DEPTH_M = 0.025
#: The dVRK's ECM controller: Cartesian control is refused until the endoscope's insertion (q3) is past 50 mm, so
#: that the scope is out of its cannula: jhu-dvrk/sawIntuitiveResearchKit, components/include/
#: sawIntuitiveResearchKit/mtsIntuitiveResearchKitECM.h, ``is_safe_for_cartesian_control`` (q3 > 50 mm; the
#: same test, as ``IsSafeForCartesianControl``, since 2013). Port-place holds every scope at least this deep.
ECM_SAFE_INSERTION_M = 0.050
#: How far the Large Needle Driver's jaws can point away from its shaft: a cone of the wrist rows' +-80 deg
#: (pitch and yaw each reach 80 deg; together they reach farther on the diagonals, so the cone is the
#: conservative reading of the two limits).
LND_WRIST_BEND_RAD = min(-LND_WRIST_LIMITS_RAD[0], LND_WRIST_LIMITS_RAD[1])

#: Instrument shaft diameter (robotic ports are 8 mm; the camera port 12 mm).
INSTRUMENT_SHAFT_DIAMETER_MM = 8.0
ENDOSCOPE_DIAMETER_MM = 12.0
#: How far behind the RCM the instrument's back end (and the arm carrying it) sits at zero insertion:
#: the RCM-to-tool-origin offset of the Classic PSM, 0.4318 m. Each RCM arm uses its own insertion row's
#: (``RcmArm.outside_length_m``: the Si PSM's 0.4826 m); this is the length for an arm whose row gives none, and
#: for the outside segment a serial arm's links are measured against.
OUTSIDE_LENGTH_M = 0.4318
