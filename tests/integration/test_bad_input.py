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


def _write_files(tmp: Path, closed_port: str) -> None:
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
    demo = (REPO / "deploy" / "sites" / "demo.toml").read_text()
    files["site-unknown-key.toml"] = demo.replace("[site]\n", "[site]\nbogus_key = 1\n", 1)
    files["site-bad-fps.toml"] = re.sub(r"(?m)^fps = .*$", "fps = -15.0", demo, count=1)
    files["agent-unreachable.toml"] = (
        f'[agent]\nid = "a1"\n[zenoh]\nconnect = ["tcp/127.0.0.1:{closed_port}"]\nconnect_timeout_ms = 1000\n'
    )
    files["agent-unknown-key.toml"] = '[agent]\nid = "a1"\ncolour = "red"\n'
    files["not-an-mcap.mcap"] = "this is not an MCAP file\n"
    files["gt.csv"] = "frame,id,x_m,y_m\n1,1,0.0,0.0\n"
    sim = (REPO / "deploy" / "nodes" / "examples" / "sim.toml").read_text()
    sim = re.sub(r"(?m)^site = .*$", f'site = "{REPO}/deploy/sites/demo.toml"', sim)
    sim = re.sub(r"(?m)^connect = .*$", f'connect = ["tcp/127.0.0.1:{closed_port}"]\nconnect_timeout_ms = 1000', sim)
    files["node-unreachable.toml"] = sim
    files["node-unknown-key.toml"] = sim.replace("[node]\n", "[node]\nbogus_key = 1\n", 1)
    files["node-bad-id.toml"] = re.sub(r'(?m)^id = "pano1"', 'id = "Bad_Id"', sim, count=1)
    files["node-unknown-camera.toml"] = re.sub(r'(?m)^camera = "pano1"', 'camera = "nosuchcam"', sim, count=1)
    files["node-missing-site.toml"] = re.sub(r"(?m)^site = .*$", f'site = "{tmp}/absent-site.toml"', sim)
    files["node-negative-fps.toml"] = re.sub(r"(?m)^fps = .*$", "fps = -30.0", sim, count=1)
    det = (
        f'[node]\nid = "c1"\n[zenoh]\nconnect = ["tcp/127.0.0.1:{closed_port}"]\nconnect_timeout_ms = 1000\n'
        '[source]\nkind = "detections"\nfile = "{file}"\ncalibration = "{calib}"\nfps = 10.0\n'
    )
    files["bad-calibration.json"] = "{ not json"
    files["calibration.json"] = json.dumps(
        {
            "model": "pinhole",
            "image_size": [640, 480],
            "K": [[400.0, 0.0, 320.0], [0.0, 400.0, 240.0], [0.0, 0.0, 1.0]],
            "R": [[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]],
            "t": [0.0, 2.0, 0.0],
        }
    )
    files["det.txt"] = "1,1,10,10,50,100,0.9,-1,-1,-1\n"
    files["node-missing-detections.toml"] = det.format(file=tmp / "absent-det.txt", calib=tmp / "calibration.json")
    files["node-bad-calibration.toml"] = det.format(file=tmp / "det.txt", calib=tmp / "bad-calibration.json")
    mgr = (REPO / "deploy" / "nodes" / "examples" / "manager.toml").read_text()
    mgr = re.sub(r"(?m)^connect = .*$", f'connect = ["tcp/127.0.0.1:{closed_port}"]\nconnect_timeout_ms = 1000', mgr)
    mgr = re.sub(r"(?m)^state_dir = .*$", f'state_dir = "{tmp}/mgr-state"', mgr)
    files["manager-unreachable.toml"] = mgr
    files["manager-unknown-key.toml"] = mgr.replace("[manager]\n", "[manager]\nbogus_key = 1\n", 1)
    files["manager-bad-matcher.toml"] = re.sub(r"(?m)^matcher = .*$", 'matcher = "fancy"', mgr)
    files["manager-negative-rate.toml"] = re.sub(r"(?m)^rate_hz = .*$", "rate_hz = -10.0", mgr)
    files["manager-bad-id.toml"] = re.sub(r'(?m)^id = "mgr1"', 'id = "MGR 1"', mgr, count=1)
    files["manager-no-sensors.toml"] = re.sub(r"(?m)^sensors = .*$", "sensors = []", mgr)
    files["manager-any-and-ids.toml"] = re.sub(r"(?m)^sensors = .*$", 'sensors = ["*", "pano1"]', mgr)
    for name, text in files.items():
        (tmp / name).write_text(text, errors="surrogateescape")
    (tmp / "a-directory.toml").mkdir(exist_ok=True)
    (tmp / "empty-dataset").mkdir(exist_ok=True)


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
    # -- node -------------------------------------------------------------------------------
    Row("node-missing-config", ("node", "--config", "{tmp}/absent.toml"), r"absent\.toml"),
    Row("node-config-is-empty", ("node", "--config", "{tmp}/empty.toml"), r"empty\.toml.*(node|source)"),
    Row("node-config-syntax", ("node", "--config", "{tmp}/syntax.toml"), r"syntax\.toml"),
    Row("node-config-is-binary", ("node", "--config", "{tmp}/binary.toml"), r"binary\.toml"),
    Row("node-config-unknown-key", ("node", "--config", "{tmp}/node-unknown-key.toml"), r"bogus_key"),
    Row("node-invalid-id", ("node", "--config", "{tmp}/node-bad-id.toml"), r"Bad_Id"),
    Row("node-unknown-camera", ("node", "--config", "{tmp}/node-unknown-camera.toml"), r"nosuchcam"),
    Row("node-missing-site", ("node", "--config", "{tmp}/node-missing-site.toml"), r"absent-site\.toml"),
    Row("node-negative-fps", ("node", "--config", "{tmp}/node-negative-fps.toml"), r"fps"),
    Row("node-missing-detections", ("node", "--config", "{tmp}/node-missing-detections.toml"), r"absent-det\.txt"),
    Row("node-bad-calibration", ("node", "--config", "{tmp}/node-bad-calibration.toml"), r"bad-calibration\.json"),
    Row("node-unreachable-router", ("node", "--config", "{tmp}/node-unreachable.toml"), r"127\.0\.0\.1:{closed}"),
    Row(
        "node-missing-zenoh-config",
        ("node", "--config", "{tmp}/node-unreachable.toml", "--zenoh-config", "{tmp}/absent.json5"),
        r"absent\.json5",
    ),
    Row("node-no-config-flag", ("node",), r"--config"),
    # -- manager ----------------------------------------------------------------------------
    Row("manager-missing-config", ("manager", "--config", "{tmp}/absent.toml"), r"absent\.toml"),
    Row("manager-config-syntax", ("manager", "--config", "{tmp}/syntax.toml"), r"syntax\.toml"),
    Row("manager-config-unknown-key", ("manager", "--config", "{tmp}/manager-unknown-key.toml"), r"bogus_key"),
    Row("manager-invalid-matcher", ("manager", "--config", "{tmp}/manager-bad-matcher.toml"), r"matcher"),
    Row("manager-negative-rate", ("manager", "--config", "{tmp}/manager-negative-rate.toml"), r"rate_hz"),
    Row("manager-invalid-id", ("manager", "--config", "{tmp}/manager-bad-id.toml"), r"MGR 1"),
    Row("manager-no-sensors", ("manager", "--config", "{tmp}/manager-no-sensors.toml"), r"no sensors to fuse"),
    Row("manager-any-and-ids", ("manager", "--config", "{tmp}/manager-any-and-ids.toml"), r"manager\.sensors"),
    Row(
        "manager-unreachable-router",
        ("manager", "--config", "{tmp}/manager-unreachable.toml"),
        r"127\.0\.0\.1:{closed}",
    ),
    # -- calib, evaluate-detections -----------------------------------------------------------
    Row(
        "calib-missing-input",
        ("calib", "convert", "--from", "tsai", "{tmp}/absent.xml", "--out", "{tmp}/c.json"),
        r"absent\.xml",
    ),
    Row(
        "calib-tsai-not-xml",
        ("calib", "convert", "--from", "tsai", "{tmp}/syntax.toml", "--out", "{tmp}/c.json"),
        r"XML",
    ),
    Row(
        "calib-p-matrix-without-size",
        ("calib", "convert", "--from", "p-matrix", "{tmp}/empty.toml", "--out", "{tmp}/c.json"),
        r"--image-size",
    ),
    Row(
        "evaluate-detections-missing-video",
        ("evaluate-detections", "{tmp}/absent.avi", "--ground-truth", "{tmp}/empty.toml"),
        r"absent\.avi",
    ),
    Row(
        "evaluate-detections-binary-boxes",
        ("evaluate-detections", "{tmp}/empty.toml", "--ground-truth", "{tmp}/binary.toml"),
        r"binary\.toml",
    ),
    # -- render -----------------------------------------------------------------------------
    Row(
        "render-missing-site",
        ("render", "--site", "{tmp}/absent.toml", "--camera", "pano1", "--out", "{tmp}/r.png"),
        r"absent\.toml",
    ),
    Row(
        "render-site-syntax",
        ("render", "--site", "{tmp}/syntax.toml", "--camera", "pano1", "--out", "{tmp}/r.png"),
        r"syntax\.toml",
    ),
    Row(
        "render-site-is-binary",
        ("render", "--site", "{tmp}/binary.toml", "--camera", "pano1", "--out", "{tmp}/r.png"),
        r"binary\.toml",
    ),
    Row(
        "render-site-is-a-directory",
        ("render", "--site", "{tmp}/a-directory.toml", "--camera", "pano1", "--out", "{tmp}/r.png"),
        r"a-directory\.toml",
    ),
    Row(
        "render-site-unknown-key",
        ("render", "--site", "{tmp}/site-unknown-key.toml", "--camera", "pano1", "--out", "{tmp}/r.png"),
        r"bogus_key",
    ),
    Row(
        "render-site-invalid-fps",
        ("render", "--site", "{tmp}/site-bad-fps.toml", "--camera", "pano1", "--out", "{tmp}/r.png"),
        r"fps",
    ),
    Row(
        "render-unknown-camera",
        ("render", "--site", "{repo}/deploy/sites/demo.toml", "--camera", "nosuchcam", "--out", "{tmp}/r.png"),
        r"nosuchcam",
    ),
    Row(
        "render-out-under-a-file",  # the output's folder cannot be created: its parent is a file
        ("render", "--site", "{repo}/deploy/sites/demo.toml", "--camera", "pano1", "--out", "{tmp}/empty.toml/r.png"),
        r"r\.png|empty\.toml",
    ),
    Row(
        "render-negative-time",
        (
            "render",
            "--site",
            "{repo}/deploy/sites/demo.toml",
            "--camera",
            "pano1",
            "--time",
            "-5",
            "--out",
            "{tmp}/r.png",
        ),
        r"time",
    ),
    # -- import -----------------------------------------------------------------------------
    Row(
        "import-missing-dataset",
        ("import", "wildtrack", "{tmp}/absent-dataset", "--out", "{tmp}/imp1"),
        r"absent-dataset",
    ),
    Row(
        "import-empty-dataset",
        ("import", "wildtrack", "{tmp}/empty-dataset", "--out", "{tmp}/imp2"),
        r"empty-dataset|annotations|calibrations",
    ),
    Row(
        "import-unknown-format",
        ("import", "mot17", "{tmp}/empty-dataset", "--out", "{tmp}/imp3"),
        r"invalid choice: 'mot17'",
    ),
    Row(
        "import-invalid-drop-rate",
        ("import", "wildtrack", "{tmp}/empty-dataset", "--out", "{tmp}/imp4", "--drop-rate", "2"),
        r"drop",
    ),
    Row("import-mot-without-fps", ("import", "mot", "{tmp}/empty-dataset", "--out", "{tmp}/imp5"), r"--fps"),
    Row(
        "import-mot-empty-dataset",
        ("import", "mot", "{tmp}/empty-dataset", "--out", "{tmp}/imp6", "--fps", "7"),
        r"calib/<cam>\.json",
    ),
    # -- evaluate-site ----------------------------------------------------------------------
    Row("evaluate-site-missing-site", ("evaluate-site", "{tmp}/absent.toml"), r"absent\.toml"),
    Row("evaluate-site-not-a-dataset", ("evaluate-site", "{repo}/deploy/sites/demo.toml"), r"not a dataset site"),
    Row("evaluate-site-unknown-key", ("evaluate-site", "{tmp}/site-unknown-key.toml"), r"bogus_key"),
    # -- up ---------------------------------------------------------------------------------
    Row("up-missing-site", ("up", "{tmp}/absent.toml"), r"absent\.toml"),
    Row("up-site-syntax", ("up", "{tmp}/syntax.toml"), r"syntax\.toml"),
    Row("up-site-unknown-key", ("up", "{tmp}/site-unknown-key.toml"), r"bogus_key"),
    Row("up-site-invalid-fps", ("up", "{tmp}/site-bad-fps.toml"), r"fps"),
    # -- demo -------------------------------------------------------------------------------
    Row("demo-missing-site", ("demo", "--site", "{tmp}/absent.toml", "--out", "{tmp}/demo1"), r"absent\.toml"),
    Row(
        "demo-site-unknown-key", ("demo", "--site", "{tmp}/site-unknown-key.toml", "--out", "{tmp}/demo2"), r"bogus_key"
    ),
    Row("demo-negative-duration", ("demo", "--duration", "-5", "--out", "{tmp}/demo3"), r"duration"),
    # -- agent ------------------------------------------------------------------------------
    Row("agent-missing-config", ("agent", "tracks", "--config", "{tmp}/absent.toml"), r"absent\.toml"),
    Row("agent-config-unknown-key", ("agent", "tracks", "--config", "{tmp}/agent-unknown-key.toml"), r"colour"),
    Row(
        "agent-unreachable-router",
        ("agent", "tracks", "--config", "{tmp}/agent-unreachable.toml", "--timeout", "1"),
        r"127\.0\.0\.1:{closed}",
    ),
    Row(
        "agent-invalid-track-id",
        ("agent", "history", "Not_An_Id", "--config", "{tmp}/agent-unreachable.toml"),
        r"Not_An_Id",
    ),
    Row(
        "agent-replay-not-mcap",
        ("agent", "replay", "{tmp}/not-an-mcap.mcap", "--config", "{tmp}/agent-unreachable.toml"),
        r"not-an-mcap\.mcap",
    ),
    Row(
        "agent-plot-missing-recording", ("agent", "plot", "{tmp}/absent.mcap", "--out", "{tmp}/p.png"), r"absent\.mcap"
    ),
    Row(
        "agent-evaluate-missing-gt",
        ("agent", "evaluate", "{tmp}/not-an-mcap.mcap", "--ground-truth", "{tmp}/absent.csv"),
        r"absent\.csv|not-an-mcap",
    ),
    Row("agent-no-subcommand", ("agent",), r"required|command"),
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
def closed_port() -> str:
    """A loopback port nobody listens on: an unreachable router."""
    return str(free_port())


@pytest.fixture(scope="module")
def results(tmp_path_factory: pytest.TempPathFactory, closed_port: str) -> Iterator[dict[str, Result]]:
    tmp = tmp_path_factory.mktemp("bad-input")
    closed = closed_port
    _write_files(tmp, closed)
    busy = socket.socket(socket.AF_INET, socket.SOCK_STREAM)  # a port really in use while the rows run
    busy.bind(("127.0.0.1", 0))
    busy.listen(1)
    values = {"tmp": str(tmp), "busy": str(busy.getsockname()[1]), "closed": closed, "repo": str(REPO)}
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
def test_bad_input_is_one_clear_line(results: dict[str, Result], row: Row, closed_port: str) -> None:
    check(results[row.id], row.expect.replace("{closed}", closed_port))


def test_rows_cover_each_landed_command() -> None:
    """Every subcommand whose module exists has rows here (add rows when a command lands)."""
    import importlib.util

    from panostereo.cli import COMMANDS

    covered = {r.argv[0] for r in ROWS}
    landed = {name for name, (module, _) in COMMANDS.items() if importlib.util.find_spec(module) is not None}
    assert landed <= covered, f"commands without bad-input rows: {sorted(landed - covered)}"
