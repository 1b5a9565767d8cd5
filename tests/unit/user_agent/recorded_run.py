"""A recorded run made in the test: two panoramic cameras, two people walking, tracks 5 cm off the truth at
20 Hz, an invalid payload; its MCAP file and ground truth (the ``recorded`` fixture of conftest.py)."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from mcap.reader import make_reader

from common.codec import encode
from common.keys import Keys
from common.schema import PairChoice, PairEntry, PanoramicModel, Pose, SensorInfo, Track, TrackSet
from user_agent.groundtruth import GtPoint, write_gt_rows
from user_agent.record import McapSink

EPOCH = 1_700_000_000_000_000_000


FPS = 10.0


K = Keys("pano")


def person(k: int, pid: int) -> tuple[float, float]:
    t = (k - 1) / FPS
    return (1.0 + 0.5 * t, 1.0 + pid * 2.0 + 0.3 * math.sin(t))


def track(tid: str, x: float, y: float, stamp: int) -> Track:
    return Track(manager_id="mgr1", seq=0, stamp_ns=stamp, track_id=tid, x_m=x, y_m=y, height_m=1.75, vx_mps=0.0,
                 vy_mps=0.0, cov_xx_m2=0.01, cov_xy_m2=0.0, cov_yy_m2=0.01, state="confirmed",
                 method="triangulation", sensors=["pano1", "pano2"], predicted_error_m=0.08)  # fmt: skip


def sensor_info(sid: str, x: float, y: float) -> SensorInfo:
    model = PanoramicModel(width_px=1080, height_px=162, f_v_px=256.0, v0_px=93.0)
    pose = Pose(x_m=x, y_m=y, z_m=1.1, yaw_rad=0.0)
    return SensorInfo(sensor_id=sid, seq=0, stamp_ns=EPOCH, kind="panoramic", model=model, pose=pose,
                      pose_source="surveyed", body_radius_m=0.18)  # fmt: skip


def record_run(tmp_path: Path) -> tuple[Path, Path]:
    """Write the run under ``tmp_path``: (its MCAP file, its ground-truth CSV)."""
    gt_path = tmp_path / "gt.csv"
    write_gt_rows(gt_path, [GtPoint(k, str(p), *person(k, p), 1.75) for k in range(1, 51) for p in (0, 1)])
    sink = McapSink(tmp_path / "run.mcap", {"epoch_ns": str(EPOCH), "fps": str(FPS), "room_x_m": "8", "room_y_m": "6"})
    for sid, x, y in (("pano1", 0.5, 0.5), ("pano2", 7.5, 0.5)):
        sink.write(K.sensor_info(sid), encode(sensor_info(sid, x, y)), EPOCH)
    sink.write(K.tracks(), b"\xc1garbage", EPOCH + 1)  # an invalid payload is kept raw and counted
    # Tracks at 20 Hz from frame 5 on, offset 5 cm from the truth.
    for i in range(80):
        stamp = EPOCH + int(0.4e9) + i * 50_000_000
        k = 1 + (stamp - EPOCH) / 1e9 * FPS
        tracks = [track(f"mgr1-{p + 1}", person(k, p)[0] + 0.05, person(k, p)[1], stamp) for p in (0, 1)]
        sink.write(K.tracks(), encode(TrackSet(manager_id="mgr1", seq=i, stamp_ns=stamp, tracks=tracks)), stamp + 10)
        pc = PairChoice(manager_id="mgr1", seq=i, stamp_ns=stamp,
                        choices=[PairEntry(track_id="mgr1-1", sensor_a="pano1", sensor_b="pano2",
                                           predicted_error_m=0.1, method="triangulation")])  # fmt: skip
        sink.write(K.manager_pairs("mgr1"), encode(pc), stamp + 20)
    sink.close()
    return tmp_path / "run.mcap", gt_path


def foxglove_messages(mcap: Path, topics: list[str]) -> list[tuple[str, Any]]:
    """(topic, decoded protobuf message) of a recording's Foxglove channels, read with the MCAP reader."""
    from mcap_protobuf.decoder import DecoderFactory

    with mcap.open("rb") as fh:
        reader = make_reader(fh, decoder_factories=[DecoderFactory()])
        return [(c.topic, msg) for _, c, _, msg in reader.iter_decoded_messages(topics=topics)]
