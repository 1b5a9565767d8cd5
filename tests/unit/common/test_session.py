"""Sessions: config from settings and flags, signals, and (with real processes) late routers and restarts."""

from __future__ import annotations

import argparse
import json
import os
import signal
import sys
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import msgspec
import pytest

from common.errors import ConfigError, SessionError
from common.keys import Keys
from common.session import (
    DEFAULT_ROUTER,
    SessionSettings,
    Shutdown,
    add_session_args,
    close_session,
    install_signal_handlers,
    on_signal,
    open_session,
    settings_from_args,
    wait_until,
    zenoh_config,
)
from tests.support import (
    ManagedProcess,
    RouterProcess,
    client_session,
    free_port,
    wait_for,
    wait_for_liveliness,
)

PEER = str(Path(__file__).resolve().parents[2] / "integration" / "peer.py")


def cfg(settings: SessionSettings, key: str, extra: dict[str, Any] | None = None) -> Any:
    return json.loads(zenoh_config(settings, extra).get_json(key))


# -- config ----------------------------------------------------------------------


def test_client_defaults() -> None:
    s = SessionSettings()
    assert cfg(s, "mode") == "client"
    assert cfg(s, "connect/endpoints") == [DEFAULT_ROUTER] == ["tcp/127.0.0.1:7447"]
    assert cfg(s, "listen/endpoints") == []  # never the default [::]:0
    assert cfg(s, "scouting/multicast/enabled") is False
    assert cfg(s, "connect/timeout_ms") == 10_000  # wait for a late router
    assert cfg(s, "transport/link/tx/lease") == 3_000


def test_router_and_peer_settings() -> None:
    r = SessionSettings(mode="router", listen=["tcp/127.0.0.1:9000"])
    assert cfg(r, "mode") == "router"
    assert cfg(r, "listen/endpoints") == ["tcp/127.0.0.1:9000"]
    assert cfg(r, "connect/endpoints") == []
    p = SessionSettings(mode="peer", multicast_scouting=True)
    assert cfg(p, "scouting/multicast/enabled") is True
    assert cfg(p, "listen/endpoints") == []


def test_extra_keys_and_auth() -> None:
    s = SessionSettings(user="sensor1", password="pw")
    assert cfg(s, "adminspace/enabled", {"adminspace/enabled": True}) is True
    assert cfg(s, "transport/auth/usrpwd/user") == "sensor1"


def test_flags_override_config() -> None:
    p = argparse.ArgumentParser()
    add_session_args(p)
    base = SessionSettings(connect=["tcp/10.0.0.1:7447"], lease_ms=5000)
    args = p.parse_args(["--mode", "peer", "--connect", "tcp/a:1", "--connect", "tcp/b:2", "--listen", "tcp/c:3"])
    s = settings_from_args(args, base)
    assert (s.mode, s.connect, s.listen, s.lease_ms) == ("peer", ["tcp/a:1", "tcp/b:2"], ["tcp/c:3"], 5000)
    assert settings_from_args(p.parse_args([]), base) == base
    s = settings_from_args(p.parse_args(["--zenoh-config", "z.json5", "--multicast-scouting"]))
    assert (s.config_file, s.multicast_scouting) == ("z.json5", True)


def test_a_zenoh_config_flag_names_the_router_not_the_process_tables_endpoint(tmp_path: Path) -> None:
    """`node --config cam.toml --zenoh-config sensor-cam.json5` (the secure deployment): the file's tls/ endpoint
    is used, not the tcp/ one of cam.toml's [zenoh] table; --connect still overrides both."""
    f = tmp_path / "sensor.json5"
    f.write_text('{ mode: "client", connect: { endpoints: ["tls/router.lab:7447"] } }')
    p = argparse.ArgumentParser()
    add_session_args(p)
    toml = SessionSettings(connect=["tcp/127.0.0.1:7447"], lease_ms=2000)
    s = settings_from_args(p.parse_args(["--zenoh-config", str(f)]), toml)
    assert cfg(s, "connect/endpoints") == ["tls/router.lab:7447"] and s.lease_ms == 2000
    s = settings_from_args(p.parse_args(["--zenoh-config", str(f), "--connect", "tls/other:1"]), toml)
    assert cfg(s, "connect/endpoints") == ["tls/other:1"]
    # The table's own config_file keeps the table's connect (documented: "overrides the file's endpoint").
    own = SessionSettings(config_file=str(f), connect=["tls/10.0.0.9:7447"])
    assert cfg(settings_from_args(p.parse_args([]), own), "connect/endpoints") == ["tls/10.0.0.9:7447"]


