"""Which hand drives which arm (issue 54 item 4): the PSM that appears on the camera image's right is the one the
surgeon's right hand (the dVRK's MTMR) should drive; paired the other way the surgeon's hands are crossed.

The image's horizon is an *assumption*: the camera is held level about its view axis, the image's up the
patient's anterior (+z) as seen along the view (where the view is vertical, the head, +y), so that its right is
view x up. An instrument enters the view from its port's direction seen from the scope's tip; of two, the right
hand's is the one entering to the right of the other (``image_right_psm``). The dVRK console's default pairing is MTMR with PSM1 and MTML with PSM2
(sawIntuitiveResearchKit's console-MTMR-PSM1-MTML-PSM2 configurations).
"""
from __future__ import annotations

import numpy as np

#: The dVRK console's default teleoperation pairing (its console-MTMR-PSM1-MTML-PSM2-Teleop configurations).
DEFAULT_PAIRING = {"MTMR": "PSM1", "MTML": "PSM2"}


def image_right(axis: np.ndarray) -> np.ndarray:
    """(n, 3) Unit vectors to the right of a level image looking along ``axis`` (n, 3): axis x up with up the
    patient's +z, or +y where the axis is (within 1e-9) vertical; NaN where the axis is."""
    right = np.cross(axis, [0.0, 0.0, 1.0])
    norm = np.linalg.norm(right, axis=1)
    vertical = norm < 1e-9
    right[vertical] = np.cross(axis[vertical], [0.0, 1.0, 0.0])
    return right / np.linalg.norm(right, axis=1)[:, None]


def image_right_psm(psm1_m: np.ndarray, psm2_m: np.ndarray, tip_m: np.ndarray, axis: np.ndarray) -> np.ndarray:
    """Per layout: 1 or 2, the working pair's PSM that enters the camera image to the right of the other (ports,
    the scope's tip and its view axis, (n, 3) each, m). Each instrument comes
    into the image from its port's direction seen from the tip, a unit vector (x right, y up) in the image: the
    right hand's is the one of larger x; where the two x are equal (both shafts from one side, one above the other)
    the one counterclockwise of the other (hands from the bottom-left and bottom-right, turned together about the
    view, keep their order). A layout's mirror image swaps it. 0: neither, where the scope cannot be placed or the
    two enter the image along one line (three ports in one plane with the view: either pairing is as good)."""
    right = image_right(axis)
    up = np.cross(right, axis)

    def in_image(port):
        d = port - tip_m
        x, y = np.einsum("ij,ij->i", d, right), np.einsum("ij,ij->i", d, up)
        norm = np.hypot(x, y)
        with np.errstate(invalid="ignore", divide="ignore"):  # a port on the view's line: NaN, neither side
            return x / norm, y / norm

    (x1, y1), (x2, y2) = in_image(psm1_m), in_image(psm2_m)
    turn = x1 * y2 - y1 * x2
    second = np.where(np.abs(x1 - x2) > 1e-9, x2 > x1, turn > 0)  # PSM2 to the right of PSM1
    sided = np.isfinite(x1) & np.isfinite(x2) & ((np.abs(x1 - x2) > 1e-9) | (np.abs(turn) > 1e-9))
    return np.where(sided, np.where(second, 2, 1), 0).astype(np.int64)


def teleop_pairing(right_psm: int) -> dict:
    """The dVRK console's pairing that keeps the surgeon's hands uncrossed: MTMR with the PSM on the image's
    right, MTML with the other ({} where neither is, ``image_right_psm`` 0)."""
    if right_psm not in (1, 2):
        return {}
    return {"MTMR": f"PSM{right_psm}", "MTML": f"PSM{3 - right_psm}"}


def pairing_words(right_psm: int) -> str:
    """The pairing in words, against the console's default."""
    pairing = teleop_pairing(right_psm)
    if not pairing:
        return "either pairing: no camera image, or the two instruments enter it along one line"
    same = pairing == DEFAULT_PAIRING
    return (f"MTMR-{pairing['MTMR']}, MTML-{pairing['MTML']} ("
            + ("the console's default" if same else "not the console's default MTMR-PSM1, which would cross the "
               "surgeon's hands") + ")")
