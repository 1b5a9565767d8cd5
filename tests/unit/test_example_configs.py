"""The annotated example configs in deploy/nodes/examples/ name every key a user can set.

A key added to a config struct without a line (set or commented out) in an example is a key nobody can find.
"""

from __future__ import annotations

import re
import tomllib
import typing
from pathlib import Path

import msgspec
import pytest

from resource_manager.config import ManagerConfig
from sensor_node.config import NodeConfig
from user_agent.config import AgentConfig

EXAMPLES = Path(__file__).resolve().parents[2] / "deploy" / "nodes" / "examples"
INTERNAL = {"path"}
"""Fields filled in by the loader, never written in a file."""


def _struct_keys(tp: type, prefix: str = "") -> set[str]:
    out: set[str] = set()
    for f in msgspec.structs.fields(tp):
        key = prefix + f.encode_name
        if not prefix and f.encode_name in INTERNAL:
            continue
        out.add(key)
        inner = [f.type, *typing.get_args(f.type)]
        for arg in [a for t in inner for a in (t, *typing.get_args(t))]:
            if isinstance(arg, type) and issubclass(arg, msgspec.Struct):
                out |= _struct_keys(arg, key + ".")
    return out


def _documented_keys(paths: list[Path]) -> set[str]:
    """Keys set in the files, and keys shown commented out (``# key = value``) under their table."""
    out: set[str] = set()

    def walk(value: object, prefix: str) -> None:
        items = value if isinstance(value, list) else [value]
        for item in items:
            if isinstance(item, dict):
                for k, v in item.items():
                    out.add(prefix + k)
                    walk(v, prefix + k + ".")

    for path in paths:
        text = path.read_text()
        walk(tomllib.loads(text), "")
        table = ""
        for line in text.splitlines():
            head = re.match(r"^#?\s*\[\[?([\w.]+)\]?\]", line)
            if head:
                out.add(head.group(1))
                table = head.group(1) + "."
                continue
            commented = re.match(r"^#\s*(\w+)\s*=", line)
            if commented:
                out.add(table + commented.group(1))
    return out


@pytest.mark.parametrize(
    ("config", "examples"),
    [
        (ManagerConfig, ["manager.toml"]),
        (NodeConfig, ["sim.toml", "opencv.toml", "folder.toml", "ptz.toml", "detections.toml", "static.toml"]),
    ],
    ids=["manager", "node"],
)
def test_every_key_is_in_an_example(config: type, examples: list[str]) -> None:
    documented = _documented_keys([EXAMPLES / e for e in examples]) | _documented_keys([EXAMPLES / "manager.toml"])
    missing = sorted(_struct_keys(config) - documented)
    assert not missing, f"keys of {config.__name__} in no example under deploy/nodes/examples: {missing}"


def test_agent_keys_are_documented() -> None:
    # Agents are configured by flags or a small TOML; its keys live in the README's agent section.
    readme = (EXAMPLES.parents[2] / "README.md").read_text()
    missing = sorted(
        k
        for k in _struct_keys(AgentConfig)
        if k.split(".")[0] not in {"zenoh", "clock"} and k.split(".")[-1] not in readme
    )
    assert not missing, f"AgentConfig keys the README never mentions: {missing}"
