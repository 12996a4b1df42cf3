"""The design kernel's float columns, each named once (issue 53: "kernels write by a named index taken from it").

``designs.design_columns`` writes a design's quantities into one float array; each column's position is a
constant below (``REACH_1`` ...), read by the kernel (numba freezes module constants at compile time) and by the
study (``studies/port_place/study.py``), which stores the column under its ``stored`` name in its ``stored_unit``
(the kernel works in m and rad). Nothing else knows a position. The order here is the kernel's; the rows'
schema order is the study's.
"""
from __future__ import annotations

from typing import NamedTuple


class Column(NamedTuple):
    """One of the kernel's float columns: the row column it becomes, the kernel's unit ("1", "m", "rad"), what it
    means (docs/port_placement.md's equation)."""

    stored: str
    kernel_unit: str
    meaning: str


#: Every float column of a design, in the kernel's order: the working pair's and the camera's (every design), the
#: least port spacing, then the third instrument's (three instruments only, last).
COLUMNS = (
    Column("psm1_reach", "1", "share of the target's points PSM1's wrist reaches (P4)"),
    Column("psm2_reach", "1", "share of the target's points PSM2's wrist reaches (P4)"),
    Column("common_reach", "1", "share every instrument reaches (P4)"),
    Column("dexterity_mean", "1", "the pair's mean isotropy over the points both reach (P5)"),
    Column("manipulation_angle_mean_deg", "rad", "the manipulation angle's mean over the target (P6)"),
    Column("manipulation_angle_min_deg", "rad", "its least (P6)"),
    Column("manipulation_angle_max_deg", "rad", "its largest (P6)"),
    Column("manipulation_angle_share_45_75", "1", "share of points with the angle within the band (P6)"),
    Column("manipulation_angle_centre_deg", "rad", "the angle at the target's centre (P6)"),
    Column("azimuth_imbalance_deg", "rad", "|azimuth PSM1 - azimuth PSM2| about the optical axis (P7)"),
    Column("camera_coverage", "1", "share of the target in the scope's cone (P8)"),
    Column("shaft_clearance_mm", "m", "the least gap between the shafts inside the body (P9)"),
    Column("external_clearance_mm", "m", "the least clearance outside the body (P10; the links' with a cart)"),
    Column("camera_off_arc_deg", "rad", "the optical axis off the arc between the instruments (P7)"),
    Column("min_port_spacing_mm", "m", "the least distance between any two ports (P11's spacing check)"),
    Column("psm3_reach", "1", "share of the target's points PSM3's wrist reaches (P4)"),
    Column("psm3_dexterity_mean", "1", "PSM3's mean isotropy over the points it reaches (P5)"),
)


def index(stored: str) -> int:
    """A stored column's position in the kernel's array."""
    return next(i for i, c in enumerate(COLUMNS) if c.stored == stored)


REACH_1 = index("psm1_reach")
REACH_2 = index("psm2_reach")
COMMON_REACH = index("common_reach")
DEXTERITY_MEAN = index("dexterity_mean")
ANGLE_MEAN = index("manipulation_angle_mean_deg")
ANGLE_MIN = index("manipulation_angle_min_deg")
ANGLE_MAX = index("manipulation_angle_max_deg")
ANGLE_SHARE = index("manipulation_angle_share_45_75")
ANGLE_CENTRE = index("manipulation_angle_centre_deg")
AZIMUTH_IMBALANCE = index("azimuth_imbalance_deg")
CAMERA_COVERAGE = index("camera_coverage")
SHAFT_CLEARANCE = index("shaft_clearance_mm")
EXTERNAL_CLEARANCE = index("external_clearance_mm")
CAMERA_OFF_ARC = index("camera_off_arc_deg")
PORT_SPACING = index("min_port_spacing_mm")
REACH_3 = index("psm3_reach")
DEXTERITY_3 = index("psm3_dexterity_mean")

#: How many columns a design of two instruments has, and of three (the third's come last).
TWO_INSTRUMENTS = REACH_3
THREE_INSTRUMENTS = len(COLUMNS)


def width(instruments: int) -> int:
    """The kernel's float columns for a design of ``instruments`` (2 or 3)."""
    return THREE_INSTRUMENTS if instruments == 3 else TWO_INSTRUMENTS


def stored_value(column: Column, kernel_value):
    """A kernel column in its stored unit: m -> mm, rad -> deg (the stored name says which), else as is."""
    import numpy as np

    if column.kernel_unit == "rad":
        return np.degrees(kernel_value)
    if column.kernel_unit == "m":
        return kernel_value * 1000
    return kernel_value
