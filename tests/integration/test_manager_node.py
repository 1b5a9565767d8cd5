"""The manager as a real process: features in over zenoh, tracks out, queries, PTZ, persistence, SIGTERM."""

from __future__ import annotations

import math
import signal
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from common.codec import decode, encode
from common.keys import Keys
from common.schema import (
    ManagerStatus,
    PinholeModel,
    Pose,
    PtzCommand,
    PtzReply,
    PtzRequest,
    SensorInfo,
    Track,
    TrackSet,
)
from common.session import MSGPACK
from tests.support import client_session, wait_for, wait_for_liveliness
from tests.unit.resource_manager.synth import Cam, Person, features_for, info_for

pytestmark = pytest.mark.integration

PREFIX = "itest-mgr"
MID = "mgr-it"
CAMS = [Cam("pa", 0.5, 0.5), Cam("pb", 4.5, 0.5)]


def _ptz_info() -> SensorInfo:
    return SensorInfo(
        sensor_id="zz1",
        seq=0,
        stamp_ns=time.time_ns(),
        kind="ptz",
        model=PinholeModel(width_px=640, height_px=480, k=[500.0, 0, 320, 0, 500, 240, 0, 0, 1]),
        pose=Pose(x_m=2.5, y_m=6.0, z_m=2.5, yaw_rad=0.0),
        pose_source="surveyed",
    )


class FakeSensors:
    """Two panoramic sensors (liveliness, SensorInfo, Features at 15 Hz) and a PTZ camera, in-process."""

    def __init__(self, session: Any, keys: Keys) -> None:
        self.session = session
        self.keys = keys
        self.stop = threading.Event()
        self.tokens = [session.liveliness().declare_token(keys.sensor(c.id)) for c in CAMS]
        self.tokens.append(session.liveliness().declare_token(keys.sensor("zz1")))
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.rng = np.random.default_rng(3)

    def person_at(self, t_s: float) -> Person:
        return Person(2.5 + 1.2 * math.cos(0.3 * t_s), 3.0 + 1.2 * math.sin(0.3 * t_s), 1.75)

    def _run(self) -> None:
        seq = 0
        t_start = time.time()
        while not self.stop.is_set():
            now_ns = time.time_ns()
            if seq % 15 == 0:
                for c in CAMS:
                    self.session.put(self.keys.sensor_info(c.id), encode(info_for(c, seq, now_ns)), encoding=MSGPACK)
                self.session.put(self.keys.sensor_info("zz1"), encode(_ptz_info()), encoding=MSGPACK)
            person = self.person_at(now_ns / 1e9 - t_start)
            for c in CAMS:
                f = features_for(c, [person], CAMS, now_ns, seq, self.rng)
                self.session.put(self.keys.sensor_features(c.id), encode(f), encoding=MSGPACK)
            seq += 1
            self.stop.wait(1 / 15)

    def __enter__(self) -> FakeSensors:
        self.thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop.set()
        self.thread.join(timeout=5)
        for t in self.tokens:
            t.undeclare()


def _config(tmp_path: Path) -> Path:
    cfg = tmp_path / "manager.toml"
    cfg.write_text(
        f'[manager]\nid = "{MID}"\nprefix = "{PREFIX}"\nrate_hz = 10.0\nlatency_ms = 150.0\n'
        'state_dir = "state"\nhistory_hz = 10.0\nsensors = ["pa", "pb", "zz1"]\n\n[planner]\nenabled = false\n'
    )
    return cfg


@pytest.fixture
def sessions(router: Any) -> Iterator[Any]:
    with client_session(router.endpoint) as s:
        yield s


def _start(spawn: Any, cfg: Path, router: Any) -> Any:
    return spawn([sys.executable, "-m", "resource_manager", "--config", cfg, "--connect", router.endpoint], name="mgr")


def _get(session: Any, selector: str, payload: bytes | None = None, timeout: float = 3.0) -> list[Any]:
    import zenoh

    # Consolidation NONE: every state of a path comes on the same key, and must not be merged into one.
    return list(session.get(selector, payload=payload, timeout=timeout, consolidation=zenoh.ConsolidationMode.NONE))


