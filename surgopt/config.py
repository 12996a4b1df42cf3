"""Config loading: TOML or YAML -> validated pydantic model; canonical form for hashing.

Precedence: command-line flag > config file > embedded default. Every field
name carries its unit (``_m``, ``_deg``, ``_rad_s`` ...); angles in configs
are degrees, kernels work in radians.

One module (~480 lines): reading, composing, validating and hashing a config are one contract that every study
and the store key depend on; its parts call one another (a file's hash enters the key the validation computed).
"""
from __future__ import annotations

import hashlib
import json
import re
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
#: What a config may be before it is validated: its file's size, how deep tables and lists nest, and how
#: many values it holds once YAML aliases are expanded (the largest shipped config: depth 4, ~300 values).
MAX_CONFIG_BYTES = 8 * 2 ** 20
MAX_CONFIG_DEPTH = 32
MAX_CONFIG_VALUES = 1_000_000


#: The physical bound of a config value by the unit its name ends in (every field name carries its unit):
#: no surgical robot, workspace or task reaches past these, so a value beyond is a typo, not a design.
#: The longest suffix that matches applies. Lengths 10 m, angles ten turns, speeds of a fast industrial arm
#: (1,000 rad/s, 100 m/s), times a million seconds.
UNIT_BOUNDS = {"_mm": 1e4, "_m": 10.0, "_deg": 3600.0, "_rad": 20 * 3.141592653589793,
               "_rad_s": 1e3, "_rad_per_s": 1e3, "_m_s": 100.0, "_m_per_s": 100.0, "_mm_s": 1e5,
               "_per_s": 1e6, "_s": 1e6, "_hz": 1e6}


def unit_bound(name: str) -> tuple[str, float] | None:
    """(unit suffix, bound) of a field name, or None for a name without a unit."""
    matches = [u for u in UNIT_BOUNDS if name.endswith(u)]
    if not matches:
        return None
    unit = max(matches, key=len)
    return unit, UNIT_BOUNDS[unit]


def check_physical_bounds(data: Any, source: str, path: str = "", bound: tuple[str, float] | None = None) -> None:
    """ConfigError naming the field if any number under a field with a unit is beyond that unit's
    UNIT_BOUNDS (a value nested in a list or a {start, stop, step} span takes its field's unit)."""
    if isinstance(data, dict):
        for k, v in data.items():
            sub = f"{path}.{k}" if path else str(k)
            check_physical_bounds(v, source, sub, unit_bound(str(k)) or bound)
    elif isinstance(data, (list, tuple)):
        for i, v in enumerate(data):
            check_physical_bounds(v, source, f"{path}[{i}]", bound)
    elif bound is not None and isinstance(data, (int, float)) and not isinstance(data, bool):
        unit, limit = bound
        if abs(data) > limit:
            raise ConfigError(source, f"{_quote(data)} is beyond what any surgical robot set-up has "
                                      f"(|value| <= {limit:g} for a field in {unit.lstrip('_')})", path)


def check_config_size(data: Any, source: str) -> None:
    """ConfigError if ``data`` nests deeper than MAX_CONFIG_DEPTH or holds more than MAX_CONFIG_VALUES values
    counting every alias expansion (a YAML alias bomb): an iterative walk that stops at the first excess."""
    stack, count = [(data, 0)], 0
    while stack:
        v, depth = stack.pop()
        count += 1
        if count > MAX_CONFIG_VALUES:
            raise ConfigError(source, f"holds more than {MAX_CONFIG_VALUES:,} values (with YAML aliases expanded); "
                                      f"no study's config is that large")
        if depth > MAX_CONFIG_DEPTH:
            raise ConfigError(source, f"nests deeper than {MAX_CONFIG_DEPTH} levels; no study's config does")
        if isinstance(v, dict):
            stack.extend((x, depth + 1) for x in v.values())
        elif isinstance(v, (list, tuple)):
            stack.extend((x, depth + 1) for x in v)


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
            try:
                hash(key)
            except TypeError:  # a list or a mapping as a key ("? [a, b]"): no config field is named so
                raise yaml.constructor.ConstructorError(
                    None, None, f"a key must be a name, not a {type(key).__name__}", key_node.start_mark)
            if key in seen:
                raise yaml.constructor.ConstructorError(
                    None, None, f"duplicate key {key!r}", key_node.start_mark)
            seen.add(key)
        return loader.construct_mapping(node, deep=deep)

    StrictLoader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG, mapping)
    return StrictLoader


