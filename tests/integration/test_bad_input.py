"""Bad input to every command: one clear line on stderr and a non-zero exit code (issue 8).

Table-driven: each row is a ``panostereo`` command line with something wrong in it (a missing
or unreadable file, a syntax error, an unknown key, an invalid value, an unknown camera, an
unreachable router). All rows run as real subprocesses, concurrently, once per module; each
row then checks that the process

* exited non-zero (1 for an expected error, 2 for a usage error; never a crash),
* printed no traceback and no Rust source location,
* printed exactly one line containing ``error:``, which says what was wrong (the row's regex).
"""

from __future__ import annotations

import json
import re
import socket
import subprocess
import sys
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import pytest

from tests.support import REPO, child_env, free_port

pytestmark = [pytest.mark.integration, pytest.mark.timeout(180)]

ROW_TIMEOUT_S = 60.0
"""Upper bound for one row (an unreachable router is given a 1 s connect timeout in its config)."""


@dataclass(frozen=True)
class Row:
    """One bad command line. ``{tmp}``, ``{busy}``, ``{closed}`` and ``{repo}`` are filled in."""

    id: str
    argv: tuple[str, ...]
    expect: str
    """Regex the single error line must match (case-insensitive)."""


@dataclass(frozen=True)
class Result:
    argv: list[str]
    returncode: int
    stdout: str
    stderr: str


# ---------------------------------------------------------------------------
# Files the rows refer to
# ---------------------------------------------------------------------------


def _write_files(tmp: Path) -> None:
    files = {
        "syntax.json5": "{ mode: ",
        "unknown-key.json5": '{ mode: "router", bogus_key: 1 }',
        "bad-tls.json5": json.dumps(
            {
                "mode": "router",
                "transport": {
                    "link": {
                        "protocols": ["tls"],
                        "tls": {
                            "root_ca_certificate": f"{tmp}/absent-ca.pem",
                            "listen_certificate": f"{tmp}/absent.pem",
                            "listen_private_key": f"{tmp}/absent.key",
                        },
                    }
                },
            }
        ),
        "empty.toml": "",
        "syntax.toml": "[node\nid = 1\n",
        "binary.toml": "\x00\x01\x02garbage\xff",
    }
    for name, text in files.items():
        (tmp / name).write_text(text, errors="surrogateescape")
    (tmp / "a-directory.toml").mkdir(exist_ok=True)


ROWS: list[Row] = [
    # -- the umbrella ----------------------------------------------------------------------
    Row("umbrella-unknown-command", ("nosuchcommand",), r"unknown command 'nosuchcommand'"),
    # -- router -----------------------------------------------------------------------------
    Row("router-missing-zenoh-config", ("router", "--zenoh-config", "{tmp}/absent.json5"), r"absent\.json5.*not exist"),
    Row("router-zenoh-config-syntax", ("router", "--zenoh-config", "{tmp}/syntax.json5"), r"zenoh config"),
    Row("router-zenoh-config-unknown-key", ("router", "--zenoh-config", "{tmp}/unknown-key.json5"), r"bogus_key"),
    Row(
        "router-tls-certificate-missing",
        ("router", "--zenoh-config", "{tmp}/bad-tls.json5", "--listen", "tls/127.0.0.1:{closed}"),
        r"TLS .*(certificate|key)",
    ),
    Row("router-endpoint-malformed", ("router", "--listen", "not-an-endpoint"), r"not-an-endpoint|endpoint"),
    Row("router-port-out-of-range", ("router", "--listen", "tcp/127.0.0.1:99999"), r"port"),
    Row("router-port-in-use", ("router", "--listen", "tcp/127.0.0.1:{busy}"), r"already in use"),
    Row("router-unknown-host", ("router", "--listen", "tcp/no-such-host.invalid:7447"), r"no-such-host\.invalid"),
    Row("router-unknown-flag", ("router", "--frobnicate"), r"unrecognized arguments: --frobnicate"),
    # -- plan -------------------------------------------------------------------------------
    Row("plan-missing-distance", ("plan", "--radius", "0.2"), r"--distance"),
    Row("plan-not-a-number", ("plan", "--distance", "five", "--radius", "0.2"), r"invalid float value: 'five'"),
    Row("plan-negative-radius", ("plan", "--distance", "5", "--radius", "-0.2"), r"--radius must be > 0"),
    Row("plan-infinite-distance", ("plan", "--distance", "inf", "--radius", "0.2"), r"--distance must be"),
    Row(
        "plan-nan-bearing-error",
        ("plan", "--distance", "5", "--radius", "0.2", "--bearing-error-deg", "nan"),
        r"bearing",
    ),
    Row(
        "plan-map-into-missing-dir",
        ("plan", "--distance", "5", "--radius", "0.2", "--map", "{tmp}/no/such/dir/map.png"),
        r"map\.png",
    ),
    Row("plan-map-is-a-directory", ("plan", "--distance", "5", "--radius", "0.2", "--map", "{tmp}"), r"--map|png"),
]


