"""Config files: every error names the file, the key, what was expected and what was given."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Literal

import msgspec
import pytest

from common.clock import ClockSettings
from common.config import ConfigStruct, load_config, parse_config, resolve_path
from common.errors import ConfigError, PanoError
from common.session import SessionSettings


class Camera(ConfigStruct, frozen=True):
    radius_m: Annotated[float, msgspec.Meta(gt=0.0)] = 0.2
    kind: Literal["panoramic", "ptz"] = "panoramic"


class Node(ConfigStruct, frozen=True):
    id: str
    fps: float = 15.0
    camera: Camera = Camera()
    bodies: list[Camera] = []
    xy_m: Annotated[list[float], msgspec.Meta(min_length=2, max_length=2)] = msgspec.field(
        default_factory=lambda: [0.0, 0.0]
    )
    pose: Camera | None = None
    zenoh: SessionSettings = SessionSettings()
    clock: ClockSettings = ClockSettings()


GOOD = """
id = "pano1"
fps = 10
xy_m = [1.5, 2.0]

[camera]
radius_m = 0.25
kind = "ptz"

[[bodies]]
radius_m = 0.3

[zenoh]
connect = ["tcp/10.0.0.1:7447"]

[clock]
ntp_server = "ntp.local"
"""


def write(tmp_path: Path, text: str, name: str = "node.toml") -> Path:
    p = tmp_path / name
    p.write_text(text)
    return p


def test_good_file_loads_typed(tmp_path: Path) -> None:
    cfg = load_config(write(tmp_path, GOOD), Node)
    assert cfg.id == "pano1"
    assert cfg.fps == 10.0 and isinstance(cfg.fps, float)
    assert cfg.camera == Camera(radius_m=0.25, kind="ptz")
    assert cfg.bodies == [Camera(radius_m=0.3)]
    assert cfg.xy_m == [1.5, 2.0]
    assert cfg.zenoh.connect == ["tcp/10.0.0.1:7447"]
    assert cfg.zenoh.mode == "client" and cfg.zenoh.multicast_scouting is False
    assert cfg.clock.ntp_server == "ntp.local"
    with pytest.raises(AttributeError):
        cfg.fps = 3.0  # type: ignore[misc]


@pytest.mark.parametrize(
    ("toml", "message"),
    [
        # wrong value: file, key, expected, got
        (
            'id = "a"\n[camera]\nradius_m = -0.2',
            "node.toml: camera.radius_m: expected a number > 0.0, got -0.2 (float)",
        ),
        ('id = "a"\nfps = "fast"', "node.toml: fps: expected a number, got 'fast' (string)"),
        ("id = 3", "node.toml: id: expected a string, got 3 (integer)"),
        (
            'id = "a"\n[[bodies]]\n[[bodies]]\nkind = "fisheye"',
            "node.toml: bodies[1].kind: expected one of 'panoramic', 'ptz', got 'fisheye' (string)",
        ),
        (
            'id = "a"\n[zenoh]\nmode = "relay"',
            "node.toml: zenoh.mode: expected one of 'client', 'peer', 'router', got 'relay' (string)",
        ),
        (
            'id = "a"\n[clock]\nsamples = 0',
            "node.toml: clock.samples: expected an integer >= 1 and <= 64, got 0 (integer)",
        ),
        (
            'id = "a"\nxy_m = [1.0]',
            "node.toml: xy_m: expected a list of exactly 2 items, each a number, got [1.0] (array)",
        ),
        ('id = "a"\nxy_m = [1.0, "b"]', "node.toml: xy_m[1]: expected a number, got 'b' (string)"),
        ('id = "a"\ncamera = 5', "node.toml: camera: expected a table, got 5 (integer)"),
        ('id = "a"\n[pose]\nradius_m = 0', "node.toml: pose.radius_m: expected a number > 0.0, got 0 (integer)"),
        (
            'id = "a"\n[zenoh]\nconnect = "tcp/x:1"',
            "node.toml: zenoh.connect: expected a list, each a string, got 'tcp/x:1' (string)",
        ),
        # unknown keys, at any depth, with what is known
        ('id = "a"\ncolour = 1', "node.toml: unknown key 'colour' (known keys: id, fps, camera,"),
        ('id = "a"\n[camera]\ncolour = 1', "node.toml: unknown key 'camera.colour' (known keys: radius_m, kind)"),
        ('id = "a"\n[zenoh]\nconect = []', "node.toml: unknown key 'zenoh.conect' (known keys: mode, connect,"),
        (
            'id = "a"\n[[bodies]]\nradius = 1.0',
            "node.toml: unknown key 'bodies[0].radius' (known keys: radius_m, kind)",
        ),
        # missing required
        ("fps = 1.0", "node.toml: missing required key 'id'"),
    ],
)
def test_errors_name_file_key_expected_and_given(tmp_path: Path, toml: str, message: str) -> None:
    path = write(tmp_path, toml)
    with pytest.raises(ConfigError) as info:
        load_config(path, Node)
    text = str(info.value)
    assert text.startswith(str(path)), text
    assert message.replace("node.toml", str(path)) in text, text
    assert isinstance(info.value, PanoError)
    assert info.value.__cause__ is not None  # chained from the msgspec error


def test_missing_file(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match=r"missing\.toml: no such config file"):
        load_config(tmp_path / "missing.toml", Node)


def test_directory_is_not_a_file(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="cannot read config file"):
        load_config(tmp_path, Node)


@pytest.mark.parametrize(
    ("text", "where"),
    [('id = "a"\nfps = 1.2.3', "line 2"), ('[camera\nid = "a"', "line 1"), ('id = "a"\nfps = what', "line 2")],
)
def test_bad_toml_names_file_and_line(tmp_path: Path, text: str, where: str) -> None:
    path = write(tmp_path, text)
    with pytest.raises(ConfigError) as info:
        load_config(path, Node)
    assert str(info.value).startswith(f"{path}: invalid TOML")
    assert where in str(info.value)


def test_not_utf8(tmp_path: Path) -> None:
    path = tmp_path / "node.toml"
    path.write_bytes(b'id = "\xff\xfe"')
    with pytest.raises(ConfigError, match="not a UTF-8 text file"):
        load_config(path, Node)


def test_parse_config_uses_the_given_source_name() -> None:
    with pytest.raises(ConfigError, match=r"^site\.toml \[process pano1\]: fps: expected a number"):
        parse_config({"id": "a", "fps": "x"}, Node, "site.toml [process pano1]")


def test_resolve_path_is_relative_to_the_config_file(tmp_path: Path) -> None:
    cfg = tmp_path / "deploy" / "nodes" / "pano1.toml"
    assert (
        resolve_path(cfg, "../calib/pano1.json").resolve() == (tmp_path / "deploy" / "calib" / "pano1.json").resolve()
    )
    assert resolve_path(cfg, "calib.json") == (tmp_path / "deploy" / "nodes").resolve() / "calib.json"
    assert resolve_path(cfg, "/abs/x.json") == Path("/abs/x.json")
    assert resolve_path(cfg, "~/x.json") == Path.home() / "x.json"
