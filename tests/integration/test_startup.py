"""The first hour: a site that cannot start says why at once, ``up --listen`` moves every process of the site,
and ``agent sensors`` shows a running site's sensors with their status, its tracks and its managers.

Real processes on loopback, on free ports, with readiness waits: a demo whose manager refuses its config, a demo
with a node for a camera the world does not have, and a small detection-file site run by ``up``.
"""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import pytest

from common.keys import Keys
from tests.support import REPO, client_session, free_port, start_router, wait_for, wait_for_liveliness
from tests.unit.panostereo.mot_synth import CAMERAS, write_dataset

pytestmark = pytest.mark.integration

DEMO = REPO / "deploy" / "sites" / "demo.toml"
NODES = REPO / "deploy" / "nodes" / "demo"
READY_TIMEOUT_S = 900
"""Far longer than the test's own timeout: a demo that waited for it instead of stopping at once fails the test."""


def _site_with(tmp_path: Path, replace: dict[str, str]) -> Path:
    """The demo site with its process configs at absolute paths, some of them swapped for files in ``tmp_path``."""
    text = DEMO.read_text()
    for name in ("pano1", "pano2", "pano3", "ptz1", "manager"):
        text = text.replace(
            f'config = "../nodes/demo/{name}.toml"', f'config = "{replace.get(name, NODES / f"{name}.toml")}"'
        )
    site = tmp_path / "site.toml"
    site.write_text(text)
    return site


def _demo(site: Path, out: Path, *net: str) -> subprocess.CompletedProcess[str]:
    """The demo on a router of its own on a free port, or with ``net`` (``--connect EP``) joining one."""
    net = net or ("--listen", f"tcp/127.0.0.1:{free_port()}")
    return subprocess.run(
        [sys.executable, "-m", "panostereo", "demo", "--site", str(site), "--duration", "20", "--out", str(out),
         *net, "--no-view", "--ready-timeout", str(READY_TIMEOUT_S)],
        capture_output=True, text=True, timeout=180, check=False, cwd=REPO,
    )  # fmt: skip


def test_demo_stops_at_once_when_the_manager_refuses_its_config(tmp_path: Path) -> None:
    broken = tmp_path / "manager.toml"
    broken.write_text((NODES / "manager.toml").read_text().replace("rate_hz = 10.0", "rate_hx = 10.0"))
    proc = _demo(_site_with(tmp_path, {"manager": str(broken)}), tmp_path / "run")
    assert proc.returncode == 1, proc.stdout[-3000:] + proc.stderr[-3000:]
    assert re.search(r"ERROR: manager exited with code 1 while the site was starting: .*rate_hx", proc.stdout)
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert list(summary["failed_to_start"]) == ["manager"]
    why = summary["failed_to_start"]["manager"]
    assert "unknown key 'manager.rate_hx'" in why["reason"] and why["exit_code"] == 1 and why["log_tail"]
    assert "mota" not in summary  # nothing was run, nothing is scored


def test_demo_says_which_node_has_a_camera_the_world_does_not(tmp_path: Path) -> None:
    """...on a router that already runs (``demo --connect``): every process of the site joins it."""
    ghost = tmp_path / "ghost.toml"
    text = (NODES / "pano3.toml").read_text().replace('id = "pano3"', 'id = "ghost"')
    ghost.write_text(text.replace('camera = "pano3"', 'camera = "ghost"').replace("../../sites/demo.toml", str(DEMO)))
    router = start_router(log_dir=tmp_path / "router")
    try:
        proc = _demo(_site_with(tmp_path, {"pano3": str(ghost)}), tmp_path / "run", "--connect", router.endpoint)
    finally:
        router.stop()
    assert proc.returncode == 1, proc.stdout[-3000:] + proc.stderr[-3000:]
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert "no camera 'ghost'" in summary["failed_to_start"]["pano3"]["reason"]
    assert summary["cameras"]["site"] == 4 and summary["cameras"]["publishing"] == 0
    assert not (tmp_path / "run" / "logs" / "router.log").exists()  # it started no router of its own