def test_config_file_is_used_and_flags_override_it(tmp_path: Path) -> None:
    f = tmp_path / "z.json5"
    f.write_text('{ mode: "peer", transport: { link: { tx: { batch_size: 8192 } } } }')
    s = SessionSettings(mode="client", config_file=str(f), connect=["tcp/127.0.0.1:1"])
    assert cfg(s, "transport/link/tx/batch_size") == 8192
    assert cfg(s, "mode") == "client"
    assert cfg(s, "connect/endpoints") == ["tcp/127.0.0.1:1"]


@pytest.mark.parametrize(
    ("content", "match"),
    [
        (None, r"zenoh config file '.*z\.json5' does not exist"),
        ("{ mode: ", r"zenoh config file .*z\.json5: syntax error at line 1, column 9: expected"),
        (
            "{ bogus_key: 1 }",
            r"zenoh config file .*z\.json5: unknown field `bogus_key`, expected one of .* \(line 1, column",
        ),
        ('{ mode: "sideways" }', r"zenoh config file .*z\.json5: unknown variant `sideways`"),
    ],
)
def test_bad_config_file_is_one_clean_line(tmp_path: Path, content: str | None, match: str) -> None:
    f = tmp_path / "z.json5"
    if content is not None:
        f.write_text(content)
    with pytest.raises(ConfigError, match=match) as info:
        zenoh_config(SessionSettings(config_file=str(f)))
    text = str(info.value)
    assert "\n" not in text and ".rs:" not in text and "Location {" not in text, text


@pytest.mark.parametrize(
    ("settings", "match"),
    [
        (
            SessionSettings(connect=["not-an-endpoint"]),
            r"^invalid zenoh configuration: Endpoints must be .*: not-an-endpoint$",
        ),
        (SessionSettings(mode="router", listen=["nope"]), r"^invalid zenoh configuration: .*nope$"),
    ],
)
def test_bad_endpoint_in_settings_is_one_clean_line(settings: SessionSettings, match: str) -> None:
    with pytest.raises(ConfigError, match=match) as info:
        zenoh_config(settings)
    assert ".rs:" not in str(info.value) and "Json5Err" not in str(info.value)


def test_bad_endpoint_is_a_clear_error() -> None:
    with (
        pytest.raises((ConfigError, SessionError), match="nonsense"),
        open_session(SessionSettings(connect=["nonsense"], connect_timeout_ms=200)),
    ):
        pass


def test_unreachable_router_fails_after_the_timeout_naming_it() -> None:
    port = free_port()
    t0 = time.monotonic()
    with (
        pytest.raises(SessionError) as info,
        open_session(SessionSettings(connect=[f"tcp/127.0.0.1:{port}"], connect_timeout_ms=500)),
    ):
        pass
    elapsed = time.monotonic() - t0
    assert f"tcp/127.0.0.1:{port}" in str(info.value)
    assert " at /" not in str(info.value), "no Rust source paths in user-facing errors"
    assert elapsed < 10.0


def test_peer_session_delivers_locally_and_closes() -> None:
    got: list[bytes] = []
    with open_session(SessionSettings(mode="peer")) as s:
        sub = s.declare_subscriber("t/local", lambda sample: got.append(sample.payload.to_bytes()))
        s.put("t/local", b"x")
        assert wait_until(lambda: bool(got), 5.0)
        sub.undeclare()
    assert s.is_closed()


# -- signals -----------------------------------------------------------------------


@pytest.fixture
def restore_signals() -> Iterator[None]:
    old = {sig: signal.getsignal(sig) for sig in (signal.SIGINT, signal.SIGTERM)}
    yield
    for sig, handler in old.items():
        signal.signal(sig, handler)


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM])
def test_signal_sets_shutdown_then_second_signal_interrupts(restore_signals: None, signum: int) -> None:
    flag = install_signal_handlers()
    assert not flag.is_set()
    os.kill(os.getpid(), signum)
    assert wait_until(flag.is_set, 2.0)
    assert flag.sleep(10.0) is True  # returns at once once set
    with pytest.raises(KeyboardInterrupt):
        os.kill(os.getpid(), signum)
        time.sleep(1.0)  # the handler raises here


