"""rcm-grid's robot section (surgopt/studies/rcm_grid/config.py): shipped models, URDF files, DH tables,
--robot, y candidates; every URDF and DH error through the CLI (exit 2, file and field named, nothing
written)."""
import json
import math
import re
from pathlib import Path

import numpy as np
import pytest

from surgopt.config import validate
from surgopt.errors import ConfigError
from surgopt.studies.rcm_grid import study as S

from conftest import cli

DATA = Path(__file__).parent / "data"
PA10_URDF = (DATA / "pa10_7c.urdf").read_text()
SMALL = ["workspace.points_per_side=3", "candidates.grid.x_count=4", "candidates.grid.z_count=3"]


def urdf_with(tmp_path, old, new, name="arm.urdf"):
    text = PA10_URDF.replace(old, new)
    assert text != PA10_URDF or old == new
    (tmp_path / name).write_text(text)
    return name


ARM = """[robot]
urdf = "{urdf}"
tool_length_m = 0.3
locked_joints_deg = {{ S3 = 0.0, W2 = 0.0 }}
{extra}
"""

BAD_URDF = [
    ("floating", ('name="S2" type="revolute"', 'name="S2" type="floating"'), "", "joint 'S2'", "floating joint"),
    ("planar", ('name="E1" type="revolute"', 'name="E1" type="planar"'), "", "joint 'E1'", "planar joint"),
    ("missing link", ('<link name="link_e2"/>', ''), "", "joint 'E2'", "child link 'link_e2'"),
    ("unknown tip", ("", ""), 'tip_link = "hand"', "tip_link", "no link 'hand'"),
    ("unknown base", ("", ""), 'base_link = "table"', "base_link", "no link 'table'"),
    ("locked unknown", ("", ""), "", "locked_joints_deg", "no joint 'W3'"),
    ("six active", ("", ""), "", "locked_joints_deg", "6 joints remain active"),
    ("no speed", ('velocity="2.0" effort="100"/>\n  </joint>\n  <joint name="E1"',
                  'effort="100"/>\n  </joint>\n  <joint name="E1"'), "", "joint 'S3'", "velocity"),
    ("not xml", ("<robot", "<<robot"), "", "arm.urdf", "not a readable URDF: line 7"),
    # lxml's recovering parser (yourdfpy's fallback) accepted this and dropped S2's origin: another arm
    ("unquoted attribute", ('<origin xyz="0 0 0.117" rpy="0 0 0"/>', '<origin xyz="0 0 0.117" rpy=0/>'), "",
     "arm.urdf", "not a readable URDF: line 30, column"),
    ("nan origin", ('<origin xyz="0 0 0.117"', '<origin xyz="0 0 nan"'), "", "joint 'S2' (line 28) <origin xyz>",
     "is not finite"),
    ("inf rpy", ('<origin xyz="0 0 0.117" rpy="0 0 0"/>', '<origin xyz="0 0 0.117" rpy="0 inf 0"/>'), "",
     "joint 'S2' (line 28) <origin rpy>", "is not finite"),
    ("huge origin", ('<origin xyz="0 0 0.117"', '<origin xyz="0 0 1e308"'), "", "<origin xyz>", "beyond 10 (m)"),
    ("huge limit", ('upper="1.5882496193148399"', 'upper="1e300"'), "", "joint 'S2' (line 28) <limit upper>",
     "not finite or beyond"),
    ("two parents", ('<joint name="S2" type="revolute">\n    <parent link="link_s1"/><child link="link_s2"/>',
                     '<joint name="S2" type="revolute">\n    <parent link="link_s1"/><child link="link_s1"/>'), "",
     "joint 'S2'", "already the child of joint 'S1'"),
    ("loop", ('<parent link="world"/><child link="base_link"/>', '<parent link="flange"/><child link="base_link"/>'),
     'base_link = "world"\ntip_link = "flange"', "tip_link", "does not descend from base_link 'world'"),
    ("limit without range", ('<limit lower="-1.5882496193148399" upper="1.5882496193148399"', '<limit'), "",
     "joint 'S2'", "cannot move: its limits are [0, 0]"),
]


@pytest.mark.parametrize("case", BAD_URDF, ids=[c[0] for c in BAD_URDF])
def test_urdf_errors_through_the_cli(tmp_path, case):
    name, (old, new), extra, where, what = case
    urdf = urdf_with(tmp_path, old, new)
    text = ARM.format(urdf=urdf, extra=extra)
    if name == "locked unknown":
        text = text.replace("W2 = 0.0", "W3 = 0.0")
    if name == "six active":
        text = text.replace("{ S3 = 0.0, W2 = 0.0 }", "{ S3 = 0.0 }")
    (tmp_path / "arm.toml").write_text(text)
    r = cli("rcm-grid", tmp_path / "arm.toml", "--store", tmp_path / "store", check=False)
    assert r.returncode == 2, r.stderr
    line = r.stderr.strip()
    assert len(line.splitlines()) == 1 and "arm.toml" in line and "robot" in line
    assert where in line and what in line, line
    assert not (tmp_path / "store").exists()


