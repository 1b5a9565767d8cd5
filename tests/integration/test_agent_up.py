"""``panostereo up``: starts a site's processes, restarts a killed one, stops everything cleanly on SIGTERM.

The site runs its own router (``--router``) and two user agents recording
MCAP (the lightest real processes of the project).
"""

from __future__ import annotations

import os
import signal
import sys
from pathlib import Path

import pytest

from common.keys import Keys
from tests.support import client_session, free_port, wait_for, wait_for_liveliness
from user_agent.recording import read_metadata

pytestmark = pytest.mark.integration


def _pids_with(arg: str) -> list[int]:
    out = []
    for d in Path("/proc").iterdir():
        if d.name.isdigit():
            try:
                cmd = (d / "cmdline").read_bytes().split(b"\0")
                state = (d / "stat").read_text().split()[2]
            except OSError:
                continue
            if any(arg.encode() in part for part in cmd) and state != "Z":
                out.append(int(d.name))
    return out


def test_up_restarts_a_killed_process_and_stops_all(spawn, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    port = free_port()
    endpoint = f"tcp/127.0.0.1:{port}"
    for name in ("rec-a", "rec-b"):
        (tmp_path / f"{name}.toml").write_text(
            f'[agent]\nid = "{name}"\nprefix = "pano"\n[zenoh]\nconnect = ["{endpoint}"]\n'
        )
    (tmp_path / "site.toml").write_text(
        f'[site]\nname = "uptest"\nrouter = "{endpoint}"\n'
        + "".join(
            f'[[process]]\nname = "{n}"\ncommand = "agent"\nconfig = "{n}.toml"\n'
            f'args = ["record", "{tmp_path / n}.mcap"]\n'
            for n in ("rec-a", "rec-b")
        )
    )
    up = spawn(
        [
            sys.executable,
            "-m",
            "panostereo",
            "up",
            str(tmp_path / "site.toml"),
            "--router",
            "--grace",
            "3",
            "--log-dir",
            str(tmp_path / "logs"),
        ],
        name="up",
    )
    keys = Keys()
    with client_session(endpoint, connect_timeout_ms=20_000) as s:
        wait_for_liveliness(s, keys.agent("rec-a"), timeout_s=30)
        wait_for_liveliness(s, keys.agent("rec-b"), timeout_s=30)
        (victim,) = _pids_with(str(tmp_path / "rec-a.toml"))
        os.kill(victim, signal.SIGKILL)
        # Restarted (after a back-off of 0.5 s) as a new process that announces itself again.
        wait_for(lambda: [p for p in _pids_with(str(tmp_path / "rec-a.toml")) if p != victim], 30, "rec-a restarted")
        wait_for_liveliness(s, keys.agent("rec-a"), timeout_s=30)
    children = _pids_with(str(tmp_path / "rec-")) + _pids_with(f"127.0.0.1:{port}")
    assert len(set(children)) >= 3  # two agents and the router
    up.signal(signal.SIGTERM)
    assert up.wait(20) == 0, up.log()
    wait_for(lambda: not set(children) & set(_pids_with("")), 10, "no orphans")
    assert "restart in 0.5 s" in (tmp_path / "logs" / "rec-a.log").read_text() + up.stderr_text()
    # The surviving recorder was stopped by SIGTERM, so it finished its file.
    assert read_metadata(tmp_path / "rec-b.mcap")["prefix"] == "pano"
