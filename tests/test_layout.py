"""Issue 53: one layout re-solved once for every view (``studies/port_place/layout.py``), and each view's numbers
equal the rows' for the same layout: the robot files (``export --format dvrk`` and ``dvrk-suj-fixed``), the closing
report's docking tables and the cart figure, each read against the stored row's own columns and the reference
forward kinematics of the setup joints (``tests/reference.py``, no code shared with the solvers)."""
import csv
import io
import json
import math

import numpy as np
import pytest

from surgopt.studies.port_place import config as PC
from surgopt.studies.port_place import export as E
from surgopt.studies.port_place import report as R
from surgopt.studies.port_place import study as S
from surgopt.studies.port_place.layout import layout_of
from surgopt.studies.port_place.model import model_of

from reference import suj_forward_reference

#: A coarse grid whose links decide feasible (``test_link_tables.LINKS``: at -45 deg some layouts keep them clear).
LINKS = {"patient": {"port_region": {"site_spacing_mm": 36.0}}, "target": {"spacing_mm": 15.0},
         "cart": {"model": "classic", "around_step_deg": 30.0, "distance_step_mm": 300.0, "clear_of_table_mm": 0.0},
         "constraints": {"min_link_clearance_mm": 0.0}, "robot": {"docking_roll_deg": -45.0}}
SUJ_COLUMNS = ("column_mm", "j1_deg", "j2_deg", "j3_deg", "j4_deg", "j5_deg")


@pytest.fixture(scope="module")
def feasible_rows():
    cfg = PC.PortPlaceConfig.model_validate(LINKS)
    cols = S.compute_task(cfg, S.n_total(cfg), 0)
    ok = np.flatnonzero(cols["feasible"])
    assert len(ok) >= 3  # the premise: feasible layouts whose links the model places
    pick = ok[np.argsort(cols["cost"][ok])[:3]]
    return cfg, [{c: (v[r].item() if hasattr(v[r], "item") else v[r]) for c, v in cols.items()} for r in pick]


def _row_joints(row: dict, arm: str) -> np.ndarray:
    """The row's own setup joints of ``arm`` in the solver's units (m, rad)."""
    got = np.array([row[f"{arm.lower()}_suj_{c}"] for c in SUJ_COLUMNS])
    return np.concatenate([[got[0] / 1000], np.radians(got[1:])])


def test_the_layout_docks_each_arm_at_the_rows_own_joints_and_clearance(feasible_rows):
    cfg, rows = feasible_rows
    for row in rows:
        layout = layout_of(model_of(cfg), row)
        assert layout.rolls == {}  # the premise: a feasible row's links clear at its own docking, nothing turned
        assert [a.arm for a in layout.docked] == ["PSM1", "PSM2", "ECM"] and all(a.joints for a in layout.docked)
        for a in layout.docked:
            np.testing.assert_allclose(a.joints, _row_joints(row, a.arm), atol=1e-9)
            base = suj_forward_reference("classic", a.arm, np.asarray(a.joints))
            np.testing.assert_allclose(base, a.base, atol=1e-9)  # the base the views write is the joints'
            port = np.array([row[f"{a.arm.lower()}_{c}_mm"] for c in "xyz"]) / 1000
            to_port = np.linalg.inv(layout.patient_in_cart) @ a.base
            np.testing.assert_allclose(to_port[:3, 3], port, atol=1e-9)  # each RCM on its port
        least = min(c.clearance_mm for c in layout.clearances)
        assert least == pytest.approx(row["external_clearance_mm"], abs=1e-3) and least >= 0.0
        assert layout_of(model_of(cfg), row).docked is layout.docked  # solved once in the process


