"""A router plus two client processes (sensor, manager) exchange typed messages on the documented keys.

Checked: liveliness presence both ways, Features through the router, a queryable (SensorInfo), a command
(PtzCommand) and its answer (PtzState), departure seen through liveliness, and clean exit on SIGTERM.
"""

from __future__ import annotations

import json
import signal
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from common.codec import decode
from common.keys import Keys
from common.schema import SensorInfo
from tests.support import (
    ManagedProcess,
    RouterProcess,
    client_session,
    wait_for,
    wait_for_liveliness,
    wait_for_no_liveliness,
)

pytestmark = pytest.mark.integration

PEER = str(Path(__file__).resolve().parent / "peer.py")


def events(proc: ManagedProcess) -> list[dict[str, Any]]:
    return [json.loads(line) for line in proc.stdout_text().splitlines() if line.startswith("{")]


def find_event(proc: ManagedProcess, name: str, **fields: Any) -> dict[str, Any] | None:
    for ev in events(proc):
        if ev["event"] == name and all(ev.get(k) == v for k, v in fields.items()):
            return ev
    return None


def has_event(proc: ManagedProcess, name: str, **fields: Any) -> dict[str, Any] | None:
    """The first matching event; fails at once if the process died (it would never come)."""
    if not proc.alive:
        raise AssertionError(f"{proc.name} died:\n{proc.log()}")
    return find_event(proc, name, **fields)


def test_two_clients_exchange_typed_messages(
    router: RouterProcess, spawn: Callable[..., ManagedProcess], request: pytest.FixtureRequest
) -> None:
    prefix = f"t{abs(hash(request.node.nodeid)) % 10**8}"  # its own prefix: the session router is shared
    keys = Keys(prefix)
    common_args = ["--connect", router.endpoint, "--prefix", prefix]
    manager = spawn([sys.executable, PEER, "manager", "--id", "mgr1", *common_args], name="manager")
    sensor = spawn([sys.executable, PEER, "sensor", "--id", "cam1", *common_args], name="sensor")

    with client_session(router.endpoint) as s:
        # Presence: both tokens visible to a third party.
        wait_for_liveliness(s, keys.sensor("cam1"), 15.0)
        wait_for_liveliness(s, keys.manager("mgr1"), 15.0)
        # The queryable answers anyone with a typed SensorInfo.
        replies = list(s.get(keys.sensor_info("cam1"), timeout=5.0))
        assert len(replies) == 1 and replies[0].ok is not None
        info = decode(replies[0].ok.payload.to_bytes(), SensorInfo)
        assert (info.sensor_id, info.model.width_px) == ("cam1", 1080)
        assert str(replies[0].ok.encoding).startswith("application/msgpack")

        # The manager saw the sensor arrive, queried it, got its features, commanded it, and got the state back.
        wait_for(lambda: has_event(manager, "sensor_alive", id="cam1"), 15.0, "manager to see the sensor's token")
        ev = wait_for(lambda: has_event(manager, "info", id="cam1"), 10.0, "manager's SensorInfo query to succeed")
        assert ev["width_px"] == 1080 and ev["key"] == keys.sensor_info("cam1")
        ev = wait_for(lambda: has_event(manager, "features", id="cam1"), 10.0, "Features to reach the manager")
        assert ev["key"] == keys.sensor_features("cam1")
        wait_for(lambda: has_event(sensor, "command", pan_rad=0.5), 10.0, "the PtzCommand to reach the sensor")
        ev = wait_for(lambda: has_event(manager, "ptz_state", id="cam1"), 10.0, "PtzState to reach the manager")
        assert ev["pan_rad"] == 0.5

        # Departure: the sensor stops cleanly; its token vanishes for everyone.
        sensor.signal(signal.SIGTERM)
        assert sensor.wait(10.0) == 0, sensor.log()
        assert find_event(sensor, "stopped")
        wait_for_no_liveliness(s, keys.sensor("cam1"), 10.0)
        wait_for(lambda: has_event(manager, "sensor_gone", id="cam1"), 10.0, "manager to see the sensor leave")

    manager.signal(signal.SIGINT)
    assert manager.wait(10.0) == 0, manager.log()
    stopped = find_event(manager, "stopped")
    assert stopped is not None and stopped["decode_errors"] == 0
