"""Configs from the command line (surgopt/compose.py, the override parser in surgopt/config.py)."""
import pytest

from surgopt.compose import variants
from surgopt.config import parse_overrides, study_key
from surgopt.errors import ConfigError
from surgopt.studies import get_study

RCM = get_study("rcm-grid")


def test_override_values_are_toml_values_and_comma_lists():
    assert parse_overrides(["a.b=0.55", "c=9", "d=true", "e=down", 'f="x,y"', "g=[[0.5, -0.2], [0.6, -0.3]]",
                            "h=1,2,3", "i={start = 0, stop = 1, step = 0.5}"]) == [
        ("a.b", [0.55]), ("c", [9]), ("d", [True]), ("e", ["down"]), ("f", ["x,y"]),
        ("g", [[[0.5, -0.2], [0.6, -0.3]]]), ("h", [1, 2, 3]), ("i", [{"start": 0, "stop": 1, "step": 0.5}])]
    for bad in ["novalue", "=3", "a..b=1", "a b=1"]:
        with pytest.raises(ConfigError, match="is not KEY=VALUE"):
            parse_overrides([bad])


def test_an_override_equal_to_the_default_is_the_same_run():
    (plain,) = variants(RCM)
    (same,) = variants(RCM, overrides=["robot.tool_length_m=0.587"])
    (other,) = variants(RCM, overrides=["robot.tool_length_m=0.55"])
    key = lambda v: study_key(RCM.name, v.config, RCM.kernel_version)  # noqa: E731
    assert key(plain) == key(same) != key(other)
    assert other.config.robot.tool_length_m == 0.55 and other.config_name.endswith("+robot.tool_length_m=0.55")


def test_multirun_is_the_cartesian_product_in_order():
    vs = variants(RCM, overrides=["robot.tool_length_m=0.5,0.6", "workspace.points_per_side=5,7,9"], multirun=True)
    assert [(v.varied["robot.tool_length_m"], v.varied["workspace.points_per_side"]) for v in vs] == [
        (0.5, 5), (0.5, 7), (0.5, 9), (0.6, 5), (0.6, 7), (0.6, 9)]
    with pytest.raises(ConfigError, match="lists several values; add --multirun"):
        variants(RCM, overrides=["robot.tool_length_m=0.5,0.6"])
    with pytest.raises(ConfigError, match="would make 1,030,301 runs"):
        variants(RCM, overrides=[f"{k}={','.join(map(str, range(1, 102)))}" for k in
                                 ("workspace.points_per_side", "candidates.grid.x_count", "candidates.grid.z_count")],
                 multirun=True)


def test_errors_name_the_field_suggest_a_key_and_the_right_study(tmp_path):
    with pytest.raises(ConfigError, match=r"overrides: robot.tool_length_m: Input should be greater than 0"):
        variants(RCM, overrides=["robot.tool_length_m=-1"])
    with pytest.raises(ConfigError, match=r"workspace.points_per_sid: unknown key \(did you mean 'points_per_side'\?\)"):
        variants(RCM, overrides=["workspace.points_per_sid=5"])
    raven = tmp_path / "r.toml"
    raven.write_text("[sweep]\nalpha_deg = [45.0]\n")
    with pytest.raises(ConfigError, match="this is a raven-sweep config, not a rcm-grid one: run `surgopt raven-sweep"):
        variants(RCM, raven)


