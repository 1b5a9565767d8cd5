"""The Python client and the agent CLI against a live network (real router, real zenoh sessions).

A driver in this test plays the other tiers' side of the documented keys:
liveliness tokens, TrackSets, statuses, and the queryables for track
history, sensor info and PTZ allocation.
"""

from __future__ import annotations

import json
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from typing import Any

import pytest

from common.codec import decode, encode
from common.keys import Keys
from common.schema import (
    NodeStatus,
    PanoramicModel,
    Pose,
    PtzReply,
    PtzRequest,
    SensorInfo,
    Track,
    TrackSet,
    ViewPlan,
)
from common.session import MSGPACK
from tests.support import client_session, wait_for
from user_agent.client import AgentClient

pytestmark = pytest.mark.integration

K = Keys("pano")


def _track(i: int, stamp: int) -> Track:
    return Track(manager_id="mgr1", seq=i, stamp_ns=stamp, track_id="mgr1-7", x_m=1.0 + 0.1 * i, y_m=2.0,
                 height_m=1.8, vx_mps=1.0, vy_mps=0.0, cov_xx_m2=0.01, cov_xy_m2=0.0, cov_yy_m2=0.01,
                 state="confirmed", method="triangulation", sensors=["pano1", "pano2"],
                 predicted_error_m=0.07)  # fmt: skip


class Driver:
    """The manager's and a sensor's side of the keys, served from one session."""

    def __init__(self, session: Any) -> None:
        self.s = session
        self.now = time.time_ns()
        self.path = [_track(i, self.now - (20 - i) * 100_000_000) for i in range(21)]
        self.requests: list[PtzRequest] = []
        self.tokens = [session.liveliness().declare_token(K.sensor("pano1")),
                       session.liveliness().declare_token(K.manager("mgr1"))]  # fmt: skip
        self.q_track = session.declare_queryable(K.all_tracks, self._on_track)
        self.q_info = session.declare_queryable(K.sensor_info("pano1"), self._on_info)
        self.q_ptz = session.declare_queryable(K.ptz_requests("mgr1"), self._on_ptz)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._publish, daemon=True)
        self._thread.start()

    def _on_track(self, q: Any) -> None:
        with q:
            if "history" in q.parameters:
                since = self.now - int(float(q.parameters["history"]) * 1e9)
                for t in self.path:
                    if t.stamp_ns >= since:
                        q.reply(K.track("mgr1-7"), encode(t), encoding=MSGPACK)
            else:
                q.reply(K.track("mgr1-7"), encode(self.path[-1]), encoding=MSGPACK)

    def _on_info(self, q: Any) -> None:
        with q:
            info = SensorInfo(sensor_id="pano1", seq=0, stamp_ns=self.now, kind="panoramic",
                              model=PanoramicModel(width_px=1080, height_px=162, f_v_px=256.0, v0_px=93.0),
                              pose=Pose(x_m=1.0, y_m=1.0, z_m=1.1, yaw_rad=0.0), pose_source="surveyed")  # fmt: skip
            q.reply(K.sensor_info("pano1"), encode(info), encoding=MSGPACK)

    def _on_ptz(self, q: Any) -> None:
        with q:
            req = decode(q.payload.to_bytes(), PtzRequest)
            self.requests.append(req)
            ok = req.action == "release" or req.track_id == "mgr1-7"
            reply = PtzReply(manager_id="mgr1", seq=len(self.requests), stamp_ns=time.time_ns(), ok=ok,
                             track_id=req.track_id, sensor_id="ptz1" if ok else "",
                             reason="" if ok else "unknown track")  # fmt: skip
            q.reply(str(q.key_expr), encode(reply), encoding=MSGPACK)

    def _publish(self) -> None:
        i = 0
        while not self._stop.wait(0.05):
            stamp = time.time_ns()
            self.s.put(K.tracks(), encode(TrackSet(manager_id="mgr1", seq=i, stamp_ns=stamp, tracks=[self.path[-1]])))
            status = NodeStatus(sensor_id="pano1", seq=i, stamp_ns=stamp, fps=15.0, frames=i, dropped_frames=1,
                                processing_ms=12.0, clock_offset_ns=-2_500_000, clock_uncertainty_ns=1000,
                                clock_source="ntp", decode_errors=0, source_state="ok")  # fmt: skip
            self.s.put(K.sensor_status("pano1"), encode(status))
            plan = ViewPlan(manager_id="mgr1", seq=i, stamp_ns=stamp, sensor_id="pano2", partner_id="pano1",
                            track_id="mgr1-7", goal_x_m=3.0, goal_y_m=1.0, baseline_m=2.0, phi1_rad=1.0,
                            predicted_error_m=0.05, current_error_m=0.2)  # fmt: skip
            self.s.put(K.plan("pano2"), encode(plan))
            i += 1

    def close(self) -> None:
        if self._stop.is_set():
            return
        self._stop.set()
        self._thread.join(5)
        for e in (self.q_track, self.q_info, self.q_ptz, *self.tokens):
            e.undeclare()


