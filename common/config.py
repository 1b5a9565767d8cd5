"""TOML config files -> typed, validated config objects.

One TOML file per process. Each tier declares its config as frozen msgspec
Structs with ``forbid_unknown_fields=True`` and loads it with
:func:`load_config`; any unknown key or bad value becomes one
:class:`~common.errors.ConfigError` that names the file, the key, what was
expected and what was given.
"""

from __future__ import annotations

import re
import tomllib
from collections.abc import Callable
from pathlib import Path
from typing import Any, TypeVar

import msgspec
import msgspec.inspect as mi

from common.errors import ConfigError

__all__ = ["ConfigStruct", "load_config", "parse_config", "resolve_path"]

T = TypeVar("T")

_AT_RE = re.compile(r"^(?P<msg>.*?) - at `\$(?P<path>[^`]*)`$")
_UNKNOWN_RE = re.compile(r"^Object contains unknown field `(?P<field>[^`]+)`$")


class ConfigStruct(msgspec.Struct, frozen=True, kw_only=True, forbid_unknown_fields=True):
    """Base of config tables: frozen, keyword-only, unknown keys are errors."""


def _dotted(path: str) -> str:
    """``.camera.pose[0]`` -> ``camera.pose[0]``."""
    return path.lstrip(".")


def _given(raw: Any, path: str) -> Any:
    """Look up the value at a msgspec error path in the raw TOML data, for the message."""
    cur = raw
    for tok in re.findall(r"\.([^.\[]+)|\[(\d+)\]", path):
        key, idx = tok
        try:
            cur = cur[key] if key else cur[int(idx)]
        except (KeyError, IndexError, TypeError):
            return None
    return cur


def _type_at(config_type: Any, path: str) -> Any:
    """The ``msgspec.inspect`` type at an error path like ``.camera.pose[0]``, or None."""
    info: Any = mi.type_info(config_type)
    for tok in re.findall(r"\.([^.\[]+)|\[(\d+)\]", path):
        key, _ = tok
        while isinstance(info, mi.UnionType):  # `X | None`: describe X
            options = [t for t in info.types if not isinstance(t, mi.NoneType)]
            info = options[0] if options else None
        if key and isinstance(info, mi.StructType):
            info = next((f.type for f in info.fields if f.encode_name == key), None)
        elif key and isinstance(info, mi.DictType):
            info = info.value_type
        elif not key and isinstance(info, (mi.ListType, mi.SetType, mi.FrozenSetType, mi.VarTupleType)):
            info = info.item_type
        elif not key and isinstance(info, mi.TupleType):
            info = None
        else:
            return None
    return info


def _bounds(info: Any) -> str:
    parts = []
    for attr, op in (("ge", ">="), ("gt", ">"), ("le", "<="), ("lt", "<")):
        value = getattr(info, attr, None)
        if value is not None:
            parts.append(f"{op} {value}")
    return " and ".join(parts)


def _number(kind: str, info: Any) -> str:
    b = _bounds(info)
    return f"{kind} {b}" if b else kind


def _expected_union(info: Any) -> str | None:
    options = [_expected(t) for t in info.types]
    return " or ".join(o for o in options if o) or None


def _expected_str(info: Any) -> str:
    extra = []
    if info.min_length:
        extra.append(f"at least {info.min_length} characters")
    if info.max_length is not None:
        extra.append(f"at most {info.max_length} characters")
    if info.pattern:
        extra.append(f"matching {info.pattern}")
    return "a string" + (" (" + ", ".join(extra) + ")" if extra else "")


def _expected_list(info: Any) -> str:
    n = []
    if info.min_length is not None and info.min_length == info.max_length:
        n.append(f"exactly {info.min_length}")
    else:
        if info.min_length is not None:
            n.append(f"at least {info.min_length}")
        if info.max_length is not None:
            n.append(f"at most {info.max_length}")
    inner = _expected(info.item_type)
    return "a list" + (f" of {' and '.join(n)} items" if n else "") + (f", each {inner}" if inner else "")


