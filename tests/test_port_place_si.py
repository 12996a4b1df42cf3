"""port-place on the Si patient cart (issue 40: "where the SUJ cannot give every orientation (Si), the reachable
docking orientations follow from the SUJ and the PSM's own joints must absorb the rest"): the batch Si inverse
against the plain one, each port's Si docking frame against a brute-force search of the yaw, the rows' docking
against the plain inverse at every cart pose, and the dvrk export's setup joints through the reference forward
kinematics (tests/reference.py, typed from the dVRK's files apart from the package)."""
import json
import re
import math

import numpy as np
import pytest

from surgopt.kinematics.port import suj as SJ
from surgopt.kinematics.port.si_docking import own_joints, si_solutions
from surgopt.robots.dvrk.platforms import PLATFORMS
from surgopt.robots.models import get_model
from surgopt.studies.port_place import config as C
from surgopt.studies.port_place import study as S
from surgopt.studies.port_place import tables as T
from surgopt.studies.port_place import model as M

from conftest import cli, invoke
import reference as REF
from reference import suj_forward_reference

SI_ARMS = {"instrument_arm": "dvrk_psm_si", "camera_arm": "dvrk_ecm_si"}
SI = {"patient": {"port_region": {"site_spacing_mm": 36.0}}, "target": {"spacing_mm": 15.0}, "robot": SI_ARMS,
      "cart": {"model": "si", "around_step_deg": 30.0, "distance_step_mm": 300.0, "trendelenburg_deg": 10.0},
      "constraints": {"min_link_clearance_mm": "off"}}  # the docking's tests (the links': tests/test_link_tables.py)