@pytest.fixture
def dataset_site(tmp_path: Path) -> Path:
    """A small detection-file site (three cameras, three people, 60 s at 5 fps) whose configs name port 7447."""
    write_dataset(tmp_path / "data", frames=300, fps=5.0)
    for path in (tmp_path / "data" / "detections").glob("*.txt"):  # no boxes clipped to nothing at the image edge
        rows = [r for r in path.read_text().splitlines() if min(float(v) for v in r.split(",")[4:6]) >= 1.0]
        path.write_text("\n".join(rows) + "\n")
    subprocess.run(
        [sys.executable, "-m", "panostereo", "import", "mot", str(tmp_path / "data"), "--out", str(tmp_path / "site"),
         "--fps", "5"],
        check=True, capture_output=True, cwd=REPO,
    )  # fmt: skip
    return tmp_path / "site" / "site.toml"


def test_up_listen_moves_every_process_and_agent_sensors_shows_the_running_site(
    spawn,  # type: ignore[no-untyped-def]
    dataset_site: Path,
    tmp_path: Path,
) -> None:
    port = free_port()
    endpoint = f"tcp/127.0.0.1:{port}"
    up = spawn(
        [sys.executable, "-m", "panostereo", "up", str(dataset_site), "--router", "--listen", endpoint,
         "--log-dir", str(tmp_path / "logs"), "--grace", "3"],
        name="up",
    )  # fmt: skip
    keys = Keys()
    with client_session(endpoint, connect_timeout_ms=30_000) as s:
        for cid in CAMERAS:  # every node joined the router on the port given, not the site's 7447
            wait_for_liveliness(s, keys.sensor(cid), timeout_s=60)
        wait_for_liveliness(s, keys.manager("mgr1"), timeout_s=60)
    agent = [sys.executable, "-m", "panostereo", "agent", "sensors", "--connect", endpoint]

    def listed() -> list[dict]:
        out = subprocess.run([*agent, "--json"], capture_output=True, text=True, timeout=60, check=True, cwd=REPO)
        rows = json.loads(out.stdout)
        return rows if all(r["status"] is not None and r["status"]["frames"] > 0 for r in rows) else []

    rows = wait_for(listed, 60, "every sensor's status through `agent sensors --json`", poll_s=0.5)
    assert sorted(r["sensor_id"] for r in rows) == sorted(CAMERAS)
    assert all(r["alive"] and r["info"] is not None for r in rows)

    def screen() -> str:
        out = subprocess.run(agent, capture_output=True, text=True, timeout=60, check=True, cwd=REPO).stdout
        return out if re.search(r"TRACKS \([1-9]", out) else ""

    text = wait_for(screen, 60, "tracks in `agent sensors`", poll_s=0.5)
    assert "SENSORS (3 up of 3)" in text and "mgr1" in text.split("MANAGERS", 1)[1], text
    # A track nobody knows is said so, with the live ones, and the command fails.
    history = [sys.executable, "-m", "panostereo", "agent", "history", "mgr1-999", "--connect", endpoint]
    out = subprocess.run(history, capture_output=True, text=True, timeout=60, check=False, cwd=REPO)
    assert out.returncode == 1 and "no manager knows track 'mgr1-999'" in out.stderr and "mgr1-" in out.stderr
    # The live view shows the same: every sensor's fps and frames, the tracks, the manager.
    watch = [sys.executable, "-m", "panostereo", "agent", "watch", "--once", "--connect", endpoint]
    screen_once = subprocess.run(watch, capture_output=True, text=True, timeout=60, check=True, cwd=REPO).stdout
    assert "SENSORS (3 up of 3)" in screen_once and "mgr1" in screen_once.split("MANAGERS", 1)[1], screen_once
    rows = [ln.split() for ln in screen_once.split("SENSORS", 1)[1].split("MANAGERS", 1)[0].splitlines()]
    assert all(r[4] != "-" for r in rows if r and r[0] in CAMERAS), screen_once  # the fps column
    up.stop(10)