_DESCRIPTIONS: tuple[tuple[type | tuple[type, ...], Callable[[Any], str | None]], ...] = (
    (mi.UnionType, _expected_union),
    (mi.LiteralType, lambda info: "one of " + ", ".join(repr(v) for v in info.values)),
    (mi.FloatType, lambda info: _number("a number", info)),
    (mi.IntType, lambda info: _number("an integer", info)),
    (mi.BoolType, lambda _: "true or false"),
    (mi.StrType, _expected_str),
    ((mi.ListType, mi.VarTupleType, mi.SetType, mi.FrozenSetType), _expected_list),
    (mi.TupleType, lambda info: f"a list of {len(info.item_types)} items"),
    (mi.NoneType, lambda _: None),
    ((mi.StructType, mi.DictType), lambda _: "a table"),
)
"""What each kind of config value must be, in plain words (the first kind that matches describes it)."""


def _expected(info: Any) -> str | None:
    """Plain-words description of what a config value must be."""
    for kinds, describe in _DESCRIPTIONS:
        if isinstance(info, kinds):
            return describe(info)
    return None


def _toml_type(value: Any) -> str:
    if isinstance(value, bool):
        return "boolean"
    if isinstance(value, dict):
        return "table"
    if isinstance(value, list):
        return "array"
    return {int: "integer", float: "float", str: "string"}.get(type(value), type(value).__name__)


def parse_config(raw: dict[str, Any], config_type: type[T], source: str) -> T:
    """Convert already-parsed TOML data to ``config_type``.

    Raises:
        ConfigError: ``"{source}: {key}: expected {what}, got {value!r} ({toml type})"``;
            ``"{source}: unknown key {key!r} (known keys: ...)"``; ``"{source}: missing required key {key!r}"``.
    """
    try:
        return msgspec.convert(raw, config_type, strict=True)
    except msgspec.ValidationError as err:
        text = str(err)
        m = _AT_RE.match(text)
        msg, path = (m.group("msg"), m.group("path")) if m else (text, "")
        unknown = _UNKNOWN_RE.match(msg)
        if unknown:
            where = _dotted(path + "." + unknown.group("field")) if path else unknown.group("field")
            table = _type_at(config_type, path)
            known = ""
            if isinstance(table, mi.StructType):
                known = " (known keys: " + ", ".join(f.encode_name for f in table.fields) + ")"
            raise ConfigError(f"{source}: unknown key {where!r}{known}") from err
        if msg.startswith("Object missing required field"):
            field = msg.split("`")[1]
            key = _dotted(f"{path}.{field}") if path else field
            raise ConfigError(f"{source}: missing required key {key!r}") from err
        key = _dotted(path) or "(top level)"
        given = _given(raw, path)
        expected = _expected(_type_at(config_type, path)) if path else None
        got = "" if given is None else f", got {given!r} ({_toml_type(given)})"
        if expected:
            raise ConfigError(f"{source}: {key}: expected {expected}{got}") from err
        raise ConfigError(f"{source}: {key}: {msg[0].lower() + msg[1:]}{got}") from err


def load_config(path: str | Path, config_type: type[T]) -> T:
    """Read a TOML file and validate it as ``config_type``.

    Raises:
        ConfigError: file missing or unreadable, TOML syntax error, unknown key,
            missing key, wrong type or out-of-range value.
    """
    p = Path(path)
    try:
        data = p.read_bytes()
    except FileNotFoundError as err:
        raise ConfigError(f"{p}: no such config file") from err
    except OSError as err:
        raise ConfigError(f"{p}: cannot read config file: {err.strerror}") from err
    try:
        raw = tomllib.loads(data.decode("utf-8"))
    except UnicodeDecodeError as err:
        raise ConfigError(f"{p}: not a UTF-8 text file") from err
    except tomllib.TOMLDecodeError as err:
        raise ConfigError(f"{p}: invalid TOML: {err}") from err
    return parse_config(raw, config_type, str(p))


def resolve_path(base_file: str | Path, value: str) -> Path:
    """Resolve a path written in a config file relative to that file's folder."""
    v = Path(value).expanduser()
    return v if v.is_absolute() else (Path(base_file).resolve().parent / v)
