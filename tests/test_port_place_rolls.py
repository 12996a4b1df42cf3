"""#54 item 2: the docking roll as a dimension of the enumeration (``robot.docking_rolls_deg``,
``studies/port_place/rolls.py``): one block of designs per roll, each the enumeration at that roll."""
from __future__ import annotations

import numpy as np
import pytest

from surgopt.config import ConfigError, validate
from surgopt.studies.port_place import config as PC
from surgopt.studies.port_place import model as M
from surgopt.studies.port_place import study as S
from surgopt.studies.port_place.layout import layout_of
from surgopt.studies.port_place.rolls import at_docking, config_of_row, dockings, model_for, per_roll

from test_link_tables import LINKS

#: The small grid with the links, its arms off the bedside (on boards they leave none of its layouts), at two
#: rolls, -45 and 0.
ROLLS = {**LINKS, "bedside": {"arms": "none"}, "robot": {"docking_rolls_deg": [-45.0, 0.0]}}


def _rows(cfg, chunk=None):
    chunk = chunk or S.n_total(cfg)
    parts = [S.compute_task(cfg, chunk, i) for i in range(S.n_tasks(cfg, chunk))]
    return {c: np.concatenate([p[c] for p in parts]) for c in parts[0]}


def test_each_rolls_block_is_the_enumeration_at_that_roll():
    """Block b of the enumeration equals the run of the config at roll b alone, column by column (design_id offset
    by b blocks), whatever the chunks (one straddles the blocks' boundary); the rolls' columns carry each PSM's
    signed roll. The premise: the blocks differ, both with feasible layouts (13 at -45, 2 at 0)."""
    cfg = PC.PortPlaceConfig.model_validate(ROLLS)
    per = per_roll(cfg)
    assert dockings(cfg) == ((-45.0, -45.0), (0.0, 0.0)) and S.n_total(cfg) == 2 * per
    rows = _rows(cfg, chunk=per + 777)  # the first chunk crosses into the second block
    assert np.array_equal(rows["design_id"], np.arange(2 * per))
    feasible_by_block = []
    for b, (roll, _) in enumerate(dockings(cfg)):
        alone = PC.PortPlaceConfig.model_validate({**ROLLS, "robot": {"docking_roll_deg": roll}})
        want = _rows(alone)
        for c, v in want.items():
            got = rows[c][b * per:(b + 1) * per]
            np.testing.assert_array_equal(got - (b * per if c == "design_id" else 0), v, err_msg=c)
        side = np.where(rows["psm1_x_mm"][b * per:(b + 1) * per] >= 0, 1.0, -1.0)
        np.testing.assert_allclose(rows["psm1_roll_deg"][b * per:(b + 1) * per], roll * side + 0.0)
        feasible_by_block.append(int(want["feasible"].sum()))
    assert feasible_by_block[0] != feasible_by_block[1] and min(feasible_by_block) > 0  # the premise


def test_per_side_each_pair_of_rolls_is_a_block_and_each_side_takes_its_own():
    """``docking_rolls_per_side``: a block per (left, right) pair of the list, the left's roll major; each block of
    two different rolls equals the single docking ``docking_roll_deg`` = left, ``docking_roll_right_deg`` = right,
    column by column (the diagonal ones are the mirrored list's, held above); a port on the patient's left rolls by
    the left's roll, one on the right by the mirror of the right's. The premise: in each such block two PSMs sit on
    either side with rolls of different size."""
    cfg = PC.PortPlaceConfig.model_validate({**ROLLS, "robot": {"docking_rolls_deg": [-45.0, 0.0],
                                                                 "docking_rolls_per_side": True}})
    per = per_roll(cfg)
    assert dockings(cfg) == ((-45.0, -45.0), (-45.0, 0.0), (0.0, -45.0), (0.0, 0.0)) and S.n_total(cfg) == 4 * per
    for b in (1, 2):
        left, right = dockings(cfg)[b]
        alone = PC.PortPlaceConfig.model_validate({**ROLLS, "robot": {"docking_roll_deg": left,
                                                                       "docking_roll_right_deg": right}})
        want = _rows(alone)
        block = S.compute_task(cfg, per, b)  # the block's model is the single docking's (one model, held)
        for c, v in want.items():
            np.testing.assert_array_equal(block[c] - (b * per if c == "design_id" else 0), v, err_msg=c)
        for arm in ("psm1", "psm2"):
            on_left = block[f"{arm}_x_mm"] >= 0
            np.testing.assert_allclose(block[f"{arm}_roll_deg"], np.where(on_left, left, -right) + 0.0)
        apart = (block["psm1_x_mm"] >= 0) != (block["psm2_x_mm"] >= 0)
        assert np.any(apart & (np.abs(block["psm1_roll_deg"]) != np.abs(block["psm2_roll_deg"])))  # the premise