BAD_DH = [
    ("no speed", [{"a_m": 0, "alpha_deg": 0, "d_m": 0.1}] * 5, "max_speed_rad_s is required"),
    ("four rows", [{"a_m": 0, "alpha_deg": 90, "d_m": 0.1, "max_speed_rad_s": 1}] * 4, "only 4 joints remain active"),
    ("half limits", [{"a_m": 0, "alpha_deg": 0, "d_m": 0.1, "max_speed_rad_s": 1, "lower_deg": -90}] * 5,
     "give both lower_deg and upper_deg"),
    ("prismatic in degrees", [{"joint": "prismatic", "a_m": 0, "alpha_deg": 0, "d_m": 0.1, "max_speed_rad_s": 1}] * 5,
     "takes lower_m, upper_m, max_speed_m_s"),
    ("nan", [{"a_m": "nan", "alpha_deg": 0, "d_m": 0.1, "max_speed_rad_s": 1}] * 5, "robot.dh[0].a_m: must be a finite number"),
]


@pytest.mark.parametrize("case", BAD_DH, ids=[c[0] for c in BAD_DH])
def test_dh_errors_through_the_cli(tmp_path, case):
    _, rows, what = case
    rows = [{k: (float("nan") if v == "nan" else v) for k, v in r.items()} for r in rows]
    (tmp_path / "dh.yaml").write_text(json.dumps({"robot": {"dh": rows, "tool_length_m": 0.2}}).replace("NaN", ".nan"))
    r = cli("rcm-grid", tmp_path / "dh.yaml", "--store", tmp_path / "store", check=False)
    assert r.returncode == 2 and "dh.yaml" in r.stderr and what in r.stderr, r.stderr
    assert not (tmp_path / "store").exists()


@pytest.mark.parametrize("data, what", [
    ({"robot": {"model": "ur5"}}, "did you mean 'ur5e'"),
    ({"robot": {"model": "ur5e", "link_d1_m": 0.3}}, "link_d1_m is a PA10-7C field"),
    ({"robot": {"model": "ur5e", "kernel": "closed_form"}}, "only for the PA10-7C"),
    ({"robot": {"model": "ur5e", "urdf": "x.urdf"}}, "give one of model, urdf or dh"),
    ({"robot": {"model": "ur5e", "seed_deg": {"wrist_3": 0}}}, "'wrist_3' is locked"),
    ({"robot": {"model": "ur5e", "seed_deg": {"wrist_9": 0}}}, "'wrist_9' is not an active joint"),
    ({"robot": {"model": "ur5e"}, "candidates": {"z_reference": "shoulder"}}, "is the PA10's"),
    ({"robot": {"dh": [{"a_m": 0, "alpha_deg": 90, "d_m": 0, "max_speed_rad_s": 1}] * 5}}, "tool_length_m is required"),
    ({"robot": {"urdf": "nowhere.urdf", "tool_length_m": 0.3}}, "file not found"),
    ({"robot": {"model": "ur5e", "tool_axis": [0, 0, 0]}}, "tool_axis must be a direction"),
    ({"candidates": {"grid": {"y_min_m": 0.0, "y_max_m": 0.1}}}, "a y range needs y_count > 1"),
    ({"candidates": {"list_m": [[0.5, 0.1], [0.5, 0.0, 0.1]]}}, "must all be [x, z] or all [x, y, z]"),
])
def test_robot_config_errors(tmp_path, data, what):
    from surgopt.compose import validate_for
    from surgopt.errors import ConfigError

    with pytest.raises(ConfigError) as e:
        validate_for(S.STUDY, data, "cfg.toml", tmp_path / "cfg.toml")
    assert what in str(e.value) and "cfg.toml" in str(e.value)


def test_the_resolved_robot_says_everything():
    """A shipped model's defaults (locks, seed, tool, workspace, grid) fill what the config leaves out; the
    config's own values win field by field."""
    from surgopt.robots.models import get_model

    m = get_model("ur5e")
    cfg = validate({"robot": {"model": "ur5e"}, "candidates": {"grid": {"x_count": 5}}}, S.Config, "t")
    assert cfg.robot.locked_joints_deg == m.locked_joints_deg and cfg.robot.seed_deg == m.seed_deg
    assert cfg.robot.tool_length_m == m.tool_length_m and cfg.candidates.z_reference == "base"
    g = cfg.candidates.grid
    assert g.x_count == 5 and g.z_count == m.grid["z_count"] and g.x_min_m == m.grid["x_min_m"]
    assert cfg.workspace.points_per_side == m.workspace["points_per_side"]
    assert not cfg.robot.closed_form and S.kernel_for(cfg).__class__.__name__ == "ChainKernel"
    assert validate({}, S.Config, "t").robot.closed_form


def test_y_candidates_grid_and_list():
    cfg = validate({"robot": {"model": "ur5e"}, "candidates": {"grid": {
        "x_min_m": 0.3, "x_max_m": 0.4, "x_count": 2, "y_min_m": -0.1, "y_max_m": 0.1, "y_count": 3,
        "z_min_m": -0.5, "z_max_m": -0.5, "z_count": 1}}}, S.Config, "t")
    xyz = S.candidate_xyz(cfg)
    assert xyz.shape == (6, 3) and xyz[:3, 1].tolist() == [-0.1, 0.0, 0.1] and (xyz[:3, 0] == 0.3).all()
    assert S.search_axes(cfg) == ("x", "y", "z") and S.candidate_count(cfg) == 6
    lst = validate({"robot": {"model": "ur5e"}, "candidates": {"list_m": [[0.3, 0.05, -0.5]]}}, S.Config, "t")
    assert S.candidate_xyz(lst).tolist() == [[0.3, 0.05, -0.5]]
    rows = S.compute_task(cfg.model_copy(update={"workspace": S.Workspace(points_per_side=3)}), 6, 0)
    assert rows["y_rcm_m"].tolist() == xyz[:, 1].tolist()
    # the mirror image about y = 0 of a UR5e candidate is not its twin (the shoulder offset), but both solve
    assert rows["feasible"].any()


