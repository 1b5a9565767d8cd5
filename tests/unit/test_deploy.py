"""deploy/: every site's processes have a config their tier accepts; zenoh and systemd files are usable."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from common.site import load_site
from panostereo.cli import COMMANDS
from panostereo.launcher import process_ids
from tests.support import REPO

SITES = sorted((REPO / "deploy" / "sites").glob("*.toml"))


@pytest.mark.parametrize("site_path", SITES, ids=[p.stem for p in SITES])
def test_every_process_config_loads_and_matches_the_site(site_path: Path) -> None:
    from resource_manager.config import load_manager_config
    from sensor_node.config import load_node_config
    from user_agent.config import load_agent_config

    site = load_site(site_path)
    assert site.process, f"{site_path.name} has no [[process]]"
    loaders = {"node": load_node_config, "manager": load_manager_config, "agent": load_agent_config}
    for proc in site.process:
        loaders[proc.command](site.resolve(proc.config))
    ids = process_ids(site)
    nodes = {i for c, i in ids.values() if c == "node"}
    assert nodes == {c.id for c in site.camera}, "one node per simulated camera, named like it"
    for cam in site.camera:
        cfg = load_node_config(site.resolve(next(p.config for p in site.process if ids[p.name][1] == cam.id)))
        assert cfg.node.mobile == (cam.mobile and cam.kind == "panoramic")
        if cam.pose == "surveyed":
            assert cfg.pose is not None and (cfg.pose.x_m, cfg.pose.y_m) == (cam.x_m, cam.y_m)
        else:
            assert cfg.pose is None  # mobile robots learn their pose by mutual calibration


@pytest.mark.parametrize("name", ["router.json5", "client.json5"])
def test_zenoh_configs_parse(name: str) -> None:
    import zenoh

    zenoh.Config.from_file(str(REPO / "deploy" / "zenoh" / name))


@pytest.mark.parametrize("unit", sorted((REPO / "deploy" / "systemd").glob("*.service")), ids=lambda p: p.name)
def test_systemd_units_run_real_subcommands(unit: Path) -> None:
    text = unit.read_text()
    (cmd,) = re.findall(r"^ExecStart=\S+/panostereo (\w+)", text, flags=re.M)
    assert cmd in COMMANDS
    assert "Restart=always" in text and "KillSignal=SIGTERM" in text


def test_a_zone_manager_prints_its_zones_cameras(capsys: pytest.CaptureFixture[str]) -> None:
    """``manager --print-sensors`` (for make_configs.py --managers ID=CAMS): the cameras that see into the zone."""
    from common.site import zone_sensor_ids
    from resource_manager.cli import main

    hall = REPO / "deploy" / "sites" / "hall.toml"
    config = REPO / "deploy" / "nodes" / "hall" / "mgr-se.toml"
    assert main(["--config", str(config), "--site", str(hall), "--zone", "se", "--print-sensors"]) == 0
    printed = capsys.readouterr().out.split()
    assert printed == zone_sensor_ids(load_site(hall), "se") and "w" not in printed, printed
