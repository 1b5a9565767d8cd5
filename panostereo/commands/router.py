"""``panostereo router``: a zenoh router in Python, the hub of a site.

No ``zenohd`` binary is obtainable here (docs/zenoh.md §2.4), and in zenoh
1.10 peers do not relay through a router (§2.2), so a site runs this router
and every process connects to it as a client.

Usage::

    panostereo router [--listen tcp/0.0.0.0:7447] [--zenoh-config FILE] [--zenoh-log warn]

Listens on ``tcp/127.0.0.1:7447`` by default with multicast scouting off,
logs the locators it listens on, and runs until SIGINT/SIGTERM, then closes
its session and exits 0. A port already in use is one clear error line and
exit code 1.

Zenoh's own log (Rust) is where a refused client leaves its trace (a
certificate from another CA, an expired one, a wrong password): it is off
unless ``--zenoh-log LEVEL`` (or ``RUST_LOG``, which refines it) turns it on,
on stdout beside the router's own lines.
"""

from __future__ import annotations

import argparse
import json
import logging
import os
import re
from typing import Any

from common.errors import SessionError
from common.memory import Trimmer, pin_mmap_threshold
from common.session import SessionSettings, install_signal_handlers, open_session, zenoh_config

__all__ = ["DEFAULT_LISTEN", "configure", "run"]

logger = logging.getLogger(__name__)

DEFAULT_LISTEN = "tcp/127.0.0.1:7447"
ZENOH_LOG_LEVELS = ("error", "warn", "info", "debug", "trace")

_IN_USE_RE = re.compile(r"(?i)address already in use")


def configure(parser: argparse.ArgumentParser) -> None:
    """Add the router's flags."""
    parser.add_argument(
        "--listen",
        action="append",
        default=None,
        metavar="ENDPOINT",
        help=f"endpoint to listen on, repeatable (default: {DEFAULT_LISTEN}; port 0 picks a free port)",
    )
    parser.add_argument(
        "--connect",
        action="append",
        default=None,
        metavar="ENDPOINT",
        help="another router to connect to, repeatable (multi-site meshes)",
    )
    parser.add_argument("--zenoh-config", default=None, metavar="FILE", help="zenoh JSON5 config (TLS, ACL, auth)")
    parser.add_argument(
        "--multicast-scouting", action="store_true", default=False, help="enable multicast scouting (off by default)"
    )
    parser.add_argument(
        "--zenoh-log",
        default=None,
        choices=ZENOH_LOG_LEVELS,
        metavar="LEVEL",
        help="turn zenoh's own log on at this level (" + ", ".join(ZENOH_LOG_LEVELS) + "); RUST_LOG refines it. "
        "'warn' shows why a client was refused (its certificate, password)",
    )


def init_zenoh_log(level: str | None) -> None:
    """Send zenoh's (Rust) log to stdout: at ``level``, or as RUST_LOG says; nothing when neither is set."""
    import zenoh

    if level:
        zenoh.init_log_from_env_or(level)
    elif os.environ.get("RUST_LOG"):
        zenoh.try_init_log_from_env()


def _settings(args: argparse.Namespace) -> SessionSettings:
    listen = list(args.listen or [])
    if not listen and not args.zenoh_config:
        listen = [DEFAULT_LISTEN]
    return SessionSettings(
        mode="router",
        listen=listen,
        connect=list(args.connect or []),
        config_file=args.zenoh_config or "",
        multicast_scouting=bool(args.multicast_scouting),
    )


def _listen_endpoints(settings: SessionSettings) -> list[str]:
    """The endpoints the router is configured to listen on (flags, else its zenoh config file)."""
    if settings.listen:
        return list(settings.listen)
    try:
        value = json.loads(zenoh_config(settings).get_json("listen/endpoints"))
    except Exception as err:  # reported properly when the session opens
        logger.debug("cannot read listen endpoints: %s", err)
        return []
    if isinstance(value, dict):  # per-mode form: {router: [...], peer: [...]}
        value = value.get("router", [])
    return [str(v) for v in value] if isinstance(value, list) else []


def _locators(session: Any, configured: list[str]) -> list[str]:
    """The locators the router really listens on.

    With an explicit port the configured endpoints are the answer. With port 0
    the kernel chose the port, so ask the router's own admin space (enabled
    only in that case, docs/zenoh.md §2.7).
    """
    if not any(ep.rsplit(":", 1)[-1] == "0" for ep in configured):
        return configured
    try:
        replies = list(session.get(f"@/{session.zid()}/router", timeout=2.0))
        for reply in replies:
            if reply.ok is not None:
                info = json.loads(reply.ok.payload.to_string())
                return [str(loc) for loc in info.get("locators", [])]
    except Exception as err:  # admin space unavailable (e.g. denied by a config file)
        logger.debug("admin space query failed: %s", err)
    return configured


def run(args: argparse.Namespace) -> int:
    """Run the router until SIGINT/SIGTERM.

    Raises:
        SessionError: the port is taken or zenoh refused the configuration.
    """
    settings = _settings(args)
    init_zenoh_log(args.zenoh_log)
    shutdown = install_signal_handlers()
    pin_mmap_threshold()  # before zenoh allocates: large buffers are mapped alone and unmapped when freed
    configured = _listen_endpoints(settings)
    wants_port0 = any(ep.rsplit(":", 1)[-1] == "0" for ep in configured)
    try:
        with open_session(settings, extra={"adminspace/enabled": True} if wants_port0 else None) as session:
            locators = _locators(session, configured)
            logger.info("zenoh router %s listening on %s", session.zid(), ", ".join(locators) or "(no endpoint)")
            # What a flood made the router buffer goes back to the system once sent (common/memory.py).
            trimmer = Trimmer()
            while not shutdown.wait(0.5):
                trimmer.tick()
            logger.info("router stopping")
    except SessionError as err:
        if _IN_USE_RE.search(str(err)):
            where = ", ".join(configured)
            raise SessionError(
                f"cannot listen on {where}: address already in use (is another router running?)"
            ) from err
        raise
    return 0