def test_several_config_files_merge_in_order_each_files_paths_its_own(tmp_path):
    """A patient file and a region file (issue 42 item 11): merged table by table, the later over the earlier;
    a mesh named in a file of another folder is taken from that file's folder; the run is the one a single file
    with the merged fields gives (same store key), named after both."""
    import numpy as np

    from surgopt.cli import _split_args

    study = get_study("port-place")
    (tmp_path / "bodies").mkdir()
    (tmp_path / "bodies" / "target.txt").write_text("0 -100 40\n10 -100 40\n0 -90 45\n")
    (tmp_path / "bodies" / "patient.toml").write_text(
        '[patient]\nsemi_axes_mm = [170.0, 210.0, 140.0]\n[patient.port_region]\nsite_spacing_mm = 36.0\n'
        '[target]\nshape = "points"\npoints_file = "target.txt"\n')
    (tmp_path / "region.toml").write_text(
        "[patient.port_region]\npolygon_mm = [[-150, -200], [150, -200], [150, 40], [-150, 40]]\n")
    args = [str(tmp_path / "bodies" / "patient.toml"), str(tmp_path / "region.toml"), "objective.angle=2.0"]
    config, overrides = _split_args(args)
    assert config == args[:2] and overrides == ["objective.angle=2.0"]
    (v,) = variants(study, config, overrides)
    cfg = v.config
    assert cfg.patient.port_region.site_spacing_mm == 36.0  # from the first file, beside the second's polygon
    assert cfg.patient.port_region.polygon_mm[0] == [-150.0, -200.0]
    assert cfg.target.points_file == str((tmp_path / "bodies" / "target.txt").resolve())
    assert cfg.objective.angle == 2.0 and v.config_name == "patient+region+objective.angle=2.0"
    one = tmp_path / "bodies" / "one.toml"
    one.write_text((tmp_path / "bodies" / "patient.toml").read_text().replace(
        "site_spacing_mm = 36.0\n", "site_spacing_mm = 36.0\npolygon_mm = [[-150, -200], [150, -200], [150, 40], "
                                    "[-150, 40]]\n") + "[objective]\nangle = 2.0\n")
    (w,) = variants(study, str(one))
    assert study_key("port-place", w.config, "k") == study_key("port-place", cfg, "k")
    assert np.isfinite(cfg.target.centre_mm).all()


def test_a_later_config_file_that_is_not_a_table_is_refused_naming_it(tmp_path):
    (tmp_path / "a.toml").write_text("[objective]\nangle = 2.0\n")
    (tmp_path / "b.yaml").write_text("- 1\n- 2\n")
    with pytest.raises(ConfigError, match=r"b\.yaml.*table of sections"):
        variants(get_study("port-place"), [str(tmp_path / "a.toml"), str(tmp_path / "b.yaml")])


def test_a_config_of_ones_own_keeps_the_robot_and_print_config_says_where_each_value_came_from(tmp_path):
    """#56 item 1: a port-place config naming only [patient] and [target] ran with the cart's model 'none' (the
    field's default then; the embedded default's 'auto' was not the base of a config file), so the cart and every
    link check vanished (80,683 feasible of 2.4 M instead of ~2,000). 'auto' is now the field's default: the file
    gives the same config as the embedded default with the same values given on the command line. --print-config
    names the file, the command line or the embedded default each given value came from."""
    from surgopt.compose import origins, variants
    from surgopt.studies import get_study

    from conftest import invoke

    study = get_study("port-place")
    own = tmp_path / "my_patient.toml"
    own.write_text("[patient]\nsemi_axes_mm = [170.0, 200.0, 130.0]\n[target]\ncentre_mm = [0.0, -90.0, 40.0]\n")
    (mine,) = variants(study, own)
    (same,) = variants(study, None, ["patient.semi_axes_mm=[170.0,200.0,130.0]", "target.centre_mm=[0.0,-90.0,40.0]"])
    assert mine.config.cart.model == "classic" and mine.config == same.config
    assert origins(study, own, ["cart.distance_mm=[900,1200]"]) == {
        "patient.semi_axes_mm": str(own), "target.centre_mm": str(own), "cart.distance_mm": "the command line"}
    assert origins(study) == {"cart.model": "embedded default port_place_dvrk.toml"}
    code, out = invoke("port-place", own, "cart.distance_mm=[900,1200]", "--print-config")
    lines = out.splitlines()
    assert code == 0 and lines[0].startswith("# where each value given came from")
    assert any(line.split() == ["#", "target.centre_mm", str(own)] for line in lines[:4])
    assert 'model = "classic"' in out
