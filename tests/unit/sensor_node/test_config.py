"""Node config: the example files load; errors name the file, key, expected and given value."""

from __future__ import annotations

from pathlib import Path

import pytest

from common.errors import ConfigError
from sensor_node.config import (
    EPOCH_ENV,
    DetectionsSource,
    SimSource,
    epoch_from,
    load_node_config,
    source_kind,
)
from tests.support import REPO

EXAMPLES = [REPO / "deploy/nodes/examples" / f"{n}.toml" for n in ("sim", "opencv", "folder", "detections", "ptz")]


def test_every_source_kind_has_an_example() -> None:
    kinds = {source_kind(load_node_config(p).source) for p in EXAMPLES}
    assert kinds == {"sim", "opencv", "folder", "detections"}


def test_sim_example_names_a_bundled_site_found_wherever_the_config_is() -> None:
    from common.site import site_file

    cfg = load_node_config(REPO / "deploy/nodes/examples/sim.toml")
    assert isinstance(cfg.source, SimSource)
    assert site_file(cfg.source.site, cfg.path).resolve() == (REPO / "deploy/sites/demo.toml").resolve()
    assert cfg.node.mobile and cfg.body[0].id == "pano2"


def _write(tmp_path: Path, text: str) -> Path:
    p = tmp_path / "node.toml"
    p.write_text(text)
    return p


@pytest.mark.parametrize(
    ("text", "needle"),
    [
        ('[node]\nid = "a"\n[source]\nkind = "sim"\nsite = "s.toml"\nbogus = 1\n', "source.bogus"),
        ('[node]\nid = "A b"\n[source]\nkind = "sim"\nsite = "s.toml"\n', "node.id"),
        ('[node]\nid = "a"\n[source]\nkind = "webcam"\n', "webcam"),
        ('[node]\nid = "a"\n[source]\nkind = "opencv"\nuri = "0"\n', "[camera]"),
        ('[node]\nid = "a"\n[source]\nkind = "sim"\nsite = "s"\n[pipeline]\nfg_threshold = 0\n', "fg_threshold"),
        ('[node]\nid = "a"\n[source]\nkind = "sim"\nsite = "s"\n[pipeline]\nhist_bins = [32, 32]\n', "hist_bins"),
        ('[node]\nid = "a"\n[source]\nkind = "detections"\nfile = "d"\n', "calibration"),
    ],
)
def test_bad_configs_name_file_and_key(tmp_path: Path, text: str, needle: str) -> None:
    p = _write(tmp_path, text)
    with pytest.raises(ConfigError) as info:
        load_node_config(p)
    assert str(p) in str(info.value) and needle in str(info.value)


def test_epoch_from_config_env_or_fallback(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    monkeypatch.delenv(EPOCH_ENV, raising=False)
    assert epoch_from(0, 42) == 42
    monkeypatch.setenv(EPOCH_ENV, "1000")
    assert epoch_from(0, 42) == 1000
    assert epoch_from(7, 42) == 7
    monkeypatch.setenv(EPOCH_ENV, "soon")
    with pytest.raises(ConfigError, match=EPOCH_ENV):
        epoch_from(0, 42)
    p = _write(tmp_path, '[node]\nid = "c1"\n[source]\nkind = "detections"\nfile = "d.txt"\ncalibration = "c.json"\n')
    src = load_node_config(p).source
    assert isinstance(src, DetectionsSource) and src.fps == 2.0
