"""A user agent's TOML config (for agents started by a site's ``[[process]]``)::

[agent]
id = "agent1"
prefix = "pano"

[zenoh]
connect = ["tcp/127.0.0.1:7447"]
"""

from __future__ import annotations

from pathlib import Path

import msgspec

from common.config import ConfigStruct, load_config
from common.keys import DEFAULT_PREFIX, Keys, validate_id
from common.session import SessionSettings

__all__ = ["AgentConfig", "AgentSection", "load_agent_config"]


class AgentSection(ConfigStruct, frozen=True):
    id: str = "agent"
    prefix: str = DEFAULT_PREFIX


class AgentConfig(ConfigStruct, frozen=True):
    agent: AgentSection = msgspec.field(default_factory=AgentSection)
    zenoh: SessionSettings = msgspec.field(default_factory=SessionSettings)


def load_agent_config(path: str | Path) -> AgentConfig:
    """Read and validate an agent config.

    Raises:
        ConfigError: naming the file and key.
    """
    cfg = load_config(path, AgentConfig)
    validate_id(cfg.agent.id, f"{path}: agent.id")
    Keys(cfg.agent.prefix)
    return cfg
