"""``panostereo router``: readiness, traffic through it, clean exit on signals, a clear error on a taken port."""

from __future__ import annotations

import json
import signal
import sys
from collections.abc import Callable
from pathlib import Path

import pytest

from common.codec import decode, encode
from common.keys import Keys
from common.schema import Features
from tests.support import ManagedProcess, RouterProcess, client_session, free_port, router_command, wait_for

pytestmark = pytest.mark.integration


def test_router_relays_between_two_clients(router: RouterProcess) -> None:
    keys = Keys("routertest")
    key = keys.sensor_features("cam1")
    got: list[Features] = []
    with client_session(router.endpoint) as a, client_session(router.endpoint) as b:
        sub = b.declare_subscriber(key, lambda s: got.append(decode(s.payload.to_bytes(), Features)))
        sent = Features(sensor_id="cam1", seq=7, stamp_ns=123, frame_index=7)

        def delivered() -> bool:
            a.put(key, encode(sent))  # re-put until the subscription has propagated through the router
            return bool(got)

        wait_for(delivered, 10.0, "a Features sample relayed by the router")
        sub.undeclare()
    assert got[0] == sent


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM])
def test_router_exits_zero_on_signal(router_factory: Callable[..., RouterProcess], signum: int) -> None:
    r = router_factory()
    r.proc.signal(signum)
    assert r.proc.wait(10.0) == 0, r.proc.log()
    assert "router stopping" in r.proc.stderr_text()


def test_router_logs_its_locator(router_factory: Callable[..., RouterProcess]) -> None:
    r = router_factory()
    assert f"listening on tcp/127.0.0.1:{r.port}" in r.proc.stderr_text()


def test_router_port_zero_logs_the_real_port(spawn: Callable[..., ManagedProcess]) -> None:
    proc = spawn(router_command(0))
    m = proc.wait_for_output(r"listening on tcp/127\.0\.0\.1:(\d+)", 15.0)
    port = int(m.group(1))
    assert port > 0
    with client_session(f"tcp/127.0.0.1:{port}", connect_timeout_ms=3000) as s:
        assert s.info.routers_zid(), "client sees no router"
    proc.signal(signal.SIGTERM)
    assert proc.wait(10.0) == 0


def test_router_taken_port_is_one_clear_error(router: RouterProcess, spawn: Callable[..., ManagedProcess]) -> None:
    proc = spawn(router_command(router.port))
    rc = proc.wait(15.0)
    err_lines = [ln for ln in proc.stderr_text().splitlines() if "error" in ln.lower()]
    assert rc == 1, proc.log()
    assert len(err_lines) == 1, proc.log()
    assert "address already in use" in err_lines[0]
    assert f"127.0.0.1:{router.port}" in err_lines[0]
    assert "Traceback" not in proc.stderr_text()


def test_router_unknown_config_file_is_an_error(spawn: Callable[..., ManagedProcess], tmp_path: Path) -> None:
    proc = spawn([*router_command(free_port()), "--zenoh-config", str(tmp_path / "missing.json5")])
    assert proc.wait(15.0) == 1
    assert "missing.json5" in proc.stderr_text()
    assert "does not exist" in proc.stderr_text()


def test_router_from_config_file_logs_its_endpoints(spawn: Callable[..., ManagedProcess], tmp_path: Path) -> None:
    port = free_port()
    conf = tmp_path / "router.json5"
    endpoint = json.dumps(f"tcp/127.0.0.1:{port}")
    conf.write_text(
        f'{{ mode: "router", listen: {{ endpoints: [{endpoint}] }}, scouting: {{ multicast: {{ enabled: false }} }} }}'
    )
    proc = spawn([sys.executable, "-m", "panostereo", "router", "--zenoh-config", str(conf)])
    proc.wait_for_output(rf"listening on tcp/127\.0\.0\.1:{port}", 15.0)
    with client_session(f"tcp/127.0.0.1:{port}", connect_timeout_ms=3000) as s:
        assert s.info.routers_zid()
    proc.signal(signal.SIGTERM)
    assert proc.wait(10.0) == 0
