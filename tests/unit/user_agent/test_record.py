"""The recorder and its MCAP sink: JSON schemas and Foxglove channels, cameras placed by the manager, drops
counted per key when the writer falls behind."""

from __future__ import annotations

import json
import threading
import time
import types
from collections.abc import Callable
from pathlib import Path
from typing import Any

from mcap.reader import make_reader
from msgspec.structs import replace as msgspec_replace

from common.codec import encode
from common.schema import Features, Pose, TrackSet
from tests.unit.user_agent.recorded_run import EPOCH, K, foxglove_messages, sensor_info
from user_agent.record import McapSink
from user_agent.recording import load_recording


def test_file_has_json_schema_and_foxglove_channels(recorded: tuple[Path, Path]) -> None:
    mcap, _ = recorded
    with mcap.open("rb") as fh:
        summary = make_reader(fh).get_summary()
    assert summary is not None
    schemas = {s.name: s for s in summary.schemas.values()}
    assert {
        "pano.TrackSet",
        "pano.SensorInfo",
        "pano.PairChoice",
        "foxglove.SceneUpdate",
        "foxglove.FrameTransform",
    } <= set(schemas)
    assert json.loads(schemas["pano.TrackSet"].data)["$defs"]["TrackSet"]["type"] == "object"
    # Foxglove's well-known schemas, as foxglove-sdk gives them: protobuf FileDescriptorSets Foxglove recognises.
    for name in ("foxglove.SceneUpdate", "foxglove.FrameTransform"):
        assert schemas[name].encoding == "protobuf" and schemas[name].data
    topics = {c.topic: c for c in summary.channels.values()}
    assert {topics[t].message_encoding for t in ("/scene/tracks", "/scene/cameras", "/tf")} == {"protobuf"}
    assert summary.schemas[topics["/tf"].schema_id].name == "foxglove.FrameTransform"
    assert topics[K.tracks()].metadata["zenoh_key"] == K.tracks()
    assert topics["/json/" + K.tracks()].message_encoding == "json"
    scenes = [m for _, m in foxglove_messages(mcap, ["/scene/tracks"])]
    assert len(scenes) == 80
    ent = scenes[0].entities[0]
    assert ent.frame_id == "world" and ent.timestamp.seconds > 0 and ent.cylinders and ent.lines
    assert ent.id == "track/mgr1-1" and {kv.key: kv.value for kv in ent.metadata}["sensors"] == "pano1,pano2"
    assert len(ent.lines[0].points) == 4  # a ray from each camera of the pair


def test_mobile_camera_is_drawn_where_the_manager_places_it(tmp_path: Path) -> None:
    from common.schema import ManagerStatus, PoseEstimate

    sink = McapSink(tmp_path / "m.mcap", {"epoch_ns": str(EPOCH)})
    sink.write(K.sensor_info("pano1"), encode(sensor_info("pano1", 0.5, 0.5)), EPOCH)
    mobile = msgspec_replace(sensor_info("robot", 0.0, 0.0), pose_source="mutual")
    sink.write(K.sensor_info("robot"), encode(mobile), EPOCH)
    est = PoseEstimate(sensor_id="robot", pose=Pose(x_m=3.0, y_m=2.0, z_m=0.0, yaw_rad=0.5), source="mutual",
                       sigma_m=0.04)  # fmt: skip
    status = ManagerStatus(manager_id="mgr1", seq=1, stamp_ns=EPOCH + 10**9, tick_ms=1.0, tick_p99_ms=1.0,
                           tick_rate_hz=10.0, poses=[est])  # fmt: skip
    sink.write(K.manager_status("mgr1"), encode(status), EPOCH + 10**9)
    sink.close()
    msgs = foxglove_messages(tmp_path / "m.mcap", ["/scene/cameras", "/tf"])
    cams = [body for topic, body in msgs if topic == "/scene/cameras"]
    # Before the manager placed it the robot is not drawn (never guessed); after, at the estimate, at its own height.
    assert [e.id for e in cams[1].entities] == ["camera/pano1"]
    robot = next(e for e in cams[-1].entities if e.id == "camera/robot")
    p = robot.cubes[0].pose.position
    assert (p.x, p.y, p.z) == (3.0, 2.0, 1.1)
    tfs = [body for topic, body in msgs if topic == "/tf" and body.child_frame_id == "robot"]
    assert tfs and (tfs[-1].translation.x, tfs[-1].translation.y, tfs[-1].translation.z) == (3.0, 2.0, 1.1)


