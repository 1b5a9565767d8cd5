"""Payloads decoded by their key, and where each camera is as far as anyone knows."""

from __future__ import annotations

import msgspec

from common.codec import encode
from common.keys import Keys
from common.schema import PanoramicModel, Pose, PoseEstimate, SensorInfo, TrackSet
from user_agent.messages import camera_poses, decode_on_key, placed_pose, type_for_key

K = Keys("pano")


def _info(sid: str, source: str, x_m: float) -> SensorInfo:
    model = PanoramicModel(width_px=1080, height_px=162, f_v_px=256.0, v0_px=93.0)
    return SensorInfo(sensor_id=sid, seq=0, stamp_ns=1, kind="panoramic", model=model,
                      pose=Pose(x_m=x_m, y_m=0.0, z_m=1.1, yaw_rad=0.0), pose_source=source)  # fmt: skip


def test_payloads_are_decoded_by_their_key_and_bad_ones_are_none() -> None:
    ts = TrackSet(manager_id="m", seq=3, stamp_ns=5, tracks=[])
    assert type_for_key(K, K.tracks()) is TrackSet
    assert type_for_key(K, "elsewhere/tracks") is None
    assert decode_on_key(K, K.tracks(), encode(ts)) == ts
    assert decode_on_key(K, K.tracks(), b"\xc1not msgpack") is None
    assert decode_on_key(K, K.sensor_info("p1"), encode(ts)) is None  # a TrackSet where a SensorInfo belongs


def test_surveyed_poses_stay_and_mobile_ones_come_from_the_manager_at_their_own_height() -> None:
    fixed, mobile = _info("p1", "surveyed", 2.0), _info("r1", "mutual", 0.0)
    assert placed_pose(fixed) == fixed.pose and placed_pose(mobile) is None
    est = [
        PoseEstimate(sensor_id="r1", pose=Pose(x_m=3.0, y_m=4.0, z_m=0.0, yaw_rad=0.2), source="mutual"),
        PoseEstimate(sensor_id="p1", pose=Pose(x_m=9.0, y_m=9.0, z_m=0.0, yaw_rad=0.0), source="mutual"),
        PoseEstimate(sensor_id="r2", pose=Pose(x_m=1.0, y_m=1.0, z_m=0.9, yaw_rad=0.0), source="mutual"),
    ]
    poses = camera_poses({"p1": fixed, "r1": mobile, "r3": msgspec.structs.replace(mobile, sensor_id="r3")}, est)
    assert poses["p1"] == fixed.pose  # surveyed: the manager's estimate does not move it
    assert poses["r1"] == Pose(x_m=3.0, y_m=4.0, z_m=1.1, yaw_rad=0.2)  # its SensorInfo's height
    assert poses["r2"].z_m == 0.9  # no SensorInfo: the estimate's height
    assert "r3" not in poses  # nobody placed it: never guessed
