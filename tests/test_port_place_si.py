"""port-place on the Si patient cart (issue 40: "where the SUJ cannot give every orientation (Si), the reachable
docking orientations follow from the SUJ and the PSM's own joints must absorb the rest"): the batch Si inverse
against the plain one, each port's Si docking frame against a brute-force search of the yaw, the rows' docking
against the plain inverse at every cart pose, and the dvrk export's setup joints through the reference forward
kinematics (tests/reference.py, typed from the dVRK's files apart from the package)."""
import json
import math

import numpy as np
import pytest

from surgopt.kinematics import suj as SJ
from surgopt.kinematics.si_docking import own_joints, si_solutions
from surgopt.robots.dvrk_suj import CARTS
from surgopt.robots.models import get_model
from surgopt.studies.port_place import config as C
from surgopt.studies.port_place import study as S
from surgopt.studies.port_place import tables as T

from conftest import cli
from reference import suj_forward_reference

SI_ARMS = {"instrument_arm": "dvrk_psm_si", "camera_arm": "dvrk_ecm_si"}
SI = {"patient": {"port_region": {"site_spacing_mm": 36.0}}, "target": {"spacing_mm": 15.0}, "robot": SI_ARMS,
      "cart": {"model": "si", "around_step_deg": 30.0, "distance_step_mm": 300.0, "trendelenburg_deg": 10.0}}


def test_the_batch_si_inverse_equals_the_plain_one():
    """``si_solutions`` over many poses equals ``suj.si_ik``'s best solution pose by pose (margin 1e-12, joints
    1e-9), on poses the reference forward kinematics makes from random joints (in and out of range); a pose turned
    off the Si's orientations is refused (-inf), as the plain inverse refuses it. Premises: some poses dock, some
    solve only outside the ranges."""
    rng = np.random.default_rng(7)
    for arm in ("PSM1", "PSM2", "ECM"):
        suj = CARTS["si"][arm]
        qs = np.column_stack([rng.uniform(-0.3, 0.9, 300), rng.uniform(-3.4, 3.4, (300, 3))])
        poses = np.array([suj_forward_reference("si", arm, q) for q in qs])
        tilt = SJ.mdh(0.2, 0, 0, 0)
        poses[::10] = poses[::10] @ tilt  # turned about the base's x: off the family
        margin, joints = si_solutions(suj, poses)
        assert np.all(margin[::10] == -np.inf)
        assert (margin >= 0).any() and ((margin < 0) & np.isfinite(margin)).any()
        for k, pose in enumerate(poses):
            answer = SJ.si_ik(suj, pose)
            sols = answer.within + answer.outside
            if not sols:
                assert margin[k] == -np.inf and answer.reason
                continue
            assert margin[k] == pytest.approx(sols[0].margin, abs=1e-12)
            np.testing.assert_allclose(joints[k], sols[0].joints, atol=1e-9)


