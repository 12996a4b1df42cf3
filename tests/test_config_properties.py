"""Property-based tests of the config models (hypothesis): any value at any field, NaN and infinity,
huge sizes, malformed spans. Every outcome is a valid config whose floats are all finite and whose
cost can be estimated, or one ConfigError naming the file and a field; through the CLI, exit 2 and
nothing written. Bounded: a few hundred examples per study, no deadline (numba is not involved)."""
import math

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from typer.testing import CliRunner

from surgopt.cli import app
from surgopt.config import validate
from surgopt.errors import ConfigError
from surgopt.studies import STUDIES, get_study

NASTY = st.one_of(
    st.sampled_from([math.nan, math.inf, -math.inf, 0, -1, 1e308, -1e308, 2 ** 63, True, None, "", "nan",
                     [], {}, [math.nan], [1.0] * 3, {"start": 0, "stop": 1, "step": 0}]),
    st.floats(allow_nan=True, allow_infinity=True),
    st.integers(min_value=-10 ** 12, max_value=10 ** 12),
    st.lists(st.floats(allow_nan=True, allow_infinity=True), max_size=5),
    st.fixed_dictionaries({"start": st.one_of(st.floats(-1e3, 1e3), st.just(math.nan)),
                           "stop": st.one_of(st.floats(-1e3, 1e3), st.just(math.inf)),
                           "step": st.one_of(st.floats(-10, 10), st.just(math.nan))}),
)


def _leaves(value, path=()):
    """Every (path, default value) of a dumped default config, lists' first items included."""
    if isinstance(value, dict):
        for k, v in value.items():
            yield from _leaves(v, path + (k,))
    else:
        yield path, value
        if isinstance(value, list) and value:
            yield from _leaves(value[0], path + (0,))


def _set(data, path, value):
    """data[path] = value, unless an earlier change replaced a container on the path."""
    d = data
    for p in path[:-1]:
        if not isinstance(d, (dict, list)) or (isinstance(d, list) and p >= len(d)) or (isinstance(d, dict) and p not in d):
            return
        d = d[p]
    if isinstance(d, dict) or (isinstance(d, list) and isinstance(path[-1], int) and path[-1] < len(d)):
        d[path[-1]] = value


def _finite(value):
    if isinstance(value, float):
        return math.isfinite(value)
    if isinstance(value, dict):
        return all(_finite(v) for v in value.values())
    if isinstance(value, (list, tuple)):
        return all(_finite(v) for v in value)
    return True


def _check(study, data):
    try:
        cfg = validate(data, study.config_model, "x.toml")
    except ConfigError as exc:
        msg = str(exc)
        assert msg.startswith("x.toml: ") and exc.exit_code == 2
        assert "\n" not in msg and len(msg) < 2000, msg[:300]
        return None
    dumped = cfg.model_dump()
    assert _finite(dumped), dumped
    est = study.estimate(cfg)
    assert est.items >= 0 and math.isfinite(est.seconds_one_core) and est.peak_bytes > 0
    return cfg


@pytest.mark.parametrize("name", sorted(STUDIES))
@settings(max_examples=250, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(data=st.data())
def test_any_value_at_any_field_is_valid_or_one_named_error(name, data):
    study = get_study(name)
    base = study.config_model().model_dump(mode="json")
    leaves = list(_leaves(base))
    for _ in range(data.draw(st.integers(1, 3))):
        path, _ = data.draw(st.sampled_from(leaves))
        _set(base, path, data.draw(NASTY))
    _check(study, base)


ODD = st.sampled_from([math.nan, math.inf, -math.inf])


@settings(max_examples=150, deadline=None)
@given(st.one_of(st.floats(-200, 200), ODD), st.one_of(st.floats(-200, 200), ODD), st.one_of(st.floats(-50, 50), ODD),
       st.sampled_from(["alpha_deg", "phi_z_deg", "bx_mm", "iso_min"]), st.booleans())
def test_raven_spans_are_valid_or_name_their_field(start, stop, step, param, extra_key):
    span = {"start": start, "stop": stop, "step": step}
    if extra_key:
        span["stpe"] = 1.0
    study = get_study("raven-sweep")
    try:
        cfg = validate({"sweep": {param: span}}, study.config_model, "x.toml")
    except ConfigError as exc:
        assert str(exc).startswith(f"x.toml: sweep.{param}"), str(exc)
        return
    assert not extra_key and step > 0 and stop >= start and all(map(math.isfinite, (start, stop, step)))
    assert len(getattr(cfg.sweep, param).values()) >= 1


@settings(max_examples=20, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(field=st.sampled_from(["workspace.cube_side_m", "robot.tool_length_m", "candidates.grid.x_min_m"]),
       value=st.sampled_from(["nan", "inf", "-inf", "1e400", "-1e400"]))
def test_cli_refuses_bad_values_with_exit_2_and_writes_nothing(tmp_path_factory, field, value):
    tmp = tmp_path_factory.mktemp("cli")
    section, key = field.rsplit(".", 1)
    (tmp / "bad.toml").write_text(f"[{section}]\n{key} = {value}\n")
    r = CliRunner().invoke(app, ["rcm-grid", str(tmp / "bad.toml"), "--store", str(tmp / "store")])
    assert r.exit_code == 2, r.output
    assert r.output.startswith(f"surgopt: error: {tmp / 'bad.toml'}: {field}: "), r.output
    assert not (tmp / "store").exists()
