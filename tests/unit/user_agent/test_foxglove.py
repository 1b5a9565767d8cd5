"""The Foxglove scene builders: foxglove-sdk's typed SceneUpdate and FrameTransform from the wire messages."""

from __future__ import annotations

from typing import Any

from msgspec.structs import replace as msgspec_replace

from common.schema import PanoramicModel, Pose, SensorInfo, Track, TrackSet
from tests.support import decode_protobuf
from tests.unit.user_agent.recorded_run import EPOCH, sensor_info
from user_agent.foxglove import WORLD_FRAME, cameras_scene, frame_transform, tracks_scene, truth_scene

STAMP = 1_700_000_000_123_456_789


def _decoded(msg: Any) -> Any:
    schema = msg.get_schema()
    assert schema.encoding == "protobuf"
    return decode_protobuf(schema.name, bytes(schema.data), msg.encode())


def _track(tid: str, speed: float, height_m: float = 1.75) -> Track:
    return Track(manager_id="mgr1", seq=0, stamp_ns=STAMP, track_id=tid, x_m=2.0, y_m=3.0, height_m=height_m,
                 vx_mps=speed, vy_mps=0.0, cov_xx_m2=0.01, cov_xy_m2=0.0, cov_yy_m2=0.01, state="confirmed",
                 method="triangulation", sensors=["pano1", "pano2"], predicted_error_m=0.08)  # fmt: skip


def test_tracks_scene_draws_body_head_label_arrow_and_the_pairs_rays() -> None:
    ts = TrackSet(manager_id="mgr1", seq=0, stamp_ns=STAMP, tracks=[_track("mgr1-1", 0.5), _track("mgr1-2", 0.0, 0.0)])
    scene = _decoded(tracks_scene(ts, {"pano1": (0.0, 0.0, 1.1)}))
    moving, still = scene.entities
    assert moving.id == "track/mgr1-1" and moving.frame_id == WORLD_FRAME
    assert (moving.timestamp.seconds, moving.timestamp.nanos) == (1_700_000_000, 123_456_789)
    assert len(moving.cylinders) == len(moving.spheres) == len(moving.texts) == len(moving.arrows) == 1
    assert len(moving.lines[0].points) == 2  # one ray: only pano1's pose is known
    assert not still.arrows  # no velocity, no arrow
    assert still.cylinders[0].size.z > 1.0  # an unknown height is drawn as a person's


def test_cameras_scene_and_transforms_only_for_placed_cameras() -> None:
    model = PanoramicModel(width_px=1080, height_px=162, f_v_px=256.0, v0_px=93.0)
    placed = SensorInfo(sensor_id="pano1", seq=0, stamp_ns=STAMP, kind="panoramic", model=model,
                        pose=Pose(x_m=1.0, y_m=2.0, z_m=1.1, yaw_rad=0.0), pose_source="surveyed",
                        body_radius_m=0.18)  # fmt: skip
    unplaced = SensorInfo(sensor_id="robot", seq=0, stamp_ns=STAMP, kind="panoramic", model=model, pose=None,
                          pose_source="mutual")  # fmt: skip
    scene = _decoded(cameras_scene([placed, unplaced], STAMP))
    assert [e.id for e in scene.entities] == ["camera/pano1"]
    assert scene.entities[0].cylinders[0].size.x == 2 * 0.18  # the robot's body
    assert frame_transform("robot", None, STAMP) is None
    tf = _decoded(frame_transform("pano1", placed.pose, STAMP))
    assert (tf.parent_frame_id, tf.child_frame_id) == (WORLD_FRAME, "pano1")
    assert (tf.translation.x, tf.translation.y, tf.translation.z) == (1.0, 2.0, 1.1) and tf.rotation.w == 1.0


def test_truth_scene_has_one_grey_figure_per_person() -> None:
    scene = _decoded(truth_scene([("1", 1.0, 1.0, 1.8), ("2", 2.0, 2.0, 0.0)], STAMP, lifetime_s=0.2))
    assert [e.id for e in scene.entities] == ["truth/1", "truth/2"]
    assert all(e.cylinders[0].color.a < 1.0 for e in scene.entities)
    assert scene.entities[0].lifetime.nanos == 200_000_000


def test_a_pose_the_manager_lost_no_longer_places_the_camera() -> None:
    from common.schema import ManagerStatus, PoseEstimate
    from user_agent.foxglove import CameraPlacements

    places = CameraPlacements()
    places.update(msgspec_replace(sensor_info("robot", 0.0, 0.0), pose_source="mutual"), EPOCH)
    est = PoseEstimate(sensor_id="robot", pose=Pose(x_m=3.0, y_m=2.0, z_m=0.0, yaw_rad=0.5), source="mutual")

    def status(poses: list[PoseEstimate]) -> ManagerStatus:
        return ManagerStatus(manager_id="mgr1", seq=1, stamp_ns=EPOCH, tick_ms=1.0, tick_p99_ms=1.0,
                             tick_rate_hz=10.0, poses=poses)  # fmt: skip

    places.update(status([est]), EPOCH)
    assert places.camera_xyz["robot"] == (3.0, 2.0, 1.1)
    places.update(status([]), EPOCH)  # the manager lost it: no rays drawn from where it was
    assert "robot" not in places.camera_xyz