def parse_text(text: str, source: str, suffix: str) -> Any:
    """TOML or YAML text -> data. An empty file (or one with comments only) is an empty table in both."""
    if suffix == ".toml":
        try:
            return tomllib.loads(text)
        except tomllib.TOMLDecodeError as exc:
            raise ConfigError(source, f"not valid TOML: {exc}") from None
        except RecursionError:
            raise ConfigError(source, f"nests deeper than {MAX_CONFIG_DEPTH} levels; no study's config does") from None
    if suffix in (".yaml", ".yml"):
        import yaml

        try:
            data = yaml.load(text, Loader=_yaml_loader())  # noqa: S506 - a SafeLoader subclass
        except yaml.YAMLError as exc:
            msg = " ".join(str(exc).split())
            raise ConfigError(source, f"not valid YAML: {msg}") from None
        except RecursionError:
            raise ConfigError(source, f"nests deeper than {MAX_CONFIG_DEPTH} levels; no study's config does") from None
        return {} if data is None else data
    raise ConfigError(source, "unknown config format (use .toml, .yaml or .yml)")


def _field_path(loc: tuple) -> str:
    out = ""
    for part in loc:
        out += f"[{part}]" if isinstance(part, int) else (f".{part}" if out else str(part))
    return out or "(top level)"


def _fields_at(model: type[BaseModel], loc: tuple) -> list[str]:
    """The field names of the (sub)model at ``loc`` (list indices and dict keys passed over)."""
    import typing

    def submodels(annotation):
        if isinstance(annotation, type) and issubclass(annotation, BaseModel):
            return [annotation]
        return [m for a in typing.get_args(annotation) for m in submodels(a)]

    current = [model]
    for part in loc:
        if isinstance(part, int):
            continue
        nxt = []
        for m in current:
            f = m.model_fields.get(part)
            if f is not None:
                nxt += submodels(f.annotation)
        current = nxt or current
    return sorted({name for m in current for name in m.model_fields})


def _error_text(err: dict, model: type[BaseModel] | None = None) -> str:
    msg = err["msg"].removeprefix("Value error, ")
    if err["type"] == "extra_forbidden":
        import difflib

        loc = _loc(err)
        near = difflib.get_close_matches(str(loc[-1]), _fields_at(model, loc[:-1]), n=1) if model else []
        return f"unknown key (did you mean {near[0]!r}?)" if near else "unknown key"
    if err["type"] == "finite_number":
        return f"must be a finite number (got {_quote(err.get('input'))})"
    if "input" in err and err["type"] not in ("missing",) and not isinstance(err["input"], dict):
        return f"{msg} (got {_quote(err['input'])})"
    return msg


def _loc(err: dict) -> tuple:
    """The error's location without the union-form tags of a discriminated field ('<span>', '<list>') or of a
    plain union's members ('constrained-float', "literal['off']", 'float')."""
    return tuple(p for p in err["loc"] if not _union_tag(p))


def _union_tag(part) -> bool:
    return isinstance(part, str) and (part.startswith(("<", "constrained-", "function-")) or "[" in part
                                      or part in ("float", "int", "str", "bool"))


def _one_per_field(errors: list[dict]) -> list[dict]:
    """A field's errors from each member of a union (``float | Literal['off']``: "should be >= -25", "should be
    'off'") as one: "Input should be greater than or equal to -25, or be 'off'"."""
    out, at = [], {}
    for e in errors:
        loc = _loc(e)
        if loc in at and len(loc) < len(e["loc"]):
            first = out[at[loc]]
            out[at[loc]] = {**first, "msg": f"{first['msg']}, or {e['msg'].removeprefix('Input should ')}"}
        else:
            at[loc] = len(out)
            out.append(e)
    return out


def validate(data: Any, model: type[M], source: str, context: dict | None = None) -> M:
    """Validate parsed data; errors become one ConfigError naming the file and each field (up to
    MAX_ERRORS_LISTED of them, in one line). ``context`` reaches the models' validators:
    ``config_dir`` (paths in the config are relative to it), ``stored`` (a stored run's config: files
    it names are not read again)."""
    if not isinstance(data, dict):
        raise ConfigError(source, "expected a table of settings at the top level")
    check_config_size(data, source)
    check_physical_bounds(data, source)
    try:
        return model.model_validate(data, context=context)
    except ValidationError as exc:
        errors = _one_per_field(exc.errors())
        first = errors[0]
        msg = _error_text(first, model)
        others = [f"{_field_path(_loc(e))}: {_error_text(e, model)}" for e in errors[1:MAX_ERRORS_LISTED]]
        if others:
            msg += "; also " + "; ".join(others)
        if len(errors) > MAX_ERRORS_LISTED:
            msg += f" (and {len(errors) - MAX_ERRORS_LISTED} more)"
        field = _field_path(_loc(first))
        if not _loc(first) and re.match(r"[A-Za-z_][\w.\[\]]*: ", msg):  # a whole-config check naming its field
            field = None
        raise ConfigError(source, msg, field) from None


