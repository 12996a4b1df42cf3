"""The dVRK patient cart's setup joints (SUJ): the passive arms that place each PSM's and the ECM's base frame
(its RCM) in space, Classic and Si, as data.

Source: jhu-dvrk/sawIntuitiveResearchKit share/arm/suj-simulated.json (Classic) and suj-si-simulated.json (Si),
as transcribed in ../shared/robots/dvrk-kinematics.md. Each arm: ``world_origin_to_SUJ`` (the cart's world
frame to the SUJ's base), modified-DH links (Craig: Rx(alpha) Tx(A) Rz(theta) Tz(D); the first a prismatic
vertical column, the rest revolute), then ``SUJ_tip_to_tool_origin``, the fixed transform from the SUJ's last
frame to the arm's base (RCM) frame. The Si's SUJs end in two fixed links (no joint): 4 joint values (PSM1,
PSM2, ECM) or 5 (PSM3). Lengths in m, angles in rad, as in the files.

Joint ranges are not in the files. ``ranges`` below: for the Classic PSM1 / PSM2 SUJs, the ranges the dVRK
documentation quotes (revolute j1 +-90 deg, j2 -135..0 deg (PSM1) / 0..+135 deg (PSM2), j3 +-90 deg, j4 and j5
+-135 deg; *quoted, not measured*); for every other SUJ and for the column, *assumptions*: each revolute joint a
full turn (+-180 deg), the column -0.10..+0.70 m (it covers the files' sample positions, -0.026..0.665 m).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from surgopt.robots.chain import DhRow

HALF_PI = 1.5708  # as the files write it (not math.pi / 2)


def _transform(translation, rotation=((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))) -> tuple:
    """A 4x4 homogeneous transform as nested tuples (data, not an array: a model is immutable)."""
    r = rotation
    return (tuple(r[0]) + (translation[0],), tuple(r[1]) + (translation[1],), tuple(r[2]) + (translation[2],),
            (0.0, 0.0, 0.0, 1.0))


def _column(a_m: float, d_m: float) -> DhRow:
    return DhRow(a_m, 0.0, d_m, 0.0, name="column", prismatic=True)


def _joint(alpha_rad: float, a_m: float, d_m: float, offset_rad: float, name: str) -> DhRow:
    return DhRow(a_m, alpha_rad, d_m, offset_rad, name=name)


@dataclass(frozen=True)
class Suj:
    """One setup-joint arm: which cart (``"classic"`` or ``"si"``) and arm it carries (``"PSM1"`` ... ``"ECM"``),
    its base in the cart's world frame, its jointed links (modified DH; the column first), the fixed links after
    them (the Si's; at zero), the SUJ tip -> arm base (RCM) transform, and each joint's range (m for the column,
    rad otherwise) with where the ranges come from."""

    cart: str
    arm: str
    world_to_suj: tuple
    links: tuple[DhRow, ...]
    fixed: tuple[DhRow, ...]
    tip_to_tool: tuple
    ranges: tuple[tuple[float, float], ...]
    ranges_source: str

    @property
    def n_joints(self) -> int:
        return len(self.links)


ROT_Z_MINUS = ((-1.0, 0.0, 0.0), (0.0, -1.0, 0.0), (0.0, 0.0, 1.0))  # diag(-1, -1, 1)
ROT_Z_QUARTER = ((0.0, -1.0, 0.0), (1.0, 0.0, 0.0), (0.0, 0.0, 1.0))
TIP_ROTATION = ((0.0, 1.0, 0.0), (-1.0, 0.0, 0.0), (0.0, 0.0, 1.0))

DEG = math.pi / 180
#: The instrument arms' setup joints, in the order of the rows' instrument ports when docked as enumerated.
INSTRUMENT_SUJS = ("PSM1", "PSM2", "PSM3")
QUOTED = "the dVRK documentation's quoted Classic PSM SUJ ranges (assumptions there, not measured)"
ASSUMED = "assumed: each revolute joint a full turn, the column -0.10..0.70 m (not in the dVRK files)"
COLUMN_M = (-0.10, 0.70)
TURN = (-math.pi, math.pi)


def _classic_psm_links(a2: float, d1: float, a3: float, d3: float, d4: float) -> tuple[DhRow, ...]:
    return (_column(0.0896, 0.0), _joint(0.0, 0.0, d1, 0.0, "j1"), _joint(0.0, a2, 0.1429, 0.0, "j2"),
            _joint(0.0, a3, d3, HALF_PI, "j3"), _joint(HALF_PI, 0.0, d4, 0.0, "j4"),
            _joint(-HALF_PI, 0.0, -0.1029, -HALF_PI, "j5"))


_CLASSIC_TIP = _transform((0.4864, 0.0, 0.1524), TIP_ROTATION)
_PSM_RANGES = {"PSM1": (COLUMN_M, (-90 * DEG, 90 * DEG), (-135 * DEG, 0.0), (-90 * DEG, 90 * DEG),
                        (-135 * DEG, 135 * DEG), (-135 * DEG, 135 * DEG)),
               "PSM2": (COLUMN_M, (-90 * DEG, 90 * DEG), (0.0, 135 * DEG), (-90 * DEG, 90 * DEG),
                        (-135 * DEG, 135 * DEG), (-135 * DEG, 135 * DEG))}

CLASSIC = {
    "PSM1": Suj("classic", "PSM1", _transform((-0.1016, -0.1016, 0.43), ROT_Z_MINUS),
                _classic_psm_links(0.4318, 0.4166, 0.4318, -0.1302, 0.4089), (), _CLASSIC_TIP,
                _PSM_RANGES["PSM1"], QUOTED + "; the column's " + ASSUMED),
    "PSM2": Suj("classic", "PSM2", _transform((0.1016, -0.1016, 0.43)),
                _classic_psm_links(0.4318, 0.4166, 0.4318, -0.1302, 0.4089), (), _CLASSIC_TIP,
                _PSM_RANGES["PSM2"], QUOTED + "; the column's " + ASSUMED),
    "PSM3": Suj("classic", "PSM3", _transform((0.0, 0.0, 0.1264), ROT_Z_QUARTER),
                _classic_psm_links(0.5842, 0.3404, 0.4318, 0.2571, 0.4089), (), _CLASSIC_TIP,
                (COLUMN_M,) + (TURN,) * 5, ASSUMED),
    "ECM": Suj("classic", "ECM", _transform((0.0, 0.0, 0.43), ROT_Z_QUARTER),
               (_column(0.0896, 0.0), _joint(0.0, 0.0, 0.4166, 0.0, "j1"), _joint(0.0, 0.4318, 0.1429, 0.0, "j2"),
                _joint(0.0, 0.4318, -0.3459, HALF_PI, "j3"), _joint(-0.7853, 0.0, 0.0, HALF_PI, "j4"),
                _joint(0.0, -0.0667, 0.0, 0.0, "j5")), (), _transform((0.6126, 0.0, 0.1016), TIP_ROTATION),
               (COLUMN_M,) + (TURN,) * 5, ASSUMED),
}


def _si_links(column_d_m: float, planar: tuple[tuple[float, float], ...]) -> tuple[DhRow, ...]:
    """The Si's jointed links: the column (its D is the offset the joint adds to), then revolute joints about
    vertical axes with their (A, D)."""
    return (_column(0.0, column_d_m),) + tuple(_joint(0.0, a, d, 0.0, f"j{i + 1}") for i, (a, d) in enumerate(planar))


def _si_fixed(a_m: float, theta_rad: float) -> tuple[DhRow, ...]:
    """The Si's two fixed ("passive") links after its joints, at their file's theta."""
    return (_joint(HALF_PI, a_m, 0.0, theta_rad, "fixed1"), _joint(-HALF_PI, 0.0, 0.0, 0.0, "fixed2"))


_SI_TIP = _transform((0.8343, 0.0, 0.0), TIP_ROTATION)
_SI_PSM = ((0.0, 0.6654), (0.4572, 0.1397), (0.4572, -0.1301))

SI = {
    "PSM1": Suj("si", "PSM1", _transform((-0.2019, -0.0757, 0.0), ROT_Z_MINUS), _si_links(0.1471, _SI_PSM),
                _si_fixed(0.0490, -0.7854), _SI_TIP, (COLUMN_M,) + (TURN,) * 3, ASSUMED),
    "PSM2": Suj("si", "PSM2", _transform((0.2019, -0.0757, 0.0)), _si_links(0.1471, _SI_PSM),
                _si_fixed(0.0490, -0.7854), _SI_TIP, (COLUMN_M,) + (TURN,) * 3, ASSUMED),
    "PSM3": Suj("si", "PSM3", _transform((0.0, -0.2776, 0.0), TIP_ROTATION),
                _si_links(0.0455, ((0.0, 0.5887), (0.3429, -0.2667), (0.4572, 0.1397), (0.4572, -0.1864))),
                _si_fixed(0.0483, -0.2618), _SI_TIP, (COLUMN_M,) + (TURN,) * 4, ASSUMED),
    "ECM": Suj("si", "ECM", _transform((0.0, 0.1262, 0.0), ROT_Z_QUARTER),
               _si_links(0.1471, ((0.0, 0.5861), (0.3302, 0.1397), (0.3302, 0.0549))),
               _si_fixed(0.1352, -1.2217), _SI_TIP, (COLUMN_M,) + (TURN,) * 3, ASSUMED),
}

#: The files' ``simulated_position`` of each SUJ (the column in m, then rad): the poses tests reproduce.
SAMPLE_JOINTS = {
    ("classic", "PSM1"): (0.0007, -0.5892, -0.8590, -0.6241, -0.2479, -0.4422),
    ("classic", "PSM2"): (0.0628, 0.0913, 1.9073, -0.1297, 0.4351, 0.0353),
    ("classic", "PSM3"): (-0.0261, -1.5892, 1.3076, 0.6994, 0.1361, 0.3359),
    ("classic", "ECM"): (0.6647, 0.5782, -1.2662, 3.7818, 0.0, 0.0),
    ("si", "PSM1"): (0.21713328162535497, -0.28985294982172416, -1.296300785720703, -1.081429816020683),
    ("si", "PSM2"): (0.19430774368524248, 0.2521927675957645, 1.463079476018301, 0.8695928416300226),
    ("si", "PSM3"): (0.2806527579034114, 1.6766721211508346, 0.048778656425950806, 1.471882438882154,
                     0.43725492343646566),
    ("si", "ECM"): (0.3079020566881523, 1.1432499826443978, -1.9844024129709243, 0.790592362875),
}
