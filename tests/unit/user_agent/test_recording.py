"""MCAP sink -> reader -> score/plot, without a network."""

from __future__ import annotations

import json
import math
import threading
import time
import types
from collections.abc import Callable
from pathlib import Path
from typing import Any

import cv2
import pytest
from mcap.reader import make_reader
from msgspec.structs import replace as msgspec_replace

from common.codec import encode
from common.keys import Keys
from common.schema import Features, PairChoice, PairEntry, PanoramicModel, Pose, SensorInfo, Track, TrackSet
from user_agent.groundtruth import GtPoint, read_gt_csv, write_gt_rows
from user_agent.record import McapSink
from user_agent.recording import iter_raw, load_recording
from user_agent.report import plot_recording, score_recording

EPOCH = 1_700_000_000_000_000_000
FPS = 10.0
K = Keys("pano")


def person(k: int, pid: int) -> tuple[float, float]:
    t = (k - 1) / FPS
    return (1.0 + 0.5 * t, 1.0 + pid * 2.0 + 0.3 * math.sin(t))


def _track(tid: str, x: float, y: float, stamp: int) -> Track:
    return Track(manager_id="mgr1", seq=0, stamp_ns=stamp, track_id=tid, x_m=x, y_m=y, height_m=1.75, vx_mps=0.0,
                 vy_mps=0.0, cov_xx_m2=0.01, cov_xy_m2=0.0, cov_yy_m2=0.01, state="confirmed",
                 method="triangulation", sensors=["pano1", "pano2"], predicted_error_m=0.08)  # fmt: skip


def _info(sid: str, x: float, y: float) -> SensorInfo:
    model = PanoramicModel(width_px=1080, height_px=162, f_v_px=256.0, v0_px=93.0)
    pose = Pose(x_m=x, y_m=y, z_m=1.1, yaw_rad=0.0)
    return SensorInfo(sensor_id=sid, seq=0, stamp_ns=EPOCH, kind="panoramic", model=model, pose=pose,
                      pose_source="surveyed", body_radius_m=0.18)  # fmt: skip


@pytest.fixture
def recorded(tmp_path: Path) -> tuple[Path, Path]:
    gt_path = tmp_path / "gt.csv"
    write_gt_rows(gt_path, [GtPoint(k, str(p), *person(k, p), 1.75) for k in range(1, 51) for p in (0, 1)])
    sink = McapSink(tmp_path / "run.mcap", {"epoch_ns": str(EPOCH), "fps": str(FPS), "room_x_m": "8", "room_y_m": "6"})
    for sid, x, y in (("pano1", 0.5, 0.5), ("pano2", 7.5, 0.5)):
        sink.write(K.sensor_info(sid), encode(_info(sid, x, y)), EPOCH)
    sink.write(K.tracks(), b"\xc1garbage", EPOCH + 1)  # an invalid payload is kept raw and counted
    # Tracks at 20 Hz from frame 5 on, offset 5 cm from the truth.
    for i in range(80):
        stamp = EPOCH + int(0.4e9) + i * 50_000_000
        k = 1 + (stamp - EPOCH) / 1e9 * FPS
        tracks = [_track(f"mgr1-{p + 1}", person(k, p)[0] + 0.05, person(k, p)[1], stamp) for p in (0, 1)]
        sink.write(K.tracks(), encode(TrackSet(manager_id="mgr1", seq=i, stamp_ns=stamp, tracks=tracks)), stamp + 10)
        pc = PairChoice(manager_id="mgr1", seq=i, stamp_ns=stamp,
                        choices=[PairEntry(track_id="mgr1-1", sensor_a="pano1", sensor_b="pano2",
                                           predicted_error_m=0.1, method="triangulation")])  # fmt: skip
        sink.write(K.manager_pairs("mgr1"), encode(pc), stamp + 20)
    sink.close()
    return tmp_path / "run.mcap", gt_path


def test_reader_returns_every_raw_sample_with_its_key(recorded: tuple[Path, Path]) -> None:
    mcap, _ = recorded
    raw = list(iter_raw(mcap))
    assert len(raw) == 2 + 1 + 160
    assert raw[0].key == K.sensor_info("pano1")
    rec = load_recording(mcap)
    assert rec.invalid == 1 and len(rec.tracksets) == 80 and set(rec.sensor_infos) == {"pano1", "pano2"}


