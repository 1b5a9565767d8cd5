"""run_main: expected errors are one line and exit 1, interrupts exit 0, bugs exit 70 with a traceback in the log."""

from __future__ import annotations

import argparse
import logging

import pytest

from common.cli import EXIT_BUG, EXIT_ERROR, EXIT_USAGE, run_command, run_main
from common.errors import ConfigError, SessionError


def _raise(exc: BaseException) -> int:
    raise exc


@pytest.mark.parametrize("exc", [ConfigError("node.toml: fps: expected a number"), SessionError("router down")])
def test_expected_errors_are_one_line(capsys: pytest.CaptureFixture[str], exc: Exception) -> None:
    assert run_main(lambda: _raise(exc), "panostereo node") == EXIT_ERROR
    err = capsys.readouterr().err
    assert err == f"panostereo node: error: {exc}\n"


def test_return_code_passes_through() -> None:
    assert run_main(lambda: 0, "x") == 0
    assert run_main(lambda: 3, "x") == 3


def test_keyboard_interrupt_is_a_clean_exit() -> None:
    assert run_main(lambda: _raise(KeyboardInterrupt()), "x") == 0


def test_bug_exits_with_exit_bug_and_logs_the_traceback(caplog: pytest.LogCaptureFixture) -> None:
    with caplog.at_level(logging.ERROR):
        assert run_main(lambda: _raise(ZeroDivisionError("oops")), "panostereo manager") == EXIT_BUG
    assert EXIT_BUG == 70
    rec = caplog.records[-1]
    assert rec.exc_info is not None and rec.exc_info[0] is ZeroDivisionError
    assert "a bug" in rec.getMessage()


def test_exit_process_flushes_what_was_said_and_exits_with_the_code() -> None:
    import subprocess
    import sys

    code = "import logging, sys; from common.cli import exit_process, setup_logging; setup_logging(); "
    code += "print('out', end=''); logging.getLogger('x').warning('said'); exit_process(3)"
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=30, check=False)
    assert res.returncode == 3 and res.stdout == "out" and "said" in res.stderr


def _configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--frames", type=int, required=True)


@pytest.mark.parametrize(("frames", "code"), [("3", 3), ("0", 0)])
def test_run_command_parses_configures_and_runs(frames: str, code: int) -> None:
    assert run_command("x", "a test command", _configure, lambda args: int(args.frames), ["--frames", frames]) == code


def test_run_command_maps_errors_and_rejects_bad_arguments(capsys: pytest.CaptureFixture[str]) -> None:
    def fail(args: argparse.Namespace) -> int:
        raise ConfigError("x.toml: frames must be > 0, got 0")

    assert run_command("x", "a test command", _configure, fail, ["--frames", "0"]) == EXIT_ERROR
    assert "x: error: x.toml" in capsys.readouterr().err
    with pytest.raises(SystemExit) as exc:
        run_command("x", "a test command", _configure, fail, [])
    assert exc.value.code == EXIT_USAGE
