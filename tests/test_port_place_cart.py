"""port-place with the patient cart (issue 40): which layouts the Classic cart's setup joints can dock, the rows'
cart pose and the docking reason, the first-dock kernel against a numpy search over the poses, a mirror-symmetric
patient with the cart on the midline, and the dvrk export, whose setup joints the reference forward kinematics
(tests/reference.py, typed from the dVRK's files apart from the package) carry onto each port."""
import json
import math

import numpy as np
import pytest

from surgopt.kinematics.port import designs as D
from surgopt.kinematics.port.place import DOCKING
from surgopt.robots.models import get_model
from surgopt.studies.port_place import config as C
from surgopt.studies.port_place import report as R
from surgopt.studies.port_place import study as S
from surgopt.studies.port_place import tables as T
from surgopt.studies.port_place import model as M

from conftest import cli, invoke
import reference as REF
from reference import suj_forward_reference

SMALL = {"patient": {"port_region": {"site_spacing_mm": 36.0}}, "target": {"spacing_mm": 15.0}, "cart": {"model": "none"}}
#: The links outside the body are the default's (min_link_clearance_mm = 0) but off here: these tests are about
#: docking alone (tests/test_link_tables.py checks the links; the ECM's one-handed setup joints are no mirror
#: image of themselves, so its links would break the mirror twins).
NO_LINKS = {"constraints": {"min_link_clearance_mm": "off"}}
MIDLINE = {**SMALL, **NO_LINKS,
           "cart": {"model": "classic", "pose": "given", "x_mm": 0.0, "y_mm": -1500.0, "heading_deg": 0.0}}
GRID = {**SMALL, **NO_LINKS, "cart": {"model": "classic", "around_step_deg": 30.0, "distance_step_mm": 300.0}}
#: The dVRK documentation's quoted Classic PSM SUJ ranges (deg; the column's in m is an assumption): j1 .. j5.
QUOTED = {"PSM1": [(-90, 90), (-135, 0), (-90, 90), (-135, 135), (-135, 135)],
          "PSM2": [(-90, 90), (0, 135), (-90, 90), (-135, 135), (-135, 135)]}


def test_first_dock_is_the_lowest_pose_where_every_arm_docks():
    """The kernel's first cart pose against a numpy search over random dock tables of 70 poses (two words): the
    lowest pose at which PSM1 and PSM2 dock on the pair's ports (either way round; the straight assignment
    preferred), PSM3 on the third and the ECM on the camera's; -1 when none (the premises: both outcomes, and
    a swapped one, occur)."""
    rng = np.random.default_rng(40)
    n, m = 6, 70
    ok = rng.random((3, n, m)) < 0.25
    cam = rng.random((n, m)) < 0.6
    bits, cam_bits = D.pack_bits(ok), D.pack_bits(cam)
    seen = {"none": 0, "swapped": 0, "straight": 0}
    for i in range(n):
        for j in range(i + 1, n):
            for l in (-1, *range(n)):
                for k in range(n):
                    if len({i, j, k, l}) < (4 if l >= 0 else 3):
                        continue
                    third = ok[2, l] if l >= 0 else np.ones(m, bool)
                    straight = ok[0, i] & ok[1, j] & third & cam[k]
                    crossed = ok[0, j] & ok[1, i] & third & cam[k]
                    either = np.flatnonzero(straight | crossed)
                    want = (int(either[0]), 0 if straight[either[0]] else 1) if len(either) else (-1, 0)
                    assert D.first_dock(bits, cam_bits, i, j, l, k) == want
                    seen["none" if want[0] < 0 else ("swapped" if want[1] else "straight")] += 1
    assert min(seen.values()) > 0


def test_with_the_cart_on_the_midline_every_dockable_layout_has_its_mirror_twin():
    """A mirror-symmetric patient with the cart at its feet on the midline: PSM1 docks at a site exactly where
    PSM2 docks at its mirror image, so a feasible layout's mirror twin (PSM1 and PSM2 exchanged) is feasible, at the
    same cost, exactly where the ECM docks at the mirror of its port (the ECM's setup joints are not mirror
    images of themselves: its tilt is one-handed). Premises: layouts that fail on docking alone, twins checked."""
    cfg = C.PortPlaceConfig.model_validate(MIDLINE)
    model = M.model_of(cfg)
    sites = model.sites_m * 1000
    mirror = np.array([int(np.flatnonzero(np.all(np.isclose(sites, s * [-1, 1, 1]), axis=1))[0]) for s in sites])
    ok = model.dock.margin[:, :, 0] >= 0
    assert np.array_equal(ok[0], ok[1][mirror]) and 0 < ok[0].sum() < len(sites)
    camera = model.dock.camera_margin[:, 0] >= 0
    cols = S.compute_task(cfg, S.n_total(cfg), 0)
    assert 0 < np.count_nonzero(cols["infeasible"] == DOCKING) and np.count_nonzero(cols["cart_pose"] == 0) > 0
    key = {(a, b, c): r for r, (a, b, c) in enumerate(zip(cols["psm1_site"], cols["psm2_site"], cols["ecm_site"]))}
    twins = 0
    for r in np.flatnonzero(cols["feasible"]):
        twin = key[(mirror[cols["psm2_site"][r]], mirror[cols["psm1_site"][r]], mirror[cols["ecm_site"][r]])]
        assert cols["feasible"][twin] == camera[mirror[cols["ecm_site"][r]]]
        if cols["feasible"][twin]:
            assert cols["cost"][twin] == pytest.approx(cols["cost"][r], rel=1e-9, abs=1e-12)
            twins += 1
    assert twins > 0


def _docking_frame(site_m, centre_m):
    """The docking frame written from its definition: z from the centre to the port, x the patient's lateral
    axis made orthogonal to it, y = z x x."""
    z = (site_m - centre_m) / np.linalg.norm(site_m - centre_m)
    x = np.array([1.0, 0.0, 0.0]) - z[0] * z
    x /= np.linalg.norm(x)
    return np.column_stack([x, np.cross(z, x), z])


def _rolled(frame, deg):
    """A docking frame turned by ``deg`` about its z (its x toward its y)."""
    r = math.radians(deg)
    return np.column_stack([math.cos(r) * frame[:, 0] + math.sin(r) * frame[:, 1],
                            math.cos(r) * frame[:, 1] - math.sin(r) * frame[:, 0], frame[:, 2]])


