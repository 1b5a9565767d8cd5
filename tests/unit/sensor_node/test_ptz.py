"""A PTZ head: its camera follows the pose the driver reports, and the wire model is that same camera."""

from __future__ import annotations

import math

import numpy as np
import pytest

from common.cameras import PinholeCamera, PtzCamera
from common.frames import PtzPose
from sensor_node.ptz import PtzDriver, PtzHead

BASE = PtzCamera(x_m=0.2, y_m=0.2, z_m=2.4, width_px=640, height_px=480, hfov_rad=math.radians(60.0))


class _Driver:
    """A head that never moves (the camera model is what is tested)."""

    def command(self, pan_rad: float, tilt_rad: float, zoom: float) -> None:
        return None

    def pose(self, now_ns: int) -> PtzPose:
        return PtzPose(0.0, 0.0, 1.0)


def _head() -> PtzHead:
    driver: PtzDriver = _Driver()
    return PtzHead(driver, BASE)


@pytest.mark.parametrize(
    "pose", [PtzPose(0.0, -0.2, 1.0), PtzPose(math.radians(135.0), -0.5, 3.0), PtzPose(-2.0, 0.1, 10.0)]
)
def test_the_optical_axis_points_where_the_head_reports(pose: PtzPose) -> None:
    cam = _head().camera(pose)
    axis = np.array([math.cos(pose.tilt_rad) * math.cos(pose.pan_rad), math.cos(pose.tilt_rad) * math.sin(pose.pan_rad),
                     math.sin(pose.tilt_rad)])  # fmt: skip
    uv, ok = cam.project(np.array([[BASE.x_m, BASE.y_m, BASE.z_m]]) + 5.0 * axis)
    assert ok.all() and uv[0] == pytest.approx([(640 - 1) / 2, (480 - 1) / 2], abs=1e-6)
    assert cam.center_world == pytest.approx([BASE.x_m, BASE.y_m, BASE.z_m])


def test_zoom_narrows_the_view() -> None:
    head = _head()
    point = np.array([[BASE.x_m + 5.0, BASE.y_m + 0.5, BASE.z_m]])  # a little left of the axis
    offsets = [abs(head.camera(PtzPose(0.0, 0.0, z)).project(point)[0][0, 0] - 319.5) for z in (1.0, 2.0, 4.0)]
    assert offsets[1] == pytest.approx(2 * offsets[0]) and offsets[2] == pytest.approx(4 * offsets[0])


def test_the_wire_model_is_the_heads_camera() -> None:
    head, pose = _head(), PtzPose(1.0, -0.3, 2.0)
    again = PinholeCamera.from_model(head.model(pose))
    points = np.array([[3.0, 4.0, 1.0], [1.0, 3.0, 0.0]])
    assert again.project(points)[0] == pytest.approx(head.camera(pose).project(points)[0])