def test_a_rows_view_reads_the_model_of_its_own_roll():
    """A stored row of block b is re-docked (``layout.layout_of``) on its roll's model: the same setup joints and
    docking as the single-roll config gives for that design; a row of its own (a given layout's, design -1) reads
    its roll from its PSM1's signed roll; a model is never built for the list itself (a caller's slip)."""
    cfg = PC.PortPlaceConfig.model_validate(ROLLS)
    per = per_roll(cfg)
    rows = _rows(cfg)
    r = int(np.flatnonzero(rows["feasible"])[0])
    row = {k: (v[r].item() if hasattr(v[r], "item") else v[r]) for k, v in rows.items()}
    alone = PC.PortPlaceConfig.model_validate({**ROLLS, "robot": {"docking_roll_deg": -45.0}})
    assert config_of_row(cfg, row).model_dump_json() == at_docking(cfg, (-45.0, -45.0)).model_dump_json()
    got, want = layout_of(model_for(cfg, row), row), layout_of(M.model_of(alone), {**row, "design_id": r % per})
    assert [a.joints for a in got.docked] == [a.joints for a in want.docked] and any(a.joints for a in got.docked)
    own = {**row, "design_id": -1}
    assert config_of_row(cfg, own).robot.docking_roll_deg == -45.0
    with pytest.raises(RuntimeError, match="one docking roll"):
        M.prepare(cfg)


@pytest.mark.parametrize("robot, match", [
    ({"docking_rolls_deg": [0.0, 0.0]}, "lists a roll twice"),
    ({"docking_rolls_deg": [0.0, -45.0], "docking_roll_deg": 30.0}, "not both"),
    ({"docking_rolls_deg": [0.0, -45.0], "docking_roll": "most_reach"}, "must be 'given'"),
    ({"docking_rolls_deg": [0.0, 120.0]}, "docking_rolls_deg"),
    ({"docking_rolls_deg": [0.0, -45.0], "docking_roll_right_deg": 30.0}, "not both"),
    ({"docking_rolls_per_side": True}, "give the list"),
    ({"docking_roll_right_deg": 30.0, "docking_roll": "most_reach"}, "docking_roll_right_deg"),
])
def test_a_roll_list_that_cannot_be_enumerated_is_refused_by_field(robot, match):
    with pytest.raises(ConfigError, match=match):
        validate({"robot": robot}, PC.Config, "x.toml")


def test_a_search_refuses_a_roll_list_and_the_si_takes_it_as_yaws_off_psi_star():
    with pytest.raises(ConfigError, match="docking_rolls_deg"):
        validate({"robot": {"docking_rolls_deg": [0.0, -45.0]},
                  "search": {"method": "tpe", "trials": 8, "batch": 4}}, PC.Config, "x.toml")
    si = {"robot": {"docking_rolls_deg": [0.0, -45.0], "instrument_arm": "dvrk_psm_si", "camera_arm": "dvrk_ecm_si"},
          "cart": {"model": "si"}}
    assert validate(si, PC.Config, "x.toml").robot.docking_rolls_deg == [0.0, -45.0]  # #54: the Si's yaws off psi*
    with pytest.raises(ConfigError, match="no roll about the shaft to choose"):
        validate({**si, "robot": {**si["robot"], "docking_rolls_deg": None, "docking_roll": "most_reach"}}, PC.Config,
                 "x.toml")
