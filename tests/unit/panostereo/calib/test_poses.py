"""A camera's pose and the parameters that move it."""

from __future__ import annotations

import math

import numpy as np
import pytest

from panostereo.calib.poses import CameraPose, pose_change, rotation_z


def test_a_level_camera_turns_about_the_vertical_only() -> None:
    p = CameraPose.from_yaw(1.0, 2.0, 1.2, math.radians(30.0))
    assert p.yaw_rad == pytest.approx(math.radians(30.0))
    q = p.moved([math.radians(10.0), 0.5, 0.0, -0.1])
    assert q.level and q.yaw_rad == pytest.approx(math.radians(40.0))
    assert np.allclose(q.centre_m, [1.5, 2.0, 1.1])
    moved, turned = pose_change(p, q)
    assert moved == pytest.approx(math.hypot(0.5, 0.1)) and turned == pytest.approx(math.radians(10.0))
    assert np.allclose(q.rotation @ q.rotation.T, np.eye(3))


def test_a_pinhole_camera_turns_by_its_rotation_vector() -> None:
    p = CameraPose(rotation_z(0.3).T, np.array([0.0, 0.0, 3.0]), level=False)
    q = p.moved([0.0, 0.02, 0.0, 0.0, 0.0, 0.0])
    assert pose_change(p, q) == pytest.approx((0.0, 0.02))
    assert np.allclose(q.t_m, -q.rotation @ q.centre_m)


@pytest.mark.parametrize(("shift", "turn_deg"), [(0.5, 5.0), (1.5, 15.0)])
def test_a_bump_moves_and_turns_by_what_it_says(shift: float, turn_deg: float) -> None:
    p = CameraPose(np.eye(3), np.zeros(3), level=False)
    axis = np.array([1.0, 2.0, -0.5]) / np.linalg.norm([1.0, 2.0, -0.5])
    direction = np.array([0.0, 0.6, 0.8])
    q = p.turned_moved(axis * math.radians(turn_deg), direction * shift)
    moved, turned = pose_change(p, q)
    assert moved == pytest.approx(shift) and math.degrees(turned) == pytest.approx(turn_deg)
