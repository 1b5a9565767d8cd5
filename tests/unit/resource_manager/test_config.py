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


def test_a_zone_floor_needs_its_zone_and_a_simple_polygon(tmp_path: Path) -> None:
    p = tmp_path / "m.toml"
    p.write_text('[manager]\nid = "m1"\nzone_polygon = [[0, 0], [5, 0], [5, 5]]\n')
    with pytest.raises(ConfigError, match=r"manager\.zone_polygon is set but manager\.zone is not"):
        load_manager_config(p)
    p.write_text('[manager]\nid = "m1"\nzone = "w"\nzone_polygon = [[0, 0], [5, 5], [5, 0], [0, 5]]\n')
    with pytest.raises(ConfigError, match=r"manager.zone_polygon.polygon is not simple"):
        load_manager_config(p)
    p.write_text('[manager]\nid = "m1"\nzone = "w"\nzone_polygon = [[0, 0], [5, 0], [5, 5]]\nzone_band_m = 0.5\n')
    assert load_manager_config(p).manager.zone_band_m == 0.5


def test_config_is_frozen() -> None:
    cfg = load_manager_config(REPO / "deploy/nodes/examples/manager.toml")
    with pytest.raises(AttributeError):
        cfg.manager.id = "x"  # type: ignore[misc]
    assert msgspec.structs.replace(cfg.manager, rate_hz=5.0).rate_hz == 5.0


def test_a_zone_manager_of_a_site_with_zones_fuses_the_cameras_that_see_into_it(tmp_path: Path) -> None:
    from common.site import load_site
    from resource_manager.config import for_site

    for sid in ("c0", "c1"):
        (tmp_path / f"{sid}.toml").write_text(f'[node]\nid = "{sid}"\n')
    zone = '[[zones]]\nname = "{n}"\npolygon = [[{x0}, 0], [{x1}, 0], [{x1}, 10], [{x0}, 10]]\nreach_m = 2.0\n'
    (tmp_path / "site.toml").write_text(
        '[site]\nname = "hall"\n'
        '[[camera]]\nid = "c0"\nx_m = 2.0\ny_m = 5.0\n[[camera]]\nid = "c1"\nx_m = 18.0\ny_m = 5.0\n'
        '[[process]]\nname = "c0"\ncommand = "node"\nconfig = "c0.toml"\n'
        '[[process]]\nname = "c1"\ncommand = "node"\nconfig = "c1.toml"\n'
        + zone.format(n="west", x0=0, x1=10)
        + zone.format(n="east", x0=10, x1=20)
    )
    site = load_site(tmp_path / "site.toml")
    (tmp_path / "m.toml").write_text('[manager]\nid = "m1"\n')
    cfg = load_manager_config(tmp_path / "m.toml")
    assert for_site(cfg, site).manager.sensors == ["c0", "c1"]  # no zone: the whole site
    assert for_site(cfg, site).manager.zone_polygon == []  # and publishes every track
    east = msgspec.structs.replace(cfg, manager=msgspec.structs.replace(cfg.manager, zone="east"))
    assert for_site(east, site).manager.sensors == ["c1"]
    # ...and owns the zone's floor, with the site's band
    assert for_site(east, site).manager.zone_polygon == [[10, 0], [20, 0], [20, 10], [10, 10]]
    assert for_site(east, site).manager.zone_band_m == 1.0
    north = msgspec.structs.replace(cfg, manager=msgspec.structs.replace(cfg.manager, zone="north"))
    with pytest.raises(ConfigError, match=r"no zone 'north' \(zones: west, east\)"):
        for_site(north, site)