def test_the_dvrk_export_puts_each_psm_rcm_on_its_port_by_the_reference_kinematics(tmp_path):
    """The CLI on a small config with a grid of cart poses: its closing report names the cart pose and the setup
    joints; the best layout's ``--format dvrk`` export, its SUJ joints carried through the reference forward
    kinematics (world -> SUJ, the DH products, SUJ tip -> tool), lands each PSM's RCM frame on its port, docked
    toward the target's centre (1e-9 m, 1e-9), within the quoted ranges, and the ECM's RCM on its port with its
    own yaw and pitch (within their ranges) aiming the scope at the centre; an instrument arm's own joints at the
    centre are the neutral shaft (yaw = pitch = 0) inserted to the centre. A run without the cart, or an undockable design,
    is refused in one line."""
    (tmp_path / "c.toml").write_text(
        "[patient.port_region]\nsite_spacing_mm = 36.0\n[target]\nspacing_mm = 15.0\n"
        "[cart]\nmodel = \"classic\"\naround_step_deg = 30.0\ndistance_step_mm = 300.0\n"
        "[robot]\ndocking_roll_deg = -45.0\n"  # at roll 0 no layout of this grid keeps its links clear
        "[bedside]\narms = \"none\"\n")  # out on their boards, the arms leave none of its 2 (test_bedside's ground)
    # in this process (the CLI's own start-up is another test's): the run, then its exports on the run's model
    code, out = invoke("port-place", tmp_path / "c.toml", "--store", tmp_path / "s")
    assert code == 0, out
    assert "Classic cart" in out and "setup joints" in out and "PSM1" in out
    assert "least clearance outside the body" in out and "PSM1 and PSM2, over the target" in out
    checks = out.split("best layout: clinical checks")[1].split("best layout: ports")[0]
    assert "within" in checks and ("yes" in checks or "OUTSIDE" in checks)
    best = int(out.split("best_design_id")[1].split()[1])
    code, out = invoke("export", "latest", "--store", tmp_path / "s", "--design", str(best), "--format", "dvrk",
                       "--out", tmp_path / "setup.json")
    assert code == 0, out
    setup = json.loads((tmp_path / "setup.json").read_text())
    patient = np.array(setup["cart_to_patient"])
    centre = np.array(C.Target().centre_mm) / 1000
    names = [a["name"] for a in setup["arms"]]
    assert names == ["PSM1", "PSM2", "ECM"]
    assert sorted(setup["teleop"].values()) == ["PSM1", "PSM2"] and set(setup["teleop"]) == {"MTMR", "MTML"}
    assert setup["teleop"]["MTMR"] in setup["teleop_note"]
    assert "+x toward the patient's left, +y toward the head" in setup["units"]  # #42 item 3: which side
    clear = setup["clearances_outside_body"]
    assert len(clear["checks"]) == 3 * 2 + 3 * 2  # 3 pairs (docked, over the target), 3 arms x (patient, table)
    assert clear["least_mm"] == min(c["clearance_mm"] for c in clear["checks"])
    # #57 item 5: the dVRK's own SUJ_Fixed file: a comment (the dVRK's reader takes it), then the four arms it
    # expects, each placed arm's measured_cp the base frame its setup joints give (the reference FK of the joints
    # the dvrk export writes), PSM3 (not in this layout) left without one, the pairing named in the comment
    code, out = invoke("export", "latest", "--store", tmp_path / "s", "--design", str(best), "--format",
                       "dvrk-suj-fixed", "--out", tmp_path / "suj-fixed.json")
    assert code == 0, out
    text = (tmp_path / "suj-fixed.json").read_text()
    assert text.startswith("/* surgopt port-place") and text.count("*/") == 1
    comment, body = text.split("*/")
    fixed = json.loads(body)["arms"]
    assert [a["name"] for a in fixed] == ["ECM", "PSM1", "PSM2", "PSM3"] and "measured_cp" not in fixed[3]
    for a in fixed[:3]:
        joints = next(x["suj_joints"] for x in setup["arms"] if x["name"] == a["name"])
        np.testing.assert_allclose(np.array(a["measured_cp"]), suj_forward_reference("classic", a["name"], joints),
                                   atol=1e-9)
    assert f"MTMR drives {setup['teleop']['MTMR']}" in comment
    whole = setup["clearances_over_whole_target"]  # (#54 item 3) each pair over every target point, no more
    assert len(whole["checks"]) == 3 and whole["least_mm"] == min(c["clearance_mm"] for c in whole["checks"])
    for c in whole["checks"]:  # than the sampled check of that pair
        pair = c["check"].split(",")[0]
        sampled = next(s for s in clear["checks"] if s["check"] == f"{pair}, over the target")
        assert c["clearance_mm"] <= sampled["clearance_mm"] + 0.1 and "points)" in c["check"]
    ecm_arm = get_model("dvrk_ecm_classic")
    ecm = setup["arms"][2]
    base = suj_forward_reference("classic", "ECM", ecm["suj_joints"])
    port = np.array(ecm["port_mm"]) / 1000
    np.testing.assert_allclose(base[:3, 3], patient[:3, :3] @ port + patient[:3, 3], atol=1e-9)
    aim = base[:3, :3].T @ (patient[:3, :3] @ (centre - port))  # the scope's shaft toward the centre, base frame
    yaw, pitch = math.atan2(aim[0], -aim[2]), -math.asin(aim[1] / np.linalg.norm(aim))
    assert ecm["arm_joints_at_target_centre"][:2] == pytest.approx([yaw, pitch], abs=1e-9)
    assert ecm_arm.yaw_limits_rad[0] <= yaw <= ecm_arm.yaw_limits_rad[1]
    assert ecm_arm.pitch_limits_rad[0] <= pitch <= ecm_arm.pitch_limits_rad[1]
    # #54: the scope inserted as the ECM can hold it: ECM.json's 0 ... 0.255 m, past the controller's 50 mm, the tip
    # (0.0007 m past q3: -0.3822 + 0.3829) 100 mm before the centre where the port is far enough, else 50.7 mm in
    insertion = ecm["arm_joints_at_target_centre"][2]
    assert 0.050 <= insertion <= 0.255
    assert insertion == pytest.approx(max(np.linalg.norm(centre - port) - 0.100, 0.0507) - 0.0007, abs=1e-9)
    for arm in setup["arms"][:2]:
        q = arm["suj_joints"]
        base = suj_forward_reference("classic", arm["name"], q)
        port = np.array(arm["port_mm"]) / 1000
        frame = _rolled(_docking_frame(port, centre), arm["docking_roll_deg"] or 0.0)  # turned where it must clear
        want = patient @ np.vstack([np.column_stack([frame, port]), [0, 0, 0, 1]])
        np.testing.assert_allclose(base, want, atol=1e-9)
        for v, (lo, hi) in zip(q[1:], QUOTED[arm["name"]]):
            assert math.radians(lo) <= v <= math.radians(hi)
        yaw, pitch, insertion = arm["arm_joints_at_target_centre"]
        assert abs(yaw) < 1e-9 and abs(pitch) < 1e-9
        # the jaw tip (the default reaching point) 9.1 mm past the wrist, which is 15.6 mm behind q3
        assert insertion == pytest.approx(np.linalg.norm(port - centre) + 0.0156 - 0.0091, abs=1e-9)
    from surgopt.store import Store

    (run,) = Store(tmp_path / "s").runs("port-place")
    rows = run.read_table(S.STUDY.schema_for(run.manifest["config"]), columns=["design_id", "cart_pose"]).to_pandas()
    undockable = rows.loc[rows.cart_pose == -1, "design_id"].astype(str).tolist()
    assert undockable  # the premise: some layouts no cart pose docks
    for fmt in ("dvrk", "dvrk-suj-fixed"):
        bad = cli("export", "latest", "--store", tmp_path / "s", "--design", undockable[0], "--format", fmt,
                  "--out", tmp_path / f"never-{fmt}.json", cwd=tmp_path, check=False)
        assert bad.returncode == 2 and "not dockable" in bad.stderr and len(bad.stderr.strip().splitlines()) == 1
        assert not (tmp_path / f"never-{fmt}.json").exists()
    plain = tmp_path / "p.toml"
    plain.write_text("[patient.port_region]\nsite_spacing_mm = 72.0\n[target]\nspacing_mm = 20.0\n")
    assert invoke("port-place", plain, "--store", tmp_path / "s2")[0] == 0
    for fmt in ("dvrk", "dvrk-suj-fixed"):
        bad = cli("export", "latest", "--store", tmp_path / "s2", "--design", "0", "--format", fmt, cwd=tmp_path,
                  check=False)
        assert bad.returncode == 2 and "no cart" in bad.stderr


def test_the_dvrk_export_names_the_runs_own_docking_roll():
    """With ``robot.docking_roll_deg = 30`` each PSM's exported ``docking_roll_deg`` is the run's roll at its port
    (+30 on the patient's left, -30 on the right; it was left null, the base rolled all the same), or the roll the
    clearance search turned it to, and its setup joints through the reference forward kinematics land exactly the
    docking frame written from its definition turned by that roll. Premise: some arm keeps the run's roll."""
    cfg = C.PortPlaceConfig.model_validate({**GRID, "robot": {"docking_roll_deg": 30.0}})
    cols = S.compute_task(cfg, S.n_total(cfg), 0)
    r = int(np.flatnonzero(cols["feasible"] & (cols["cart_pose"] >= 0))[0])
    row = {c: v[r].item() for c, v in cols.items()}
    setup = json.loads(S.dvrk_export(cfg, row))
    patient = np.array(setup["cart_to_patient"])
    centre = np.asarray(cfg.target.centre_mm, float) / 1000
    kept = 0
    for arm in setup["arms"][:2]:
        port = np.array(arm["port_mm"]) / 1000
        roll = arm["docking_roll_deg"]
        kept += roll == (30.0 if port[0] >= 0 else -30.0)
        want = patient @ np.vstack([np.column_stack([_rolled(_docking_frame(port, centre), roll), port]), [0, 0, 0, 1]])
        np.testing.assert_allclose(suj_forward_reference("classic", arm["name"], arm["suj_joints"]), want, atol=1e-9)
    assert kept > 0 and setup["arms"][2]["docking_roll_deg"] is None  # the ECM aims with its own joints


