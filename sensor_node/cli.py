"""``sensor-node --config FILE`` (also ``python -m sensor_node`` and ``panostereo node``).

The node's own arguments and its run: the config file with the session flags laid over it, handed to
:func:`sensor_node.node.run_node`; the rest of the entry point (logging, exit codes) is
:func:`common.cli.run_command` (docs/STYLE.md habit 1).
"""

from __future__ import annotations

import argparse

import msgspec

from common.cli import run_command
from common.session import add_session_args, settings_from_args

__all__ = ["configure", "main", "run"]


def configure(parser: argparse.ArgumentParser) -> None:
    """Add the node's arguments to ``parser`` (used by ``panostereo node`` too)."""
    parser.add_argument("--config", required=True, metavar="FILE", help="node config (TOML)")
    parser.add_argument(
        "--max-frames", type=int, default=0, metavar="N", help="stop after publishing N frames (0: run until stopped)"
    )
    add_session_args(parser)


def run(args: argparse.Namespace) -> int:
    """Load the config and run the node until SIGINT/SIGTERM (or ``--max-frames``)."""
    from sensor_node.config import load_node_config
    from sensor_node.node import run_node

    cfg = load_node_config(args.config)
    cfg = msgspec.structs.replace(cfg, zenoh=settings_from_args(args, cfg.zenoh))
    return run_node(cfg, max_frames=int(args.max_frames))


def main(argv: list[str] | None = None) -> int:
    return run_command("sensor-node", "Run one sensor node (one camera).", configure, run, argv)
