"""The manager's config: the example loads, bad configs are refused naming the key, the result is frozen."""

from __future__ import annotations

from pathlib import Path

import msgspec
import pytest

from common.errors import ConfigError
from resource_manager.config import load_manager_config
from tests.support import REPO


def test_example_config_loads() -> None:
    cfg = load_manager_config(REPO / "deploy/nodes/examples/manager.toml")
    assert cfg.manager.id == "mgr1" and cfg.manager.matcher == "greedy" and cfg.keys.root == "pano/@v1"
    assert Path(cfg.manager.state_dir).is_absolute()


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ('[manager]\nid = "m1"\nmatcher = "best"\n', "matcher"),
        ('[manager]\nid = "M 1"\n', "manager.id"),
        ('[manager]\nid = "m1"\nbogus = 1\n', "unknown key 'manager.bogus'"),
        ('[manager]\nid = "m1"\n[planner]\nroom = [0, 0, -1, 5]\n', "planner.room"),
        (
            '[manager]\nid = "m1"\n' + '[[pose]]\nid = "a"\nx_m = 0\ny_m = 0\nz_m = 1\n' * 2,
            "unique",
        ),
        ("[zenoh]\n", "missing required key 'manager'"),
        ('[manager]\nid = "m1"\nrate_hz = 0\n', "rate_hz"),
        ('[manager]\nid = "m1"\nzone = "Hall A"\n', r"manager.zone must match \[a-z0-9\]"),
    ],
)
def test_bad_configs(tmp_path: Path, text: str, message: str) -> None:
    p = tmp_path / "m.toml"
    p.write_text(text)
    with pytest.raises(ConfigError, match=message):
        load_manager_config(p)


def test_a_zone_is_optional(tmp_path: Path) -> None:
    p = tmp_path / "m.toml"
    p.write_text('[manager]\nid = "m1"\n')
    assert load_manager_config(p).manager.zone == ""  # no election: the manager always publishes
    p.write_text('[manager]\nid = "m1"\nzone = "hall-2"\n')
    assert load_manager_config(p).manager.zone == "hall-2"


def test_config_is_frozen() -> None:
    cfg = load_manager_config(REPO / "deploy/nodes/examples/manager.toml")
    with pytest.raises(AttributeError):
        cfg.manager.id = "x"  # type: ignore[misc]
    assert msgspec.structs.replace(cfg.manager, rate_hz=5.0).rate_hz == 5.0
