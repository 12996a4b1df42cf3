"""The bedside as obstacles (#54, "the arms clear of the bedside"): the table's slab, its side rails, the patient's
arms and legs, each a box in the patient frame (m: +x the patient's left, +y cranial, z up from the table top),
tilted with the table. The arms' links must clear every box as they clear the table (``link_tables.to_bedside``,
C2: each link's distance to a box is convex along it, found by golden-section search), in every row and in one
layout's clearances.

What is sourced and what is assumed (docs/port_placement.md, "The bedside"):

- the side rails' profile, 25 mm high and 10 mm thick: ISO 19054:2005, "Rail systems for supporting medical
  equipment" (the OR table's accessory rail along both long sides); its stand-off from the table's edge (20 mm)
  and its top level with the table top are assumptions;
- the patient's arms out on arm boards at 90 degrees at the shoulders (the default: a board 150 mm wide and
  660 mm long, the arm 120 mm above it), or tucked at the sides (common in robotic pelvic surgery: a box 110 mm
  wide and 120 mm high from the shoulder 750 mm toward the feet, lying on the table's edge): sizes from adult
  anthropometry (upper-arm breadth ~100 mm, acromion to fingertip ~750-780 mm), assumptions;
- the legs not modelled by default (the default cart docks from the side); flat on the table (each 180 mm wide and 170 mm high, from the hip to the table's foot end) or in
  lithotomy (each leg in its stirrup as one box from the hip 450 mm toward the feet, 100-500 mm off the midline
  and up to 800 mm above the table: where the thighs and shanks stand), assumptions;
- the shoulders' and hips' level (``bedside.shoulder_y_mm``, ``hip_y_mm``): by default 420 mm cranial and 220 mm
  caudal of the patient frame's origin, from the umbilicus's typical height between the acromion and the greater
  trochanter (an assumption on the dome, whose umbilicus is the origin; a CT patient gives its own).
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np

#: Every obstacle the bedside may hold, in the order of the rows' codes (``link_tables.SURROUNDINGS``: after the
#: patient's body): a stored run's code names its obstacle without its config.
BEDSIDE = ("table", "left side rail", "right side rail", "patient's left arm", "patient's right arm",
           "patient's left leg", "patient's right leg")

#: The table's thickness as a slab under the patient frame's z = 0 (m, an assumption).
TABLE_THICKNESS_M = 0.10
#: ISO 19054 rail: 25 mm high, 10 mm thick; held this far off the table's side (m, an assumption).
RAIL_HEIGHT_M, RAIL_THICKNESS_M, RAIL_STANDOFF_M = 0.025, 0.010, 0.020
#: A tucked arm: its breadth across the table, its height above it, its length from the shoulder (m, assumptions).
ARM_BREADTH_M, ARM_HEIGHT_M, ARM_LENGTH_M = 0.110, 0.120, 0.750
#: An arm out on its board at 90 degrees: the board's width (along the body) and length, its thickness under the
#: table top's level (m, assumptions).
BOARD_WIDTH_M, BOARD_LENGTH_M, BOARD_THICKNESS_M = 0.150, 0.660, 0.050
#: A leg flat on the table: its breadth and height (m, assumptions), from 20 mm off the midline.
LEG_BREADTH_M, LEG_HEIGHT_M, LEG_GAP_M = 0.180, 0.170, 0.020
#: A leg in lithotomy: from the hip this far toward the feet, this far off the midline, this high (m, assumptions).
LITHOTOMY_LENGTH_M, LITHOTOMY_X_M, LITHOTOMY_HEIGHT_M = 0.450, (0.100, 0.500), 0.800


class Box(NamedTuple):
    """One obstacle: its name (one of ``BEDSIDE``) and its corners (m, patient frame)."""

    name: str
    lo: np.ndarray
    hi: np.ndarray


def _box(name: str, lo, hi) -> Box:
    return Box(name, np.array(lo, float), np.array(hi, float))


def _mirrored(name: str, lo, hi) -> list[Box]:
    """The box on the patient's left (x > 0) and its mirror on the right."""
    return [_box(name.format(side="left"), lo, hi),
            _box(name.format(side="right"), (-hi[0], lo[1], lo[2]), (-lo[0], hi[1], hi[2]))]


def table_box(cfg) -> Box:
    """The table as a slab under the patient frame's z = 0."""
    w = cfg.cart.table_half_width_mm / 1000
    y0, y1 = (v / 1000 for v in cfg.cart.table_y_mm)
    return _box("table", (-w, y0, -TABLE_THICKNESS_M), (w, y1, 0.0))