def test_cull_finds_the_full_maps_best_for_a_generic_arm():
    cfg = validate({"robot": {"model": "panda"}, "workspace": {"points_per_side": 5},
                    "candidates": {"grid": {"x_count": 7, "z_count": 9}}}, S.Config, "t")
    full = S.compute_task(cfg, 10 ** 6, 0)
    cull = S.cull_search(cfg.model_copy(update={"search": "cull"}))
    i, j = np.argmax(full["gii"]), np.argmax(np.where(cull["gii_is_exact"], cull["gii"], -1))
    assert full["gii"][i] > 0 and i == j and cull["gii"][j] == full["gii"][i]
    assert cull["points_evaluated"].sum() < full["points_evaluated"].sum()


def test_robot_flag_runs_a_shipped_model_and_a_urdf(tmp_path):
    store = tmp_path / "store"
    r = cli("rcm-grid", *SMALL, "--robot", "lbr_iiwa_14", "--store", store, "--quiet")
    assert "best_y_rcm_m" in r.stdout
    again = cli("rcm-grid", *SMALL, "--robot", "lbr_iiwa_14", "--store", store, "--quiet")
    assert "cache hit" in (again.stdout + again.stderr).lower()
    # the URDF given on the command line, relative to the working directory
    (tmp_path / "pa10.urdf").write_text(PA10_URDF)
    r = cli("rcm-grid", *SMALL, "--robot", "pa10.urdf", "robot.tool_length_m=0.587",
            "robot.locked_joints_deg={S3=0.0,W2=0.0}", "--store", store, "--quiet", cwd=tmp_path)
    assert r.returncode == 0
    bad = cli("rcm-grid", "--robot", "nosuch", "--store", store, check=False)
    assert bad.returncode == 2 and "neither a shipped model" in bad.stderr
    # #28 item 7: an error in what --robot FILE brought names the flag first, not only the embedded PA10 config
    bad = cli("rcm-grid", "--robot", "pa10.urdf", "--store", store, check=False, cwd=tmp_path)
    assert bad.returncode == 2 and bad.stderr.startswith("surgopt: error: --robot pa10.urdf: robot: tool_length_m")
    assert "embedded" not in bad.stderr  # #28 item 7: the PA10 default the user never gave is not named
    assert "tool_length_m is required" in bad.stderr
    # and its runs are labelled with it
    runs = cli("runs", "--store", store, "--format", "json").stdout
    assert "--robot=pa10.urdf" in runs and "--robot=lbr_iiwa_14" in runs


def test_urdf_paths_are_relative_to_the_config_and_its_content_is_in_the_key(tmp_path):
    (tmp_path / "sub").mkdir()
    (tmp_path / "sub" / "arm.urdf").write_text(PA10_URDF)
    (tmp_path / "sub" / "arm.toml").write_text(ARM.format(urdf="arm.urdf", extra=""))
    r = cli("rcm-grid", tmp_path / "sub" / "arm.toml", "--print-config")
    assert f'urdf = "{tmp_path / "sub" / "arm.urdf"}"' in r.stdout and "urdf_sha256 = " in r.stdout
    k1 = cli("rcm-grid", tmp_path / "sub" / "arm.toml", *SMALL, "--dry-run").stdout
    (tmp_path / "sub" / "arm.urdf").write_text(PA10_URDF.replace('xyz="0 0 0.25"', 'xyz="0 0 0.26"'))
    k2 = cli("rcm-grid", tmp_path / "sub" / "arm.toml", *SMALL, "--dry-run").stdout
    key = lambda out: [w for w in out.split() if len(w) == 12 and all(c in "0123456789abcdef" for c in w)]  # noqa: E731
    assert key(k1) and key(k1) != key(k2)
    # #27 item 4: the key holds the URDF's content, not its path: a copy elsewhere (same content) is the same run
    (tmp_path / "elsewhere").mkdir()
    (tmp_path / "elsewhere" / "copy.urdf").write_text((tmp_path / "sub" / "arm.urdf").read_text())
    (tmp_path / "elsewhere" / "arm.toml").write_text(ARM.format(urdf="copy.urdf", extra=""))
    k3 = cli("rcm-grid", tmp_path / "elsewhere" / "arm.toml", *SMALL, "--dry-run").stdout
    assert key(k3) == key(k2)
    # a config that pins the hash refuses a changed file
    pinned = tmp_path / "sub" / "pinned.toml"
    pinned.write_text(ARM.format(urdf="arm.urdf", extra='urdf_sha256 = "' + "0" * 64 + '"'))
    bad = cli("rcm-grid", pinned, check=False)
    assert bad.returncode == 2 and "changed since this config was written" in bad.stderr


def test_the_worked_urdf_example_gives_table_I():
    """docs/robots.md's example config: the PA10 as a URDF file reproduces the closed form's Table I rows."""
    from surgopt.config import load_config

    from conftest import REPO

    ex = load_config(REPO / "configs" / "rcm_pa10_urdf_table1.toml", S.Config)
    t1 = load_config(REPO / "configs" / "rcm_table1.toml", S.Config)
    assert not ex.robot.closed_form and t1.robot.closed_form
    np.testing.assert_allclose(S.candidate_rcms(ex, S.candidate_xyz(ex)), S.candidate_rcms(t1, S.candidate_xyz(t1)),
                               atol=1e-12)
    a, b = S.compute_task(t1, 15, 0), S.compute_task(ex, 15, 0)
    assert (a["feasible"] == b["feasible"]).all()
    np.testing.assert_allclose(b["gii"], a["gii"], rtol=1e-9)