def test_diff_of_two_port_place_runs_matches_layouts_by_their_ports(tmp_path):
    """Issue 42 item 1: a run on the whole abdomen and one on a marked region number their sites, so their
    designs, differently; ``diff`` joins them on each arm's port, so every layout of the region's run is found
    in the other with identical numbers (0 changed in every metric: only the enumeration differs), and the
    design_id and site indices are not reported as changes. A diff by design_id (the old join) would compare
    unrelated layouts: the premise checked on the same rows."""
    import pandas as pd

    from surgopt.results import diff_runs
    from surgopt.store import Store

    from surgopt.runner import run_study

    store = Store(tmp_path / "s")
    region = {**SMALL, "patient": {"port_region": {"site_spacing_mm": 36.0, "polygon_mm": [
        [-150.0, -150.0], [150.0, -150.0], [150.0, 120.0], [-150.0, 120.0]]}}}
    for name, raw in (("all", SMALL), ("region", region)):  # the SMALL config, then with a marked region
        run_study(S.STUDY, C.PortPlaceConfig.model_validate(raw), config_name=name, store=store, jobs=1, quiet=True)
    runs = sorted(store.runs("port-place"), key=lambda r: r.rows, reverse=True)
    d = diff_runs(store, runs[0].key, runs[1].key)
    assert d["rows_joined"] == runs[1].rows and d["rows_only_b"] == 0 and d["rows_only_a"] > 0
    assert all(m["changed"] == 0 for m in d["metrics"].values()) and "cost" in d["metrics"]
    assert "design_id" not in d["metrics"] and "psm1_site" not in d["metrics"]
    a, b = (r.read_table(S.schema()).to_pandas() for r in runs)
    by_id = pd.merge(a, b, on="design_id", suffixes=("_a", "_b"))
    assert (by_id["psm1_x_mm_a"] != by_id["psm1_x_mm_b"]).any()  # the premise: ids name other layouts
    from test_export import pandas_diff, same_diff

    ka, ia = S.STUDY.design_identity(runs[0].manifest["config"])
    same_diff(d, pandas_diff(*(r.read_table(S.schema()) for r in runs), list(ka), list(ia), "cost", decimals=6,
                             least_feasible=True))
    # export of both runs stacked: says which columns match a layout across them, and matched on those the
    # region's every layout has the whole run's cost (#42 item 1, for export)
    import pyarrow as pa

    from surgopt.export import export_runs

    stacked = export_runs(store, [runs[0].key, runs[1].key])
    assert len(stacked.notes) == 1 and "design_id, psm1_site" in stacked.notes[0] and "psm1_x_mm" in stacked.notes[0]
    rows = pa.concat_tables(list(stacked.tables())).to_pandas()
    assert len(rows) == stacked.num_rows == runs[0].rows + runs[1].rows
    ports = [c for c in rows.columns if c.endswith(("_x_mm", "_y_mm", "_z_mm")) and c.split("_")[0] in ("psm1", "psm2", "ecm")]
    whole, part = (rows[rows.run_key == r.key].round({c: 6 for c in ports}) for r in runs)
    matched = part.merge(whole, on=ports, suffixes=("_r", "_w"))
    assert len(matched) == len(part) and (matched.cost_r == matched.cost_w).all()


def test_a_clinical_check_outside_its_band_is_marked():
    """#42 item 11: the closing report's clinical checks mark a value outside the literature's band (any of
    two values: the manipulation angle's range over the target), and leave checks without a band unmarked."""
    assert R.within_band([62.3], (45.0, 75.0)) == "yes"
    assert R.within_band([49.1, 82.4], (45.0, 75.0)) == "OUTSIDE"
    assert R.within_band([82.0], (80.0, math.inf)) == "yes" and R.within_band([1.0], None) == ""
    bands = {label: band for label, *_, band in R.clinical_checks()}
    assert bands["manipulation angle over the target (deg)"] == (45.0, 75.0)
    assert bands["port spacing (mm)"] == (80.0, math.inf)


def test_the_clinical_checks_hold_a_layout_to_the_runs_own_constraints():
    """#53: a run with min_port_spacing_mm = 60, port_to_target_mm = [60, 150] and manipulation_angle_deg =
    [40, 80] is checked against those numbers (it was against 80, 180 and 45-75 whatever the run), each said
    beside the literature's; a horizontal port-to-target constraint is not the 3-D column's band."""
    cfg = C.PortPlaceConfig.model_validate({"constraints": {"min_port_spacing_mm": 60.0, "port_to_target_mm": [60.0, 150.0],
                                                            "manipulation_angle_deg": [40.0, 80.0]}})
    checks = {label: (clinical, band) for label, _, _, _, clinical, band in R.clinical_checks(cfg)}
    assert checks["port spacing (mm)"][1] == (60.0, math.inf) and checks["port spacing (mm)"][0].startswith(">= 60 ")
    assert checks["instrument port to target centre, 3-D (mm)"][1] == (60.0, 150.0)
    assert checks["manipulation angle at the centre (deg)"][1] == (40.0, 80.0)
    assert "Hanna 1997" in checks["manipulation angle at the centre (deg)"][0]
    assert R.within_band([70.0], checks["port spacing (mm)"][1]) == "yes"  # 70 mm: OUTSIDE against the old 80
    flat = C.PortPlaceConfig.model_validate({"constraints": {"port_to_target_measure": "horizontal"}})
    assert {label: band for label, *_, band in R.clinical_checks(flat)}[
        "instrument port to target centre, 3-D (mm)"] is None


def test_the_embedded_default_docks_on_the_classic_cart_and_other_arms_say_why_not():
    """The embedded default's ``cart.model = "auto"`` is the Classic cart for the Classic PSMs and ECM (the same run,
    the same key, as cart.model = "classic"), and "none" with a note for arms it cannot carry (the Si PSM, a
    serial arm), which the closing report's headline says (``no_cart_note``, in the rows' metadata); "classic" given
    with such an arm is refused naming the field."""
    from surgopt.compose import variants
    from surgopt.config import ConfigError, study_key
    from surgopt.studies import get_study
    from surgopt.studies.port_place.study import no_cart_note

    study = get_study("port-place")
    (default,) = variants(study, None, [])
    (given,) = variants(study, None, ["cart.model=classic"])
    assert default.config.cart.model == "classic"
    assert study_key(study.name, default.config, "k") == study_key(study.name, given.config, "k")
    (si,) = variants(study, None, ["robot.instrument_arm=dvrk_psm_si"])
    assert si.config.cart.model == "none"
    note = no_cart_note(si.config)
    assert S.schema(si.config).metadata[b"cart"].decode() == note
    assert note.startswith("none: docking assumed") and "not dvrk_psm_si" in note
    (plain,) = variants(study, None, ["cart.model=none"])
    assert no_cart_note(plain.config.model_dump(mode="json")) == "none: docking assumed (cart.model = none)"
    with pytest.raises(ConfigError, match="cart.model: 'classic' carries the Classic PSMs and ECM, not dvrk_ecm_si"):
        variants(study, None, ["cart.model=classic", "robot.camera_arm=dvrk_ecm_si"])