@pytest.mark.timeout(20)
def test_a_signal_that_lands_while_the_main_thread_holds_the_flag_s_lock_does_not_hang_it() -> None:
    """A signal handler runs in the main thread between two bytecodes, also inside Shutdown.wait where that thread
    holds the event's lock: raising the flag there must not wait on that lock."""
    flag = Shutdown()
    handler = on_signal(flag)
    with flag._event._cond:  # the main thread inside Event.wait, between taking its lock and waiting
        handler(signal.SIGTERM, None)
        assert flag.is_set()
    assert flag.wait(5.0) is True  # and the waiters wake once the lock is free
    with pytest.raises(KeyboardInterrupt):  # a second signal still unwinds a stuck loop
        handler(signal.SIGTERM, None)


def test_shutdown_sleep_times_out_false() -> None:
    flag = Shutdown()
    t0 = time.monotonic()
    assert flag.sleep(0.05) is False
    assert time.monotonic() - t0 >= 0.04
    flag.set()
    assert flag.wait(0) is True


# -- processes: late router, restart, clean exit -------------------------------------


def _sensor(spawn: Callable[..., ManagedProcess], endpoint: str, prefix: str) -> ManagedProcess:
    return spawn(
        [sys.executable, PEER, "sensor", "--id", "cam1", "--connect", endpoint, "--prefix", prefix], name="sensor"
    )


def _next_features(endpoint: str, keys: Keys, timeout_s: float) -> int:
    """Open a fresh client session and return the seq of the next Features the sensor publishes."""
    from common.codec import decode
    from common.schema import Features

    seqs: list[int] = []
    with client_session(endpoint) as s:
        sub = s.declare_subscriber(
            keys.sensor_features("cam1"), lambda sample: seqs.append(decode(sample.payload.to_bytes(), Features).seq)
        )
        try:
            wait_for(lambda: seqs, timeout_s, "Features from the sensor through the router")
        finally:
            sub.undeclare()
    return seqs[0]


@pytest.mark.integration
def test_client_started_before_the_router_waits_then_connects(
    spawn: Callable[..., ManagedProcess], router_factory: Callable[..., RouterProcess]
) -> None:
    port = free_port()
    keys = Keys("latejoin")
    sensor = _sensor(spawn, f"tcp/127.0.0.1:{port}", "latejoin")
    sensor.wait_for_output(r'"event": "opening"', 10.0)
    assert '"opened"' not in sensor.stdout_text(), "opened a session with no router up"
    router = router_factory(port)  # now the router comes up
    sensor.wait_for_output(r'"event": "ready"', 15.0)
    with client_session(router.endpoint) as s:
        wait_for_liveliness(s, keys.sensor("cam1"), 10.0)
    assert sensor.alive


@pytest.mark.integration
def test_client_reconnects_after_router_restart(
    spawn: Callable[..., ManagedProcess], router_factory: Callable[..., RouterProcess]
) -> None:
    keys = Keys("restart")
    first = router_factory()
    sensor = _sensor(spawn, first.endpoint, "restart")
    before = _next_features(first.endpoint, keys, 15.0)
    assert first.stop() == 0
    second = router_factory(first.port)  # same port, new process
    after = _next_features(second.endpoint, keys, 20.0)
    assert after > before, "the sensor kept publishing across the restart"
    assert sensor.alive
    with client_session(second.endpoint) as s:
        wait_for_liveliness(s, keys.sensor("cam1"), 10.0)  # its token came back too


@pytest.mark.integration
@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM])
def test_client_with_callbacks_exits_cleanly_on_signal(
    router: RouterProcess, spawn: Callable[..., ManagedProcess], signum: int
) -> None:
    sensor = _sensor(spawn, router.endpoint, f"sig{signum}")
    sensor.wait_for_output(r'"event": "ready"', 15.0)
    t0 = time.monotonic()
    sensor.signal(signum)
    assert sensor.wait(10.0) == 0, sensor.log()
    assert time.monotonic() - t0 < 5.0, "exit hung (callback threads kept the process alive?)"
    assert '"event": "stopped"' in sensor.stdout_text()
    assert "Traceback" not in sensor.stderr_text()