def test_standard_jacobian_gii_against_the_reference():
    """Sec. III-E: the standard 6 x 6 Jacobian (S3 held, W2 spinning the tool) with the paper's task scaling
    (10 mm/s, pi/2 rad/s) against dense SVD at the closed-form IK poses (tests/reference.py); the map has
    the alternative GII's profile (rank correlation > 0.95) with much lower values."""
    import reference as ref
    from surgopt.robots import pa10_7c
    from surgopt.studies.rcm_track.study import rank_correlation

    base = {"workspace": {"points_per_side": 3}, "candidates": {"grid": {"x_count": 9, "z_count": 9}}}
    std = validate({**base, "metric": "standard"}, S.Config, "t")
    alt = validate(base, S.Config, "t")
    a, b = S.compute_task(alt, 81, 0), S.compute_task(std, 81, 0)
    assert (a["feasible"] == b["feasible"]).all() and a["feasible"].sum() >= 20
    qmax7 = np.array([pa10_7c.MAX_JOINT_SPEED_RAD_S[n] for n in pa10_7c.JOINT_NAMES])
    rcms = S.candidate_rcms(std, S.candidate_xyz(std))
    off = S.workspace_offsets(std.workspace)
    for i in np.flatnonzero(b["feasible"])[::4]:
        want = ref.pa10_standard_gii(rcms[i], off, pa10_7c.LINKS_BIELEFELD_M, pa10_7c.TOOL_LENGTH_M, qmax7)
        assert abs(b["gii"][i] / want - 1) < 1e-9
    f = a["feasible"]
    assert rank_correlation(a["gii"][f], b["gii"][f]) > 0.95 and b["gii"].max() < a["gii"].max() / 20


def test_the_algorithmic_singularity_only_the_alternative_jacobian_sees():
    """A tip approaching the RCM: the alternative Jacobian's sigma_min falls in proportion (the lever arm
    through the RCM), the standard Jacobian's does not change."""
    out = {}
    for metric in ("alternative", "standard"):
        for depth in (0.1, 0.01):
            cfg = validate({"metric": metric, "robot": {"kernel": "generic"},
                            "workspace": {"points_per_side": 1, "depth_below_rcm_m": depth},
                            "candidates": {"list_m": [[0.535, -0.21]]}}, S.Config, "t")
            rows = S.compute_task(cfg, 1, 0)
            name = {"alternative": "sigma_min_m_per_s", "standard": "sigma_min_task_scaled"}[metric]
            assert {"sigma_min_m_per_s", "sigma_min_task_scaled"} & set(rows) == {name}  # unit-true names (#24)
            assert S.STUDY.schema_for(cfg).names == list(rows)
            assert S.STUDY.schema_for(cfg.model_dump(mode="json")).field(name).metadata[b"unit"] == \
                {"alternative": b"m/s", "standard": b"1"}[metric]
            out[metric, depth] = rows[name][0]
    assert 0.07 < out["alternative", 0.01] / out["alternative", 0.1] < 0.1
    standard = {"metric": "standard", "robot": {"kernel": "generic"}}
    validate({**standard, "search": {"method": "tpe", "trials": 10, "objectives": ["sigma_min_task_scaled"]}},
             S.Config, "t")
    with pytest.raises(ConfigError, match="'sigma_min_m_per_s' is not one of gii, sigma_min_task_scaled"):
        validate({**standard, "search": {"method": "tpe", "trials": 10, "objectives": ["sigma_min_m_per_s"]}},
                 S.Config, "t")
    assert abs(out["standard", 0.01] / out["standard", 0.1] - 1) < 0.03


@pytest.mark.parametrize("data, what", [
    ({"metric": "standard", "robot": {"kernel": "closed_form"}}, "runs on the generic kernel"),
    ({"metric": "standard", "robot": {"model": "ur5e", "spin_joint": None}}, "needs the joint that spins the tool"),
    ({"metric": "standard", "robot": {"model": "ur5e", "spin_joint": "elbow"}}, "must be one of locked_joints_deg"),
    ({"metric": "standard", "robot": {"model": "ur5e", "tool_axis": [1, 0, 1]}}, "does not turn about the tool's axis"),
])
def test_standard_metric_errors(tmp_path, data, what):
    from surgopt.compose import validate_for
    from surgopt.errors import ConfigError

    with pytest.raises(ConfigError) as e:
        validate_for(S.STUDY, data, "cfg.toml", tmp_path / "cfg.toml")
    assert what in str(e.value)


