"""Platform trajectories: a loop at the platform's speed, goals that chain, and a bumper that stops short."""

from __future__ import annotations

import math

import pytest

from common.site import CameraSpec
from sim.robots import RobotMotion, stop_short


def test_a_static_camera_never_moves_even_with_waypoints() -> None:
    motion = RobotMotion(CameraSpec(id="c", x_m=1.0, y_m=2.0, waypoints=[[3.0, 2.0]]))
    assert [motion.xy(t) for t in (0.0, 5.0, 100.0)] == [(1.0, 2.0)] * 3


def test_a_mobile_platform_drives_its_loop_at_its_speed_and_comes_back() -> None:
    cam = CameraSpec(id="r", x_m=0.0, y_m=0.0, mobile=True, max_speed_mps=0.5, waypoints=[[2.0, 0.0]])
    motion = RobotMotion(cam)
    assert motion.xy(2.0) == pytest.approx((1.0, 0.0))  # 0.5 m/s for 2 s along the first leg
    assert motion.xy(4.0) == pytest.approx((2.0, 0.0))
    assert motion.xy(6.0) == pytest.approx((1.0, 0.0))  # on its way back
    assert motion.xy(8.0) == pytest.approx((0.0, 0.0))  # one loop of 4 m


def test_goals_drive_from_where_it_is_then_stop_and_chain() -> None:
    motion = RobotMotion(CameraSpec(id="r", mobile=True, max_speed_mps=1.0))
    motion.append_goal(1.0, (3.0, 0.0))
    motion.append_goal(5.0, (3.0, 4.0))
    assert motion.destination(0.5) is None
    assert motion.xy(2.0) == pytest.approx((1.0, 0.0))
    assert motion.xy(4.5) == pytest.approx((3.0, 0.0))  # arrived at 4 s and stopped
    assert motion.destination(4.5) == (3.0, 0.0)
    assert motion.xy(7.0) == pytest.approx((3.0, 2.0))
    motion.clear_goals()
    assert motion.xy(7.0) == pytest.approx((0.0, 0.0))  # parked start (no waypoints)


@pytest.mark.parametrize(
    ("blockers", "stop_x"),
    [
        ([], 4.0),  # nothing in the way: the goal
        ([(2.0, 0.0, 0.5)], 1.5),  # stops at the blocker's keep-out circle (less a centimetre)
        ([(2.0, 3.0, 0.5)], 4.0),  # passes clear
        ([(-2.0, 0.0, 0.5)], 4.0),  # behind
        ([(0.2, 0.0, 0.5)], 0.0),  # already touching, and the drive goes deeper: no move
        ([(-0.2, 0.0, 0.5)], 4.0),  # already touching, driving away: allowed
    ],
)
def test_stop_short(blockers: list[tuple[float, float, float]], stop_x: float) -> None:
    x, y = stop_short((0.0, 0.0), (4.0, 0.0), blockers)
    assert y == pytest.approx(0.0)
    assert x == pytest.approx(stop_x, abs=0.011)
    for cx, cy, keep in blockers:
        if math.hypot(cx, cy) > keep:  # started clear: ends clear
            assert math.hypot(x - cx, y - cy) >= keep
