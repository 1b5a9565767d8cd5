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
from pathlib import Path
from typing import Any, TypeVar

import msgspec

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


def parse_config(raw: dict[str, Any], config_type: type[T], source: str) -> T:
    """Convert already-parsed TOML data to ``config_type``.

    Raises:
        ConfigError: ``"{source}: {key}: {expected}, got {value!r}"``.
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
            raise ConfigError(f"{source}: unknown key {where!r}") from err
        key = _dotted(path) or "(top level)"
        given = _given(raw, path)
        tail = "" if given is None else f", got {given!r}"
        if msg.startswith("Object missing required field"):
            field = msg.split("`")[1]
            key = _dotted(f"{path}.{field}") if path else field
            raise ConfigError(f"{source}: missing required key {key!r}") from err
        raise ConfigError(f"{source}: {key}: {msg[0].lower() + msg[1:]}{tail}") from err


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