@pytest.mark.parametrize("data, what", [
    # the UR5e: a 0.30 m tool, the cube 0.4 m below the RCM (1,642 'feasible' candidates, GII 0.468 before)
    ({"robot": {"model": "ur5e", "tool_length_m": 0.3}, "workspace": {"depth_below_rcm_m": 0.4}},
     "farthest point is 426 mm from the RCM but the tool reaches 300 mm past the flange"),
    # the PA10 with the cube 0.75 m below (GII 0.133 against the paper's 0.044 before)
    ({"workspace": {"depth_below_rcm_m": 0.75}}, "farthest point is 776 mm from the RCM but the tool reaches 587 mm"),
    ({"workspace": {"depth_below_rcm_m": 0.02, "cube_side_m": 0.05}}, "reaches 5 mm above the RCM"),
])
def test_a_workspace_no_tool_reaches_from_the_rcm_is_refused_before_running(data, what):
    """docs/robots.md's RCM geometry: the tip below the RCM and the RCM on the tool (insertion <= the tool's length
    past the flange); it depends on the workspace and the tool only, so no candidate of such a config is real."""
    from surgopt.errors import ConfigError

    with pytest.raises(ConfigError, match="workspace: ") as e:
        validate(data, S.Config, "x.toml")
    assert what in str(e.value), str(e.value)


def test_speeds_and_ranges_from_the_config_replace_the_files(tmp_path):
    """A published URDF with velocity="0" (or placeholder speeds) runs once the config gives the rated speeds;
    a joint range in the config replaces the file's, and both change the answer as they should."""
    urdf = urdf_with(tmp_path, 'velocity="1.0" effort="100"/>\n  </joint>\n  <joint name="S2"',
                     'velocity="0" effort="100"/>\n  </joint>\n  <joint name="S2"')
    base = {"robot": {"urdf": str(tmp_path / urdf), "tool_length_m": 0.3,
                      "locked_joints_deg": {"S3": 0.0, "W2": 0.0}},
            "workspace": {"points_per_side": 3}, "candidates": {"list_m": [[0.535, -0.21], [0.45, -0.3]]}}
    from surgopt.errors import ConfigError

    with pytest.raises(ConfigError, match="joint 'S1'.*speed_override_rad_s"):
        validate(base, S.Config, "x.toml")
    fixed = validate({**base, "robot": {**base["robot"], "speed_override_rad_s": {"S1": 1.0}}}, S.Config, "x.toml")
    ref = validate({**base, "robot": {**base["robot"], "urdf": str(DATA / "pa10_7c.urdf")}}, S.Config, "x.toml")
    a, b = S.compute_task(fixed, 10, 0), S.compute_task(ref, 10, 0)
    assert np.allclose(a["gii"], b["gii"], atol=1e-12) and a["feasible"].all()  # 1.0 is the file's own S1 speed
    faster = validate({**base, "robot": {**base["robot"], "speed_override_rad_s": {"S1": 3.0}}}, S.Config, "x.toml")
    assert not np.allclose(S.compute_task(faster, 10, 0)["gii"], b["gii"])
    narrow = validate({**base, "robot": {**base["robot"], "speed_override_rad_s": {"S1": 1.0},
                                         "range_override_deg": {"E1": [0.0, 1.0]}}}, S.Config, "x.toml")
    assert not S.compute_task(narrow, 10, 0)["feasible"].any()  # the elbow cannot bend into any workspace
    with pytest.raises(ConfigError, match="range_override_deg: no joint 'E9'"):
        validate({**base, "robot": {**base["robot"], "speed_override_rad_s": {"S1": 1.0},
                                    "range_override_deg": {"E9": [0.0, 1.0]}}}, S.Config, "x.toml")


def test_a_tool_pointing_sideways_is_noted_and_a_map_with_nothing_feasible_says_why(tmp_path):
    """#28 item 3: the UR5e's wrist_3 is locked and spins the flange; with tool_axis along x the tool sticks out
    sideways: a note before the run (and with --dry-run), none for the shipped set-ups. A map where nothing is
    feasible says which constraint failed on how many candidates, and names no best design on an edge."""
    r = cli("rcm-grid", "--robot", "ur5e", "robot.tool_axis=[1,0,0]", "--dry-run", "--store", tmp_path)
    assert "note: robot: the last joint 'wrist_3' is locked but the tool does not point along its axis (at 90 deg" \
        in r.stderr
    for model in ("ur5e", "panda", "lbr_iiwa_14"):  # no note but which IK branch the map follows (#42 item 9)
        notes = [line for line in cli("rcm-grid", "--robot", model, "--dry-run", "--store", tmp_path).stderr
                 .splitlines() if line.startswith("note:")]
        assert all("follows one IK branch" in line for line in notes), notes
    # a URDF given no seed_deg has no branch chosen: the map runs once per IK branch (#27 item 10, #28 item 1)
    (tmp_path / "pa10.urdf").write_text(PA10_URDF)
    arm = ["--robot", "pa10.urdf", "robot.tool_length_m=0.587", "robot.locked_joints_deg={S3=0.0,W2=0.0}"]
    r = cli("rcm-grid", *arm, "--dry-run", "--store", tmp_path, cwd=tmp_path)
    n = len(S.ik_branches(validate({"robot": {"urdf": str(tmp_path / "pa10.urdf"), "tool_length_m": 0.587,
                                              "locked_joints_deg": {"S3": 0.0, "W2": 0.0}}}, S.Config, "x")))
    assert n >= 1 and f"note: robot: no seed_deg: the map runs once per IK branch found at the grid's centre, " \
        f"seeded on it (give robot.seed_deg to run one branch) ({n} runs; --branches is implied)" in r.stderr
    assert r.stdout.count("+branch=") == n  # the dry-run's table: one run per branch
    r = cli("rcm-grid", *arm, "robot.seed_deg={S2=30.0,E1=90.0,W1=60.0}", "--dry-run", "--store", tmp_path, cwd=tmp_path)
    assert "seed_deg" not in r.stderr and "branch" not in r.stdout
    far = ["candidates.grid.x_min_m=1.4", "candidates.grid.x_max_m=1.5", "candidates.grid.x_count=2",
           "candidates.grid.z_count=2", "workspace.points_per_side=3"]
    out = " ".join(cli("rcm-grid", *far, "--store", tmp_path, "-q").stdout.split())
    assert "4 of 4 candidates leave workspace points unreachable" in out.replace("│ │", "")
    assert "edge of the box" not in out