def test_manager_end_to_end(router: Any, spawn: Any, sessions: Any, tmp_path: Path) -> None:
    keys = Keys(PREFIX)
    cfg = _config(tmp_path)
    mgr = _start(spawn, cfg, router)
    wait_for_liveliness(sessions, keys.manager(MID), timeout_s=20)
    tracksets: list[TrackSet] = []
    statuses: list[ManagerStatus] = []
    commands: list[PtzCommand] = []
    subs = [
        sessions.declare_subscriber(keys.tracks(), lambda s: tracksets.append(decode(s.payload.to_bytes(), TrackSet))),
        sessions.declare_subscriber(
            keys.manager_status(MID), lambda s: statuses.append(decode(s.payload.to_bytes(), ManagerStatus))
        ),
        sessions.declare_subscriber(
            keys.sensor_ptz("zz1"), lambda s: commands.append(decode(s.payload.to_bytes(), PtzCommand))
        ),
    ]
    try:
        with FakeSensors(sessions, keys):
            # Tracks arrive on keys.tracks().
            ts = wait_for(
                lambda: next((t for t in reversed(tracksets) if t.tracks), None), 20, "a TrackSet with a track"
            )
            tid = ts.tracks[0].track_id
            assert tid.startswith(f"{MID}-")
            assert sorted(ts.sensors_used) == ["pa", "pb"]
            # the TrackSet says when it was published: after its fusion instant, on the same (NTP) clock
            assert ts.published_ns >= ts.stamp_ns
            wait_for(lambda: len([t for t in tracksets if t.tracks]) >= 12, 10, "more tracked ticks")
            # get keys.track(tid): the latest state.
            replies = _get(sessions, keys.track(tid))
            assert len(replies) == 1 and replies[0].ok is not None
            latest = decode(replies[0].ok.payload.to_bytes(), Track)
            assert latest.track_id == tid and latest.state in ("confirmed", "coasting")
            # ?history=SECONDS: the path, one reply per state, oldest first.
            path = [decode(r.ok.payload.to_bytes(), Track) for r in _get(sessions, keys.track(tid) + "?history=30")]
            assert len(path) >= 5
            assert [p.stamp_ns for p in path] == sorted(p.stamp_ns for p in path)
            bad = _get(sessions, keys.track(tid) + "?history=abc")
            assert bad and bad[0].err is not None
            # PTZ allocation: acquire, a lower priority is refused with a reason, commands follow, release.
            req = PtzRequest(agent_id="ag1", seq=1, stamp_ns=time.time_ns(), action="acquire", track_id=tid, priority=5)
            rep = decode(_get(sessions, keys.ptz_request(MID, "ag1"), encode(req))[0].ok.payload.to_bytes(), PtzReply)
            assert rep.ok and rep.sensor_id == "zz1", rep
            assert 0 < rep.lease_s <= 30.0, rep
            low = PtzRequest(agent_id="ag2", seq=1, stamp_ns=time.time_ns(), action="acquire", track_id=tid, priority=1)
            rep2 = decode(_get(sessions, keys.ptz_request(MID, "ag2"), encode(low))[0].ok.payload.to_bytes(), PtzReply)
            assert not rep2.ok and "priority" in rep2.reason
            cmd = wait_for(lambda: commands[-1] if commands else None, 5, "a PTZ command")
            assert cmd.sensor_id == "zz1" and cmd.track_id == tid and -1.2 < cmd.tilt_rad < 0.2
            rel = PtzRequest(agent_id="ag1", seq=2, stamp_ns=time.time_ns(), action="release", track_id=tid)
            # Identity is the key's: ag2 cannot release ag1's view by naming ag1 in its payload.
            forged = _get(sessions, keys.ptz_request(MID, "ag2"), encode(rel))
            assert forged and forged[0].err is not None and "ag1" in forged[0].err.payload.to_string()
            rep3 = decode(_get(sessions, keys.ptz_request(MID, "ag1"), encode(rel))[0].ok.payload.to_bytes(), PtzReply)
            assert rep3.ok and rep3.sensor_id == "zz1"
            junk = _get(sessions, keys.ptz_request(MID, "ag1"), b"\x00garbage")
            assert junk and junk[0].err is not None
            old_key = _get(sessions, keys.manager_ptz(MID), encode(req))
            assert old_key and old_key[0].err is not None and "ptz/" in old_key[0].err.payload.to_string()
            st = wait_for(lambda: statuses[-1] if statuses else None, 5, "a ManagerStatus")
            assert st.tracks >= 1 and "pa" in st.sensors_in_use and st.tick_ms > 0
            assert st.sensors_expected == ["pa", "pb", "zz1"]
            # where the latency went, and each sensor's frame timing as the schedule measures it
            st = wait_for(lambda: statuses[-1] if statuses and statuses[-1].latency else None, 5, "a latency split")
            assert st.schedule == "watermark" and st.latency is not None
            assert 0 < st.latency.age_p50_ms < 1000 and st.latency.fusion_ms > 0
            timing = {t.sensor_id: t for t in st.timing}
            assert {"pa", "pb"} <= set(timing) and timing["pa"].frames > 0 and timing["pa"].period_ms > 0
            assert st.frames_received >= timing["pa"].frames
            wait_for(
                lambda: any(r.sender_id == "ag2" and r.wrong_id >= 1 for r in statuses[-1].refused),
                5,
                "the forged release counted against ag2 in ManagerStatus.refused",
            )
        # SIGTERM: a clean exit.
        mgr.signal(signal.SIGTERM)
        assert mgr.wait(10) == 0
        # Restart on the same state: the history before the restart is still served, ids do not repeat.
        mgr2 = _start(spawn, cfg, router)
        wait_for_liveliness(sessions, keys.manager(MID), timeout_s=20)
        old = [decode(r.ok.payload.to_bytes(), Track) for r in _get(sessions, keys.track(tid) + "?history=120")]
        assert len(old) >= len(path)
        with FakeSensors(sessions, keys):
            n0 = len(tracksets)
            ts2 = wait_for(
                lambda: next((t for t in tracksets[n0:] if t.tracks), None), 20, "a TrackSet after the restart"
            )
        assert all(int(t.track_id.rsplit("-", 1)[1]) > int(tid.rsplit("-", 1)[1]) for t in ts2.tracks)
        mgr2.signal(signal.SIGTERM)
        assert mgr2.wait(10) == 0
    finally:
        for s in subs:
            s.undeclare()