def test_the_robot_files_write_the_rows_layout(feasible_rows):
    cfg, rows = feasible_rows
    for row in rows:
        setup = json.loads(E.dvrk_setup(cfg, row))
        fixed = json.loads(E.suj_fixed(cfg, row).split("*/", 1)[1])
        assert setup["design_id"] == row["design_id"] and setup["feasible"] and setup["fails_on"] == []
        assert (setup["cart"]["x_mm"], setup["cart"]["y_mm"]) == (row["cart_x_mm"], row["cart_y_mm"])
        measured = {a["name"]: a.get("measured_cp") for a in fixed["arms"]}
        for arm in setup["arms"]:
            name = arm["name"]
            np.testing.assert_allclose(arm["suj_joints"], _row_joints(row, name), atol=1e-9)
            np.testing.assert_allclose(arm["port_mm"], [row[f"{name.lower()}_{c}_mm"] for c in "xyz"], atol=1e-9)
            reference = suj_forward_reference("classic", name, np.asarray(arm["suj_joints"]))
            np.testing.assert_allclose(arm["base_in_cart"], reference, atol=1e-9)
            np.testing.assert_allclose(measured[name], reference, atol=1e-9)  # SUJ_Fixed: the same frame
        assert measured["PSM3"] is None  # a two-PSM layout places no PSM3
        ports_csv = {r["name"]: r for r in csv.DictReader(io.StringIO(E.ports_csv(cfg, row))) if r["what"] == "port"}
        for arm in setup["arms"]:  # #57 item 2: each port from the landmark, as the ports CSV gives it
            mark, port = arm["port_from_landmark"], arm["port_mm"]
            theirs = ports_csv[arm["name"]]
            assert mark["landmark"] == "umbilicus" and mark["top_view"] == theirs["from_umbilicus"]
            assert (mark["left_mm"], mark["cranial_mm"]) == pytest.approx((port[0], port[1]), abs=0.051)  # at (0, 0)
            assert mark["left_along_skin_mm"] == pytest.approx(float(theirs["left_of_umbilicus_along_skin_mm"]), abs=0.051)
            assert mark["cranial_along_skin_mm"] == pytest.approx(float(theirs["cranial_of_umbilicus_along_skin_mm"]),
                                                                  abs=0.051)
            assert abs(mark["left_along_skin_mm"]) >= abs(mark["left_mm"]) - 0.1  # an arc is no shorter than its chord
        least = setup["clearances_outside_body"]["least_mm"]
        assert least == pytest.approx(row["external_clearance_mm"], abs=0.051)  # written to 0.1 mm


def test_the_closing_reports_docking_tables_show_the_rows_joints(feasible_rows):
    cfg, rows = feasible_rows
    meta = {"config": cfg.model_dump_json()}
    for row in rows:
        tables = R.docking_tables(row, meta)
        pose, joints = tables[0][2][0], {r[0]: r[2] for r in tables[1][2]}
        assert pose[:2] == [f"{row['cart_x_mm']:.0f}", f"{row['cart_y_mm']:.0f}"]
        for arm in ("PSM1", "PSM2", "ECM"):
            assert joints[arm] == " ".join(f"{v:.4f}" for v in _row_joints(row, arm))
            margin = row[f"{arm.lower()}_suj_margin_deg"]
            assert [r for r in tables[1][2] if r[0] == arm][0][3].startswith(f"{margin:.1f}")


def test_the_cart_figure_draws_each_arms_setup_joints_where_the_rows_joints_put_them(feasible_rows, tmp_path):
    """The cart figure's polyline of each arm's setup joints ends at the SUJ's tip that the row's own joints give
    (reference forward kinematics: the base times the tip -> tool inverse)."""
    from reference import SUJ_TIP_ROTATION
    from surgopt.studies.plotting import pyplot
    from surgopt.studies.port_place.figures import cart_figure

    from surgopt.studies.port_place import figures as F

    cfg, rows = feasible_rows
    captured = {}
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(F, "save", lambda fig, path: captured.setdefault("fig", fig))
        cart_figure(pyplot(), model_of(cfg), rows[0], tmp_path)
    ax = captured["fig"].axes[0]
    tool = np.eye(4)
    tool[:3, :3], tool[:3, 3] = SUJ_TIP_ROTATION, (0.4864, 0.0, 0.1524)  # dvrk-kinematics.md, every PSM
    drawn = {line.get_label(): np.array(line.get_data_3d()).T for line in ax.get_lines()}
    for arm in ("PSM1", "PSM2"):
        tip = (suj_forward_reference("classic", arm, _row_joints(rows[0], arm)) @ np.linalg.inv(tool))[:3, 3]
        np.testing.assert_allclose(drawn[f"{arm} setup joints"][-1], tip, atol=1e-9)
    assert math.isfinite(rows[0]["cost"])


def test_the_console_file_loads_the_suj_fixed_file_and_keeps_the_hands_uncrossed(feasible_rows):
    """#57 item 5: ``--format dvrk-console``, shaped as the dVRK's own console files (sawIntuitiveResearchKit
    share/console/console-patient-cart-fixed-simulated.json: the SUJ_Fixed component reading a kinematic file, each
    arm's base frame from its interface of the arm's name; console-full-system-simulated.json: the MTMs,
    psm_teleops, ecm_teleop): it names the SUJ_Fixed file written beside it, places exactly the arms that file gives a
    frame, and pairs MTMR with the PSM the dvrk export's teleop pairing names (the one on the camera image's right)."""
    cfg, rows = feasible_rows
    for row in rows:
        text = E.dvrk_console(cfg, row)
        assert text.startswith("/* surgopt port-place") and text.count("*/") == 1
        doc = json.loads(text.split("*/", 1)[1])
        by_name = {a["name"]: a for a in doc["arms"]}
        assert by_name["SUJ"] == {"name": "SUJ", "type": "SUJ_Fixed", "kinematic": E.CONSOLE_SUJ_FILE}
        fixed = json.loads(E.suj_fixed(cfg, row).split("*/", 1)[1])["arms"]
        placed = {a["name"] for a in fixed if "measured_cp" in a}
        assert {n for n, a in by_name.items() if "base_frame" in a} == placed == {"PSM1", "PSM2", "ECM"}
        for name in placed:
            assert by_name[name]["base_frame"] == {"component": "SUJ", "interface": name}
            assert by_name[name]["type"] == ("ECM" if name == "ECM" else "PSM")
            assert set(by_name[name]) == {"name", "type", "simulation", "arm", "base_frame"}
        teleop = json.loads(E.dvrk_setup(cfg, row))["teleop"]
        assert {t["mtm"]: t["psm"] for t in doc["psm_teleops"]} == teleop
        assert doc["ecm_teleop"] == {"mtm_left": "MTML", "mtm_right": "MTMR", "ecm": "ECM"}


