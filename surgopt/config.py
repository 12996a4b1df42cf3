"""Config loading: TOML or YAML -> validated pydantic model; canonical form for hashing.

Precedence: command-line flag > config file > embedded default. Every field
name carries its unit (``_m``, ``_deg``, ``_rad_s`` ...); angles in configs
are degrees, kernels work in radians.
"""
from __future__ import annotations

import hashlib
import json
import tomllib
from importlib import resources
from pathlib import Path
from typing import Any, TypeVar

from pydantic import BaseModel, ConfigDict, ValidationError

from surgopt.errors import ConfigError

M = TypeVar("M", bound=BaseModel)


class StrictModel(BaseModel):
    """Base for config sections: unknown keys are errors, values are not coerced silently, and every
    float is finite (NaN and infinity are refused wherever a number is expected)."""

    model_config = ConfigDict(extra="forbid", strict=True, frozen=True, allow_inf_nan=False)


#: Longest value quoted back in an error message (a huge list is cut, not printed whole).
MAX_QUOTED_CHARS = 120
#: How many validation errors one message lists.
MAX_ERRORS_LISTED = 5


def _quote(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= MAX_QUOTED_CHARS else text[:MAX_QUOTED_CHARS] + f"... ({len(text):,} characters)"


def _yaml_loader():
    """yaml.SafeLoader that refuses duplicate keys (plain PyYAML keeps the last one silently)."""
    import yaml

    class StrictLoader(yaml.SafeLoader):
        pass

    def mapping(loader, node, deep=False):
        seen = set()
        for key_node, _ in node.value:
            key = loader.construct_object(key_node, deep=deep)
            if key in seen:
                raise yaml.constructor.ConstructorError(
                    None, None, f"duplicate key {key!r}", key_node.start_mark)
            seen.add(key)
        return loader.construct_mapping(node, deep=deep)

    StrictLoader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG, mapping)
    return StrictLoader


def _parse_text(text: str, source: str, suffix: str) -> Any:
    """TOML or YAML text -> data. An empty file (or one with comments only) is an empty table in both."""
    if suffix == ".toml":
        try:
            return tomllib.loads(text)
        except tomllib.TOMLDecodeError as exc:
            raise ConfigError(source, f"not valid TOML: {exc}") from None
    if suffix in (".yaml", ".yml"):
        import yaml

        try:
            data = yaml.load(text, Loader=_yaml_loader())  # noqa: S506 - a SafeLoader subclass
        except yaml.YAMLError as exc:
            msg = " ".join(str(exc).split())
            raise ConfigError(source, f"not valid YAML: {msg}") from None
        return {} if data is None else data
    raise ConfigError(source, "unknown config format (use .toml, .yaml or .yml)")


def _field_path(loc: tuple) -> str:
    out = ""
    for part in loc:
        out += f"[{part}]" if isinstance(part, int) else (f".{part}" if out else str(part))
    return out or "(top level)"


def _error_text(err: dict) -> str:
    msg = err["msg"].removeprefix("Value error, ")
    if err["type"] == "extra_forbidden":
        return "unknown key"
    if err["type"] == "finite_number":
        return f"must be a finite number (got {_quote(err.get('input'))})"
    if "input" in err and err["type"] not in ("missing",) and not isinstance(err["input"], dict):
        return f"{msg} (got {_quote(err['input'])})"
    return msg


def _loc(err: dict) -> tuple:
    """The error's location without the union-form tags of a discriminated field ('<span>', '<list>')."""
    return tuple(p for p in err["loc"] if not (isinstance(p, str) and p.startswith("<")))


def validate(data: Any, model: type[M], source: str) -> M:
    """Validate parsed data; errors become one ConfigError naming the file and each field (up to
    MAX_ERRORS_LISTED of them, in one line)."""
    if not isinstance(data, dict):
        raise ConfigError(source, "expected a table of settings at the top level")
    try:
        return model.model_validate(data)
    except ValidationError as exc:
        errors = exc.errors()
        first = errors[0]
        msg = _error_text(first)
        others = [f"{_field_path(_loc(e))}: {_error_text(e)}" for e in errors[1:MAX_ERRORS_LISTED]]
        if others:
            msg += "; also " + "; ".join(others)
        if len(errors) > MAX_ERRORS_LISTED:
            msg += f" (and {len(errors) - MAX_ERRORS_LISTED} more)"
        raise ConfigError(source, msg, _field_path(_loc(first))) from None


def load_config(path: str | Path, model: type[M]) -> M:
    """Read and validate a TOML or YAML config file."""
    p = Path(path)
    source = str(path)
    try:
        text = p.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ConfigError(source, "file not found") from None
    except IsADirectoryError:
        raise ConfigError(source, "is a directory, not a config file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(source, f"cannot read: {exc}") from None
    return validate(_parse_text(text, source, p.suffix.lower()), model, source)


def embedded_default_text(filename: str) -> str:
    """Text of a default config shipped inside the package (surgopt/defaults)."""
    return resources.files("surgopt.defaults").joinpath(filename).read_text(encoding="utf-8")


def load_embedded(filename: str, model: type[M]) -> M:
    source = f"<embedded default {filename}>"
    return validate(_parse_text(embedded_default_text(filename), source, ".toml"), model, source)


def canonical_json(model: BaseModel) -> str:
    """Canonical form of a validated config: defaults filled, keys sorted, compact."""
    return json.dumps(model.model_dump(mode="json"), sort_keys=True, separators=(",", ":"))


def study_key(study: str, model: BaseModel, kernel_version: str) -> str:
    """Store key: sha256 of study name + kernel version + canonical config."""
    h = hashlib.sha256()
    h.update(f"{study}\n{kernel_version}\n".encode())
    h.update(canonical_json(model).encode())
    return h.hexdigest()
