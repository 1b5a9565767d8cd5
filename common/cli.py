"""Helpers every entry point shares: logging set-up and error-to-exit-code mapping.

Entry points stay thin (docs/STYLE.md habit 1): parse arguments, load config,
configure logging, call ``run``, and map exceptions to exit codes with
:func:`run_main`.
"""

from __future__ import annotations

import argparse
import contextlib
import logging
import math
import os
import sys
from collections.abc import Callable
from typing import NoReturn

from common.errors import ConfigError, PanoError

__all__ = [
    "EXIT_BUG",
    "EXIT_ERROR",
    "EXIT_USAGE",
    "add_logging_args",
    "exit_process",
    "non_negative",
    "positive",
    "probability",
    "run_command",
    "run_main",
    "setup_logging",
]

EXIT_ERROR = 1
"""A clear, expected failure (bad config, unreachable router, corrupt file)."""
EXIT_USAGE = 2
EXIT_BUG = 70
"""An unexpected exception: a bug; the supervisor restarts the process."""


def _number(text: str) -> float:
    try:
        value = float(text)
    except ValueError as err:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from err
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"expected a finite number, got {text!r}")
    return value


def positive(text: str) -> float:
    """An argparse ``type``: a positive, finite number (a frame rate, a duration, a distance, a speed factor).

    A bad value stops the command with argparse's one line naming the option, before anything runs.
    """
    value = _number(text)
    if not value > 0:
        raise argparse.ArgumentTypeError(f"must be > 0, got {text}")
    return value


def non_negative(text: str) -> float:
    """An argparse ``type``: a finite number >= 0 (a duration where 0 means "none" or "until Ctrl-C")."""
    value = _number(text)
    if value < 0:
        raise argparse.ArgumentTypeError(f"must be >= 0, got {text}")
    return value


def probability(text: str) -> float:
    """An argparse ``type``: a number in [0, 1]."""
    value = _number(text)
    if not 0 <= value <= 1:
        raise argparse.ArgumentTypeError(f"must be in [0, 1], got {text}")
    return value


def exit_process(code: int) -> NoReturn:
    """End a finished command-line process without finalizing the interpreter.

    Its zenoh sessions are closed by now, but zenoh's own threads may still be on their way into Python (a
    callback, a query returning) while the interpreter finalizes; Python then ends such a thread with
    ``pthread_exit``, whose unwinding through Rust frames aborts the process with ``FATAL: exception not
    rethrown`` (issue 24: ``agent watch`` stopped by SIGTERM). Logs and stdio are flushed first; only a process
    entry point may call this (never a library, never a test).
    """
    logging.shutdown()
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(OSError, ValueError):  # a closed pipe: nothing more to say
            stream.flush()
    os._exit(code)


def add_logging_args(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--log-level",
        default="INFO",
        choices=["DEBUG", "INFO", "WARNING", "ERROR"],
        help="what is logged (default INFO)",
    )


def setup_logging(level: str = "INFO") -> None:
    """Configure the root logger once, for a process entry point."""
    logging.basicConfig(
        level=getattr(logging, level.upper(), logging.INFO),
        format="%(asctime)s %(levelname).1s %(name)s: %(message)s",
        datefmt="%H:%M:%S",
        stream=sys.stderr,
    )


def run_main(fn: Callable[[], int], prog: str) -> int:
    """Call ``fn`` and turn expected errors into one line on stderr and an exit code.

    ``PanoError`` (bad config, unreachable router, corrupt file): one line, exit
    :data:`EXIT_ERROR`. KeyboardInterrupt: exit 0. Any other exception is a bug:
    its traceback is logged and the exit code is :data:`EXIT_BUG`, so a
    supervisor restarts the process and the log says why.
    """
    try:
        return fn()
    except KeyboardInterrupt:
        return 0
    except ConfigError as err:
        print(f"{prog}: error: {err}", file=sys.stderr)
        return EXIT_ERROR
    except PanoError as err:
        print(f"{prog}: error: {err}", file=sys.stderr)
        return EXIT_ERROR
    except BrokenPipeError:
        return EXIT_ERROR
    except Exception:  # a bug: full traceback in the log, a distinct exit code for the supervisor
        logging.getLogger(prog.replace(" ", ".")).exception("unexpected error (a bug): exiting with %d", EXIT_BUG)
        return EXIT_BUG


def run_command(
    prog: str,
    description: str,
    configure: Callable[[argparse.ArgumentParser], None],
    run: Callable[[argparse.Namespace], int],
    argv: list[str] | None = None,
) -> int:
    """A process's ``main``: parse ``argv`` (the process's own arguments if None) with the logging flags and the
    ones ``configure`` adds, set up logging, and call ``run`` under :func:`run_main`. Returns the exit code.

    Each tier's entry point (``sensor-node``, ``resource-manager``, ``user-agent``) is this with its own
    ``configure`` and ``run``.
    """
    parser = argparse.ArgumentParser(prog=prog, description=description)
    add_logging_args(parser)
    configure(parser)
    args = parser.parse_args(sys.argv[1:] if argv is None else argv)
    setup_logging(args.log_level)
    return run_main(lambda: run(args), prog)
