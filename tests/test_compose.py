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
