"""``resource-manager --config FILE`` (also ``python -m resource_manager`` and ``panostereo manager``).

Thin entry point (docs/STYLE.md habit 1): parse arguments, load the config, overlay
the session flags, hand over to :func:`resource_manager.node.run`.
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

import msgspec

from common.cli import add_logging_args, run_main, setup_logging
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
    add_session_args(parser)


def run(args: argparse.Namespace) -> int:
    """Load the config and run the manager until SIGINT/SIGTERM."""
    from resource_manager.config import load_manager_config
    from resource_manager.node import run as run_manager

    cfg = load_manager_config(args.config)
    if args.site:
        from common.site import load_site
        from resource_manager.config import for_site

        cfg = for_site(cfg, load_site(args.site))
    manager = cfg.manager
    env_dir = os.environ.get("PANOSTEREO_STATE_DIR", "")
    if args.state_dir:
        manager = msgspec.structs.replace(manager, state_dir=str(args.state_dir))
    elif env_dir:  # the launcher's per-run state (demo runs must not reload an earlier run's log)
        manager = msgspec.structs.replace(manager, state_dir=str(Path(env_dir) / manager.id))
    cfg = msgspec.structs.replace(cfg, manager=manager, zenoh=settings_from_args(args, cfg.zenoh))
    return run_manager(cfg)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="resource-manager", description="Run the resource manager.")
    add_logging_args(parser)
    configure(parser)
    args = parser.parse_args(sys.argv[1:] if argv is None else argv)
    setup_logging(args.log_level)
    return run_main(lambda: run(args), "resource-manager")
