"""Building views: known robot bodies are not people, a pinhole camera's field of view."""

from __future__ import annotations

import math

import msgspec
import pytest

from common.schema import PanoramicModel, PinholeModel, SensorInfo

SIG = math.radians(0.2)


def test_known_bodies_are_not_people() -> None:
    from resource_manager.ingest.align import AlignedBlob, AlignedView
    from resource_manager.poses.solver import PoseEstimate
    from resource_manager.views.build import build_views

    def b(lid: int, bearing: float, width: float) -> AlignedBlob:
        return AlignedBlob(lid, bearing, width, 0.0 if lid == 1 else 0.15, -0.3, [], True)

    poses = {
        "p1": PoseEstimate("p1", 0.0, 0.0, 1.1, 0.0, "surveyed"),
        "r1": PoseEstimate("r1", 3.0, 0.0, 1.1, 0.0, "mutual"),
    }
    # p1 sees r1's body (R = 0.18 m at 3 m: 0.12 rad wide, top at the camera) straight ahead, a person at
    # 0.5 rad, people merged in front of it (wide), and a person right behind it (taller top)
    blobs = [b(1, 0.002, 0.12), b(2, 0.5, 0.1), b(3, 0.01, 0.8), b(4, 0.003, 0.1)]
    av = AlignedView("p1", 1, blobs, [], "interpolated")
    model = PanoramicModel(width_px=1080, height_px=162, f_v_px=256.0, v0_px=93.0)
    robot = SensorInfo(sensor_id="r1", seq=0, stamp_ns=1, kind="panoramic", model=model, body_radius_m=0.18)
    views = build_views({"p1": av}, poses, {"r1": robot}, lambda s: SIG)
    assert views.sensor_ids == ("p1",) and list(views.local_id) == [2, 3, 4]  # only the body is gone
    bodiless = msgspec.structs.replace(robot, body_radius_m=0.0)
    assert list(build_views({"p1": av}, poses, {"r1": bodiless}, lambda s: SIG).local_id) == [1, 2, 3, 4]


def test_pinhole_field_of_view() -> None:
    from resource_manager.views.build import pinhole_fov

    # camera looking along world +y, level: R rows are the camera axes in world coordinates
    model = PinholeModel(
        width_px=640, height_px=480, k=[320.0, 0, 320, 0, 320, 240, 0, 0, 1], r=[1.0, 0, 0, 0, 0, -1, 0, 1, 0]
    )
    fov = pinhole_fov(model, margin_rad=0.0)
    assert fov is not None
    assert fov[0] == pytest.approx(math.pi / 2) and fov[1] == pytest.approx(math.pi / 4)
    down = PinholeModel(width_px=640, height_px=480, k=[320.0, 0, 320, 0, 320, 240, 0, 0, 1])  # R = I: looks down z
    assert pinhole_fov(down) is None
