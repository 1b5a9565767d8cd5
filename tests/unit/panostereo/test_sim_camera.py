"""The simulated camera reaches the sensor node by kind: its builder is an entry point, not an import."""

from __future__ import annotations

from pathlib import Path

import pytest

from common.errors import ConfigError
from panostereo.sim_camera import build_simulated
from sensor_node import build
from sensor_node.config import load_node_config

EXAMPLES = Path(__file__).resolve().parents[3] / "deploy" / "nodes" / "examples"


def test_the_sim_kind_is_found_by_its_entry_point(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delitem(build.SOURCES, "sim", raising=False)
    assert build.source_builder("sim") is build_simulated
    parts = build.build_node(load_node_config(EXAMPLES / "sim.toml"), lambda: 10**18)
    assert parts.kind == "panoramic" and parts.camera_height_m > 0.0


def test_a_kind_nobody_provides_is_a_config_error() -> None:
    with pytest.raises(ConfigError, match=r"kind 'nope': no builder registered"):
        build.source_builder("nope")