def test_branches_runs_the_map_once_per_ik_branch(tmp_path):
    """#28 item 1: --branches finds the shipped UR5e's IK branches (seeds within its limits, distinct solutions at
    the workspace's centre), runs the map once per branch and names the best overall. Branch 0 is the configured
    seed's own: its best equals a plain run's; another branch ranks the RCMs differently (the issue's other
    shoulder branch: a higher best GII elsewhere). The PA10's closed form is refused (its branch is robot.elbow)."""
    import json

    from surgopt.config import validate

    small = ["workspace.points_per_side=3", "candidates.grid.x_count=13", "candidates.grid.z_count=16"]
    cfg = validate({"robot": {"model": "ur5e"}, "workspace": {"points_per_side": 3},
                    "candidates": {"grid": {"x_count": 13, "z_count": 16}}}, S.Config, "x")
    branches = S.ik_branches(cfg)
    assert len(branches) >= 2 and all(set(b) == set(branches[0]) for b in branches)
    r = cli("rcm-grid", "--robot", "ur5e", *small, "--branches", "--store", tmp_path, "-q")
    assert f"--multirun: {len(branches)} runs" in r.stdout and "best of the" in r.stdout
    plain = json.loads(cli("rcm-grid", "--robot", "ur5e", *small, "--store", tmp_path / "plain", "-q").stdout
                       and cli("summarize", "--store", tmp_path / "plain", "--format", "json").stdout)["headline"]
    names = {r["key"]: r["config_name"].rsplit("branch=", 1)[1]
             for r in json.loads(cli("runs", "--store", tmp_path, "--format", "json").stdout)}
    compared = json.loads(cli("runs", "--compare", "--study", "rcm-grid", "--store", tmp_path, "--format", "json").stdout)
    heads = {names[r["key"]]: r["metrics"] for r in compared}
    assert any(k.startswith("robot.seed_deg.") for k in compared[0]["params"])  # each run's branch: its seed
    assert heads["0"]["best_gii"] == pytest.approx(plain["best_gii"], rel=1e-9)
    assert (heads["0"]["best_x_rcm_m"], heads["0"]["best_z_rcm_m"]) == (plain["best_x_rcm_m"], plain["best_z_rcm_m"])
    assert max(h["best_gii"] for h in heads.values()) > 1.1 * heads["0"]["best_gii"]
    # #42 item 9: a plain run says it follows one branch of several; runs with one answer are named as such
    said = cli("rcm-grid", "--robot", "ur5e", *small, "--store", tmp_path / "plain", "-q")
    assert f"follows one IK branch, the one ur5e's seed lands on; the branch search finds {len(branches)}" in (
        said.stdout + said.stderr)
    first = {}
    for k in sorted(heads, key=int):
        numbers = tuple(f"{v:.9g}" if isinstance(v, float) else v for v in heads[k].values())
        if numbers in first:
            assert f"branch={k} gives the headline numbers of branch={first[numbers]}" in r.stdout + r.stderr
        first.setdefault(numbers, k)
    assert len(first) < len(heads)  # the premise: two seeds gave one answer
    bad = cli("rcm-grid", "--branches", "--dry-run", "--store", tmp_path / "none", check=False)
    assert bad.returncode == 2 and "robot.elbow" in bad.stderr



def test_an_unseeded_urdf_arm_runs_the_branches_the_search_finds_or_is_told_why_none_works(tmp_path):
    """#28 items 1-2: the PA10 URDF with W1 held negative: the all-zero seed (with the run's restarts) finds few
    feasible candidates; without seed_deg the command line runs the map once per branch the search finds (seeds
    within the limits), and the best of those finds far more. With E1 held negative no seed within the limits
    reaches the workspace: one line says so and what to check, and the one run is left as it is."""
    (tmp_path / "pa10.urdf").write_text(PA10_URDF)
    small = ["workspace.points_per_side=3", "candidates.grid.x_count=25", "candidates.grid.z_count=25",
             "candidates.grid.x_min_m=0.2", "candidates.grid.x_max_m=0.8", "candidates.grid.z_min_m=-0.6",
             "candidates.grid.z_max_m=0.0"]
    arm = ["--robot", "pa10.urdf", "robot.tool_length_m=0.587", "robot.locked_joints_deg={S3=0.0,W2=0.0}", *small]
    neg_w1 = [*arm, "robot.range_override_deg={W1=[-120,-20]}"]

    def feasible(store):
        runs = json.loads(cli("runs", "--compare", "--study", "rcm-grid", "--store", store, "--format", "json").stdout)
        return [r["metrics"]["feasible"] for r in runs]

    zero = cli("rcm-grid", *neg_w1, "robot.seed_deg={S2=0.0}", "--store", tmp_path / "a", "-q", cwd=tmp_path)
    assert "branch" not in zero.stdout
    r = cli("rcm-grid", *neg_w1, "--store", tmp_path / "b", "-q", cwd=tmp_path)
    assert "--branches is implied" in r.stderr and "sized from the arm's reach" not in r.stderr
    (zero_feasible,), branch_feasible = feasible(tmp_path / "a"), feasible(tmp_path / "b")
    assert len(branch_feasible) >= 1 and max(branch_feasible) > 1.5 * zero_feasible, (branch_feasible, zero_feasible)
    none = cli("rcm-grid", *arm, "robot.range_override_deg={E1=[-150,-30]}", "--dry-run", "--store", tmp_path / "c",
               cwd=tmp_path)
    assert "no seed within the joint limits (96 tried) reaches the workspace's centre" in none.stderr
    assert "implied" not in none.stderr and "branch" not in none.stdout


