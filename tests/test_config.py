"""Config loading and validation: clear errors naming the file and field, exit code 2."""
import subprocess
import sys

import pytest

from surgopt.config import canonical_json, load_config, load_embedded, study_key
from surgopt.errors import ConfigError
from surgopt.studies.rcm_grid import study as S

from conftest import REPO


def test_embedded_default_equals_shipped_config():
    emb = load_embedded(S.DEFAULT_CONFIG, S.Config)
    shipped = load_config(REPO / "configs" / S.DEFAULT_CONFIG, S.Config)
    assert emb == shipped
    assert canonical_json(emb) == canonical_json(shipped)
    # and the file spells out every default of the model
    assert emb == S.Config()


def test_yaml_and_toml_agree(tmp_path):
    (tmp_path / "a.toml").write_text('search = "cull"\n[workspace]\npoints_per_side = 9\n'
                                     '[candidates]\nlist_m = [[0.5, -0.2], [0.6, -0.3]]\n')
    (tmp_path / "a.yaml").write_text("search: cull\nworkspace:\n  points_per_side: 9\n"
                                     "candidates:\n  list_m: [[0.5, -0.2], [0.6, -0.3]]\n")
    a = load_config(tmp_path / "a.toml", S.Config)
    b = load_config(tmp_path / "a.yaml", S.Config)
    assert a == b
    assert study_key("rcm-grid", a, "k") == study_key("rcm-grid", b, "k")
    assert study_key("rcm-grid", a, "k") != study_key("rcm-grid", a, "k2")


BAD = {
    "unknown key": ("[workspace]\npoints_per_sid = 9\n", "workspace.points_per_sid", "unknown key"),
    "wrong type": ('[workspace]\npoints_per_side = "nine"\n', "workspace.points_per_side", "integer"),
    "out of range": ("[robot]\nlink_d3_m = -0.45\n", "robot.link_d3_m", "greater than 0"),
    "bad literal": ('[robot]\nelbow = "sideways"\n', "robot.elbow", "'up' or 'down'"),
    "nested": ("[robot.joint_limit_deg]\nE1 = 400\n", "robot.joint_limit_deg.E1", "less than or equal to 360"),
    "list item": ("[candidates]\nlist_m = [[0.5, -0.2], [0.6]]\n", "candidates.list_m[1]", "at least 2"),
    "grid order": ("[candidates.grid]\nx_min_m = 0.8\nx_max_m = 0.2\n", "candidates.grid", "x_max_m must be"),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_config_message_names_file_and_field(tmp_path, case):
    text, field, words = BAD[case]
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(ConfigError) as e:
        load_config(path, S.Config)
    msg = str(e.value)
    assert msg.startswith(f"{path}: {field}: "), msg
    assert words in msg
    assert e.value.exit_code == 2


def test_unparsable_and_missing(tmp_path):
    (tmp_path / "x.toml").write_text("[workspace\npoints = 1")
    (tmp_path / "x.yaml").write_text("workspace: [1, 2\n")
    (tmp_path / "x.ini").write_text("a=1")
    for name, words in (("x.toml", "not valid TOML"), ("x.yaml", "not valid YAML"),
                        ("x.ini", "unknown config format"), ("missing.toml", "file not found")):
        with pytest.raises(ConfigError, match=words) as e:
            load_config(tmp_path / name, S.Config)
        assert str(tmp_path / name) in str(e.value)


def test_yaml_safe_load_only(tmp_path):
    (tmp_path / "evil.yaml").write_text("search: !!python/object/apply:os.system ['echo hi']\n")
    with pytest.raises(ConfigError, match="not valid YAML"):
        load_config(tmp_path / "evil.yaml", S.Config)


@pytest.mark.parametrize("text", ["[workspace]\npoints_per_side = 0\n", "[robot\n"])
def test_cli_bad_config_exits_2_and_writes_nothing(tmp_path, text):
    path = tmp_path / "bad.toml"
    path.write_text(text)
    store = tmp_path / "store"
    r = subprocess.run([sys.executable, "-m", "surgopt", "rcm-grid", str(path), "--store", str(store)],
                       capture_output=True, text=True)
    assert r.returncode == 2
    lines = [line for line in r.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and str(path) in lines[0], r.stderr
    assert not store.exists()


def test_cli_missing_config_exits_2(tmp_path):
    r = subprocess.run([sys.executable, "-m", "surgopt", "rcm-grid", str(tmp_path / "nope.toml"),
                        "--store", str(tmp_path / "s")], capture_output=True, text=True)
    assert r.returncode == 2 and "file not found" in r.stderr
    assert not (tmp_path / "s").exists()


@pytest.mark.parametrize("value, says", [(-30.0, "Input should be greater than or equal to -25, or be 'off' (got -30"),
                                         ("offf", "Input should be a valid number, or be 'off' (got 'offf')")])
def test_a_field_of_a_number_or_a_word_says_both_in_one_error(value, says):
    """A field that takes a number or a word (port-place's ``min_link_clearance_mm``: mm, or 'off') refused in one
    error naming the field, not once per member of its union with pydantic's tags ('constrained-float',
    "literal['off']") in the field's path."""
    from surgopt.config import validate
    from surgopt.studies.port_place.config import Config

    with pytest.raises(ConfigError) as info:
        validate({"constraints": {"min_link_clearance_mm": value}}, Config, "my.toml")
    text = str(info.value)
    assert "constraints.min_link_clearance_mm: " + says in text and "also" not in text
    assert "constrained-float" not in text and "literal[" not in text
    assert validate({"constraints": {"min_link_clearance_mm": "off"}}, Config, "x").constraints.link_least_mm is None


def test_every_shipped_port_place_config_validates_and_the_clinical_ones_name_their_sources():
    """configs/port_place_*.toml, port_region_*.toml and clinical_*.toml are port-place configs (the clinical
    set-ups of issue 54 each say where its numbers come from, and run on the Classic cart)."""
    from surgopt.studies import get_study

    study = get_study("port-place")
    names = sorted(p.name for p in (REPO / "configs").glob("*.toml")
                   if p.name.startswith(("port_place_", "port_region_", "clinical_")))
    assert len([n for n in names if n.startswith("clinical_")]) == 2
    for name in names:
        cfg = load_config(REPO / "configs" / name, study.config_model)
        if name.startswith("clinical_"):
            text = (REPO / "configs" / name).read_text()
            assert "Sources" in text or "Source" in text, name
            assert cfg.cart.model == "classic"