@pytest.fixture
def driver(router: Any) -> Iterator[Driver]:
    with client_session(router.endpoint) as s:
        d = Driver(s)
        try:
            yield d
        finally:
            d.close()


def test_python_client_reads_and_queries(router: Any, driver: Driver) -> None:
    seen: list[TrackSet] = []
    with AgentClient(connect=[router.endpoint], agent_id="tester") as agent:
        sub = agent.subscribe(seen.append)
        tracks = agent.tracks(timeout_s=10)
        assert [t.track_id for t in tracks] == ["mgr1-7"]
        wait_for(lambda: len(seen) >= 3, 10, "three TrackSets through subscribe()")
        sub.close()
        n = len(seen)
        time.sleep(0.3)
        assert len(seen) <= n + 1  # closed: no more callbacks (one may be in flight)
        latest = agent.latest("mgr1-7")
        assert latest is not None and latest.seq == 20
        path = agent.history("mgr1-7", seconds=0.55)
        assert [t.seq for t in path] == [15, 16, 17, 18, 19, 20]
        sensors = wait_for(lambda: [s for s in agent.sensors() if s.status is not None], 10, "sensor status")
        (s,) = sensors
        assert s.alive and s.info is not None and s.info.pose is not None and s.clock_offset_ns == -2_500_000
        (m,) = agent.managers()
        assert m.manager_id == "mgr1" and m.alive
        wait_for(agent.plans, 5, "a view plan")
        assert agent.plans()[0].sensor_id == "pano2"
        reply = agent.request_view("mgr1-7", priority=5)
        assert reply.ok and reply.sensor_id == "ptz1"
        assert not agent.request_view("mgr1-9").ok
        assert agent.release_view("mgr1-7").ok
        driver.close()  # the manager goes silent: its tracks stop being current after stale_s
        wait_for(lambda: not agent.tracks(timeout_s=0, stale_s=0.5), 5, "stale tracks to drop out")
    assert [(r.action, r.track_id, r.agent_id) for r in driver.requests] == [
        ("acquire", "mgr1-7", "tester"),
        ("acquire", "mgr1-9", "tester"),
        ("release", "mgr1-7", "tester"),
    ]
    assert driver.requests[0].priority == 5


def _cli(router: Any, *args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "user_agent", *args, "--connect", router.endpoint],
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )


def test_cli_tracks_history_sensors_watch(router: Any, driver: Driver) -> None:
    p = _cli(router, "tracks", "--json")
    assert p.returncode == 0, p.stderr
    (t,) = json.loads(p.stdout)
    assert t["track_id"] == "mgr1-7" and t["type"] == "pano.Track"
    p = _cli(router, "history", "mgr1-7", "--seconds", "0.25", "--json")
    assert p.returncode == 0, p.stderr
    assert [x["seq"] for x in json.loads(p.stdout)] == [18, 19, 20]
    p = _cli(router, "history", "mgr1-7", "--seconds", "1")
    assert p.returncode == 0 and p.stdout.count("confirmed") == 11
    p = _cli(router, "watch", "--once")
    assert p.returncode == 0, p.stderr
    assert "mgr1-7" in p.stdout and "pano1+pano2" in p.stdout and "mgr1" in p.stdout and "pano1" in p.stdout
    p = _cli(router, "view", "mgr1-9")
    assert p.returncode == 1 and "unknown track" in p.stdout