def test_a_killed_agents_ptz_hold_goes_to_the_next_agent_within_3_s(
    router: Any, spawn: Any, sessions: Any, tmp_path: Path
) -> None:
    """`agent view` holds the PTZ camera while it runs; kill -9 it, and another agent at the same priority gets
    the camera within 3 s (its liveliness token went, so its hold did)."""
    from user_agent.client import AgentClient

    keys = Keys(PREFIX)
    _start(spawn, _config(tmp_path), router)
    wait_for_liveliness(sessions, keys.manager(MID), timeout_s=20)
    tracksets: list[TrackSet] = []
    sub = sessions.declare_subscriber(keys.tracks(), lambda s: tracksets.append(decode(s.payload.to_bytes(), TrackSet)))
    try:
        with FakeSensors(sessions, keys), AgentClient(sessions, prefix=PREFIX, agent_id="second") as other:
            ts = wait_for(lambda: next((t for t in reversed(tracksets) if t.tracks), None), 20, "a track")
            tid = ts.tracks[0].track_id
            holder = spawn(
                [sys.executable, "-m", "panostereo", "agent", "view", tid, "--prefix", PREFIX,
                 "--connect", router.endpoint, "--agent-id", "holder"],
                name="holder",
            )  # fmt: skip
            holder.wait_for_output(r"holding zz1", 20)
            refused = other.request_view(tid)
            assert not refused.ok and "held" in refused.reason, refused
            assert "holder" not in refused.reason, f"a refusal names who holds the camera: {refused}"
            t_kill = time.monotonic()
            holder.signal(signal.SIGKILL)
            reply = wait_for(lambda: (r := other.request_view(tid)).ok and r, 10, "the camera for the second agent")
            taken_s = time.monotonic() - t_kill
            assert reply.sensor_id == "zz1"
            assert taken_s <= 3.0, f"the second agent got the camera {taken_s:.2f} s after the holder was killed"
    finally:
        sub.undeclare()