def test_the_best_layouts_are_screened_for_their_links_clearance(monkeypatch):
    """The closing report checks the best layouts' links outside the body in cost order until one clears docked as
    its row is, at most SCREEN_LAYOUTS: the first whose least clearance is >= 0 is named in the headline; one that
    clears only with its PSMs rolled is advice beside it (``chosen``, ``cheaper_if_rolled_words``), never the
    answer (#54 item 2); when none clears it says so with the least overlap among them; each row's least is the
    least of that layout's clearances."""
    import json

    from surgopt.studies.port_place import clashes

    rows = [{"design_id": i, "cost": 0.3 + i / 100, "feasible": True} for i in range(R.SCREEN_LAYOUTS + 3)]
    least_mm = {0: -100.0, 1: -20.0, 2: 5.0, 3: 40.0}
    seen = []

    def fake(cfg, row):
        seen.append(row["design_id"])
        v = least_mm.get(row["design_id"], -50.0)
        return [clashes.Clearance("PSM1 and PSM2, docked", v, "a", "b", "docked"),
                clashes.Clearance("PSM1 and the bedside", v + 10, "c", "table", "docked")]

    rolled = {}  # design -> (rolls, least clearance) that the roll search finds

    def fake_rolls(cfg, row):
        if row["design_id"] in rolled:
            rolls, mm = rolled[row["design_id"]]
            return clashes.RollsThatClear(rolls, clashes.Clearance("PSM2 and ECM", mm, "p", "q", "x"), 9,
                                          dexterity=0.5, cost=row["cost"] + 0.01)
        return clashes.RollsThatClear({}, None, 9)

    monkeypatch.setattr(clashes, "memoised", lambda what, cfg, row, compute: compute())  # no fake kept
    monkeypatch.setattr(clashes, "layout_clearances", fake)
    monkeypatch.setattr(clashes, "rolls_that_clear", fake_rolls)
    monkeypatch.setattr(R, "_below_table", lambda cfg, row, rolls: "")  # these rows have no cart pose to dock at
    meta = {"config": json.dumps(C.PortPlaceConfig.model_validate(SMALL).model_dump(mode="json"))}
    word, (title, header, table), chosen = R.clearance_screen(rows, meta)
    assert seen == [0, 1, 2] and len(table) == 3 and chosen is None  # screened by cost until one clears
    assert word.startswith("design 2 (") and [r[2] for r in table] == ["-100", "-20", "5"]
    assert table[0][-1] == "none of 9 that reach and dock" and table[2][-1] == "-"  # tried only where it overlaps
    least_mm.update({2: -5.0, 3: -8.0, 4: 30.0})
    rolled[3] = ({"PSM1": 0.0, "PSM2": -60.0}, 12.0)
    word, (_, _, table), chosen = R.clearance_screen(rows, meta)
    assert word.startswith("design 4 (the best feasible layout whose links clear")  # the answer's check goes on
    assert chosen[0]["design_id"] == 3 and chosen[1].rolls == {"PSM1": 0.0, "PSM2": -60.0}  # the advice
    assert table[3][-1].startswith("PSM1 +0, PSM2 -60: 12 mm") and table[3][-1].endswith("cost 0.34")
    advice = R.cheaper_if_rolled_words(*chosen)
    assert advice.startswith("design 3 (cost 0.3400 so docked) is not a feasible row") and "PSM2 -60 deg" in advice
    assert "by 12 mm" in advice and "Not the answer" in advice and title.startswith("the best feasible layouts")
    del least_mm[4]
    word, _, chosen = R.clearance_screen(rows, meta)
    assert word.startswith(f"none of the {R.SCREEN_LAYOUTS} best feasible layouts, docked as its row is")
    assert word.endswith("design 3 clears with its PSMs' docking rolled (cheaper_if_rolled)") and chosen is not None
    rows[3]["feasible"] = False  # with the links in feasible: a cheaper layout failing only on them, screened first
    seen.clear()
    least_mm[4] = 30.0
    word, (title, _, _), chosen = R.clearance_screen(rows, meta)
    assert seen[0] == 3 and chosen[0]["design_id"] == 3 and word.startswith("design 4 (")
    assert title.startswith("the best layouts (the feasible ones and, as the links are in feasible")
    rows[3]["feasible"] = True
    rolled.clear()
    del least_mm[4]
    seen.clear()
    word, (_, _, table), _ = R.clearance_screen(rows, meta)
    assert word.startswith(f"none of the {R.SCREEN_LAYOUTS} best") and "by 5 mm or more" in word
    assert seen == list(range(R.SCREEN_LAYOUTS)) and len(table) == R.SCREEN_LAYOUTS  # at most SCREEN_LAYOUTS


def test_a_layout_whose_links_overlap_clears_with_a_psm_rolled_about_its_shaft(tmp_path):
    """``clashes.rolls_that_clear`` on the small grid-cart run: a best layout whose links overlap at roll 0 (the
    premise) clears with its PSMs rolled, and what it returns holds by things apart from the search: each rolled
    PSM's base keeps the neutral shaft (z) with x turned by the roll from the docking frame written from its
    definition, its setup joints through the reference FK land that base, every target point is reached within
    the joint limits (closed-form inverse, then the forward map back to the point), and every clearance of the
    layout so docked is >= 0."""
    from surgopt.kinematics.port import place as K
    from surgopt.runner import run_study
    from surgopt.store import Store
    from surgopt.studies.port_place.clashes import layout_clearances, least, rolled_docks, rolls_that_clear

    store = Store(tmp_path / "s")
    cfg = C.PortPlaceConfig.model_validate(GRID)
    run_study(S.STUDY, cfg, config_name="grid", store=store, jobs=1, quiet=True)
    (run,) = store.runs("port-place")
    rows = R.least_cost_layouts(run.parts(S.STUDY.schema_for(run.manifest["config"])), 10).to_pylist()
    found = [(r, rolls_that_clear(M.model_of(cfg), r)) for r in rows]
    row, got = next((r, g) for r, g in found if g.least is not None)
    assert least(layout_clearances(M.model_of(cfg), row)).clearance_mm < 0  # the premise: it overlaps at the run's roll
    assert got.least.clearance_mm >= 0 and any(d != 0 for d in got.rolls.values())
    patient = T.patient_in_cart(cfg.cart, row["cart_x_mm"], row["cart_y_mm"], row["cart_heading_deg"])
    centre = np.asarray(cfg.target.centre_mm, float) / 1000
    model = M.model_of(cfg)
    arms = []
    for name, deg in got.rolls.items():
        arm = dict(rolled_docks(M.model_of(cfg), row, name.lower(), patient))[deg]
        port = np.array([row[f"{name.lower()}_{c}_mm"] for c in "xyz"]) / 1000
        want = _rolled(_docking_frame(port, centre), deg)
        np.testing.assert_allclose(arm.base[:3, :3], patient[:3, :3] @ want, atol=1e-12)
        np.testing.assert_allclose(suj_forward_reference("classic", name, arm.joints), arm.base, atol=1e-9)
        lim = model.limits
        world = model.targets_m @ patient[:3, :3].T + patient[:3, 3]
        for p in (world - arm.base[:3, 3]) @ arm.base[:3, :3]:
            q = K.rcm_inverse(p, lim.along_shaft_m)
            assert lim.yaw_lo <= q[0] <= lim.yaw_hi and lim.pitch_lo <= q[1] <= lim.pitch_hi
            assert lim.insertion_lo <= q[2] <= lim.insertion_hi
            np.testing.assert_allclose(K.rcm_point(*q, lim.along_shaft_m), p, atol=1e-12)
        arms.append(arm)
    # its cost so docked: the dexterity at those rolls written out (P5), the other terms the row's
    iso = [_isotropy_reference(_rolled(_docking_frame(np.array([row[f"{n.lower()}_{c}_mm"] for c in "xyz"]) / 1000,
                                                      centre), deg),
                               np.array([row[f"{n.lower()}_{c}_mm"] for c in "xyz"]) / 1000, model.targets_m,
                               cfg.constraints.dexterity_length_m) for n, deg in got.rolls.items()]
    assert got.dexterity == pytest.approx(np.minimum(*iso).mean(), abs=1e-12)
    assert got.cost == pytest.approx(row["cost"] + row["dexterity_mean"] - got.dexterity, abs=1e-12)
    ecm = [a for a in T.docked_arms(M.model_of(cfg), row) if a.arm == "ECM"]
    again = layout_clearances(M.model_of(cfg), row, arms + ecm)
    assert min(c.clearance_mm for c in again) == got.least.clearance_mm >= 0
    assert list(got.clearances) == again  # kept with the rolls: what the report's and the export's tables show
    assert rolls_that_clear(M.model_of(cfg), row) is got  # kept for the process: the report, the figure, the export share it
    # an arm whose mount (the SUJ's tip) lies below the table top is named with its depth: the tip from the
    # reference FK of the tool origin and the cart data's tip-to-tool transform
    from surgopt.robots.dvrk.platforms import PLATFORMS
    from surgopt.studies.port_place.clashes import mounts_below_table_top

    low = mounts_below_table_top(cfg, row, arms + ecm)
    assert not [a for a in low if a.startswith("PSM")]  # #54: a roll parking a PSM's mount there is refused
    for name, _ in got.rolls.items():  # every roll it tried docked its mount above the table top
        for deg, arm in rolled_docks(M.model_of(cfg), row, name.lower(), patient):
            tip = suj_forward_reference("classic", arm.arm, arm.joints) @ np.linalg.inv(
                PLATFORMS["classic"].suj(arm.arm).tip_to_tool)
            assert float((tip[:3, 3] - patient[:3, 3]) @ patient[:3, 2]) >= 0.0
    allow = C.PortPlaceConfig.model_validate({**GRID, "cart": {**GRID["cart"], "mount_below_table_top": "allow"}})
    more = {n: {d for d, _ in rolled_docks(M.model_of(allow), row, n.lower(), patient)} for n in got.rolls}
    fewer = {n: {d for d, _ in rolled_docks(M.model_of(cfg), row, n.lower(), patient)} for n in got.rolls}
    assert all(fewer[n] <= more[n] for n in got.rolls) and any(fewer[n] < more[n] for n in got.rolls)  # the premise
    for arm in arms + ecm:
        tip = suj_forward_reference("classic", arm.arm, arm.joints) @ np.linalg.inv(PLATFORMS["classic"].suj(arm.arm).tip_to_tool)
        height_mm = float((tip[:3, 3] - patient[:3, 3]) @ patient[:3, 2]) * 1000
        assert (arm.arm in low) == (height_mm < 0) and low.get(arm.arm, -height_mm) == pytest.approx(-height_mm, abs=1e-6)
    # the robot's file docks it so: each PSM's roll, its SUJ joints landing the rolled frame, its links clear
    setup = json.loads(S.dvrk_export(cfg, row))
    assert "turned about its neutral shaft" in setup["docking"] and setup["clearances_outside_body"]["least_mm"] >= 0
    assert [c["clearance_mm"] for c in setup["clearances_outside_body"]["checks"]] == [
        round(c.clearance_mm, 1) for c in again]
    for arm in setup["arms"][:-1]:
        assert arm["docking_roll_deg"] == got.rolls[arm["name"]]
        port = np.array(arm["port_mm"]) / 1000
        want = patient @ np.vstack([np.column_stack([_rolled(_docking_frame(port, centre), arm["docking_roll_deg"]),
                                                     port]), [0, 0, 0, 1]])
        np.testing.assert_allclose(suj_forward_reference("classic", arm["name"], arm["suj_joints"]), want, atol=1e-9)