def _foxglove_messages(mcap: Path, topics: list[str]) -> list[tuple[str, Any]]:
    """(topic, decoded protobuf message) of a recording's Foxglove channels, read with the MCAP reader."""
    from mcap_protobuf.decoder import DecoderFactory

    with mcap.open("rb") as fh:
        reader = make_reader(fh, decoder_factories=[DecoderFactory()])
        return [(c.topic, msg) for _, c, _, msg in reader.iter_decoded_messages(topics=topics)]


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
    scenes = [m for _, m in _foxglove_messages(mcap, ["/scene/tracks"])]
    assert len(scenes) == 80
    ent = scenes[0].entities[0]
    assert ent.frame_id == "world" and ent.timestamp.seconds > 0 and ent.cylinders and ent.lines
    assert ent.id == "track/mgr1-1" and {kv.key: kv.value for kv in ent.metadata}["sensors"] == "pano1,pano2"
    assert len(ent.lines[0].points) == 4  # a ray from each camera of the pair


def test_score_of_recording_with_constant_offset(recorded: tuple[Path, Path]) -> None:
    mcap, gt_path = recorded
    scored = score_recording(load_recording(mcap), read_gt_csv(gt_path), threshold_m=0.5)
    m = scored.metrics
    assert scored.tracks_published == 2
    # Every frame from the first is scored, up to the last TrackSet (4.35 s) plus the 0.25 s gap: frames 1..47
    # ((k - 1) / 10 s). Frames 1 and 2 come before the first TrackSet (0.4 s) by more than the gap: both people
    # are missed there; from frame 3 on, both are tracked.
    assert scored.frames_scored == 47
    assert m.misses == 4 and m.false_positives == 0 and m.id_switches == 0
    assert m.mota == pytest.approx(1 - 4 / 94)
    assert m.mean_error_m == pytest.approx(0.05, abs=0.01)
    # The recording's warm-up end (its score_from_ns) is where scoring starts, when it has one.
    late = score_recording(load_recording(mcap), read_gt_csv(gt_path), start_ns=EPOCH + int(0.2e9))
    assert late.frames_scored == 47 - 3 + 1 and late.metrics.mota == 1.0 and late.metrics.idf1 == 1.0


def test_plot_draws_tracks_and_ground_truth_side_by_side(recorded: tuple[Path, Path], tmp_path: Path) -> None:
    mcap, gt_path = recorded
    out = plot_recording(mcap, tmp_path / "top.png", gt_path)
    img = cv2.imread(str(out))
    assert img is not None and img.shape[1] > 1.8 * img.shape[0] * (6 / 8) * 0.9
    # Coloured (non-grey) pixels exist in both halves: the tracks and the ground-truth paths.
    sat = cv2.cvtColor(img, cv2.COLOR_BGR2HSV)[:, :, 1]
    half = img.shape[1] // 2
    assert (sat[:, :half] > 120).sum() > 200 and (sat[:, half:] > 120).sum() > 200


def test_mobile_cameras_placed_by_mutual_calibration_are_collected_and_drawn(tmp_path: Path) -> None:
    from common.schema import ManagerStatus
    from common.schema import PoseEstimate as WirePose

    sink = McapSink(tmp_path / "m.mcap", {"epoch_ns": str(EPOCH), "fps": str(FPS), "room_x_m": "8", "room_y_m": "6"})
    for i in range(5):
        poses = [
            WirePose(sensor_id="pano1", pose=Pose(x_m=1.0, y_m=1.0, z_m=1.1, yaw_rad=0.0), source="surveyed"),
            WirePose(sensor_id="pano2", pose=Pose(x_m=2.0 + i, y_m=3.0, z_m=1.1, yaw_rad=0.0), source="mutual"),
        ]
        ms = ManagerStatus(manager_id="mgr1", seq=i, stamp_ns=EPOCH + i, tick_ms=1.0, tick_p99_ms=2.0,
                           tick_rate_hz=10.0, poses=poses)  # fmt: skip
        sink.write(K.manager_status("mgr1"), encode(ms), EPOCH + i)
    sink.close()
    rec = load_recording(tmp_path / "m.mcap")
    assert rec.mutual_paths == {"pano2": [(2.0 + i, 3.0) for i in range(5)]}  # surveyed poses are not paths
    with_path = cv2.imread(str(plot_recording(load_recording(tmp_path / "m.mcap"), tmp_path / "a.png")))
    rec.mutual_paths.clear()
    without = cv2.imread(str(plot_recording(rec, tmp_path / "b.png")))
    assert with_path is not None and without is not None
    assert (with_path != without).any()  # the mobile camera's path and body are drawn