def test_the_batch_si_inverse_equals_the_plain_one():
    """``si_solutions`` over many poses equals ``suj.si_ik``'s best solution pose by pose (margin 1e-12, joints
    1e-9), on poses the reference forward kinematics makes from random joints (in and out of range); a pose turned
    off the Si's orientations is refused (-inf), as the plain inverse refuses it. Premises: some poses dock, some
    solve only outside the ranges."""
    rng = np.random.default_rng(7)
    for arm in ("PSM1", "PSM2", "ECM"):
        suj = PLATFORMS["si"].suj(arm)
        qs = np.column_stack([rng.uniform(-0.3, 0.9, 300), rng.uniform(-3.4, 3.4, (300, 3))])
        poses = np.array([suj_forward_reference("si", arm, q) for q in qs])
        tilt = SJ.mdh(0.2, 0, 0, 0)
        poses[::10] = poses[::10] @ tilt  # turned about the base's x: off the family
        margin, joints = si_solutions(suj, poses)
        assert np.all(margin[::10] == -np.inf)
        assert (margin >= 0).any() and ((margin < 0) & np.isfinite(margin)).any()
        for k, pose in enumerate(poses):
            answer = REF.si_ik(suj, pose)
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
    model = M.model_of(cfg)
    sites = model.sites_m[::17]
    aims = model.centre_m - sites
    aims /= np.linalg.norm(aims, axis=1)[:, None]
    frames = T.si_frames(cfg, PLATFORMS["si"].suj("PSM1"), sites, aims)
    np.testing.assert_allclose(frames, T.si_frames(cfg, PLATFORMS["si"].suj("PSM2"), sites, aims), atol=1e-12)
    poses = T.cart_poses(cfg)
    yaws = np.radians(np.arange(-180.0, 180.0, 0.01))
    for p in poses.patient[:: max(1, len(poses.patient) // 4)]:
        for site, aim, frame in zip(sites, aims, frames):
            w = p[:3, :3] @ aim
            shafts = np.array([SJ.si_orientation(PLATFORMS["si"].suj("PSM1"), y)[:, 2] for y in yaws[::100]]) * -1
            coarse = yaws[::100][np.argmax(shafts @ w)]
            fine = coarse + np.radians(np.arange(-1.0, 1.0, 0.01))
            best = max(fine, key=lambda y: -SJ.si_orientation(PLATFORMS["si"].suj("PSM1"), y)[:, 2] @ w)
            np.testing.assert_allclose(p[:3, :3].T @ SJ.si_orientation(PLATFORMS["si"].suj("PSM1"), best), frame, atol=2e-4)


def _arms(row):
    return [a for a in ("psm1", "psm2", "psm3", "ecm") if f"{a}_site" in row]


def _plain_docks(cfg, row, patient):
    """Whether every arm of ``row`` docks with the cart at ``patient`` (4x4) by the plain inverse (``suj.si_ik``)
    and, for the ECM, its own yaw and pitch aiming the scope at the centre within its ranges."""
    centre = np.asarray(cfg.target.centre_mm, float) / 1000
    ecm = get_model("dvrk_ecm_si")
    for arm in _arms(row):
        port = np.array([row[f"{arm}_{c}_mm"] for c in "xyz"]) / 1000
        aim = (centre - port) / np.linalg.norm(centre - port)
        suj = PLATFORMS["si"].suj(arm.upper())
        frame = T.si_frames(cfg, suj, port[None], aim[None])[0]
        base = np.eye(4)
        base[:3, :3], base[:3, 3] = frame, port
        if not REF.si_ik(suj, patient @ base).within:
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


def test_three_psms_on_the_si_cart_dock_the_third_in_its_own_frame():
    """Three PSMs on the Si cart (S7: its PSM3 hangs 15 deg off the vertical, PSM1 and PSM2 45): a chunk of a
    small run's rows. Each row's cart pose is the first at which the plain inverse docks all four arms, PSM3 in its
    own Si frame (-1 where none does); its five setup joints through the reference forward kinematics put its base
    on its port; its reach is the share of the target it reaches in that frame (``instrument_tables`` on frames
    the tables do not share), not in PSM1's. Premises: the two frames reach differently at some of the rows'
    third ports; docked and undocked rows both checked."""
    from surgopt.kinematics.port import place as K

    cfg = C.PortPlaceConfig.model_validate({**SI, "robot": {**SI_ARMS, "instrument_count": 3}})
    model = M.model_of(cfg)
    cols = S.compute_task(cfg, 60_000, 3)
    third = np.unique(cols["psm3_site"])
    aims = model.centre_m - model.sites_m[third]
    aims /= np.linalg.norm(aims, axis=1)[:, None]
    own = T.si_frames(cfg, PLATFORMS["si"].suj("PSM3"), model.sites_m[third], aims)
    theirs = T.si_frames(cfg, PLATFORMS["si"].suj("PSM1"), model.sites_m[third], aims)
    reach = {}
    for frames, key in ((own, "own"), (theirs, "theirs")):
        got, _ = K.instrument_tables(model.sites_m[third], frames, model.targets_m, model.limits,
                                     model.criteria.dexterity_length_m, model.cone)
        reach[key] = dict(zip(third.tolist(), got.sum(axis=1) / len(model.targets_m)))
    assert any(reach["own"][s] != reach["theirs"][s] for s in third.tolist())
    np.testing.assert_allclose(cols["psm3_reach"], [reach["own"][s] for s in cols["psm3_site"].tolist()], atol=1e-12)
    poses = T.cart_poses(cfg)
    docked, undocked = np.flatnonzero(cols["cart_pose"] >= 0), np.flatnonzero(cols["cart_pose"] < 0)
    assert len(docked) and len(undocked)
    rng = np.random.default_rng(5)
    for r in np.concatenate([rng.choice(docked, 4, replace=False), rng.choice(undocked, 2, replace=False)]):
        row = {c: v[r].item() for c, v in cols.items()}
        assert row["cart_pose"] == next((k for k, p in enumerate(poses.patient) if _plain_docks(cfg, row, p)), -1)
        if row["cart_pose"] < 0:
            continue
        patient = poses.patient[row["cart_pose"]]
        q = [row["psm3_suj_column_mm"] / 1000] + [math.radians(row[f"psm3_suj_j{j}_deg"]) for j in (1, 2, 3, 4)]
        port = np.array([row[f"psm3_{c}_mm"] for c in "xyz"]) / 1000
        np.testing.assert_allclose(suj_forward_reference("si", "PSM3", q)[:3, 3], patient[:3, :3] @ port
                                   + patient[:3, 3], atol=1e-9)


def test_the_si_export_lands_each_rcm_on_its_port_and_its_own_joints_aim_the_shaft(tmp_path):
    """The CLI on a small Si config with the links out of feasible (asked): the report names the Si cart and
    measures its links (the Si PSM's own, from the dVRK's Si description), saying they are not in feasible; the best
    layout's ``--format dvrk`` export: ``suj`` "si", four joint values per arm, which the reference forward
    kinematics carry onto each port (1e-9 m); each arm's own yaw and pitch at the target's centre (within the Si
    arm's ranges) point its shaft through the centre from the base so docked; its clearances, the Si arms' links
    named, the least the least of them."""
    (tmp_path / "si.toml").write_text(
        "[patient.port_region]\nsite_spacing_mm = 36.0\n[target]\nspacing_mm = 15.0\n"
        "[robot]\ninstrument_arm = \"dvrk_psm_si\"\ncamera_arm = \"dvrk_ecm_si\"\n"
        "[cart]\nmodel = \"si\"\naround_step_deg = 30.0\ndistance_step_mm = 300.0\n"
        "[constraints]\nmin_link_clearance_mm = \"off\"\n")  # the links: tests/test_link_tables.py
    code, out = invoke("port-place", tmp_path / "si.toml", "--store", tmp_path / "s")  # in this process
    assert code == 0 and "Si cart" in out and "not part of feasible" in out, out
    best = int(out.split("best_design_id")[1].split()[1])
    code, out = invoke("export", "latest", "--store", tmp_path / "s", "--design", str(best), "--format", "dvrk",
                       "--out", tmp_path / "setup.json")
    setup = json.loads((tmp_path / "setup.json").read_text())
    assert code == 0 and setup["feasible"] is True and setup["fails_on"] == [] and "not feasible" not in out
    _a_docked_infeasible_design_is_written_with_its_reasons_and_a_note(tmp_path)
    clear = setup["clearances_outside_body"]
    assert len(clear["checks"]) == 3 * 2 + 3 * 2 and clear["least_mm"] == min(c["clearance_mm"] for c in clear["checks"])
    assert any("parallelogram" in c["link"] for c in clear["checks"]) and "not part of feasible" in clear["model"]
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


def _a_docked_infeasible_design_is_written_with_its_reasons_and_a_note(tmp_path):
    """The dvrk export of a design that docks but fails another check: ``feasible`` false, ``fails_on`` its
    row's reasons in words (``reasons.REASONS``), and a note on stderr that it is not a layout to use."""
    import pyarrow.compute as pc

    from surgopt.kinematics.port.reasons import REASONS
    from surgopt.store import Store

    (run,) = Store(tmp_path / "s").runs("port-place")
    t = run.parts(S.STUDY.schema_for(run.manifest["config"])).table()
    t = t.filter(pc.and_(pc.greater_equal(t["cart_pose"], 0), pc.invert(t["feasible"])))
    row = t.slice(0, 1).to_pylist()[0]
    r = cli("export", "latest", "--store", tmp_path / "s", "--design", str(row["design_id"]), "--format", "dvrk",
            "--out", tmp_path / "bad.json", cwd=tmp_path)
    bad = json.loads((tmp_path / "bad.json").read_text())
    assert bad["feasible"] is False and bad["fails_on"]
    assert bad["fails_on"] == [text for bit, text in REASONS.items() if row["infeasible"] & bit]
    assert f"design {row['design_id']} is not feasible" in r.stderr


@pytest.mark.parametrize("change, words", [
    ({"robot": {**SI_ARMS, "docking_roll": "most_reach"}}, "no roll about the shaft"),
    ({"robot": {}}, "carries the Si PSMs and ECM"),
])
def test_what_the_si_cart_does_not_do_is_refused_by_name(change, words):
    """A config asking the Si cart for what it does not do here is refused, naming the field: a docking roll, the
    Classic's arms."""
    with pytest.raises(ValueError, match=words):
        C.PortPlaceConfig.model_validate({**SI, **change, "cart": SI["cart"]})


def test_the_page_colours_the_target_by_the_si_psm3s_own_isotropy(tmp_path, page):
    """The HTML page of a three-PSM run on the Si cart opens in chromium without errors, embeds the third
    instrument's own reach and isotropy (PSM3's Si frames: ``instrument_tables`` on them here), and colours each
    target point of the first layout by the least isotropy of the three instruments, PSM3's in its own frame.
    Premise: the first layout's PSM3 isotropy in its own frame differs from PSM1's frame's at some point."""
    from surgopt.kinematics.port import place as K

    (tmp_path / "si3.toml").write_text(
        "rows_stored = \"feasible\"\n[patient.port_region]\nsite_spacing_mm = 36.0\n[target]\nspacing_mm = 15.0\n"
        "[robot]\ninstrument_arm = \"dvrk_psm_si\"\ncamera_arm = \"dvrk_ecm_si\"\ninstrument_count = 3\n"
        "[cart]\nmodel = \"si\"\naround_step_deg = 30.0\ndistance_step_mm = 300.0\n"
        "[constraints]\nmin_link_clearance_mm = \"off\"\n")  # the links: tests/test_link_tables.py
    assert invoke("port-place", tmp_path / "si3.toml", "--store", tmp_path / "s", "--quiet")[0] == 0
    assert invoke("report", "latest", "--store", tmp_path / "s", "--out", tmp_path / "si3.html")[0] == 0
    errors = []
    page.on("pageerror", lambda e: errors.append(str(e)))
    page.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
    page.goto((tmp_path / "si3.html").as_uri())
    page.wait_for_selector("body[data-ready]", timeout=120_000)
    assert not errors, errors
    page.wait_for_function("document.getElementById('pp-scene').dataset.layout !== undefined", timeout=60_000)
    data = json.loads(page.evaluate("document.getElementById('pp-data').textContent"))
    first = page.evaluate("document.getElementById('pp-scene').dataset.layout")
    row = data["layouts"]["design_id"].index(int(first))
    sites = [data["layouts"][f"psm{a}_site"][row] for a in (1, 2, 3)]
    assert data["reach3"] is not None and data["dex3"] is not None
    iso = page.evaluate("document.getElementById('pp-scene').data.find(t => t.name === 'target (isotropy)')"
                        ".marker.color")
    # #56 item 4: the cart and its arms as the clicked layout's row docks them (read back from the scene's traces:
    # each arm's lines through its port), and each port from the landmark along the skin
    names = page.evaluate("document.getElementById('pp-scene').data.map(t => t.name)")
    assert {f"{a} setup joints and links (docked)" for a in ("PSM1", "PSM2", "PSM3", "ECM")} <= set(names)
    assert "the cart (its base on the floor, its column) and its arms as docked: click to hide or show" in names
    for a in ("PSM1", "PSM2", "PSM3", "ECM"):
        drawn = page.evaluate(f"(() => {{ const t = document.getElementById('pp-scene').data.find(t => t.name === "
                              f"'{a} setup joints and links (docked)'); return [t.x, t.y, t.z]; }})()")
        pts = np.array([[x, y, z] for x, y, z in zip(*drawn) if x is not None], float)
        port = np.array([data["layouts"][f"{a.lower()}_{c}_mm"][row] for c in "xyz"])
        assert np.linalg.norm(pts - port, axis=1).min() < 0.087  # through its port (to 0.1 mm)
    cells = page.locator("#pp-ports tbody tr").first.locator("td").all_inner_texts()
    assert re.fullmatch(r"(\d+\.\d cm (left|right)|midline), (\d+\.\d cm (cranial|caudal)|level)", cells[-1]), cells
    cfg = C.PortPlaceConfig.model_validate({"rows_stored": "feasible", "patient": SI["patient"],
                                            "target": SI["target"], "robot": {**SI_ARMS, "instrument_count": 3},
                                            "cart": {k: v for k, v in SI["cart"].items() if k != "trendelenburg_deg"},
                                            "constraints": SI["constraints"]})  # the run's: no link tables
    model = M.model_of(cfg)
    at = model.sites_m[sites]
    aims = model.centre_m - at
    aims /= np.linalg.norm(aims, axis=1)[:, None]
    frames = [T.si_frames(cfg, PLATFORMS["si"].suj(arm), at[a:a + 1], aims[a:a + 1])[0]
              for a, arm in enumerate(("PSM1", "PSM2", "PSM3"))]
    reach, dex = K.instrument_tables(at, np.array(frames), model.targets_m, model.limits,
                                     model.criteria.dexterity_length_m, model.cone)
    _, dex_theirs = K.instrument_tables(at[2:], np.array(frames[:1]), model.targets_m, model.limits,
                                        model.criteria.dexterity_length_m, model.cone)
    assert np.abs(dex_theirs[0] - dex[2]).max() > 1e-3
    want = np.where(reach.all(axis=0), dex.min(axis=0), np.nan)
    got = np.array([np.nan if v is None else v for v in iso], float)
    np.testing.assert_array_equal(np.isnan(got), np.isnan(want))
    np.testing.assert_allclose(got[~np.isnan(got)], want[~np.isnan(want)], atol=1e-4)  # the page rounds to 1e-4


def test_an_si_psm_yawed_off_psi_star_docks_on_the_si_family_and_still_reaches():
    """The Si's counterpart of the Classic's roll search (``clashes.rolled_docks``): each PSM yawed off psi* by a
    turn of the grid is docked by setup joints that, through the reference forward kinematics, put its base
    there (1e-9); that base's neutral shaft heads the aim's heading turned by exactly that turn (the Si turns the
    base about the vertical only: 1e-9 deg), tilted as at psi*; every target point is reached from it within the
    Si PSM's ranges (the RCM inverse written out here). Premise: several turns dock, 0 among them."""
    from surgopt.studies.port_place import clashes as CL

    cfg = C.PortPlaceConfig.model_validate(SI)
    cols = S.compute_task(cfg, S.n_total(cfg), 0)
    r = int(np.flatnonzero(cols["feasible"])[0])
    row = {c: v[r].item() for c, v in cols.items()}
    patient = T.patient_in_cart(cfg.cart, row["cart_x_mm"], row["cart_y_mm"], row["cart_heading_deg"])
    model = M.model_of(cfg)
    psm = get_model("dvrk_psm_si")
    lim = model.limits
    for arm in ("psm1", "psm2"):
        port = np.array([row[f"{arm}_{c}_mm"] for c in "xyz"]) / 1000
        docks = CL.rolled_docks(M.model_of(cfg), row, arm, patient)
        assert len(docks) > 2 and 0.0 in [d for d, _ in docks]
        aim = patient[:3, :3] @ (model.centre_m - port)
        shaft0 = None
        for deg, docked in docks:
            np.testing.assert_allclose(suj_forward_reference("si", arm.upper(), docked.joints), docked.base, atol=1e-9)
            shaft = -docked.base[:3, 2]
            turn = math.degrees(math.atan2(shaft[1], shaft[0]) - math.atan2(aim[1], aim[0]))
            assert (turn - deg + 180) % 360 - 180 == pytest.approx(0.0, abs=1e-9)
            shaft0 = shaft[2] if shaft0 is None else shaft0
            assert shaft[2] == pytest.approx(shaft0, abs=1e-12)  # the same tilt at every yaw
            local = (model.targets_m @ patient[:3, :3].T + patient[:3, 3] - docked.base[:3, 3]) @ docked.base[:3, :3]
            rho = np.linalg.norm(local, axis=1)
            q2, q1 = -np.arcsin(local[:, 1] / rho), np.arctan2(local[:, 0], -local[:, 2])
            q3 = rho - lim.along_shaft_m
            assert np.all((psm.yaw_limits_rad[0] <= q1) & (q1 <= psm.yaw_limits_rad[1])
                          & (psm.pitch_limits_rad[0] <= q2) & (q2 <= psm.pitch_limits_rad[1])
                          & (lim.insertion_lo <= q3) & (q3 <= lim.insertion_hi))


def test_each_arms_shaft_outside_is_its_own_length():
    """#53: the shafts' outside segment (the arms' external clearance without the cart's links, and the page's
    drawn shafts) was the Classic PSM's 0.4318 m for every arm; the Si PSM's insertion row puts its carriage
    0.4826 m behind the RCM. Each RCM arm's own length now (a file arm whose row gives none: the Classic's, said).
    Measured: no row of the Si grid here changes with it (shafts that diverge outward come closest at their ports),
    so the rows' outside table is checked against the sampled reference at the arm's own length."""
    from reference import segment_distance_sampled

    from surgopt.studies.port_place import tables as T

    cfg = C.PortPlaceConfig.model_validate({**SI, "cart": {"model": "none"}})
    classic = C.PortPlaceConfig.model_validate({"patient": SI["patient"], "target": SI["target"],
                                                "cart": {"model": "none"}})
    assert T.criteria(cfg).outside_length_m == pytest.approx(0.4826) == T.outside_length_m(cfg)
    assert T.criteria(classic).outside_length_m == pytest.approx(0.4318)
    model = M.model_of(cfg)
    sites, centre = model.sites_m, model.centre_m
    outside = model.grid.tables.outside

    def back(k):
        u = (centre - sites[k]) / np.linalg.norm(centre - sites[k])
        return sites[k] - 0.4826 * u

    for i in range(0, len(sites), 3):
        for j in range(i + 1, len(sites), 4):
            assert outside[i, j] == pytest.approx(segment_distance_sampled(back(i), sites[i], back(j), sites[j],
                                                                           n=801), abs=1e-3)


def test_the_si_yaw_off_psi_star_is_a_dimension_of_the_enumeration():
    """#54: "the yaw off psi* (Si) as a dimension of the enumeration itself". ``docking_rolls_deg`` on the Si is a
    list of yaws of the setup joints off psi*, one block of layouts each: every docked PSM of a block's rows is
    docked by setup joints whose base (reference forward kinematics) holds its RCM on its port with the neutral
    shaft heading the psi* heading turned by the block's yaw (signed by the port's side, as the Classic's roll),
    the rows' roll columns carry that yaw, and yaw 0's block is the run at psi* (every column). The premise: each
    block has docked layouts, and the yawed block's rows differ from psi*'s."""
    from surgopt.studies.port_place.rolls import dockings, per_roll

    yawed = {**SI, "robot": {**SI_ARMS, "docking_rolls_deg": [0.0, 20.0]}}
    cfg = C.PortPlaceConfig.model_validate(yawed)
    per = per_roll(cfg)
    assert dockings(cfg) == ((0.0, 0.0), (20.0, 20.0))
    at_psi = S.compute_task(C.PortPlaceConfig.model_validate(SI), per, 0)
    first = S.compute_task(cfg, per, 0)
    for c, v in at_psi.items():
        np.testing.assert_array_equal(first[c], v, err_msg=c)
    block = S.compute_task(cfg, per, 1)  # the 20 deg block (task 1 of chunks of one block)
    docked = np.flatnonzero(block["cart_pose"] >= 0)
    assert len(docked) > 0 and not np.array_equal(block["cart_pose"], first["cart_pose"])
    row = {c: v[docked[0]].item() for c, v in block.items()}
    model = M.model_of(C.PortPlaceConfig.model_validate({**SI, "robot": {**SI_ARMS, "docking_roll_deg": 20.0}}))
    patient = T.patient_in_cart(cfg.cart, row["cart_x_mm"], row["cart_y_mm"], row["cart_heading_deg"])
    for arm in T.docked_arms(model, row):
        if arm.arm == "ECM":
            continue
        side = 1.0 if row[f"{arm.arm.lower()}_x_mm"] >= 0 else -1.0
        assert row[f"{arm.arm.lower()}_roll_deg"] == pytest.approx(20.0 * side)
        base = suj_forward_reference("si", arm.arm, np.asarray(arm.joints))
        port = np.array([row[f"{arm.arm.lower()}_{c}_mm"] for c in "xyz"]) / 1000
        np.testing.assert_allclose((np.linalg.inv(patient) @ base)[:3, 3], port, atol=1e-9)  # the RCM on its port
        aim = patient[:3, :3] @ (model.centre_m - port)
        shaft = -base[:3, 2]
        turn = math.degrees(math.atan2(shaft[1], shaft[0]) - math.atan2(aim[1], aim[0]))
        assert (turn - 20.0 * side + 180) % 360 - 180 == pytest.approx(0.0, abs=1e-6)
