"""Issue 54 item 4: which hand drives which arm. The rows say which of the working pair's PSMs appears on the
camera image's right (``image_right_psm``); the report and the dVRK export give the console's pairing that keeps the
surgeon's hands uncrossed."""
import numpy as np
import pytest

from surgopt.studies.port_place import config as C
from surgopt.studies.port_place import study as S
from surgopt.studies.port_place.hands import image_right_psm, pairing_words, teleop_pairing

SMALL = {"patient": {"port_region": {"site_spacing_mm": 36.0}}, "target": {"spacing_mm": 15.0}, "cart": {"model": "none"}}


def test_a_surgeon_at_the_head_sees_the_patients_right_on_the_right_and_at_the_feet_the_left():
    """Closed-form cases (the patient supine, +x the patient's left, +y the head): a scope from the head looking
    caudally and down sees the patient's right (-x) on the image's right; from the feet, the patient's left; looking
    straight down (the horizon then by the head, +y up) the patient's left... as one standing at the feet sees it."""
    left, right = np.array([[0.1, 0.0, 0.1]]), np.array([[-0.1, 0.0, 0.1]])
    tip = np.zeros((1, 3))
    from_head = np.array([[0.0, -0.8, -0.6]])
    from_feet = np.array([[0.0, 0.8, -0.6]])
    down = np.array([[0.0, 0.0, -1.0]])
    assert image_right_psm(left, right, tip, from_head)[0] == 2  # PSM2 on the patient's right
    assert image_right_psm(left, right, tip, from_feet)[0] == 1
    assert image_right_psm(left, right, tip, down)[0] == 1  # up = the head: the view of one at the feet
    assert image_right_psm(left, right, tip, np.full((1, 3), np.nan))[0] == 0
    ahead, behind = np.array([[0.0, -0.1, 0.1]]), np.array([[0.0, 0.1, 0.1]])
    assert image_right_psm(ahead, behind, tip, from_head)[0] == 0  # one line in the image: neither


def test_a_mirrored_layout_swaps_the_pairing():
    """On the mirror-symmetric default (patient and target symmetric about x = 0), each layout's mirror image puts
    on the image's right the mirror of the port that was on its left: the pairing swaps."""
    cfg = C.PortPlaceConfig.model_validate(SMALL)
    cols = S.compute_task(cfg, S.n_total(cfg), 0)
    port = {a: np.round(np.column_stack([cols[f"{a}_{c}_mm"] for c in "xyz"]), 6) for a in ("psm1", "psm2", "ecm")}
    key = {(tuple(sorted([tuple(port["psm1"][r]), tuple(port["psm2"][r])])), tuple(port["ecm"][r])): r
           for r in range(len(cols["design_id"]))}
    mirror = np.array([-1.0, 1.0, 1.0])
    checked = 0
    for r in np.flatnonzero(cols["image_right_psm"] > 0)[::37]:
        a, b, e = port["psm1"][r] * mirror, port["psm2"][r] * mirror, port["ecm"][r] * mirror
        m = key.get((tuple(sorted([tuple(a + 0.0), tuple(b + 0.0)])), tuple(e + 0.0)))
        if m is None:
            continue
        on_right = port[f"psm{cols['image_right_psm'][r]}"][r]
        on_left = port[f"psm{3 - cols['image_right_psm'][r]}"][r]
        assert np.allclose(port[f"psm{cols['image_right_psm'][m]}"][m], on_left * mirror)
        assert not np.allclose(on_right, on_left)
        checked += 1
    assert checked > 50  # the premise: many layouts had their mirror among the rows


def test_the_pairing_in_the_consoles_terms():
    assert teleop_pairing(1) == {"MTMR": "PSM1", "MTML": "PSM2"} and teleop_pairing(0) == {}
    assert teleop_pairing(2) == {"MTMR": "PSM2", "MTML": "PSM1"}
    assert "the console's default" in pairing_words(1) and "cross the surgeon's hands" in pairing_words(2)