class _Session:
    def __init__(self) -> None:
        self.callbacks: list[Callable[[Any], None]] = []

    def declare_subscriber(self, key_expr: str, callback: Callable[[Any], None]) -> Any:
        self.callbacks.append(callback)
        return types.SimpleNamespace(undeclare=lambda: None)


def _sample(key: str, data: bytes) -> Any:
    return types.SimpleNamespace(key_expr=key, payload=types.SimpleNamespace(to_bytes=lambda: data))


def test_recorder_drops_features_first_counts_every_drop_per_key_and_writes_the_counts(tmp_path: Path) -> None:
    from user_agent.record import RECORDER_META, Recorder
    from user_agent.recording import read_metadata

    session = _Session()
    sink = McapSink(tmp_path / "r.mcap", {"epoch_ns": str(EPOCH)})
    gate = threading.Event()
    write = sink.write

    def slow_write(key: str, data: bytes, t: int) -> None:
        gate.wait()  # the writer is stuck until the test lets it go: everything queues
        write(key, data, t)

    sink.write = slow_write  # type: ignore[method-assign]
    rec = Recorder(session, [K.all], sink, capacity=50, raw_capacity=10, max_lag_s=0.2)
    (deliver,) = session.callbacks
    feat = encode(Features(sensor_id="pano1", seq=0, stamp_ns=EPOCH, frame_index=0))
    for i in range(40):
        deliver(_sample(K.tracks(), encode(TrackSet(manager_id="mgr1", seq=i, stamp_ns=EPOCH + i))))
    for _ in range(100):
        deliver(_sample(K.sensor_features("pano1"), feat))
    for i in range(40, 60):  # the queue is full: the queued features go before any track
        deliver(_sample(K.tracks(), encode(TrackSet(manager_id="mgr1", seq=i, stamp_ns=EPOCH + i))))
    st = rec.status()
    assert st.dropped == 100 + 10 and st.dropped_raw == 100  # 90 refused at the door, 10 pushed out; 10 tracks
    assert rec.drops == {K.sensor_features("pano1"): 100, K.tracks(): 10}
    assert rec.top_drops(1) == [(K.sensor_features("pano1"), 100)]  # what the record/demo screens name
    time.sleep(0.3)
    gate.set()
    rec.stop()
    meta = read_metadata(tmp_path / "r.mcap")
    assert meta["dropped"] == "110" and meta[f"dropped:{K.tracks()}"] == "10"
    assert RECORDER_META.startswith("panostereo.")
    tracks = load_recording(tmp_path / "r.mcap").tracksets
    assert [t.seq for t in tracks] == list(range(10, 60))  # the oldest tracks went only when no feature was left


def test_recorder_drops_features_that_waited_too_long_and_caps_its_keys(tmp_path: Path) -> None:
    from user_agent.record import Recorder

    session = _Session()
    sink = McapSink(tmp_path / "r.mcap", {})
    gate = threading.Event()
    write = sink.write
    sink.write = lambda k, d, t: (gate.wait(), write(k, d, t))  # type: ignore[method-assign, func-returns-value]
    rec = Recorder(session, K.all, sink, capacity=1000, raw_capacity=500, max_lag_s=0.1, max_keys=5)
    (deliver,) = session.callbacks
    deliver(_sample(K.tracks(), b"\xc1"))  # the writer takes it and waits on the gate
    for i in range(20):
        deliver(_sample(K.sensor_features(f"s{i}"), b"\x00"))
    assert rec.status().dropped == 16  # 5 keys at most: tracks and s0..s3
    time.sleep(0.2)
    gate.set()
    rec.stop()
    st = rec.status()
    assert st.dropped == 20 and st.dropped_raw == 20 and st.written == 1  # the 4 stale features too