UR5E_DH = [{"name": n, "a_m": a, "alpha_deg": al, "d_m": d, "lower_deg": -360.0, "upper_deg": 360.0,
            "max_speed_rad_s": math.pi} for n, a, al, d in (
    ("shoulder_pan", 0.0, 90.0, 0.1625), ("shoulder_lift", -0.425, 0.0, 0.0), ("elbow", -0.3922, 0.0, 0.0),
    ("wrist_1", 0.0, 90.0, 0.1333), ("wrist_2", 0.0, -90.0, 0.0997), ("wrist_3", 0.0, 0.0, 0.0996))]


def test_a_file_arms_default_grid_covers_its_reach(tmp_path):
    """#28 item 5: a DH (or URDF) arm given no candidate grid gets one sized from its reach, not the PA10's.
    The UR5e as a DH table (the shipped model's seed, so one branch): on the PA10's old grid (x 0.2-0.8,
    z -0.6-0) its best lands on the z edge; on the reach-sized grid no feasible candidate lies on the box's
    outer edges (the disc holds every RCM the tool can hold) and the best is the shipped model's, near
    (0.34, -0.84) m. Counts given alone keep the reach's ranges."""
    import surgopt

    robot = {"dh": UR5E_DH, "locked_joints_deg": {"wrist_3": 0.0}, "tool_length_m": 0.3,
             "seed_deg": {"shoulder_pan": 163.0, "shoulder_lift": -95.0, "elbow": 115.0, "wrist_1": -110.0,
                          "wrist_2": -90.0}}
    cfg = validate({"robot": robot}, S.Config, "x")
    g = cfg.candidates.grid
    assert cfg.grid_from_reach and g.x_min_m == 0.0 and g.x_max_m >= 1.2 and g.z_min_m <= -1.1 and g.z_max_m >= 1.4
    assert "sized from the arm's reach" in S.reach_grid_advice(cfg)[0]
    counts = validate({"robot": robot, "candidates": {"grid": {"x_count": 5}}}, S.Config, "x").candidates.grid
    assert counts.x_count == 5 and (counts.x_max_m, counts.z_min_m, counts.z_count) == (g.x_max_m, g.z_min_m, g.z_count)
    assert not validate({"robot": {"model": "ur5e"}}, S.Config, "x").grid_from_reach  # shipped models keep theirs
    (tmp_path / "ur5e_dh.yaml").write_text(json.dumps({"robot": robot, "workspace": {"points_per_side": 5}}))
    df = surgopt.run("rcm-grid", tmp_path / "ur5e_dh.yaml", store=tmp_path / "s")
    ok = df[df.feasible]
    assert len(ok) > 100
    assert ok.x_rcm_m.max() < g.x_max_m and ok.z_rcm_m.min() > g.z_min_m and ok.z_rcm_m.max() < g.z_max_m
    best = ok.loc[ok.gii.idxmax()]
    assert abs(best.x_rcm_m - 0.34) < 0.06 and abs(best.z_rcm_m + 0.84) < 0.06, best
    old = ok[(ok.x_rcm_m >= 0.2) & (ok.x_rcm_m <= 0.8) & (ok.z_rcm_m >= -0.6) & (ok.z_rcm_m <= 0.0)]
    assert old.loc[old.gii.idxmax()].z_rcm_m <= -0.6 + 0.03  # the old default's best sits on its z edge


def dh_rows_of(name: str) -> tuple[list[dict], str]:
    """A shipped model's DH table as an inline [[robot.dh]] config, and its convention."""
    from surgopt.robots.models import get_model

    m = get_model(name)
    rows = []
    for r in m.dh:
        row = dict(name=r.name, a_m=r.a_m, alpha_deg=math.degrees(r.alpha_rad), d_m=r.d_m,
                   theta_offset_deg=math.degrees(r.theta_offset_rad), max_speed_rad_s=r.max_speed)
        if r.lower is not None:
            row.update(lower_deg=math.degrees(r.lower), upper_deg=math.degrees(r.upper))
        rows.append(row)
    return rows, m.convention


def urdf_from_dh(rows: list[dict]) -> str:
    """A URDF written from standard DH rows (joint i+1's origin: Tz(d_i) Tx(a_i) Rx(alpha_i)): a chain built
    apart from surgopt's own DH reader."""
    out, parent, origin = ['<?xml version="1.0"?>', '<robot name="from_dh">', '  <link name="base"/>'], "base", (0, 0, 0)
    for i, r in enumerate(rows):
        x, z, roll = origin
        out += [f'  <joint name="{r["name"]}" type="revolute"><parent link="{parent}"/><child link="l{i}"/>'
                f'<origin xyz="{x} 0 {z}" rpy="{roll} 0 0"/><axis xyz="0 0 1"/><limit lower="{math.radians(-360)}" '
                f'upper="{math.radians(360)}" velocity="{r["max_speed_rad_s"]}" effort="1"/></joint>',
                f'  <link name="l{i}"/>']
        parent, origin = f"l{i}", (r["a_m"], r["d_m"], math.radians(r["alpha_deg"]))
    x, z, roll = origin
    out += [f'  <joint name="to_flange" type="fixed"><parent link="{parent}"/><child link="flange"/>'
            f'<origin xyz="{x} 0 {z}" rpy="{roll} 0 0"/></joint>', '  <link name="flange"/>', '</robot>']
    return "\n".join(out)