def _isotropy_reference(frame, port, points, length_m):
    """Each point's isotropy (eq. P5) for an RCM arm docked at ``port`` in ``frame``, written out: the point in
    the base frame, rho and the pitch q2 = -asin(y / rho), then sigma_min / sigma_max of (rho cos q2 / L, rho / L,
    1)."""
    local = (points - port) @ frame
    rho = np.linalg.norm(local, axis=1)
    q2 = -np.arcsin(local[:, 1] / rho)
    norms = np.stack([rho * np.cos(q2) / length_m, rho / length_m, np.ones(len(rho))])
    return norms.min(axis=0) / norms.max(axis=0)


def test_a_rolled_layouts_cost_takes_the_dexterity_at_its_rolls():
    """``clashes.rolled_cost``: at the neutral roll it is the row's own dexterity_mean and cost (the design
    kernel's pair tables, 1e-12); at other rolls the pair's dexterity is the mean of the smaller isotropy written
    out here from the rolled docking frame (P3 turned, P5), and the cost the row's with that term replaced. With
    L = 0.2 m (longer than the ports' distances, so that the pitch matters) the premise holds: the dexterity
    changes with the roll (with the default 0.1 m it mostly does not: where rho cos q2 >= L the isotropy is
    L / rho, whatever the roll)."""
    from surgopt.studies.port_place.clashes import ROLL_GRID_DEG, rolled_cost, rolled_reach

    cfg = C.PortPlaceConfig.model_validate({**SMALL, "constraints": {"dexterity_length_m": 0.2}})
    cols = S.compute_task(cfg, S.n_total(cfg), 0)
    r = int(np.flatnonzero(cols["feasible"])[0])
    row = {c: v[r].item() for c, v in cols.items()}
    centre = np.asarray(cfg.target.centre_mm, float) / 1000
    points = M.model_of(cfg).targets_m
    iso = {a: rolled_reach(M.model_of(cfg), row, a)[2] for a in ("psm1", "psm2")}
    zero = ROLL_GRID_DEG.index(0)
    dexterity, cost = rolled_cost(cfg, row, {a: iso[a][zero] for a in iso})
    assert dexterity == pytest.approx(row["dexterity_mean"], abs=1e-12) and cost == pytest.approx(row["cost"], abs=1e-12)
    a, b = ROLL_GRID_DEG.index(45), ROLL_GRID_DEG.index(-30)
    want = []
    for arm, k in (("psm1", a), ("psm2", b)):
        port = np.array([row[f"{arm}_{c}_mm"] for c in "xyz"]) / 1000
        want.append(_isotropy_reference(_rolled(_docking_frame(port, centre), ROLL_GRID_DEG[k]), port, points, 0.2))
        np.testing.assert_allclose(iso[arm][k], want[-1], atol=1e-12)  # every point reached: full reach kept
    dexterity, cost = rolled_cost(cfg, row, {"psm1": iso["psm1"][a], "psm2": iso["psm2"][b]})
    assert dexterity == pytest.approx(np.minimum(*want).mean(), abs=1e-12)
    assert abs(dexterity - row["dexterity_mean"]) > 1e-4  # the premise: the roll moves the dexterity here (far
    # beyond the 1e-12 the values above are held to)
    assert cost == pytest.approx(row["cost"] + cfg.objective.dexterity * (row["dexterity_mean"] - dexterity), abs=1e-12)


def test_a_search_docks_on_the_cart_as_the_grid_does(tmp_path):
    """#40 "the cart searched": a [search] with the cart evaluates each design with the cart's dock tables of its
    own ports: a design evaluated alone equals its row of the grid's enumeration in every column, the cart's
    included (every 97th design of the small grid-cart config; some dockable, some not: the premise); a CMA-ES
    search runs, each feasible trial docked (a cart pose, in the cart's columns); a search that also tilts the
    docking is refused naming the field."""
    from surgopt.config import validate
    from surgopt.errors import ConfigError
    from surgopt.runner import run_study
    from surgopt.store import Store

    cfg = validate(GRID, C.Config, "x")
    grid = S.compute_task(cfg, 10 ** 6, 0)
    pick = np.arange(0, len(grid["design_id"]), 97)
    assert 0 < int(np.sum(grid["cart_pose"][pick] >= 0)) < len(pick) and int(np.sum(grid["feasible"][pick])) > 0
    x = np.column_stack([grid[f"{a}_site"][pick] for a in S.arms_of(cfg)]).astype(float)
    alone = S.evaluate_designs(cfg, x, grid["design_id"][pick], "t")
    assert set(alone) == set(grid)
    for c, v in grid.items():
        np.testing.assert_allclose(np.asarray(alone[c], float), np.asarray(v, float)[pick], rtol=0, atol=1e-9,
                                   err_msg=c)
    # seed 2: a run whose 64 trials find feasible layouts (the premise, asserted below; with the scope held at the
    # ECM's least insertion, #54, seeds 0 and 1 find none in 64)
    searched = validate({**GRID, "search": {"method": "cmaes", "trials": 64, "batch": 32, "seed": 2}}, C.Config, "x")
    rows = run_study(S.STUDY, searched, config_name="s", store=Store(tmp_path / "s"), jobs=1, quiet=True).table
    feasible = rows.filter(rows["feasible"]).to_pydict()
    assert len(rows) == 64 and feasible["cart_pose"] and all(p >= 0 for p in feasible["cart_pose"])
    assert not np.isnan(np.asarray(feasible["cart_x_mm"], float)).any()
    with pytest.raises(ConfigError, match="robot.docking_range_deg"):
        validate({**GRID, "robot": {"docking_range_deg": 10.0}, "search": {"method": "cmaes", "trials": 8}},
                 C.Config, "x")


def test_the_closing_report_searches_each_layouts_rolls_once(tmp_path, monkeypatch):
    """The closing report's screen and its "best layout" tables ask for the same layout's clearances and rolls:
    each is computed once in a process (``clashes._memoised``), the premise (the best layout's links overlap at
    the run's roll, so its rolls are searched) asserted; and the tables show the rolled docking's clearances."""
    from surgopt.runner import run_study
    from surgopt.store import Store
    from surgopt.studies.port_place import clashes

    store = Store(tmp_path / "s")
    cfg = C.PortPlaceConfig.model_validate(GRID)
    run_study(S.STUDY, cfg, config_name="grid", store=store, jobs=1, quiet=True)
    (run,) = store.runs("port-place")
    calls = {"rolls": [], "clearances": []}
    search = clashes._rolls_that_clear

    def counted_search(cfg, row):
        calls["rolls"].append(row["design_id"])
        return search(cfg, row)

    monkeypatch.setattr(clashes, "_rolls_that_clear", counted_search)
    monkeypatch.setattr(clashes, "_memo", {})
    summary = R.summary(run.parts(S.STUDY.schema_for(run.manifest["config"])))
    best = summary.headline["best_design_id"]
    assert best in calls["rolls"]  # the premise: the best layout overlaps at the run's roll
    assert len(calls["rolls"]) == len(set(calls["rolls"]))  # each layout's rolls searched once
    (clear,) = [t for t in summary.tables if t[0].startswith("best layout: least clearance")]
    row = next(r for r in R.least_cost_layouts(run.parts(S.STUDY.schema_for(run.manifest["config"])), 1).to_pylist())
    rolled = clashes.rolls_that_clear(M.model_of(cfg), row)  # kept: not searched again
    shown = rolled.clearances or clashes.layout_clearances(M.model_of(cfg), row)  # docked to clear where a roll clears it
    sampled = [r for r in clear[2] if "over the whole target" not in r[0]]  # (and a row a pair over every point)
    assert [r[1] for r in sampled] == [f"{c.clearance_mm:.0f}" for c in shown]
    assert calls["rolls"].count(best) == 1
    # issue 40's "done means": the closing report names what the model leaves out
    assert all(w in summary.headline["not_modelled"] for w in ("Xi", "tissue", "assistant's port", "rails"))


