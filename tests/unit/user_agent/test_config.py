"""The agent's config: defaults, and bad ids, prefixes and keys refused naming the file and key."""

from __future__ import annotations

from pathlib import Path

import pytest

from common.errors import ConfigError
from user_agent.config import load_agent_config


def _write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "agent.toml"
    path.write_text(text, encoding="utf-8")
    return path


def test_an_agent_config_loads_with_defaults(tmp_path: Path) -> None:
    cfg = load_agent_config(_write(tmp_path, '[agent]\nid = "ua-1"\n[zenoh]\nconnect = ["tcp/127.0.0.1:7447"]\n'))
    assert (cfg.agent.id, cfg.agent.prefix) == ("ua-1", "pano")
    assert cfg.zenoh.connect == ["tcp/127.0.0.1:7447"]
    assert load_agent_config(_write(tmp_path, "")).agent.id == "agent"


@pytest.mark.parametrize(
    ("text", "key"),
    [
        ('[agent]\nid = "ua 1"\n', "agent.id"),
        ('[agent]\nid = "ua/1"\n', "agent.id"),
        ('[agent]\nprefix = "a/*"\n', "a/*"),
        ('[agent]\nname = "x"\n', "agent.name"),
        ("[agent]\nid = 3\n", "agent.id"),
    ],
)
def test_a_bad_agent_config_is_refused_naming_the_key(tmp_path: Path, text: str, key: str) -> None:
    with pytest.raises(ConfigError) as caught:
        load_agent_config(_write(tmp_path, text))
    assert key in str(caught.value)