@pytest.mark.integration
def test_client_gives_up_when_no_router_comes(spawn: Callable[..., ManagedProcess]) -> None:
    port = free_port()
    proc = spawn(
        [
            sys.executable,
            PEER,
            "sensor",
            "--id",
            "cam1",
            "--connect",
            f"tcp/127.0.0.1:{port}",
            "--connect-timeout-ms",
            "300",
        ]
    )
    assert proc.wait(15.0) == 1
    assert f"tcp/127.0.0.1:{port}" in proc.stderr_text()
    assert "Traceback" not in proc.stderr_text()


@pytest.mark.parametrize(
    ("settings", "says"),
    [
        (SessionSettings(connect=["tcp/127.0.0.1:PORT"]), ["panostereo router --listen tcp/127.0.0.1:PORT", "tls/"]),
        (
            SessionSettings(connect=["tls/127.0.0.1:PORT"]),
            ["panostereo router --listen tls/127.0.0.1:PORT", "certificates"],
        ),
    ],
)
def test_a_client_with_no_router_is_told_what_to_try(settings: SessionSettings, says: list[str]) -> None:
    port = str(free_port())
    s = msgspec.structs.replace(settings, connect=[e.replace("PORT", port) for e in settings.connect],
                                connect_timeout_ms=300)  # fmt: skip
    with pytest.raises(SessionError) as err, open_session(s):
        pass
    text = str(err.value)
    assert "cannot open a zenoh client session" in text
    for part in says:
        assert part.replace("PORT", port) in text, text


class _Closing:
    """A session whose close waits until released (zenoh's on a link that went down waits ~10 s)."""

    def __init__(self, hangs: bool) -> None:
        self.release = threading.Event()
        self.hangs = hangs
        self.closed = False

    def close(self) -> None:
        if self.hangs:
            self.release.wait(10.0)
        self.closed = True


def test_a_session_whose_close_hangs_is_left_closing_and_the_process_goes_on(caplog: pytest.LogCaptureFixture) -> None:
    quick = _Closing(hangs=False)
    assert close_session(quick, wait_s=5.0) and quick.closed
    stuck = _Closing(hangs=True)
    try:
        assert not close_session(stuck, wait_s=0.1)
        assert not stuck.closed
        assert "still closing" in caplog.text
    finally:
        stuck.release.set()
    wait_for(lambda: stuck.closed, 5.0, "the close to finish in its own thread once released")


class _Answers:
    """A session whose liveliness ``get`` answers from a script: a list of replies per query (the last repeats)."""

    def __init__(self, *answers: list[Any]) -> None:
        self.answers = list(answers)
        self.gets = 0

    def liveliness(self) -> _Answers:
        return self

    def get(self, key: str, timeout: float) -> list[Any]:
        self.gets += 1
        return self.answers[min(self.gets, len(self.answers)) - 1]


def _token(key: str) -> Any:
    return argparse.Namespace(ok=argparse.Namespace(key_expr=key), err=None)


TIMED_OUT = argparse.Namespace(ok=None, err="Timeout")


def test_a_second_process_is_refused_also_when_the_first_answer_timed_out() -> None:
    """A liveliness reply that errs (the router answered late) is no "nobody holds the id": asked again, the other
    process's token is there, and the second process is refused."""
    from common.session import refuse_second

    key = "pano/sensor/cam1"
    session = _Answers([TIMED_OUT], [_token(key)])
    with pytest.raises(ConfigError, match="already runs in this site"):
        refuse_second(session, key, "sensor node cam1", wait_s=0.3)
    assert session.gets >= 2
    free = _Answers([TIMED_OUT], [])
    refuse_second(free, key, "sensor node cam1", wait_s=5.0)  # the whole answer: nobody holds it
    assert free.gets == 2


def test_a_router_that_never_answers_whole_lets_the_process_start_with_a_warning(
    caplog: pytest.LogCaptureFixture,
) -> None:
    from common.session import refuse_second

    session = _Answers([TIMED_OUT])
    refuse_second(session, "pano/sensor/cam1", "sensor node cam1", wait_s=0.3)
    assert session.gets >= 2
    assert "could not tell whether sensor node cam1 already runs" in caplog.text
