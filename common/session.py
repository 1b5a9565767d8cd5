"""Opening zenoh sessions from config and the shared command-line flags.

Deployment shape (docs/zenoh.md §2.2): in zenoh 1.10 peers do not relay
through a router, so a site runs one router (``panostereo router``, a zenoh
router in Python) and every process is a *client* of it. Clients wait and
retry while the router is not up yet, and reconnect by themselves after it
restarts.

Multicast scouting is off unless asked for: the default config would leak
onto every interface and cross-talk between concurrent runs.

Shutdown: callback subscribers start non-daemon threads that keep a process
alive until the session closes (docs/zenoh.md §5.1), so every shell opens
its session with ``with open_session(...) as session:`` and installs
:func:`install_signal_handlers` so SIGTERM unwinds like SIGINT.
"""

from __future__ import annotations

import argparse
import json
import logging
import re
import signal
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from types import FrameType
from typing import Any, Literal

import msgspec

from common.codec import MAX_PAYLOAD_BYTES
from common.errors import ConfigError, SessionError

__all__ = [
    "DEFAULT_ROUTER",
    "MSGPACK",
    "SessionSettings",
    "Shutdown",
    "add_session_args",
    "connect_hint",
    "install_signal_handlers",
    "on_signal",
    "open_session",
    "refuse_second",
    "settings_from_args",
    "wait_until",
    "zenoh_config",
]

logger = logging.getLogger(__name__)

MSGPACK = "application/msgpack"
"""Encoding string of every panostereo payload (zenoh has no predefined constant)."""

Mode = Literal["peer", "client", "router"]


class SessionSettings(msgspec.Struct, frozen=True, kw_only=True, forbid_unknown_fields=True):
    """How to join the zenoh network; the ``[zenoh]`` table of every process config."""

    mode: Mode = "client"
    connect: list[str] = []
    """Endpoints to connect to, e.g. ``tcp/192.168.1.10:7447``."""
    listen: list[str] = []
    """Endpoints to listen on (routers, and peers that others connect to)."""
    config_file: str = ""
    """A zenoh JSON5 config file (TLS, ACL, auth); flags override its endpoints and mode."""
    multicast_scouting: bool = False
    connect_timeout_ms: int = 10_000
    """How long a client waits for its router at start (-1: forever)."""
    lease_ms: int = 3_000
    """Transport lease this process announces: peers detect its freezing after this long."""
    user: str = ""
    password: str = ""


DEFAULT_ROUTER = "tcp/127.0.0.1:7447"


def add_session_args(parser: argparse.ArgumentParser) -> None:
    """Add the shared session flags (``--mode --connect --listen --zenoh-config``)."""
    g = parser.add_argument_group("zenoh session")
    g.add_argument("--mode", choices=["peer", "client", "router"], default=None, help="zenoh mode (default: client)")
    g.add_argument(
        "--connect",
        action="append",
        default=None,
        metavar="ENDPOINT",
        help=f"endpoint to connect to, repeatable (default for clients: {DEFAULT_ROUTER})",
    )
    g.add_argument("--listen", action="append", default=None, metavar="ENDPOINT", help="endpoint to listen on")
    g.add_argument("--zenoh-config", default=None, metavar="FILE", help="zenoh JSON5 config (TLS, ACL, auth)")
    g.add_argument(
        "--multicast-scouting", action="store_true", default=None, help="enable multicast scouting (off by default)"
    )


def settings_from_args(args: argparse.Namespace, base: SessionSettings | None = None) -> SessionSettings:
    """Overlay command-line flags on ``base`` (from the process config).

    Precedence: flags, then a ``--zenoh-config`` file given on the command line, then the process config's
    ``[zenoh]`` table. So ``--zenoh-config`` replaces the table's ``connect``/``listen`` (a TLS client file
    names its router's ``tls/`` endpoint; the table's ``tcp/`` one would override it and time out) unless
    ``--connect``/``--listen`` are given too.
    """
    s = base or SessionSettings()
    changes: dict[str, Any] = {}
    if getattr(args, "zenoh_config", None):
        changes["config_file"] = args.zenoh_config
        if s.config_file != args.zenoh_config:
            changes["connect"] = []
            changes["listen"] = []
    if getattr(args, "mode", None):
        changes["mode"] = args.mode
    if getattr(args, "connect", None):
        changes["connect"] = list(args.connect)
    if getattr(args, "listen", None):
        changes["listen"] = list(args.listen)
    if getattr(args, "multicast_scouting", None):
        changes["multicast_scouting"] = True
    return msgspec.structs.replace(s, **changes) if changes else s