# ---------------------------------------------------------------------------
# Running the table
# ---------------------------------------------------------------------------


def _fill(arg: str, values: dict[str, str]) -> str:
    for k, v in values.items():
        arg = arg.replace("{" + k + "}", v)
    return arg


def _run(argv: list[str]) -> Result:
    try:
        res = subprocess.run(
            argv,
            cwd=REPO,
            env=child_env(),
            stdin=subprocess.DEVNULL,
            capture_output=True,
            text=True,
            errors="replace",
            timeout=ROW_TIMEOUT_S,
            check=False,
        )
    except subprocess.TimeoutExpired as err:
        out = err.stdout.decode(errors="replace") if isinstance(err.stdout, bytes) else str(err.stdout or "")
        errs = err.stderr.decode(errors="replace") if isinstance(err.stderr, bytes) else str(err.stderr or "")
        return Result(argv, -9, out, errs + f"\n[still running after {ROW_TIMEOUT_S:g} s: killed]")
    return Result(argv, res.returncode, res.stdout, res.stderr)


@pytest.fixture(scope="module")
def results(tmp_path_factory: pytest.TempPathFactory) -> Iterator[dict[str, Result]]:
    tmp = tmp_path_factory.mktemp("bad-input")
    _write_files(tmp)
    busy = socket.socket(socket.AF_INET, socket.SOCK_STREAM)  # a port really in use while the rows run
    busy.bind(("127.0.0.1", 0))
    busy.listen(1)
    values = {"tmp": str(tmp), "busy": str(busy.getsockname()[1]), "closed": str(free_port()), "repo": str(REPO)}
    jobs: dict[str, list[str]] = {
        row.id: [sys.executable, "-m", "panostereo", *(_fill(a, values) for a in row.argv)] for row in ROWS
    }
    try:
        with ThreadPoolExecutor(max_workers=4) as pool:
            futures = {rid: pool.submit(_run, argv) for rid, argv in jobs.items()}
            yield {rid: f.result() for rid, f in futures.items()}
    finally:
        busy.close()


_RUST_PATH = re.compile(r"\.rs:\d+")
_ERROR_LINE = re.compile(r"\berror:", re.IGNORECASE)


def check(res: Result, expect: str) -> None:
    where = f"{' '.join(res.argv)}\n--- rc {res.returncode}\n--- stderr:\n{res.stderr}--- stdout:\n{res.stdout}"
    assert res.returncode not in (0, -9), f"expected a non-zero exit:\n{where}"
    assert res.returncode in (1, 2), f"expected exit code 1 (error) or 2 (usage), not a crash:\n{where}"
    assert "Traceback" not in res.stderr, f"a traceback instead of one clear line:\n{where}"
    assert not _RUST_PATH.search(res.stderr), f"a Rust source location leaked into the message:\n{where}"
    lines = [ln for ln in res.stderr.splitlines() if _ERROR_LINE.search(ln)]
    assert len(lines) == 1, f"expected exactly one error line, got {len(lines)}:\n{where}"
    assert re.search(expect, lines[0], re.IGNORECASE), f"error line does not say {expect!r}:\n{where}"
    # The message is the last thing printed: nothing after it pretends the command went on.
    tail = res.stderr.rstrip().splitlines()[-1]
    assert _ERROR_LINE.search(tail), f"the error is not the last line on stderr:\n{where}"


@pytest.mark.parametrize("row", ROWS, ids=[r.id for r in ROWS])
def test_bad_input_is_one_clear_line(results: dict[str, Result], row: Row) -> None:
    check(results[row.id], row.expect)


def test_rows_cover_each_landed_command() -> None:
    """Every subcommand whose module exists has rows here (add rows when a command lands)."""
    import importlib.util

    from panostereo.cli import COMMANDS

    covered = {r.argv[0] for r in ROWS}
    landed = {name for name, (module, _) in COMMANDS.items() if importlib.util.find_spec(module) is not None}
    assert landed <= covered, f"commands without bad-input rows: {sorted(landed - covered)}"