def test_a_searched_cart_pose_docks_each_design_at_its_own_pose(tmp_path):
    """#40 "the cart ... searched": with ``cart.pose = "search"`` the cart's pose is three dimensions of the
    [search] (around the target, distance, heading off facing it) and each design docks at its own: a design
    evaluated at (around, distance, offset) equals, in every column, its row of the grid enumerated with the cart
    given at that floor pose (``tables.floor_pose``: the grid's own formula; three poses, some designs dockable
    there and some not: the premise); a pose within ``clear_of_table_mm`` of the table docks nothing; a CMA-ES
    search keeps each trial's pose, its feasible trials docked there (cart_x/y/heading from the pose), and the best
    one's dvrk export lands PSM1's RCM on its port by the reference forward kinematics; ``pose = "search"``
    without a [search] is refused naming the field."""
    from surgopt.config import validate
    from surgopt.errors import ConfigError
    from surgopt.runner import run_study
    from surgopt.store import Store

    searched = {**GRID, "cart": {**GRID["cart"], "pose": "search"}}
    cfg = validate({**searched, "search": {"method": "cmaes", "trials": 48, "batch": 16, "seed": 1}}, C.Config, "x")
    names = list(S.design_dims(cfg))
    assert names[-3:] == ["cart_around_deg", "cart_distance_mm", "cart_yaw_offset_deg"]
    for around, distance, offset in ((-60.0, 900.0, 20.0), (60.0, 1200.0, -20.0), (0.0, 1500.0, 0.0)):
        x_mm, y_mm, heading = T.floor_pose(cfg, around, distance, offset)
        assert T.off_table(cfg.cart, np.array([[x_mm, y_mm, heading]]))[0]  # the cart can stand there
        given = validate({**SMALL, **NO_LINKS, "cart": {"model": "classic", "pose": "given", "x_mm": x_mm, "y_mm": y_mm,
                                            "heading_deg": heading}}, C.Config, "x")
        grid = S.compute_task(given, 10 ** 6, 0)
        pick = np.arange(0, len(grid["design_id"]), 211)
        assert 0 < int(np.sum(grid["cart_pose"][pick] >= 0)) < len(pick)  # the premise: some dock, some do not
        x = np.column_stack([grid[f"{a}_site"][pick] for a in S.arms_of(cfg)]
                            + [np.full(len(pick), v) for v in (around, distance, offset)]).astype(float)
        alone = S.evaluate_designs(cfg, x, grid["design_id"][pick], "t")
        for c, v in grid.items():
            np.testing.assert_allclose(np.asarray(alone[c], float), np.asarray(v, float)[pick], rtol=0, atol=1e-9,
                                       err_msg=f"{c} at {around, distance, offset}")
        assert np.all(alone["cart_around_deg"] == around) and np.all(alone["cart_distance_mm"] == distance)
    near = T.floor_pose(cfg, 0.0, 400.0, 0.0)  # the foot of the table: not clear of it
    assert not T.off_table(cfg.cart, np.array([near]))[0]
    x = np.array([[float(grid["psm1_site"][pick[0]]), float(grid["psm2_site"][pick[0]]),
                   float(grid["ecm_site"][pick[0]]), 0.0, 400.0, 0.0]])
    assert S.evaluate_designs(cfg, x, np.array([0]), "t")["cart_pose"][0] == -1
    narrow = validate({**searched, "cart": {**searched["cart"], "around_deg": [-90.0, -45.0],
                                            "distance_mm": [850.0, 950.0]},
                       "search": {"method": "cmaes", "trials": 64, "batch": 16, "seed": 2}}, C.Config, "x")
    # seed 2: its 64 trials find a feasible layout (the premise below); with the scope at the ECM's least insertion
    # and no mount below the table top (#54) feasible layouts on this narrow arc are rare (seeds 0, 1, 3-7: none)
    rows = run_study(S.STUDY, narrow, config_name="s", store=Store(tmp_path / "s"), jobs=1, quiet=True).table
    assert len(rows) == 64 and len({round(a, 6) for a in rows["cart_around_deg"].to_pylist()}) > 10
    assert -90 <= min(rows["cart_around_deg"].to_pylist()) <= max(rows["cart_around_deg"].to_pylist()) <= -45
    feasible = rows.filter(rows["feasible"]).to_pylist()
    assert feasible  # the premise
    for r in feasible:
        assert r["cart_pose"] == 0
        np.testing.assert_allclose([r["cart_x_mm"], r["cart_y_mm"], r["cart_heading_deg"]],
                                   T.floor_pose(narrow, r["cart_around_deg"], r["cart_distance_mm"],
                                                r["cart_yaw_offset_deg"]), atol=1e-9)
    best = min(feasible, key=lambda r: r["cost"])
    setup = json.loads(S.dvrk_export(narrow, best))
    patient = np.array(setup["cart_to_patient"])
    psm1 = setup["arms"][0]
    port = np.array(psm1["port_mm"]) / 1000
    np.testing.assert_allclose(suj_forward_reference("classic", "PSM1", psm1["suj_joints"])[:3, 3],
                               patient[:3, :3] @ port + patient[:3, 3], atol=1e-9)
    with pytest.raises(ConfigError, match="cart.pose"):
        validate(searched, C.Config, "x")


def test_the_report_says_why_the_best_layouts_without_the_cart_do_not_dock(tmp_path):
    """#40 "how many of the previous best layouts are not dockable, and why": of the 1,000 layouts of least cost
    that are feasible without the cart (pandas over the run's rows), the count the cart cannot dock; and each
    reason held, for sample layouts, by the setup joints solved pose by pose in plain Python apart from the
    tables (S2 for the PSMs, the numpy S4 grid for the ECM): a pair's PSMs that take its ports at no pose either
    way round, or arms each docking somewhere but never all at one pose (the premise: some layouts of a reason)."""
    from surgopt.kinematics.port.reasons import DOCKING
    from surgopt.robots.dvrk.platforms import PLATFORMS
    from surgopt.runner import run_study
    from surgopt.store import Store

    cfg = C.PortPlaceConfig.model_validate(GRID)
    run_study(S.STUDY, cfg, config_name="g", store=Store(tmp_path / "s"), jobs=1, quiet=True)
    (run,) = Store(tmp_path / "s").runs("port-place")
    parts = run.parts(S.STUDY.schema_for(run.manifest["config"]))
    meta = {k.decode(): v.decode() for k, v in parts.schema.metadata.items()}
    ((title, _, rows),) = R.undocked_table(parts, meta)
    df = parts.table().to_pandas()
    best = df[df["infeasible"].isin([0, DOCKING])].sort_values(["cost", "design_id"]).head(R.UNDOCKED_OF_BEST)
    undocked = best[best["infeasible"] == DOCKING]
    assert f": {len(undocked):,} the Classic cart" in title and len(undocked) > 0
    assert sum(int(r[1].replace(",", "")) for r in rows) == len(undocked)
    model = M.model_of(cfg)
    why = R.why_undocked(model.dock, undocked[["psm1_site", "psm2_site", "ecm_site"]].to_numpy())
    assert {1, 3} <= set(why.tolist())  # the premise: both kinds occur here
    poses = model.dock.poses.patient
    centre = np.asarray(cfg.target.centre_mm, float) / 1000
    arm = T.camera_arm_of(cfg)

    def psm_docks(name, site):
        return [bool(REF.classic_psm_ik(PLATFORMS["classic"].suj(name), p @ T.base_pose(model.instrument_rot[site],
                                                                                 model.sites_m[site])).within)
                for p in poses]

    def ecm_docks(site):
        shaft = (centre - model.sites_m[site]) / np.linalg.norm(centre - model.sites_m[site])
        origins = np.array([p[:3, :3] @ model.sites_m[site] + p[:3, 3] for p in poses])
        aims = np.array([p[:3, :3] @ shaft for p in poses])
        return list(REF.ecm_classic_dock(PLATFORMS["classic"].suj("ECM"), arm.yaw_limits_rad, arm.pitch_limits_rad,
                                         origins, aims)[0] >= 0)

    for kind in (1, 3):
        for a, b, k in undocked[["psm1_site", "psm2_site", "ecm_site"]].to_numpy()[why == kind][:2]:
            p1a, p2b, p1b, p2a = psm_docks("PSM1", a), psm_docks("PSM2", b), psm_docks("PSM1", b), psm_docks("PSM2", a)
            if kind == 1:  # no way round has both PSMs docking anywhere
                assert not (any(p1a) and any(p2b)) and not (any(p1b) and any(p2a))
            else:  # each docks somewhere; at no pose do all
                e = ecm_docks(k)
                assert any(e) and ((any(p1a) and any(p2b)) or (any(p1b) and any(p2a)))
                assert not any(e[p] and ((p1a[p] and p2b[p]) or (p1b[p] and p2a[p])) for p in range(len(poses)))