_RUST_AT_RE = re.compile(r"\s*\bat /\S+?\.rs:\d+\.?")
_PEST_RE = re.compile(r"-->\s*(?P<line>\d+):(?P<col>\d+).*?=\s*(?P<msg>.+)$", re.S)
_SERDE_RE = re.compile(
    r'msg: "(?P<msg>.*?)", location: Some\(Location \{ line: (?P<line>\d+), column: (?P<col>\d+) \}\)', re.S
)


def _zerror_text(err: BaseException, with_location: bool = False) -> str:
    """A zenoh error as one readable line: no Rust source locations or Debug wrappers.

    Args:
        with_location: keep the line/column zenoh reports (meaningful for a
            config file, not for a value inserted from a flag).
    """
    text = _RUST_AT_RE.sub("", str(err))
    if m := _SERDE_RE.search(text):
        text = m.group("msg") + (f" (line {m.group('line')}, column {m.group('col')})" if with_location else "")
    elif m := _PEST_RE.search(text):
        text = f"syntax error at line {m.group('line')}, column {m.group('col')}: {m.group('msg')}"
    return " ".join(text.split())


def _base_config(config_file: str) -> Any:
    """The zenoh config file's ``zenoh.Config`` (an empty one without a file).

    Raises:
        ConfigError: the file is missing or zenoh rejects it.
    """
    import zenoh

    if not config_file:
        return zenoh.Config()
    path = Path(config_file)
    if not path.is_file():
        raise ConfigError(f"zenoh config file {config_file!r} does not exist")
    try:
        return zenoh.Config.from_file(str(path))
    except Exception as err:  # ZError: syntax error, unknown key, bad value
        raise ConfigError(f"zenoh config file {config_file}: {_zerror_text(err, True)}") from err


def zenoh_config(settings: SessionSettings, extra: dict[str, Any] | None = None) -> Any:
    """Build a ``zenoh.Config`` from settings.

    Args:
        settings: the ``[zenoh]`` table merged with the command-line flags.
        extra: further zenoh config keys (``"adminspace/enabled": True``),
            inserted last; values are JSON-encoded here.

    Raises:
        ConfigError: if the config file is missing or zenoh rejects a value.
    """
    try:
        conf = _base_config(settings.config_file)
        conf.insert_json5("mode", json.dumps(settings.mode))
        connect = list(settings.connect)
        if not connect and settings.mode == "client" and not settings.config_file:
            connect = [DEFAULT_ROUTER]
        if connect or not settings.config_file:
            conf.insert_json5("connect/endpoints", json.dumps(connect))
        if settings.listen:
            conf.insert_json5("listen/endpoints", json.dumps(list(settings.listen)))
        elif settings.mode != "router" and not settings.config_file:
            # Never leave the default [::]:0 listener: it leaks onto every interface.
            conf.insert_json5("listen/endpoints", json.dumps([]))
        conf.insert_json5("scouting/multicast/enabled", json.dumps(bool(settings.multicast_scouting)))
        if settings.mode == "client":
            conf.insert_json5("connect/timeout_ms", json.dumps(settings.connect_timeout_ms))
            conf.insert_json5(
                "connect/retry",
                json.dumps({"period_init_ms": 200, "period_max_ms": 1000, "period_increase_factor": 2}),
            )
        conf.insert_json5("transport/link/tx/lease", json.dumps(settings.lease_ms))
        # Oversize messages are dropped by the receiving session (router included), so a
        # flood of them never reaches, or fills, a process's buffers.
        conf.insert_json5("transport/link/rx/max_message_size", json.dumps(2 * MAX_PAYLOAD_BYTES))
        # No shared-memory transport: on one host zenoh would pass messages over 3 KB through each sender's 16 MB
        # pool, mapped into every receiver (the router, the manager) and counted in its memory for as long as it
        # runs, a flooding client's pool too (issue 24: +50 MB after a flood, never given back). Our messages are a
        # few KB at tens a second: the copy costs nothing worth that.
        conf.insert_json5("transport/shared_memory/enabled", "false")
        if settings.user:
            conf.insert_json5(
                "transport/auth/usrpwd", json.dumps({"user": settings.user, "password": settings.password})
            )
        for key, value in (extra or {}).items():
            conf.insert_json5(key, json.dumps(value))
    except ConfigError:
        raise
    except Exception as err:  # zenoh raises ZError for any bad value
        raise ConfigError(f"invalid zenoh configuration: {_zerror_text(err)}") from err
    return conf


