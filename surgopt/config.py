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
    """Base for config sections: unknown keys are errors, values are not coerced silently."""

    model_config = ConfigDict(extra="forbid", strict=True, frozen=True)


def _parse_text(text: str, source: str, suffix: str) -> Any:
    if suffix == ".toml":
        try:
            return tomllib.loads(text)
        except tomllib.TOMLDecodeError as exc:
            raise ConfigError(source, f"not valid TOML: {exc}") from None
    if suffix in (".yaml", ".yml"):
        import yaml

        try:
            return yaml.safe_load(text)
        except yaml.YAMLError as exc:
            msg = " ".join(str(exc).split())
            raise ConfigError(source, f"not valid YAML: {msg}") from None
    raise ConfigError(source, "unknown config format (use .toml, .yaml or .yml)")


def _field_path(loc: tuple) -> str:
    out = ""
    for part in loc:
        out += f"[{part}]" if isinstance(part, int) else (f".{part}" if out else str(part))
    return out or "(top level)"


def validate(data: Any, model: type[M], source: str) -> M:
    """Validate parsed data; the first error becomes one ConfigError naming the field."""
    if not isinstance(data, dict):
        raise ConfigError(source, "expected a table of settings at the top level")
    try:
        return model.model_validate(data)
    except ValidationError as exc:
        err = exc.errors()[0]
        field = _field_path(err["loc"])
        msg = err["msg"]
        if err["type"] == "extra_forbidden":
            msg = "unknown key"
        elif "input" in err and err["type"] not in ("missing",):
            msg = f"{msg} (got {err['input']!r})"
        more = len(exc.errors()) - 1
        if more:
            msg += f" (and {more} more error{'s' if more > 1 else ''})"
        raise ConfigError(source, msg, field) from None


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