def rail_boxes(cfg) -> list[Box]:
    """The side rails along both long sides of the table (ISO 19054's profile)."""
    w = cfg.cart.table_half_width_mm / 1000 + RAIL_STANDOFF_M
    y0, y1 = (v / 1000 for v in cfg.cart.table_y_mm)
    return _mirrored("{side} side rail", (w, y0, -RAIL_HEIGHT_M), (w + RAIL_THICKNESS_M, y1, 0.0))


def arm_boxes(cfg) -> list[Box]:
    """The patient's arms: tucked at the sides on the table's edge, or out on arm boards at 90 degrees."""
    bed = cfg.bedside
    w, shoulder = cfg.cart.table_half_width_mm / 1000, bed.shoulder_y_mm / 1000
    if bed.arms == "tucked":
        return _mirrored("patient's {side} arm", (w - ARM_BREADTH_M, shoulder - ARM_LENGTH_M, 0.0),
                         (w, shoulder, ARM_HEIGHT_M))
    if bed.arms == "out":
        return _mirrored("patient's {side} arm", (w, shoulder - BOARD_WIDTH_M, -BOARD_THICKNESS_M),
                         (w + BOARD_LENGTH_M, shoulder, ARM_HEIGHT_M))
    return []


def leg_boxes(cfg) -> list[Box]:
    """The patient's legs: flat on the table from the hips to its foot end, or up in lithotomy stirrups."""
    bed = cfg.bedside
    hip, foot = bed.hip_y_mm / 1000, cfg.cart.table_y_mm[0] / 1000
    if bed.legs == "flat":
        return _mirrored("patient's {side} leg", (LEG_GAP_M, foot, 0.0), (LEG_GAP_M + LEG_BREADTH_M, hip, LEG_HEIGHT_M))
    if bed.legs == "lithotomy":
        return _mirrored("patient's {side} leg", (LITHOTOMY_X_M[0], hip - LITHOTOMY_LENGTH_M, 0.0),
                         (LITHOTOMY_X_M[1], hip, LITHOTOMY_HEIGHT_M))
    return []


def bedside_boxes(cfg) -> list[Box]:
    """Every obstacle beside and on the table the config holds: the table, its rails, the patient's arms and
    legs."""
    boxes = [table_box(cfg), *(rail_boxes(cfg) if cfg.bedside.rails else []), *arm_boxes(cfg), *leg_boxes(cfg)]
    return [b for b in boxes if np.all(b.hi > b.lo)]


def box_edges(lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """(12, 2, 3) A box's edges from its corners (for drawing)."""
    corners = np.array([[hi[i] if (c >> i) & 1 else lo[i] for i in range(3)] for c in range(8)])
    return np.array([[corners[a], corners[a | 1 << i]] for a in range(8) for i in range(3) if not (a >> i) & 1])


def bedside_lines_mm(cfg, near_mm: tuple[float, float]) -> list:
    """Every bedside box's edges, each box cut to within ``near_mm`` (half widths, x and y) of the patient frame's
    origin so that a scene keeps the body's scale, as one polyline for a 3-D scene (mm, patient frame; None between
    edges, as plotly breaks a line)."""
    window = np.array([near_mm[0], near_mm[1], np.inf]) / 1000
    out = []
    for box in bedside_boxes(cfg):
        lo, hi = np.maximum(box.lo, -window), np.minimum(box.hi, window)
        if np.any(hi <= lo):
            continue
        for a, b in box_edges(lo, hi) * 1000:
            out += [[round(float(v), 1) for v in a], [round(float(v), 1) for v in b], None]
    return out


def bedside_words(cfg) -> str:
    """What the links clear beside the table, in words, its sizes' status said (the closing report's ``bedside``)."""
    bed = cfg.bedside
    arms = {"out": "the patient's arms out on arm boards at 90 deg", "tucked": "the patient's arms tucked at the sides",
            "none": "not the patient's arms (bedside.arms = 'none')"}[bed.arms]
    legs = {"flat": "the legs flat on the table", "lithotomy": "the legs up in lithotomy stirrups",
            "none": "not the legs (bedside.legs = 'none')"}[bed.legs]
    return ("the arms' links clear the table's slab" + (", its ISO 19054 side rails" if bed.rails else "")
            + f", {arms} and {legs}; shoulders at y = {bed.shoulder_y_mm:g} mm, hips at {bed.hip_y_mm:g} mm; the "
            "rails' profile is ISO 19054's, every other size an assumption (bedside.py)")