def connect_hint(settings: SessionSettings, error: str) -> str:
    """What to try when a session cannot open: start the router, check the endpoint, the certificates ("" when
    the error says nothing a user can act on)."""
    low = error.lower()
    if settings.mode == "client" and ("unable to connect" in low or "timeout" in low):
        endpoints = settings.connect or ([] if settings.config_file else [DEFAULT_ROUTER])
        listen = endpoints[0] if endpoints else "ENDPOINT"
        tips = [
            f"is a router listening there? Start one with `panostereo router --listen {listen}` (or a whole site "
            "with `panostereo up SITE --router`); check the endpoint (--connect, or [zenoh] connect in the config)"
        ]
        secure = settings.config_file or any(e.startswith(("tls/", "quic/")) for e in endpoints)
        if secure:
            tips.append(
                "the router speaks TLS: check the certificates the zenoh config names (CA, this client's certificate "
                "and key) and that the router's certificate names the host connected to; `panostereo router "
                "--zenoh-log warn` logs why it refuses a client"
            )
        elif any(e.startswith("tcp/") for e in endpoints):
            tips.append("a router that listens on tls/ takes no tcp/ client: connect with its tls/ endpoint and config")
        return "; ".join(tips)
    if "address already in use" in low or "can not create a new" in low:
        return "another router (or demo) already listens there: choose another port with --listen"
    return ""


@contextmanager
def open_session(settings: SessionSettings, extra: dict[str, Any] | None = None) -> Iterator[Any]:
    """Open a zenoh session and close it on exit, whatever happens.

    Args:
        settings: mode, endpoints, config file (see :class:`SessionSettings`).
        extra: further zenoh config keys, see :func:`zenoh_config`.

    Raises:
        SessionError: if the session cannot be opened (router unreachable within
            ``connect_timeout_ms``, port taken, TLS/auth refused).
    """
    import zenoh

    conf = zenoh_config(settings, extra)
    try:
        session = zenoh.open(conf)
    except Exception as err:
        where = ", ".join(settings.connect or settings.listen or [DEFAULT_ROUTER])
        text = _zerror_text(err)
        hint = connect_hint(settings, text)
        raise SessionError(
            f"cannot open a zenoh {settings.mode} session ({where}): {text}" + (f" -- {hint}" if hint else "")
        ) from err
    try:
        yield session
    finally:
        close_session(session)


CLOSE_WAIT_S = 3.0
"""How long a process waits for its zenoh session to close at exit. On a working link the close takes
milliseconds; after the link went down and came back, zenoh waits about 10 s on the dead connection's sends
(zenoh#2675, zenoh#1979) before it gives up. The router drops the session's tokens when its lease runs out anyway."""


def close_session(session: Any, wait_s: float = CLOSE_WAIT_S) -> bool:
    """Close ``session``, waiting at most ``wait_s``: the close goes on in a thread of its own while the process
    exits (a supervisor's SIGTERM is answered within seconds, not after zenoh's own timeout). True if it closed."""
    done = threading.Event()

    def close() -> None:
        try:
            session.close()
        except Exception as err:  # close can time out on lossy links (zenoh#2675)
            logger.warning("zenoh session close failed: %s", err)
        finally:
            done.set()

    threading.Thread(target=close, name="zenoh-close", daemon=True).start()
    if done.wait(wait_s):
        return True
    logger.warning(
        "zenoh session still closing after %.0f s (a link that went down): exiting without waiting; the router "
        "drops this session when its lease runs out",
        wait_s,
    )
    return False