def read_config_data(path: str | Path) -> Any:
    """The parsed (not yet validated) contents of a TOML or YAML config file."""
    from surgopt.files import FileProblem, note_read, read_bounded

    p = Path(path)
    source = str(path)
    try:
        text = note_read(p, read_bounded(p, MAX_CONFIG_BYTES)).decode("utf-8")
    except FileNotFoundError:
        raise ConfigError(source, "file not found") from None
    except IsADirectoryError:
        raise ConfigError(source, "is a directory, not a config file") from None
    except FileProblem as exc:
        raise ConfigError(source, str(exc).split(": ", 1)[-1]) from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(source, f"cannot read: {exc}") from None
    return parse_text(text, source, p.suffix.lower())


def with_files_from(data: Any, folder: Path) -> Any:
    """``data`` with every relative path under a file field (``files.FILE_FIELDS``) taken from ``folder``: a
    layer's files stay its own when layers from several folders are merged."""
    from surgopt.files import FILE_FIELDS

    if isinstance(data, dict):
        return {k: (str((folder / v).resolve()) if k in FILE_FIELDS and isinstance(v, str)
                    and not Path(v).expanduser().is_absolute() else with_files_from(v, folder))
                for k, v in data.items()}
    if isinstance(data, list):
        return [with_files_from(v, folder) for v in data]
    return data


def merged(base: Any, layer: Any, source: str, where: str = "") -> Any:
    """``layer`` over ``base``: tables merged key by key, recursively; any other value (a list, a number, a
    table over a value) replaces what was there, as Hydra composes config groups."""
    if not isinstance(layer, dict):
        raise ConfigError(source, f"{where or 'the file'}: a layered config is a table of sections, not "
                                  f"{type(layer).__name__}")
    out = dict(base) if isinstance(base, dict) else {}
    for k, v in layer.items():
        out[k] = merged(out.get(k), v, source, f"{where}.{k}" if where else k) if isinstance(v, dict) \
            and isinstance(out.get(k), dict) else v
    return out


def read_layered_data(paths: list) -> Any:
    """Several config files merged in order, the later over the earlier (``merged``), each one's file fields
    taken from its own folder (``with_files_from``)."""
    data: Any = {}
    for path in paths:
        layer = read_config_data(path)
        if layer is None:
            continue
        if not isinstance(layer, dict):
            raise ConfigError(str(path), f"a layered config is a table of sections, not {type(layer).__name__}")
        data = merged(data, with_files_from(layer, Path(path).resolve().parent), str(path))
    return data


def load_config(path: str | Path, model: type[M]) -> M:
    """Read and validate a TOML or YAML config file."""
    return validate(read_config_data(path), model, str(path), {"config_dir": str(Path(path).resolve().parent)})


# ---------------------------------------------------------------------------
# command-line overrides: key.path=value (Hydra style)
# ---------------------------------------------------------------------------


def _split_top_level(text: str) -> list[str]:
    """Split at commas outside brackets and quotes: "0.5,[1, 2]" -> ["0.5", "[1, 2]"]."""
    out, depth, quote, cur = [], 0, None, ""
    for ch in text:
        if quote:
            quote = None if ch == quote else quote
        elif ch in "\"'":
            quote = ch
        elif ch in "[{":
            depth += 1
        elif ch in "]}":
            depth -= 1
        elif ch == "," and depth == 0:
            out.append(cur)
            cur = ""
            continue
        cur += ch
    out.append(cur)
    return out


def parse_value(text: str) -> Any:
    """One override value: a TOML value (0.55, 9, true, "x", [1, 2], {start = 0, stop = 1, step = 1}),
    or else the bare text as a string (elbow=down)."""
    try:
        return tomllib.loads(f"v = {text}")["v"]
    except tomllib.TOMLDecodeError:
        return text
    except RecursionError:
        raise ConfigError("<command line>", f"a value nests deeper than {MAX_CONFIG_DEPTH} levels") from None


def parse_overrides(items: list[str]) -> list[tuple[str, list[Any]]]:
    """["a.b=1,2", "c=x"] -> [("a.b", [1, 2]), ("c", ["x"])]: each key with its value(s)."""
    out = []
    for item in items:
        key, sep, raw = item.partition("=")
        key = key.strip()
        if not sep or not key or any(not part.isidentifier() for part in key.split(".")):
            raise ConfigError("<command line>", f"{item!r} is not KEY=VALUE with a dotted key "
                                                f"(e.g. robot.tool_length_m=0.55)")
        values = [parse_value(v.strip()) for v in _split_top_level(raw)]
        earlier = next((v for k, v in out if k == key), None)
        if earlier is not None:  # the last would silently win
            raise ConfigError("<command line>", f"{key} is given twice ({_quote_values(earlier)} and "
                                                f"{_quote_values(values)}); give it once (several values: "
                                                f"{key}=a,b with --multirun)")
        out.append((key, values))
    return out


