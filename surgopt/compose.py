"""From what a user gives (a config file or the embedded default, KEY=VALUE overrides, study flags)
to validated configs: one per combination when overrides list several values (--multirun).

Used by the CLI and the Python API alike, so that an override is validated exactly like a value in a
file and becomes part of the hashed config (an override equal to the default is the same run).
"""
from __future__ import annotations

import itertools
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from surgopt.config import (
    ConfigError,
    embedded_default_text,
    parse_overrides,
    parse_text,
    read_config_data,
    read_layered_data,
    validate,
    with_override,
)


@dataclass
class Variant:
    """One validated config to run: ``varied`` holds the override values that make it this one."""

    config: Any
    config_name: str
    varied: dict[str, Any] = field(default_factory=dict)


#: Most combinations one --multirun may make.
MAX_VARIANTS = 1000


def base_data(study, config: str | Path | list | None) -> tuple[dict, str, str]:
    """(parsed data, source for messages, config name for the manifest) of a config file, of several merged in
    order (a list: ``config.read_layered_data``; named "a+b"), or of the default."""
    if config is None:
        source = f"<embedded default {study.default_config}>"
        data = parse_text(embedded_default_text(study.default_config), source, ".toml")
        return data, source, f"embedded:{Path(study.default_config).stem}"
    if isinstance(config, (list, tuple)):
        if len(config) > 1:
            return (read_layered_data(list(config)), " + ".join(str(c) for c in config),
                    "+".join(Path(c).stem for c in config))
        config = config[0]
    return read_config_data(config), str(config), Path(config).stem


def _leaves(data: Any, where: str = "") -> list[str]:
    """The dotted keys of a parsed config's values (a table's keys recursively; a list or number is a leaf)."""
    if not isinstance(data, dict):
        return [where] if where else []
    return [k for key, v in data.items() for k in _leaves(v, f"{where}.{key}" if where else str(key))]


def origins(study, config: str | Path | list | None = None, overrides: list[str] | None = None,
            updates: dict | None = None, flags_text: str = "") -> dict[str, str]:
    """Where each value a command sets comes from (``--print-config``, issue 56 item 1): each dotted key the
    embedded default (no config given), each config file (the later over the earlier), the command line's
    overrides and a study flag name, with the last that set it. A key none of them names is the field's default."""
    if config is None:
        layers = [(f"embedded default {study.default_config}", base_data(study, None)[0])]
    else:
        paths = list(config) if isinstance(config, (list, tuple)) else [config]
        layers = [(str(p), read_config_data(p)) for p in paths]
    out: dict[str, str] = {}
    for source, data in layers:
        out.update({k: source for k in _leaves(data or {})})
    out.update({k: "the command line" for k, _ in parse_overrides(list(overrides or []))})
    out.update({k: flags_text or "a flag" for k in (updates or {})})
    return out


def first_config(config: str | Path | list | None):
    """The config file whose folder relative paths of the command line are taken from: the first of several."""
    return config[0] if isinstance(config, (list, tuple)) else config


def _format(v: Any) -> str:
    return str(v).replace(" ", "") if not isinstance(v, str) else v


def variants(study, config: str | Path | None = None, overrides: list[str] | dict | None = None,
             updates: dict | None = None, multirun: bool = False, flags_text: str = "") -> list[Variant]:
    """Validated configs for a study: the base config with ``overrides`` ("a.b=1,2" strings or a dict
    {"a.b": value}) applied, and ``updates`` (a study flag's config update) on top. ``flags_text``: the flags
    that made ``updates`` as the user typed them ("--robot arm.urdf"): errors and run labels name them first.

    A comma list in an override value is several values: with ``multirun`` every combination is a
    config of its own (cartesian product, in the order given); without it, that is an error.
    """
    data, source, name = base_data(study, config)
    if isinstance(overrides, dict):
        pairs = [(k, [v]) for k, v in overrides.items()]
    else:
        pairs = parse_overrides(list(overrides or []))
    several = [k for k, vs in pairs if len(vs) > 1]
    if several and not multirun:
        raise ConfigError("<command line>", f"{several[0]} lists several values; add --multirun to run each "
                                            f"combination, or give one value")
    n = 1
    for _, vs in pairs:
        n *= len(vs)
    if n > MAX_VARIANTS:
        raise ConfigError("<command line>", f"--multirun would make {n:,} runs (at most {MAX_VARIANTS:,})")
    if flags_text and config is None:  # the flag replaces the embedded default's subject (--robot NAME|FILE):
        source, name = flags_text, flags_text.replace(" ", "=")  # errors and labels name what the user gave
    elif flags_text:
        source, name = f"{flags_text} (on {source})", f"{name}+{flags_text.replace(' ', '=')}"
    if pairs:
        source = f"{source} with the command-line overrides"
    out = []
    for values in itertools.product(*[vs for _, vs in pairs]):
        d = data
        varied = {}
        for (key, _), v in zip(pairs, values):
            d = with_override(d, key, v)
            varied[key] = v
        for key, v in (updates or {}).items():
            d = with_override(d, key, v)
        cfg = validate_for(study, d, source, first_config(config))
        suffix = "".join(f"+{k}={_format(v)}" for k, v in varied.items())
        out.append(Variant(cfg, name + suffix, varied))
    return out


def context_for(config) -> dict:
    """Validation context: paths in a config file are relative to its folder (the embedded default's
    and the command line's: to the working directory)."""
    return {"config_dir": str(Path(config).resolve().parent) if config else str(Path.cwd())}


def validate_for(study, data: Any, source: str, config=None):
    """Validate for this study; when the data is another study's config, say which command it is for."""
    try:
        return validate(data, study.config_model, source, context_for(config))
    except ConfigError:
        from surgopt.studies import STUDIES, get_study

        for other in STUDIES:
            if other == study.name:
                continue
            try:
                validate(data, get_study(other).config_model, source, context_for(config))
            except ConfigError:
                continue
            if data:  # an empty file fits every study
                raise ConfigError(source, f"this is a {other} config, not a {study.name} one: run "
                                          f"`surgopt {other}{' ' + str(config) if config else ''}`") from None
        raise