SECOND_POLL_S = 0.25
"""How often :func:`refuse_second` looks again for the other process's token."""


def refuse_second(session: Any, key: str, what: str, wait_s: float) -> None:
    """Refuse to run a second process under one id: ``key`` is the liveliness token the process is about to
    declare (its presence, e.g. ``R/sensor/{id}``). While another process holds it, wait up to ``wait_s`` (a
    process that just died: its token goes when the router notices, within a lease), then refuse.

    Raises:
        ConfigError: ``what`` already runs in the site under this id.
    """
    deadline = time.monotonic() + wait_s
    while True:
        try:
            replies = list(session.liveliness().get(key, timeout=1.0))
        except Exception as err:  # a query the router's access rules deny, a closing session: nothing to see
            logger.debug("liveliness get %s: %s", key, err)
            return
        held = any(r.ok is not None for r in replies)
        # An error reply (the router's answer timed out: a busy host, a link coming back) says nothing of whether
        # another process holds the token: asked again, never taken for "nobody".
        unsure = not held and any(r.ok is None for r in replies)
        if not held and not unsure:
            return
        if time.monotonic() >= deadline:
            if unsure:
                logger.warning("could not tell whether %s already runs: the router did not answer for %s", what, key)
                return
            raise ConfigError(
                f"{what} already runs in this site: another process holds {key}; give each process its own id "
                "(or stop the other one)"
            )
        time.sleep(SECOND_POLL_S)


class Shutdown:
    """A stop flag set by SIGINT/SIGTERM; shells poll it or wait on it."""

    def __init__(self) -> None:
        self._event = threading.Event()
        self._requested = False

    def set(self) -> None:
        self._event.set()

    def request(self) -> None:
        """Set the flag from a signal handler. The handler runs in the main thread between two bytecodes, possibly
        while that thread is inside :meth:`wait` holding the event's (non-reentrant) lock, where setting the event
        there would wait on itself forever: the flag is raised at once, and the event is set by a thread of its
        own, as soon as the lock is free."""
        self._requested = True
        threading.Thread(target=self._event.set, name="shutdown", daemon=True).start()

    def is_set(self) -> bool:
        return self._requested or self._event.is_set()

    def wait(self, timeout: float | None = None) -> bool:
        return self._event.wait(timeout)

    def sleep(self, seconds: float) -> bool:
        """Sleep up to ``seconds``; return True if shutdown was requested."""
        return self._event.wait(max(0.0, seconds))


def install_signal_handlers(shutdown: Shutdown | None = None) -> Shutdown:
    """Make SIGINT and SIGTERM set a :class:`Shutdown` flag (main thread only).

    A second signal raises KeyboardInterrupt so a stuck loop still unwinds.
    """
    flag = shutdown or Shutdown()
    handler = on_signal(flag)
    signal.signal(signal.SIGINT, handler)
    signal.signal(signal.SIGTERM, handler)
    return flag


def on_signal(flag: Shutdown) -> Callable[[int, FrameType | None], None]:
    """The SIGINT/SIGTERM handler that raises ``flag`` (:meth:`Shutdown.request`); a second signal raises
    KeyboardInterrupt."""

    def _handler(signum: int, frame: FrameType | None) -> None:
        if flag.is_set():
            raise KeyboardInterrupt
        logger.info("received %s: shutting down", signal.Signals(signum).name)
        flag.request()

    return _handler


def wait_until(pred: Callable[[], bool], timeout_s: float, poll_s: float = 0.01) -> bool:
    """Poll ``pred`` until it is true or ``timeout_s`` passes; return its last value."""
    deadline = time.monotonic() + timeout_s
    while True:
        if pred():
            return True
        if time.monotonic() >= deadline:
            return False
        time.sleep(poll_s)
