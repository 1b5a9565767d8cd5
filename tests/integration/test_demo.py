"""``panostereo demo`` end to end: a short seeded run of the embedded site, scored against its ground truth.

Then the run's recording is replayed through a fresh router into a new
recording, and ``agent evaluate`` on it gives the figures of the live run.
"""

from __future__ import annotations

import importlib.util
import json
import subprocess
import sys
from pathlib import Path

import pytest

from common.keys import Keys
from tests.support import client_session, free_port, skip_or_fail, wait_for, wait_for_liveliness

pytestmark = pytest.mark.integration

DURATION_S = 25


def _need_pipeline() -> None:
    for mod in ("sensor_node.node", "resource_manager.node", "resource_manager.cli"):
        if importlib.util.find_spec(mod) is None:
            skip_or_fail(f"{mod} is not there yet")


@pytest.fixture(scope="module")
def demo_run(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict]:
    _need_pipeline()
    out = tmp_path_factory.mktemp("demo")
    port = free_port()
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "panostereo",
            "demo",
            "--duration",
            str(DURATION_S),
            "--seed",
            "7",
            "--out",
            str(out),
            "--listen",
            f"tcp/127.0.0.1:{port}",
            "--no-view",
        ],
        capture_output=True,
        text=True,
        timeout=DURATION_S + 120,
        check=False,
    )
    logs = "".join(f"--- {p.name}\n{p.read_text()[-3000:]}" for p in sorted((out / "logs").glob("*.log")))
    assert proc.returncode == 0, f"{proc.stdout[-3000:]}\n{proc.stderr[-3000:]}\n{logs}"
    return out, json.loads((out / "summary.json").read_text())


def test_demo_tracks_people_accurately(demo_run: tuple[Path, dict]) -> None:
    out, s = demo_run
    for key in ("cameras", "people", "frames", "tracks_published", "mota", "motp_m", "idf1", "id_switches",
                "mean_error_m", "p90_error_m", "recording", "plot"):  # fmt: skip
        assert key in s
    assert s["cameras"]["site"] == s["cameras"]["started"] == s["cameras"]["publishing"] == 4 and s["people"] == 4
    assert s["cameras"]["fused"] >= 3 and s["cameras_silent"] == [] and s["interrupted"] is False
    # A clean run: nobody else there, nobody forged (a late frame on a loaded machine is no forgery).
    assert s["sensors_not_started"] == [] and s["refused_by_manager"] == {}, s
    assert set(s["recording_lost"]) == {"dropped", "dropped_raw", "max_lag_s", "unscored_s"}
    assert s["frames"] >= 10 * 15  # at least 10 s of the run scored at the site's 15 fps
    assert s["mota"] >= 0.9, s  # issue 7's goal, on every run (live runs differ in start-up and frame timing)
    assert s["mean_error_m"] < 0.3
    assert Path(s["recording"]).stat().st_size > 10_000
    assert Path(s["plot"]).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert (out / "gt.csv").read_text().startswith("frame,id,x_m,y_m")
    from mcap.reader import make_reader

    with Path(s["recording"]).open("rb") as fh:
        summary = make_reader(fh).get_summary()
    assert summary is not None
    topics = {c.topic for c in summary.channels.values()}
    assert {"/scene/tracks", "/scene/ground_truth", "/tf", "pano/@v1/tracks"} <= topics


def test_replayed_recording_scores_the_same(demo_run: tuple[Path, dict], router, spawn, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    out, s = demo_run
    again = tmp_path / "replayed.mcap"
    agent = [sys.executable, "-m", "panostereo", "agent"]
    meta_epoch = json.loads(
        subprocess.run(
            [*agent, "evaluate", s["recording"], "--ground-truth", str(out / "gt.csv"), "--json"],
            capture_output=True, text=True, timeout=60, check=True,
        ).stdout
    )  # fmt: skip
    assert meta_epoch["mota"] == s["mota"] and meta_epoch["idf1"] == s["idf1"]
    from user_agent.recording import read_metadata

    meta = read_metadata(s["recording"])
    rec = spawn([*agent, "record", str(again), "--connect", router.endpoint, "--agent-id", "rerec",
                 "--epoch-ns", meta["epoch_ns"], "--fps", meta["fps"]], name="rerec")  # fmt: skip
    with client_session(router.endpoint) as session:
        wait_for_liveliness(session, Keys().agent("rerec"), timeout_s=20)
        rep = spawn([*agent, "replay", s["recording"], "--speed", "8", "--connect", router.endpoint], name="replay")
        wait_for(lambda: not rep.alive, DURATION_S + 30, "replay to finish")
        assert rep.returncode == 0, rep.log()
    assert rec.stop() == 0
    res = subprocess.run(
        [*agent, "evaluate", str(again), "--ground-truth", str(out / "gt.csv"), "--json",
         "--score-from-ns", meta["score_from_ns"]],
        capture_output=True, text=True, timeout=60, check=True,
    )  # fmt: skip
    replayed = json.loads(res.stdout)
    for key in ("mota", "motp_m", "idf1", "id_switches", "mean_error_m", "p90_error_m", "frames"):
        assert replayed[key] == pytest.approx(s[key] if key in s else meta_epoch[key], abs=1e-6), key