def test_a_file_arm_runs_with_the_tool_length_alone(tmp_path):
    """#28 done-means: `surgopt rcm-grid --robot ARM.urdf robot.tool_length_m=L` runs on a UR5-class URDF with no
    other override: the joints to lock are found (the last when it spins the tool; a 7-axis arm's rotation
    whose axis coincides with an earlier one's at the zero pose), each said in a note, and equal the shipped
    models' choices for the UR5e, Panda and LBR iiwa tables; the grid is sized from the reach and every IK
    branch runs. The UR5e URDF (written here from its DH table) gives the DH table's branch count and best."""
    for name in ("ur5e", "panda", "lbr_iiwa_14"):
        from surgopt.robots.models import get_model

        rows, convention = dh_rows_of(name)
        cfg = validate({"robot": {"dh": rows, "dh_convention": convention, "tool_length_m": 0.3}}, S.Config, "x")
        assert cfg.robot.locked_joints_deg == get_model(name).locked_joints_deg, name
        assert cfg.robot.auto_lock_advice()[0].startswith("robot: no locked_joints_deg: ")
    given = validate({"robot": {"dh": rows, "dh_convention": convention, "tool_length_m": 0.3,
                                "locked_joints_deg": {"A1": 0.0, "A7": 0.0}}}, S.Config, "x").robot
    assert given.locked_joints_deg == {"A1": 0.0, "A7": 0.0} and not given.auto_lock_advice()
    rows, _ = dh_rows_of("ur5e")
    (tmp_path / "ur5e.urdf").write_text(urdf_from_dh(rows))
    r = cli("rcm-grid", "--robot", "ur5e.urdf", "robot.tool_length_m=0.3", "workspace.points_per_side=5",
            "--store", tmp_path / "s", "-q", cwd=tmp_path)
    assert "wrist_3 locked at 0 (it spins the tool about its own axis)" in r.stderr
    assert "sized from the arm's reach" in r.stderr and "--branches is implied" in r.stderr
    (tmp_path / "dh.yaml").write_text(json.dumps({"robot": {"dh": rows, "tool_length_m": 0.3},
                                                  "workspace": {"points_per_side": 5}}))
    d = cli("rcm-grid", "dh.yaml", "--store", tmp_path / "s", "-q", cwd=tmp_path)
    best = lambda out: re.search(r"best of the (\d+) runs by best_gii: ([0-9.]+)", out).groups()  # noqa: E731
    n, gii = best(" ".join(r.stdout.split()))
    assert int(n) >= 2 and (n, gii) == best(" ".join(d.stdout.split()))


def test_every_row_of_a_branch_run_carries_its_branch_when_exported(tmp_path):
    """#28 item 1 ("store the branch with every row"): each branch run stores its branch as its seed_deg (config
    and key); the runs exported together give every row the seed of the branch it was computed on, one seed per
    run, as many distinct seeds as branches."""
    import pandas as pd

    small = ["workspace.points_per_side=3", "candidates.grid.x_count=5", "candidates.grid.z_count=6"]
    cli("rcm-grid", "--robot", "ur5e", *small, "--branches", "--store", tmp_path, "-q")
    runs = json.loads(cli("runs", "--store", tmp_path, "--format", "json").stdout)
    assert len(runs) >= 2
    out = tmp_path / "all.csv"
    cli("export", *[r["key"][:12] for r in runs], "--store", tmp_path, "--out", out)
    df = pd.read_csv(out)
    seed_cols = [c for c in df.columns if c.startswith("robot.seed_deg.")]
    assert seed_cols and len(df) == 30 * len(runs)
    per_run = df.groupby("run_key")[seed_cols].nunique()
    assert (per_run == 1).all().all()  # one branch per run, on every one of its rows
    assert len(df[seed_cols].drop_duplicates()) == len(runs)


def test_a_tool_too_short_for_the_papers_cube_gets_the_cube_scaled_to_it():
    """A DH arm with a 0.1 m tool and no workspace: the paper's cube (its far corner 0.130 m from the RCM) would be
    refused, so it is scaled to reach 90% of the tool; a workspace the config gives is left as it is (and refused)."""
    from surgopt.errors import ConfigError

    robot = {"dh": UR5E_DH, "locked_joints_deg": {"wrist_3": 0.0}, "tool_length_m": 0.1}
    ws = validate({"robot": robot}, S.Config, "x").workspace
    far = math.sqrt((ws.depth_below_rcm_m + ws.cube_side_m / 2) ** 2 + 2 * (ws.cube_side_m / 2) ** 2)
    assert ws.cube_side_m < 0.05 and far == pytest.approx(0.09, rel=1e-3)
    assert ws.depth_below_rcm_m / ws.cube_side_m == pytest.approx(2.0, rel=1e-2)  # the paper's (rounded to 0.1 mm)
    with pytest.raises(ConfigError, match="farthest point is 130 mm from the RCM"):
        validate({"robot": robot, "workspace": {"cube_side_m": 0.05}}, S.Config, "x")
