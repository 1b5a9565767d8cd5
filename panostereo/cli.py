"""``panostereo``: one command, many subcommands.

Each subcommand lives in its own module exposing ``configure(parser)`` and
``run(args) -> int``; only the chosen one is imported, so ``panostereo
--help`` is instant and a broken optional extra cannot break other commands.
"""

from __future__ import annotations

import argparse
import importlib
import sys
from typing import Final

from common.cli import add_logging_args, exit_process, run_main, setup_logging

COMMANDS: Final[dict[str, tuple[str, str]]] = {
    "demo": ("panostereo.commands.demo", "run the whole network of a site on this machine and score it"),
    "up": ("panostereo.commands.up", "run a site's processes until interrupted, restarting crashed ones"),
    "router": ("panostereo.commands.router", "run a zenoh router (the hub every process connects to)"),
    "node": ("sensor_node.cli", "run one sensor node (same as `sensor-node`)"),
    "manager": ("resource_manager.cli", "run the resource manager (same as `resource-manager`)"),
    "agent": (
        "user_agent.cli",
        "user-agent tools: watch, tracks, history, sensors, view, record, replay, foxglove, plot, evaluate, export",
    ),
    "plan": ("panostereo.commands.plan", "best stereo configuration and error map for a target (Eqs. 4-6, Fig. 4)"),
    "render": ("panostereo.commands.render", "render one simulated camera frame and its panorama"),
    "import": ("panostereo.commands.import_dataset", "convert a dataset (mot, wildtrack) into a runnable site"),
    "evaluate-site": ("panostereo.commands.evaluate_site", "play a dataset site in dataset time and score it"),
    "evaluate-detections": (
        "panostereo.commands.evaluate_detections",
        "score a camera's blobs in the image against ground-truth boxes (a video offline, or a recording)",
    ),
    "calib": (
        "panostereo.commands.calib",
        "calibration: convert Tsai, OpenCV YAML or a P matrix to our JSON; refine poses from people walking",
    ),
}


def _top_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="panostereo",
        description="Adaptive panoramic stereo: find and follow people in 3D with cooperating cameras.",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="commands:\n" + "\n".join(f"  {name:<19} {text}" for name, (_, text) in COMMANDS.items()),
    )
    p.add_argument("command", nargs="?", help="one of: " + ", ".join(COMMANDS))
    return p


def main(argv: list[str] | None = None) -> int:
    args_in = list(sys.argv[1:] if argv is None else argv)
    top = _top_parser()
    if not args_in or args_in[0] in ("-h", "--help"):
        top.print_help()
        return 0
    name, rest = args_in[0], args_in[1:]
    if name not in COMMANDS:
        top.error(f"unknown command {name!r} (choose from {', '.join(COMMANDS)})")
    module = importlib.import_module(COMMANDS[name][0])
    parser = argparse.ArgumentParser(prog=f"panostereo {name}", description=COMMANDS[name][1])
    add_logging_args(parser)
    module.configure(parser)
    args = parser.parse_args(rest)
    setup_logging(args.log_level)
    code = run_main(lambda: int(module.run(args)), f"panostereo {name}")
    if argv is None and name == "agent":
        exit_process(code)  # a process, not a call: no interpreter finalization under zenoh's threads
    return code


if __name__ == "__main__":
    sys.exit(main())