def test_each_ports_si_frame_is_the_yaw_that_leaves_the_least_to_absorb_at_every_cart_pose():
    """A port's Si docking frame (patient frame, ``tables.si_frames``) is, at every cart pose of the grid, the
    orientation the Si's setup joints give at the yaw a 0.01-degree brute-force search finds the shaft nearest the
    aim at (the least the arm's own yaw and pitch absorb), expressed in the patient's frame at that pose: one frame
    per port for every pose (the table tilted 10 degrees head down)."""
    cfg = C.PortPlaceConfig.model_validate(SI)
    model = T.model_of(cfg)
    sites = model.sites_m[::17]
    aims = model.centre_m - sites
    aims /= np.linalg.norm(aims, axis=1)[:, None]
    frames = T.si_frames(cfg, CARTS["si"]["PSM1"], sites, aims)
    np.testing.assert_allclose(frames, T.si_frames(cfg, CARTS["si"]["PSM2"], sites, aims), atol=1e-12)
    poses = T.cart_poses(cfg)
    yaws = np.radians(np.arange(-180.0, 180.0, 0.01))
    for p in poses.patient[:: max(1, len(poses.patient) // 4)]:
        for site, aim, frame in zip(sites, aims, frames):
            w = p[:3, :3] @ aim
            shafts = np.array([SJ.si_orientation(CARTS["si"]["PSM1"], y)[:, 2] for y in yaws[::100]]) * -1
            coarse = yaws[::100][np.argmax(shafts @ w)]
            fine = coarse + np.radians(np.arange(-1.0, 1.0, 0.01))
            best = max(fine, key=lambda y: -SJ.si_orientation(CARTS["si"]["PSM1"], y)[:, 2] @ w)
            np.testing.assert_allclose(p[:3, :3].T @ SJ.si_orientation(CARTS["si"]["PSM1"], best), frame, atol=2e-4)


def _plain_docks(cfg, row, patient):
    """Whether every arm of ``row`` docks with the cart at ``patient`` (4x4) by the plain inverse (``suj.si_ik``)
    and, for the ECM, its own yaw and pitch aiming the scope at the centre within its ranges."""
    centre = np.asarray(cfg.target.centre_mm, float) / 1000
    ecm = get_model("dvrk_ecm_si")
    for arm in ("psm1", "psm2", "ecm"):
        port = np.array([row[f"{arm}_{c}_mm"] for c in "xyz"]) / 1000
        aim = (centre - port) / np.linalg.norm(centre - port)
        suj = CARTS["si"][arm.upper()]
        frame = T.si_frames(cfg, suj, port[None], aim[None])[0]
        base = np.eye(4)
        base[:3, :3], base[:3, 3] = frame, port
        if not SJ.si_ik(suj, patient @ base).within:
            return False
        if arm == "ecm":
            q1, q2, _ = own_joints(frame, aim)
            if not (ecm.yaw_limits_rad[0] <= q1 <= ecm.yaw_limits_rad[1]
                    and ecm.pitch_limits_rad[0] <= q2 <= ecm.pitch_limits_rad[1]):
                return False
    return True


def test_the_rows_dock_on_the_si_cart_at_the_first_pose_the_plain_inverse_docks_every_arm():
    """The rows of a small Si run: a row's cart pose is the first of the grid at which the plain Si inverse docks
    PSM1, PSM2 and the ECM (its own yaw and pitch within range), -1 where none does; its setup-joint columns
    (the column and three planar joints: no j4, j5 on the Si) carried through the reference forward kinematics put
    each arm's base on its port; each PSM's roll is 0 (the Si fixes it). Premises: docked and undocked rows both
    checked, and rows feasible."""
    cfg = C.PortPlaceConfig.model_validate(SI)
    assert cfg.constraints.min_link_clearance_mm == "off"  # the links are the Classic's: left out on the Si
    cols = S.compute_task(cfg, S.n_total(cfg), 0)
    assert "psm1_suj_j3_deg" in cols and "psm1_suj_j4_deg" not in cols and "psm1_roll_deg" in cols
    assert np.all(cols["psm1_roll_deg"] == 0) and np.all(cols["psm2_roll_deg"] == 0)
    poses = T.cart_poses(cfg)
    docked, undocked = np.flatnonzero(cols["cart_pose"] >= 0), np.flatnonzero(cols["cart_pose"] < 0)
    assert len(docked) and len(undocked) and cols["feasible"].any()
    rng = np.random.default_rng(3)
    for r in np.concatenate([rng.choice(docked, 6, replace=False), rng.choice(undocked, 3, replace=False)]):
        row = {c: v[r].item() for c, v in cols.items()}
        first = next((k for k, p in enumerate(poses.patient) if _plain_docks(cfg, row, p)), -1)
        assert row["cart_pose"] == first
        if first < 0:
            continue
        patient = poses.patient[first]
        for arm in ("psm1", "psm2", "ecm"):
            q = [row[f"{arm}_suj_column_mm"] / 1000] + [math.radians(row[f"{arm}_suj_j{j}_deg"]) for j in (1, 2, 3)]
            port = np.array([row[f"{arm}_{c}_mm"] for c in "xyz"]) / 1000
            base = suj_forward_reference("si", arm.upper(), q)
            np.testing.assert_allclose(base[:3, 3], patient[:3, :3] @ port + patient[:3, 3], atol=1e-9)
            assert row[f"{arm}_suj_margin_deg"] >= 0 and row[f"{arm}_suj_column_margin_mm"] >= 0


def test_the_si_export_lands_each_rcm_on_its_port_and_its_own_joints_aim_the_shaft(tmp_path):
    """The CLI on a small Si config: the report names the Si cart and says the links are not measured; the best
    layout's ``--format dvrk`` export: ``suj`` "si", four joint values per arm, which the reference forward
    kinematics carry onto each port (1e-9 m); each arm's own yaw and pitch at the target's centre (within the Si
    arm's ranges) point its shaft through the centre from the base so docked; no clearances claimed."""
    (tmp_path / "si.toml").write_text(
        "[patient.port_region]\nsite_spacing_mm = 36.0\n[target]\nspacing_mm = 15.0\n"
        "[robot]\ninstrument_arm = \"dvrk_psm_si\"\ncamera_arm = \"dvrk_ecm_si\"\n"
        "[cart]\nmodel = \"si\"\naround_step_deg = 30.0\ndistance_step_mm = 300.0\n")
    r = cli("port-place", "si.toml", "--store", tmp_path / "s", cwd=tmp_path)
    assert "Si cart" in r.stdout and "not measured" in r.stdout
    best = int(r.stdout.split("best_design_id")[1].split()[1])
    cli("export", "latest", "--store", tmp_path / "s", "--design", str(best), "--format", "dvrk", "--out",
        tmp_path / "setup.json", cwd=tmp_path)
    setup = json.loads((tmp_path / "setup.json").read_text())
    assert setup["clearances_outside_body"]["checks"] == [] and "not modelled" in setup["clearances_outside_body"]["model"]
    patient = np.array(setup["cart_to_patient"])
    centre = patient[:3, :3] @ (np.array(C.Target().centre_mm) / 1000) + patient[:3, 3]
    for arm in setup["arms"]:
        assert arm["suj"] == "si" and len(arm["suj_joints"]) == 4
        base = suj_forward_reference("si", arm["name"], arm["suj_joints"])
        port = patient[:3, :3] @ (np.array(arm["port_mm"]) / 1000) + patient[:3, 3]
        np.testing.assert_allclose(base[:3, 3], port, atol=1e-9)
        holder = get_model("dvrk_ecm_si" if arm["name"] == "ECM" else "dvrk_psm_si")
        q1, q2 = arm["arm_joints_at_target_centre"][:2]
        assert holder.yaw_limits_rad[0] <= q1 <= holder.yaw_limits_rad[1]
        assert holder.pitch_limits_rad[0] <= q2 <= holder.pitch_limits_rad[1]
        shaft = np.array([math.sin(q1) * math.cos(q2), -math.sin(q2), -math.cos(q1) * math.cos(q2)])  # P2's inverse
        toward = (centre - port) / np.linalg.norm(centre - port)
        np.testing.assert_allclose(base[:3, :3] @ shaft, toward, atol=1e-9)


@pytest.mark.parametrize("change, words", [
    ({"robot": {**SI_ARMS, "instrument_count": 3}}, "its PSM3 hangs 15 deg"),
    ({"robot": {**SI_ARMS, "docking_roll_deg": 30.0}}, "no roll about the shaft"),
    ({"robot": SI_ARMS, "constraints": {"min_link_clearance_mm": 0.0}}, "not modelled"),
    ({"robot": {}}, "carries the Si PSMs and ECM"),
])
def test_what_the_si_cart_does_not_do_is_refused_by_name(change, words):
    """A config asking the Si cart for what it does not do here is refused, naming the field: a third PSM, a
    docking roll, the links deciding feasible (asked for; left out unasked), the Classic's arms."""
    with pytest.raises(ValueError, match=words):
        C.PortPlaceConfig.model_validate({**SI, **change, "cart": SI["cart"]})