def _in_patient_mm(p_world_m: np.ndarray, row: dict, cfg) -> np.ndarray:
    """A point of the cart's world frame (m) in the patient's frame (mm), written out from the cart pose's
    definition (``carts.patient_in_cart``'s docstring): the cart's world turned by -heading about the vertical and
    moved to (x, y, its height above the floor - the table's height) in the untilted frame, then the tilt undone."""
    from surgopt.robots.dvrk.platforms import PLATFORMS

    h = math.radians(row["cart_heading_deg"])
    turn = np.array([[math.cos(h), math.sin(h), 0.0], [-math.sin(h), math.cos(h), 0.0], [0.0, 0.0, 1.0]])
    at = np.array([row["cart_x_mm"] / 1000, row["cart_y_mm"] / 1000,
                   PLATFORMS["classic"].world_above_floor_m - cfg.cart.table_height_mm / 1000])
    t, lat = math.radians(cfg.cart.trendelenburg_deg), math.radians(cfg.cart.lateral_tilt_deg)
    rx = np.array([[1.0, 0.0, 0.0], [0.0, math.cos(-t), -math.sin(-t)], [0.0, math.sin(-t), math.cos(-t)]])
    ry = np.array([[math.cos(-lat), 0.0, math.sin(-lat)], [0.0, 1.0, 0.0], [-math.sin(-lat), 0.0, math.cos(-lat)]])
    return (rx @ ry).T @ (turn @ p_world_m + at) * 1000


def test_the_pages_scene_draws_each_arm_docked_where_the_rows_joints_put_it(feasible_rows):
    """#56 item 4: the page's scene draws the cart and its arms as the row docks them (``layout.docked_lines_mm``,
    patient frame, mm). Each PSM's setup-joint polyline reaches the SUJ's tip that the row's own joints give
    (reference forward kinematics, put in the patient's frame by the row's cart pose written out here), each
    arm's lines pass through its port (its shaft's capsule starts there), and the cart's column stands on the
    row's cart origin, as high as the cart's world frame above the floor."""
    from reference import SUJ_TIP_ROTATION
    from surgopt.robots.dvrk.platforms import PLATFORMS
    from surgopt.studies.port_place.layout import docked_lines_mm

    cfg, rows = feasible_rows
    tool = np.eye(4)
    tool[:3, :3], tool[:3, 3] = SUJ_TIP_ROTATION, (0.4864, 0.0, 0.1524)  # dvrk-kinematics.md, every PSM
    for row in rows:
        drawn = docked_lines_mm(model_of(cfg), row)
        lines = {role: np.array([p for p in line if p is not None]) for role, line in drawn["arms"]}
        assert sorted(lines) == ["ECM", "PSM1", "PSM2"]
        for role, pts in lines.items():
            port = np.array([row[f"{role.lower()}_{c}_mm"] for c in "xyz"])
            assert np.linalg.norm(pts - port, axis=1).min() < 0.087  # through its port (drawn to 0.1 mm: 0.05 mm a coordinate)
        column = np.array([p for p in drawn["cart"] if p is not None])[-2:]  # from the floor to the world's origin
        np.testing.assert_allclose(column, [_in_patient_mm(np.array([0.0, 0.0, z]), row, cfg) for z in
                                            (-PLATFORMS["classic"].world_above_floor_m, 0.0)], atol=0.051)
        for arm in ("PSM1", "PSM2"):
            tip = (suj_forward_reference("classic", arm, _row_joints(row, arm)) @ np.linalg.inv(tool))[:3, 3]
            assert np.linalg.norm(lines[arm] - _in_patient_mm(tip, row, cfg), axis=1).min() < 0.087
    assert docked_lines_mm(model_of(PC.PortPlaceConfig.model_validate({"cart": {"model": "none"}})), rows[0]) is None
