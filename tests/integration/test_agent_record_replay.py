"""record -> evaluate, then replay -> record -> evaluate: the same figures (real processes, real router).

The TrackSets come from this test (a driver standing in for the manager's
output): two people on known paths, tracked with a small error and one
injected identity swap, so the figures are non-trivial.
"""

from __future__ import annotations

import json
import math
import subprocess
import sys
import time
from pathlib import Path

import pytest

from common.codec import encode
from common.keys import Keys
from common.schema import Track, TrackSet
from common.session import MSGPACK
from tests.support import client_session, wait_for, wait_for_liveliness
from user_agent.groundtruth import GtPoint, write_gt_rows

pytestmark = pytest.mark.integration

FPS = 10.0
K = Keys("pano")


def truth(t_s: float, pid: int) -> tuple[float, float]:
    return (1.0 + 0.6 * t_s, 1.5 + 2.0 * pid + 0.2 * math.sin(2 * t_s + pid))


def _track(tid: str, x: float, y: float, stamp: int, seq: int) -> Track:
    return Track(manager_id="mgr1", seq=seq, stamp_ns=stamp, track_id=tid, x_m=x, y_m=y, height_m=1.7, vx_mps=0.6,
                 vy_mps=0.0, cov_xx_m2=0.01, cov_xy_m2=0.0, cov_yy_m2=0.01, state="confirmed",
                 method="triangulation", sensors=["pano1", "pano2"])  # fmt: skip


def _agent(*args: str) -> list[str]:
    return [sys.executable, "-m", "panostereo", "agent", *args]


def _evaluate(mcap: Path, gt: Path) -> dict[str, float]:
    proc = subprocess.run(
        _agent("evaluate", str(mcap), "--ground-truth", str(gt), "--json"),
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )
    assert proc.returncode == 0, proc.stderr
    return json.loads(proc.stdout)


def _log_span_s(path: Path) -> float:
    """Seconds of log time between a recording's first and last message."""
    from mcap.reader import make_reader

    with path.open("rb") as fh:
        stats = make_reader(fh).get_summary().statistics  # type: ignore[union-attr]
    assert stats is not None
    return (stats.message_end_time - stats.message_start_time) / 1e9


def test_record_replay_evaluate_same_figures(router, spawn, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    epoch = time.time_ns()
    gt = tmp_path / "gt.csv"
    write_gt_rows(gt, [GtPoint(k, str(p), *truth((k - 1) / FPS, p), 1.7) for k in range(1, 61) for p in (0, 1)])
    first = tmp_path / "live.mcap"
    rec1 = spawn(
        _agent(
            "record",
            str(first),
            "--connect",
            router.endpoint,
            "--epoch-ns",
            str(epoch),
            "--fps",
            str(FPS),
            "--agent-id",
            "rec1",
        ),
        name="rec1",
    )
    with client_session(router.endpoint) as s:
        wait_for_liveliness(s, K.agent("rec1"), timeout_s=20)
        pub = s.declare_publisher(K.tracks(), encoding=MSGPACK)
        # 40 TrackSets at 20 Hz (0.3 .. 2.25 s world time): 3 cm error; ids swap halfway.
        for i in range(40):
            t = 0.3 + i * 0.05
            stamp = epoch + int(t * 1e9)
            ids = ("mgr1-1", "mgr1-2") if i < 20 else ("mgr1-2", "mgr1-1")
            tracks = [_track(ids[p], truth(t, p)[0] + 0.03, truth(t, p)[1], stamp, i) for p in (0, 1)]
            pub.put(encode(TrackSet(manager_id="mgr1", seq=i, stamp_ns=stamp, tracks=tracks)))
            time.sleep(0.02)
        time.sleep(0.3)  # let the last samples reach the recorder before it stops
    assert rec1.stop() == 0
    live = _evaluate(first, gt)
    assert live["id_switches"] == 2 and 0.5 < live["mota"] < 1.0
    assert live["mean_error_m"] == pytest.approx(0.03, abs=0.005)

    second = tmp_path / "replayed.mcap"
    rec2 = spawn(
        _agent(
            "record",
            str(second),
            "--connect",
            router.endpoint,
            "--epoch-ns",
            str(epoch),
            "--fps",
            str(FPS),
            "--agent-id",
            "rec2",
        ),
        name="rec2",
    )
    with client_session(router.endpoint) as s:
        wait_for_liveliness(s, K.agent("rec2"), timeout_s=20)
        t0 = time.monotonic()
        replay = spawn(_agent("replay", str(first), "--speed", "2", "--connect", router.endpoint), name="replay")
        wait_for(lambda: not replay.alive, 30, "replay to finish")
        assert replay.returncode == 0, replay.log()
        # The replay kept the schedule, not a burst: at 2x it takes about half the recording's span of log time
        # (measured from the file: a loaded machine stretches or bunches the live samples).
        assert time.monotonic() - t0 > 0.9 * _log_span_s(first) / 2.0
        time.sleep(0.3)
    assert rec2.stop() == 0
    assert _evaluate(second, gt) == live