def _quote_values(values: list[Any]) -> str:
    return ",".join(_quote(v) for v in values)


def with_override(data: dict, key: str, value: Any) -> dict:
    """A copy of ``data`` with the dotted ``key`` set to ``value`` (tables created on the way)."""
    import copy

    data = copy.deepcopy(data)
    d = data
    parts = key.split(".")
    for p in parts[:-1]:
        if not isinstance(d.get(p, {}), dict):
            raise ConfigError("<command line>", f"{key}: {p} is a value, not a table", key)
        d = d.setdefault(p, {})
    d[parts[-1]] = value
    return data


# ---------------------------------------------------------------------------
# writing a config back as TOML (--print-config)
# ---------------------------------------------------------------------------


def _toml_value(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, float)):
        return repr(v)
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{k} = {_toml_value(x)}" for k, x in v.items()) + "}"
    raise TypeError(f"cannot write {type(v).__name__} as TOML")


def to_toml(data: dict, _prefix: str = "") -> str:
    """TOML text of nested dicts: a table's values first, then one [table] per nested dict (spans
    inline). Values that are None (an unset optional) are left out. ``tomllib.loads`` reads it back."""
    lines, tables = [], []
    for k, v in data.items():
        if v is None:
            continue
        if isinstance(v, dict) and not _is_inline(v):
            tables.append((k, v))
        else:
            lines.append(f"{k} = {_toml_value(v)}")
    out = "".join(line + "\n" for line in lines)
    for k, v in tables:
        out += f"\n[{_prefix}{k}]\n" + to_toml(v, f"{_prefix}{k}.")
    return out


def _is_inline(v: dict) -> bool:
    """A sweep span {start, stop, step} reads better inline."""
    return set(v) == {"start", "stop", "step"}


def embedded_default_text(filename: str) -> str:
    """Text of a default config shipped inside the package (surgopt/defaults)."""
    return resources.files("surgopt.defaults").joinpath(filename).read_text(encoding="utf-8")


def load_embedded(filename: str, model: type[M]) -> M:
    source = f"<embedded default {filename}>"
    return validate(parse_text(embedded_default_text(filename), source, ".toml"), model, source)


def _unsigned_zeros(v):
    """``v`` with every -0.0 written 0.0: the two are the same value in every computation a config feeds."""
    if isinstance(v, float) and v == 0.0:
        return 0.0
    if isinstance(v, dict):
        return {k: _unsigned_zeros(x) for k, x in v.items()}
    if isinstance(v, list):
        return [_unsigned_zeros(x) for x in v]
    return v


#: json_schema_extra of a field the store key leaves out: a file's path, whose content hash is in the key beside
#: it (a copied or moved file with the same content is the same run).
NOT_IN_KEY = {"key": False}


def canonical_json(model: BaseModel) -> str:
    """Canonical form of a validated config: defaults filled, keys sorted, compact, -0.0 as 0.0, and the fields
    marked NOT_IN_KEY left out."""
    return json.dumps(_unsigned_zeros(_keyed(model, model.model_dump(mode="json"))), sort_keys=True,
                      separators=(",", ":"))


def _keyed(model, data):
    """``data`` (the model's JSON dump) without the fields marked NOT_IN_KEY, at any depth."""
    if isinstance(model, BaseModel) and isinstance(data, dict):
        out = {}
        for name, value in data.items():
            info = type(model).model_fields.get(name)
            if info is not None and info.json_schema_extra == NOT_IN_KEY:
                continue
            out[name] = _keyed(getattr(model, name, None), value)
        return out
    if isinstance(model, (list, tuple)) and isinstance(data, list):
        return [_keyed(m, d) for m, d in zip(model, data)]
    return data


def study_key(study: str, model: BaseModel, kernel_version: str) -> str:
    """Store key: sha256 of study name + kernel version + the row code's sha256 (``surgopt.code_identity``:
    an edited kernel, model or study is a new key) + canonical config."""
    from surgopt.code_identity import code_sha256

    h = hashlib.sha256()
    h.update(f"{study}\n{kernel_version}\n{code_sha256()}\n".encode())
    h.update(canonical_json(model).encode())
    return h.hexdigest()
