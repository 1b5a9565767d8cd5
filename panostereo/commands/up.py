"""``panostereo up SITE``: run a site's processes on this host until interrupted.

Usage::

    panostereo up deploy/sites/demo.toml [--host NAME] [--router [--listen EP]] [--connect EP] [--log-dir DIR]

Starts every ``[[process]]`` whose ``host`` is ``NAME`` (default
``localhost``), each with its own config; with ``--router`` also a zenoh router
listening on the site's ``router`` endpoint (or ``--listen``), and every process
connects to it; ``--connect`` joins a router elsewhere (without either, each
process connects where its own config says). A process that
exits is restarted with a doubling back-off (0.5 s up to 30 s, reset after
30 s of running). SIGINT/SIGTERM stop every process (SIGTERM, then SIGKILL
after a grace period, whole process groups: no orphans) and exit 0.

Simulated sources share the world epoch ``PANOSTEREO_EPOCH_NS``: set it in the
environment to share one epoch across hosts; otherwise ``up`` uses its start time.
"""

from __future__ import annotations

import argparse
import logging
import os
import time
from pathlib import Path

from common.cli import non_negative, positive
from common.errors import ConfigError
from common.session import install_signal_handlers
from common.site import load_site
from panostereo.launcher import (
    EPOCH_ENV,
    STATE_ENV,
    ProcessPlan,
    Supervisor,
    router_plan,
    site_endpoints,
    site_plans,
)

__all__ = ["configure", "run"]

logger = logging.getLogger(__name__)


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("site", metavar="SITE", help="site file (deploy/sites/*.toml)")
    parser.add_argument("--host", default="localhost", help="run the processes of this host (default localhost)")
    parser.add_argument("--router", action="store_true", help="also run the site's zenoh router here")
    parser.add_argument(
        "--listen",
        action="append",
        default=None,
        metavar="ENDPOINT",
        help="with --router: where it listens (repeatable; default: the site's router); every process started here "
        "connects to the first",
    )
    parser.add_argument(
        "--connect",
        default=None,
        metavar="ENDPOINT",
        help="join the router there: every process started here connects to it (default: with --router, that "
        "router; else each process's own config)",
    )
    parser.add_argument("--log-dir", default=None, metavar="DIR", help="per-process log files (default: inherit)")
    parser.add_argument(
        "--state-dir",
        default=None,
        metavar="DIR",
        help="managers keep their track logs in DIR/<id> (env PANOSTEREO_STATE_DIR)",
    )
    parser.add_argument("--grace", type=non_negative, default=5.0, help="seconds between SIGTERM and SIGKILL at stop")
    parser.add_argument("--backoff-max", type=positive, default=30.0, help="longest restart delay (s)")


def run(args: argparse.Namespace) -> int:
    site = load_site(args.site)
    env = {EPOCH_ENV: os.environ.get(EPOCH_ENV) or str(time.time_ns())}
    if args.state_dir:
        env[STATE_ENV] = str(Path(args.state_dir).resolve())
    log_dir = Path(args.log_dir) if args.log_dir else None
    plans: list[ProcessPlan] = []
    first = args.listen[0] if args.listen else None
    listen, connect = site_endpoints(site, listen=first, connect=args.connect, router=args.router)
    if listen is not None:
        plans.append(router_plan(args.listen or [listen], log_path=log_dir / "router.log" if log_dir else None))
    plans += site_plans(site, host=args.host, connect=connect, env=env, log_dir=log_dir)
    if not plans:
        raise ConfigError(f"{args.site}: no [[process]] for host {args.host!r} (and no --router)")
    shutdown = install_signal_handlers()
    sup = Supervisor(plans, backoff_max_s=args.backoff_max, grace_s=args.grace)
    logger.info("site %s: running %s", site.site.name, ", ".join(p.name for p in plans))
    sup.start()
    try:
        sup.run(shutdown.sleep)
    finally:
        codes = sup.stop()
    logger.info("stopped: %s", ", ".join(f"{k}={v}" for k, v in codes.items()))
    return 0
