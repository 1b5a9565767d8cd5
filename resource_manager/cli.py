"""``resource-manager --config FILE`` (also ``python -m resource_manager`` and ``panostereo manager``).

The manager's own arguments and its run: the config file, narrowed to a site's sensors if one is given, with
the state directory and the session flags laid over it, handed to :func:`resource_manager.node.run`; the rest of
the entry point (logging, exit codes) is :func:`common.cli.run_command` (docs/STYLE.md habit 1).
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path

import msgspec

from common.cli import run_command
from common.session import add_session_args, settings_from_args

__all__ = ["configure", "main", "run"]


def configure(parser: argparse.ArgumentParser) -> None:
    """Add the manager's arguments to ``parser`` (used by ``panostereo manager`` too)."""
    parser.add_argument("--config", required=True, metavar="FILE", help="manager config (TOML)")
    parser.add_argument(
        "--state-dir",
        default=None,
        metavar="DIR",
        help="override [manager] state_dir (track log and id counter); else $PANOSTEREO_STATE_DIR/{id} if set",
    )
    parser.add_argument(
        "--site",
        default=None,
        metavar="FILE",
        help="the site file: the manager fuses exactly its sensor nodes (replaces [manager] sensors) and knows its "
        "[area]",
    )
    parser.add_argument(
        "--zone",
        default=None,
        metavar="ZONE",
        help="override [manager] zone: lead this zone, or stand by for it while another manager leads it (with --site "
        "and the site's [[zones]]: fuse only the cameras that see into it)",
    )
    parser.add_argument(
        "--print-sensors",
        action="store_true",
        help="print the sensor ids this manager would fuse (after --site and --zone), space separated, and exit "
        "(e.g. for deploy/security/make_configs.py --managers ID=CAMS)",
    )
    add_session_args(parser)


def run(args: argparse.Namespace) -> int:
    """Load the config and run the manager until SIGINT/SIGTERM."""
    from resource_manager.config import load_manager_config
    from resource_manager.node import run as run_manager

    cfg = load_manager_config(args.config)
    if args.zone is not None:  # before the site: a zone of the site narrows what the manager fuses
        from common.keys import validate_id

        zone = validate_id(args.zone, "--zone") if args.zone else ""
        cfg = msgspec.structs.replace(cfg, manager=msgspec.structs.replace(cfg.manager, zone=zone))
    if args.site:
        from common.site import load_site
        from resource_manager.config import for_site

        cfg = for_site(cfg, load_site(args.site))
    manager = cfg.manager
    if args.print_sensors:
        print(" ".join(manager.sensors))
        return 0
    env_dir = os.environ.get("PANOSTEREO_STATE_DIR", "")
    if args.state_dir:
        manager = msgspec.structs.replace(manager, state_dir=str(args.state_dir))
    elif env_dir:  # the launcher's per-run state (demo runs must not reload an earlier run's log)
        manager = msgspec.structs.replace(manager, state_dir=str(Path(env_dir) / manager.id))
    cfg = msgspec.structs.replace(cfg, manager=manager, zenoh=settings_from_args(args, cfg.zenoh))
    return run_manager(cfg)


def main(argv: list[str] | None = None) -> int:
    return run_command("resource-manager", "Run the resource manager.", configure, run, argv)