def test_the_rows_give_each_arms_setup_joint_margins_at_its_pose():
    """The rows' per-arm setup joints and their margins (revolute in deg, the column in mm, at the row's cart pose) against
    the setup joints solved again for that row by the plain S2 and the S4 grid for its one port (``docked_arms``), their
    margins computed here from the quoted and assumed ranges; the rows' joints through the reference forward
    kinematics land each arm's base where that solution does; undocked rows NaN. Premises: docked rows of both
    ways round (PSM1 on the pair's first port and on its second) are among those checked."""
    from surgopt.robots.dvrk.platforms import PLATFORMS

    cfg = C.PortPlaceConfig.model_validate(GRID)
    cols = S.compute_task(cfg, S.n_total(cfg), 0)
    docked = np.flatnonzero(cols["cart_pose"] >= 0)
    assert np.isnan(cols["psm1_suj_margin_deg"][cols["cart_pose"] < 0]).all()
    swapped = cols["psm1_site"][docked] > cols["psm2_site"][docked]
    pick = np.concatenate([docked[swapped][:4], docked[~swapped][:4]])
    assert swapped.any() and (~swapped).any()
    for r in pick:
        row = {c: v[r].item() for c, v in cols.items()}
        for arm in T.docked_arms(M.model_of(cfg), row):
            ranges = np.asarray(PLATFORMS["classic"].suj(arm.arm).ranges, float)
            q = np.asarray(arm.joints)
            margin = np.minimum(q - ranges[:, 0], ranges[:, 1] - q)
            name = arm.arm.lower()
            assert row[f"{name}_suj_margin_deg"] == pytest.approx(math.degrees(margin[1:].min()), abs=1e-6)
            assert row[f"{name}_suj_column_margin_mm"] == pytest.approx(margin[0] * 1000, abs=1e-6)
            # the row's joints (mm, deg) are that solution's, and carry the arm's base (its RCM) onto the port
            names = ("column_mm", "j1_deg", "j2_deg", "j3_deg", "j4_deg", "j5_deg")
            got = np.array([row[f"{name}_suj_{c}"] for c in names])
            np.testing.assert_allclose(got, np.concatenate([[q[0] * 1000], np.degrees(q[1:])]), atol=1e-6)
            q_row = np.concatenate([[got[0] / 1000], np.radians(got[1:])])
            np.testing.assert_allclose(suj_forward_reference("classic", arm.arm, q_row)[:3, 3], arm.base[:3, 3],
                                       atol=1e-6)
    undocked = cols["cart_pose"] < 0
    assert undocked.any() and all(np.isnan(cols[f"{a}_suj_j1_deg"][undocked]).all() for a in ("psm1", "psm2", "ecm"))