def test_mobile_camera_is_drawn_where_the_manager_places_it(tmp_path: Path) -> None:
    from common.schema import ManagerStatus, PoseEstimate

    sink = McapSink(tmp_path / "m.mcap", {"epoch_ns": str(EPOCH)})
    sink.write(K.sensor_info("pano1"), encode(_info("pano1", 0.5, 0.5)), EPOCH)
    mobile = msgspec_replace(_info("robot", 0.0, 0.0), pose_source="mutual")
    sink.write(K.sensor_info("robot"), encode(mobile), EPOCH)
    est = PoseEstimate(sensor_id="robot", pose=Pose(x_m=3.0, y_m=2.0, z_m=0.0, yaw_rad=0.5), source="mutual",
                       sigma_m=0.04)  # fmt: skip
    status = ManagerStatus(manager_id="mgr1", seq=1, stamp_ns=EPOCH + 10**9, tick_ms=1.0, tick_p99_ms=1.0,
                           tick_rate_hz=10.0, poses=[est])  # fmt: skip
    sink.write(K.manager_status("mgr1"), encode(status), EPOCH + 10**9)
    sink.close()
    msgs = _foxglove_messages(tmp_path / "m.mcap", ["/scene/cameras", "/tf"])
    cams = [body for topic, body in msgs if topic == "/scene/cameras"]
    # Before the manager placed it the robot is not drawn (never guessed); after, at the estimate, at its own height.
    assert [e.id for e in cams[1].entities] == ["camera/pano1"]
    robot = next(e for e in cams[-1].entities if e.id == "camera/robot")
    p = robot.cubes[0].pose.position
    assert (p.x, p.y, p.z) == (3.0, 2.0, 1.1)
    tfs = [body for topic, body in msgs if topic == "/tf" and body.child_frame_id == "robot"]
    assert tfs and (tfs[-1].translation.x, tfs[-1].translation.y, tfs[-1].translation.z) == (3.0, 2.0, 1.1)


def test_a_pose_the_manager_lost_no_longer_places_the_camera() -> None:
    from common.schema import ManagerStatus, PoseEstimate
    from user_agent.foxglove import CameraPlacements

    places = CameraPlacements()
    places.update(msgspec_replace(_info("robot", 0.0, 0.0), pose_source="mutual"), EPOCH)
    est = PoseEstimate(sensor_id="robot", pose=Pose(x_m=3.0, y_m=2.0, z_m=0.0, yaw_rad=0.5), source="mutual")

    def status(poses: list[PoseEstimate]) -> ManagerStatus:
        return ManagerStatus(manager_id="mgr1", seq=1, stamp_ns=EPOCH, tick_ms=1.0, tick_p99_ms=1.0,
                             tick_rate_hz=10.0, poses=poses)  # fmt: skip

    places.update(status([est]), EPOCH)
    assert places.camera_xyz["robot"] == (3.0, 2.0, 1.1)
    places.update(status([]), EPOCH)  # the manager lost it: no rays drawn from where it was
    assert "robot" not in places.camera_xyz


def test_lost_tracksets_are_not_scored_but_a_silent_manager_is(recorded: tuple[Path, Path], tmp_path: Path) -> None:
    """Frames where the recording lost TrackSets (a gap in their seq) are skipped, not counted as misses;
    frames where the manager published nothing (no gap: it was silent) are scored."""
    _, gt_path = recorded
    gt = read_gt_csv(gt_path)

    def run(name: str, keep: Callable[[int], bool], seq: Callable[[int], int]) -> Any:
        sink = McapSink(tmp_path / name, {"epoch_ns": str(EPOCH), "fps": str(FPS)})
        for i in range(80):
            if not keep(i):
                continue
            stamp = EPOCH + int(0.4e9) + i * 50_000_000
            k = 1 + (stamp - EPOCH) / 1e9 * FPS
            tracks = [_track(f"mgr1-{p + 1}", *person(k, p), stamp) for p in (0, 1)]
            ts = TrackSet(manager_id="mgr1", seq=seq(i), stamp_ns=stamp, tracks=tracks)
            sink.write(K.tracks(), encode(ts), stamp)
        sink.close()
        return score_recording(load_recording(tmp_path / name), gt)

    lost = run("lost.mcap", lambda i: not 20 <= i < 50, lambda i: i)  # 1.5 s of TrackSets the recorder lost
    silent = run("silent.mcap", lambda i: not 20 <= i < 50, lambda i: i if i < 20 else i - 30)  # manager silent
    assert lost.unseen_s == pytest.approx(1.05, abs=0.06) and silent.unseen_s == 0.0
    # Frames 1 and 2 come before the first TrackSet (both people missed there); the lost span costs nothing.
    assert lost.metrics.misses == 4 and lost.metrics.false_positives == 0
    assert silent.metrics.misses > 4 and silent.frames_scored > lost.frames_scored


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
