"""#54 "the arms clear of the bedside": the table's slab, its side rails, the patient's arms and legs as boxes
(``studies/port_place/bedside.py``) the links must clear, in the rows and in one layout's clearances."""
from __future__ import annotations

import numpy as np
import pytest

from surgopt.config import ConfigError, validate
from surgopt.kinematics.port.reasons import OUTSIDE
from surgopt.studies.port_place import config as PC
from surgopt.studies.port_place import study as S
from surgopt.studies.port_place.bedside import BEDSIDE, bedside_boxes, bedside_words
from surgopt.studies.port_place.link_tables import SURROUNDINGS, pair_name, to_bedside

import reference as REF
from test_link_tables import LINKS


def _cfg(**bedside):
    return PC.PortPlaceConfig.model_validate({"cart": {"model": "classic"}, "bedside": bedside})


def test_each_position_puts_its_boxes_where_it_says():
    """The boxes of each choice: the table a slab under z = 0 across its width; the rails just outside it at the
    table top's level; tucked arms on the table's edge, from the shoulder toward the feet; arms out beyond the
    table at the shoulders; legs flat between the hips and the table's foot, in lithotomy raised beside the midline;
    each right one the mirror of its left; every name one of BEDSIDE, which the rows' codes follow."""
    w = 0.28
    names = {b.name: b for b in bedside_boxes(_cfg(arms="tucked", legs="flat"))}
    assert set(names) == set(BEDSIDE) and SURROUNDINGS[1:] == BEDSIDE
    assert names["table"].hi[2] == 0.0 and names["table"].lo[2] < 0 and names["table"].hi[0] == w
    assert names["left side rail"].lo[0] > w and names["left side rail"].hi[2] == 0.0
    arm = names["patient's left arm"]
    assert arm.hi[0] == w and arm.lo[0] > 0 and arm.hi[1] == 0.42 and arm.lo[2] == 0.0
    leg = names["patient's left leg"]
    assert leg.hi[1] == -0.22 and leg.lo[1] == -1.0 and leg.lo[0] > 0
    for left, right in (("left side rail", "right side rail"), ("patient's left arm", "patient's right arm"),
                        ("patient's left leg", "patient's right leg")):
        a, b = names[left], names[right]
        np.testing.assert_allclose([a.lo[0], a.hi[0]], [-b.hi[0], -b.lo[0]])
        np.testing.assert_allclose([a.lo[1:], a.hi[1:]], [b.lo[1:], b.hi[1:]])
    out = {b.name: b for b in bedside_boxes(_cfg(arms="out", legs="lithotomy", rails=False))}
    assert "left side rail" not in out and out["patient's left arm"].lo[0] == w
    assert out["patient's left arm"].hi[1] == 0.42 and out["patient's left leg"].hi[2] > 0.5
    assert [b.name for b in bedside_boxes(_cfg(arms="none", legs="none", rails=False))] == ["table"]
    assert "arms out on arm boards" in bedside_words(_cfg()) and "not the legs" in bedside_words(_cfg())


def test_a_bedside_whose_shoulders_lie_below_its_hips_is_refused():
    with pytest.raises(ConfigError, match="bedside.shoulder_y_mm"):
        validate({"bedside": {"shoulder_y_mm": -300.0, "hip_y_mm": -200.0}}, PC.Config, "x.toml")


def test_the_bedside_clearance_is_the_sampled_least_over_every_box():
    """``link_tables.to_bedside`` (golden-section per box, C2) against sampling each segment densely
    (``reference.segment_box_distance_sampled``, numpy, no code shared): the least over the boxes less the radius,
    within the sampling step, and the nearest box named where it is nearer than the others by more than that. The
    premise: segments nearest to each kind of box, and some inside a box (clearance below minus the radius)."""
    cfg = _cfg(arms="tucked", legs="flat")
    boxes = bedside_boxes(cfg)
    rng = np.random.default_rng(54)
    centres = [0.5 * (b.lo + b.hi) for b in boxes]
    segs = np.stack([np.stack([c + rng.normal(0, 0.15, 3), c + rng.normal(0, 0.15, 3)])
                     for c in centres for _ in range(12)])[None]
    radii = rng.uniform(0.0, 0.05, segs.shape[1])
    got, which = to_bedside(cfg, segs, radii)
    named, inside = set(), 0
    for k in range(segs.shape[1]):
        d = np.array([REF.segment_box_distance_sampled(*segs[0, k], b.lo, b.hi) for b in boxes])
        step = np.linalg.norm(segs[0, k, 1] - segs[0, k, 0]) / 2000
        assert d.min() - step - 1e-12 <= got[0, k] + radii[k] <= d.min() + 1e-12
        order = np.sort(d)
        if order[1] - order[0] > 2 * step:
            assert BEDSIDE[which[0, k]] == boxes[int(np.argmin(d))].name
            named.add(boxes[int(np.argmin(d))].name)
        inside += d.min() == 0.0
    assert named == set(BEDSIDE) and inside > 0


def test_the_rows_fail_a_layout_on_the_patients_tucked_arm_and_name_it():
    """With the arms tucked, layouts of the small grid that clear everything else fail on a patient's arm: the rows'
    least names it (``external_link_pair``), and the same layouts without the arms clear more (the premise: the
    bedside decides some rows)."""
    with_arms = PC.PortPlaceConfig.model_validate({**LINKS, "bedside": {"arms": "tucked"}})
    without = PC.PortPlaceConfig.model_validate({**LINKS, "bedside": {"arms": "none"}})
    a, b = (S.compute_task(c, S.n_total(c), 0) for c in (with_arms, without))
    names = [pair_name(int(c)) for c in a["external_link_pair"]]
    on_arm = np.array([k for k, n in enumerate(names) if n.endswith(("patient's left arm", "patient's right arm"))])
    overlap = on_arm[a["external_clearance_mm"][on_arm] < 0] if len(on_arm) else on_arm
    assert len(overlap) > 0 and np.all(a["infeasible"][overlap] & OUTSIDE)
    assert np.all(a["external_clearance_mm"][on_arm] <= np.nan_to_num(b["external_clearance_mm"][on_arm], nan=np.inf)
                  + 1e-9)
    assert a["feasible"].sum() <= b["feasible"].sum()


def test_the_pages_scene_draws_the_bedside_near_the_body():
    """#56 item 4 / #54: the scene's bedside lines are the boxes' edges cut to twice the body's extent (the scene
    keeps the body's scale): every point within that window and on a box's surface; none without the links."""
    from surgopt.studies.port_place.geometry import body_extent_mm
    from surgopt.studies.port_place.scene import scene_marks

    cfg = _cfg(arms="tucked", legs="flat")
    a, b, _ = body_extent_mm(cfg.patient)
    points = np.array([p for p in scene_marks(cfg)["bedside"] if p is not None]) / 1000
    assert len(points) > 0 and np.all(np.abs(points[:, 0]) <= 2 * a / 1000 + 1e-9)
    assert np.all(np.abs(points[:, 1]) <= 2 * b / 1000 + 1e-9)
    on_a_box = [any(np.all((p >= box.lo - 1e-6) & (p <= box.hi + 1e-6)) for box in bedside_boxes(cfg)) for p in points]
    assert all(on_a_box)
    assert scene_marks(PC.PortPlaceConfig.model_validate({"cart": {"model": "none"}}))["bedside"] == []