def test_a_psm_whose_mount_would_stand_below_the_table_top_does_not_dock():
    """#54, the bedside: the height of each PSM's mount (its setup joints' last frame) over the table top, written
    out here from the solved setup joints by the reference forward kinematics (world -> SUJ, the DH products; the
    mount is the base times the tip -> tool inverse) at every docked (site, pose) of a small grid with
    ``mount_below_table_top = 'allow'``, equals ``tables.mount_heights_m`` of the site's docking frame (1e-9 m,
    whatever the pose); some stand below (the premise), and with the default 'refuse' exactly those do not dock."""
    from reference import SUJ_TIP_ROTATION

    allow = C.PortPlaceConfig.model_validate({**GRID, "cart": {**GRID["cart"], "mount_below_table_top": "allow"}})
    model = M.prepare(allow)
    dock = model.dock
    below = np.zeros(dock.margin.shape, bool)
    for a, arm in enumerate(("PSM1", "PSM2")):
        z = T.mount_heights_m(allow, arm, model.instrument_rot, model.sites_m)
        tool = np.eye(4)
        tool[:3, :3], tool[:3, 3] = SUJ_TIP_ROTATION, (0.4864, 0.0, 0.1524)  # dvrk-kinematics.md, every PSM
        docked = np.argwhere(dock.margin[a] >= 0)
        for i, p in docked[:: max(1, len(docked) // 60)]:
            mount = suj_forward_reference("classic", arm, dock.joints[a, i, p]) @ np.linalg.inv(tool)
            in_patient = np.linalg.inv(dock.poses.patient[p]) @ mount
            assert in_patient[2, 3] == pytest.approx(z[i], abs=1e-9)
        below[a] = (z < 0)[:, None] & (dock.margin[a] >= 0)
    assert below.any() and (~below & (dock.margin >= 0)).any()  # the premise: both kinds dock when allowed
    refused = M.prepare(C.PortPlaceConfig.model_validate(GRID)).dock
    np.testing.assert_array_equal(refused.margin >= 0, (dock.margin >= 0) & ~below)


def test_the_report_says_when_the_answers_cart_pose_lies_on_a_bound_of_the_grid():
    """#54 item 5: the grid's places (around, distance, heading offset) numbered as ``cart_poses`` numbers the
    poses (each place's floor pose written again from it); an answer on the nearest ring and an end of the arc is
    said so, with how many feasible layouts dock on each bound (counted here from a stub of the rows); one inside the
    grid says nothing, nor does a given pose."""
    import pyarrow as pa

    cfg = C.PortPlaceConfig.model_validate(GRID)
    places = T.grid_place_of_pose(cfg)
    floor = T.cart_poses(cfg).floor
    assert len(places) == len(floor)
    for place, pose in zip(places, floor):
        np.testing.assert_allclose(T.floor_pose(cfg, *place), pose, atol=1e-9)
    near = float(cfg.cart.distance_mm[0])
    corner = int(np.flatnonzero((places[:, 1] == near) & (places[:, 0] == places[:, 0].min())
                                & (places[:, 2] != places[:, 2].min()) & (places[:, 2] != places[:, 2].max()))[0])
    inner = np.flatnonzero((places[:, 1] > near) & (places[:, 1] < places[:, 1].max())
                           & (places[:, 0] > places[:, 0].min()) & (places[:, 0] < places[:, 0].max())
                           & (places[:, 2] != places[:, 2].min()) & (places[:, 2] != places[:, 2].max()))
    assert len(inner)  # the premise: the grid has an inside

    class Rows:
        num_rows = 5

        def only(self, columns):
            yield pa.table({"cart_pose": [corner, corner, int(inner[0]), -1, corner],
                            "feasible": [True, True, True, True, False]})

    words = R.cart_bound_words(Rows(), {"cart_pose": corner}, cfg)
    assert f"on the grid's nearest ring ({near:g}, cart.distance_mm; 2 of the 3 feasible layouts dock there)" in words
    assert "arc's end" in words and "widen them" in words
    assert R.cart_bound_words(Rows(), {"cart_pose": int(inner[0])}, cfg) == ""
    given = C.PortPlaceConfig.model_validate({**GRID, "cart": {**GRID["cart"], "pose": "given"}})
    assert R.cart_bound_words(Rows(), {"cart_pose": 0}, given) == ""


def test_a_grid_of_cart_poses_is_counted_by_arithmetic_and_bounded():
    """#55 item 6: ``config.grid_count`` equals the length of the array ``tables.grid_places`` builds (random spans
    and steps); a grid past ``MAX_CART_POSES`` is refused when the config is read, naming the step, before anything is
    built (a 1e-300 step counts as inf, not numpy's 'Maximum allowed size exceeded')."""
    from pydantic import ValidationError

    rng = np.random.default_rng(3)
    for _ in range(200):
        lo = float(rng.uniform(-180, 180))
        span, step = (lo, lo + float(rng.uniform(0, 300))), float(rng.uniform(0.5, 60))
        assert C.grid_count(span, step) == len(np.arange(span[0], span[1] + 1e-9, step))
    assert len(T.cart_poses(C.PortPlaceConfig.model_validate({"cart": {"model": "classic"}})).floor) <= C.MAX_CART_POSES
    for step, field in (({"around_step_deg": 0.01, "distance_step_mm": 1.0}, "around_step_deg"),
                        ({"around_step_deg": 1e-300}, "around_step_deg"), ({"distance_step_mm": 0.001}, "distance_step_mm")):
        with pytest.raises(ValidationError, match=f"{field}: .* cart poses .* more than the 10,000"):
            C.PortPlaceConfig.model_validate({"cart": {"model": "classic", **step}})


def test_a_targets_grid_is_counted_by_arithmetic_before_it_is_built():
    """#55 item 6, the target's part: ``geometry.shape_grid_count`` equals the bounding-box grid
    ``target_points_mm`` builds (random radii and spacings), and a grid far past MAX_TARGET_POINTS is refused from
    that count, before a point is built (before: radii of 300 mm at 0.5 mm built 1.7 G points to count them)."""
    import tracemalloc

    from pydantic import ValidationError

    from surgopt.studies.port_place import geometry as G

    rng = np.random.default_rng(5)
    for _ in range(50):
        t = C.Target(shape="box", radii_mm=list(rng.uniform(1, 40, 3)), spacing_mm=float(rng.uniform(1, 10)))
        assert G.shape_grid_count(t) == len(G.target_points_mm(t))
    tracemalloc.start()
    with pytest.raises(ValidationError, match=r"target: about 907,042,516 sample points \(at most 20,000"):
        C.PortPlaceConfig.model_validate({"target": {"radii_mm": [300, 300, 300], "spacing_mm": 0.5}})
    assert tracemalloc.get_traced_memory()[1] < 50 * 2 ** 20  # counted, not built (the grid is ~40 GB)
    tracemalloc.stop()


def test_the_setup_joint_table_gives_the_revolute_and_column_margins_apart():
    """#56 item 10: the closing report's setup-joint table had one "least range margin" column holding rad for
    some arms and m for others. Now the revolute joints' least margin (deg, which joint) and the column's (mm) are
    two columns, checked on joints placed at known distances from their ranges."""
    from types import SimpleNamespace

    from surgopt.robots.dvrk.platforms import PLATFORMS

    suj = PLATFORMS["classic"].suj("PSM2")
    (c_lo, _), *revolute = suj.ranges
    joints = [c_lo + 0.123] + [(lo + hi) / 2 for lo, hi in revolute]
    joints[2] = revolute[1][1] - np.radians(4.0)  # the second revolute joint 4 deg inside its upper end
    assert all(min(j - lo, hi - j) > np.radians(4.0) for k, (j, (lo, hi)) in enumerate(zip(joints[1:], revolute)) if k != 1)
    cfg = SimpleNamespace(cart=SimpleNamespace(model="classic"))
    arm = SimpleNamespace(arm="PSM2", joints=tuple(joints))
    assert R.suj_margin_words(cfg, arm) == (f"4.0 ({suj.links[2].name})", "123")
    assert R.suj_margin_words(cfg, SimpleNamespace(arm="ECM", joints=())) == ("-", "-")


def test_diff_of_runs_with_no_layout_in_common_says_so_and_compares_their_best_feasible_layouts(tmp_path):
    """#56 item 9: diff of two runs on different site grids printed 29 rows of zeros (no row joined) and named the
    best design by the penalised score. It says there is no layout in common and compares the feasible layouts
    of least cost (pandas over each run's rows)."""
    from surgopt.results import diff_runs
    from surgopt.runner import run_study
    from surgopt.store import Store

    from conftest import invoke

    store = Store(tmp_path / "s")
    keys = []
    for spacing in (72.0, 60.0):
        cfg = C.PortPlaceConfig.model_validate({"patient": {"port_region": {"site_spacing_mm": spacing}},
                                                "target": {"spacing_mm": 20.0}, "cart": {"model": "none"}})
        keys.append(run_study(S.STUDY, cfg, config_name=f"s{spacing:.0f}", store=store, jobs=1, quiet=True).run.key)
    d = diff_runs(store, keys[0], keys[1])
    assert d["rows_joined"] == 0 and d["metrics"] == {} and d["worst"] == [] and d["objective"] == "cost"
    for side, key in zip("ab", keys):
        df = store.open("port-place", key).read_table().to_pandas()
        want = df[df["feasible"]].sort_values("cost", kind="stable").iloc[0]
        assert d["best"][side]["design_id"] == want["design_id"] and d["best"][side]["cost"] == want["cost"]
    code, out = invoke("diff", keys[0][:12], keys[1][:12], "--store", tmp_path / "s")
    assert code == 0 and "no layout in common" in out and "rows changed" not in out
    assert "best design of each by cost (feasible, least first)" in " ".join(out.split())


def test_the_pages_reach_is_the_grids_without_building_the_grid():
    """#56 (report <= 10 s): the page colours the target by each port's reach and isotropy; it read them from
    ``model.grid``, whose pair, cart and link tables it never used (6.5 s of the default run's 13.6 s page).
    ``PortModel.site_reach`` gives the same arrays without building the grid (with the cart and its links)."""
    cfg = C.PortPlaceConfig.model_validate({**GRID, "constraints": {}})
    assert T.links_decide(cfg)  # the premise: the grid would build link tables
    fresh = M.model_of(cfg)
    for built in ("grid", "site_reach"):
        fresh.__dict__.pop(built, None)
    reach, dex = fresh.site_reach
    assert "grid" not in fresh.__dict__  # not built
    _, want_reach, want_dex = fresh.grid
    np.testing.assert_array_equal(reach, want_reach)
    np.testing.assert_array_equal(dex, want_dex)


def test_the_carts_base_stands_clear_of_the_table_by_its_own_footprint():
    """#54 (the cart's footprint): ``tables.footprint_gap_mm`` against brute force apart from it: both outlines
    sampled every 5 mm along their edges and inside, the least distance between the samples (within 5 mm of the
    exact gap, never below it by more than that), 0 where a sample of one lies inside the other; at random poses
    around the table, some overlapping, some apart (the premises). The Classic's footprint is its mesh's extent."""
    from surgopt.robots.dvrk.platforms import PLATFORMS

    cart = C.PortPlaceConfig.model_validate({"cart": {"model": "classic"}}).cart
    assert PLATFORMS["classic"].footprint_m == ((-0.456, -0.568), (0.456, 0.365))
    assert "base_link.stl" in PLATFORMS["classic"].footprint_source
    rng = np.random.default_rng(3)
    floor = np.column_stack([rng.uniform(-1300, 1300, 40), rng.uniform(-1400, 1400, 40), rng.uniform(-180, 180, 40)])
    gap = T.footprint_gap_mm(cart, floor)
    w, (y0, y1) = cart.table_half_width_mm, cart.table_y_mm

    def fill(lo, hi):  # a rectangle's samples: every 5 mm inside and on its edges
        xs, ys = np.arange(lo[0], hi[0] + 1e-9, 5.0), np.arange(lo[1], hi[1] + 1e-9, 5.0)
        return np.array(np.meshgrid(np.append(xs, hi[0]), np.append(ys, hi[1]))).reshape(2, -1).T

    table = fill((-w, y0), (w, y1))
    (fx0, fy0), (fx1, fy1) = (np.array(v) * 1000 for v in PLATFORMS["classic"].footprint_m)
    base = fill((fx0, fy0), (fx1, fy1))
    edges = [p for p in table if abs(abs(p[0]) - w) < 1e-9 or min(abs(p[1] - y0), abs(p[1] - y1)) < 1e-9]
    edges = np.array(edges)
    for (x, y, heading), g in zip(floor, gap):
        h = math.radians(heading)
        world = np.column_stack([x + math.cos(h) * base[:, 0] + math.sin(h) * base[:, 1],
                                 y - math.sin(h) * base[:, 0] + math.cos(h) * base[:, 1]])
        inside = (np.abs(world[:, 0]) <= w) & (world[:, 1] >= y0) & (world[:, 1] <= y1)
        if inside.any():
            assert g == 0.0
            continue
        rim = world[np.isin(np.arange(len(base)), np.flatnonzero(
            (np.abs(base[:, 0] - fx0) < 1e-9) | (np.abs(base[:, 0] - fx1) < 1e-9)
            | (np.abs(base[:, 1] - fy0) < 1e-9) | (np.abs(base[:, 1] - fy1) < 1e-9)))]
        brute = np.sqrt(((rim[:, None, :] - edges[None, :, :]) ** 2).sum(axis=2)).min()
        assert g <= brute + 1e-6 and brute - g < 5.0
    assert (gap == 0.0).any() and (gap > 0.0).any()
    # a cart squarely facing the table's side from the patient's right: its base's front 365 mm ahead of its origin
    side = np.array([[-w - 365.0 - 100.0, 0.0, 90.0]])
    assert T.footprint_gap_mm(cart, side)[0] == pytest.approx(100.0, abs=1e-9)
