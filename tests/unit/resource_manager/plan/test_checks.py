"""The planner's checks: baselines that keep the bands and heads in view, where a robot may go, and what it pays."""

from __future__ import annotations

import math

import numpy as np
import pytest

from resource_manager.plan.checks import (
    feasible,
    found,
    head_min_range,
    max_baseline,
    min_baseline,
    move_payoff,
    others_error,
    predicted_error,
    segment_dist,
)
from resource_manager.plan.scene import PlanCamera, PlannerParams, PlanTarget, Scene

P = PlannerParams(room=(0.0, 0.0, 8.0, 6.0))
SIGMA = math.radians(0.2)


def _cam(sid: str, x: float, y: float, *, mobile: bool = False, z_m: float = 1.1) -> PlanCamera:
    return PlanCamera(sid, np.array([x, y]), 0.18, SIGMA, mobile, z_m, width_px=1080)


def _scene(fixed: int = 1) -> Scene:
    robot, main = _cam("r", 6.0, 1.0, mobile=True), _cam("m", 1.0, 3.0)
    tgt = PlanTarget("t1", np.array([4.0, 3.0]), 0.3, ("m", "r"), 1.8)
    extra = [_cam("x", 7.0, 5.0)][: max(fixed - 1, 0)]
    return Scene(cam=robot, main=main, tgt=tgt, others=[main, *extra], people=[tgt], fixed=[main, *extra])


@pytest.mark.parametrize(
    ("q", "dist"),
    [((1.0, 1.0), 1.0), ((-1.0, 0.0), 1.0), ((5.0, 0.0), 3.0), ((2.0, 0.0), 0.0)],
)
def test_segment_dist(q: tuple[float, float], dist: float) -> None:
    got = segment_dist(np.array([0.0, 0.0]), np.array([[2.0, 0.0], [0.0, 0.0]]), np.array(q))
    assert got[0] == pytest.approx(dist)
    assert got[1] == pytest.approx(math.hypot(*q))  # a segment of zero length: the distance to its point


def test_found_falls_with_the_predicted_error() -> None:
    assert found(0.0, 0.5) == 1.0
    probs = [found(e, 0.5) for e in (0.1, 0.3, 0.5, 1.0, 3.0)]
    assert probs == sorted(probs, reverse=True) and 0.0 < probs[-1] < 0.05 and probs[0] > 0.99
    assert found(0.5, 0.5) == pytest.approx(1.0 - math.exp(-1.0))  # Rayleigh at one RMS error


@pytest.mark.parametrize("z_m", [0.9, 1.1, 1.6])
def test_at_the_minimum_baseline_the_band_sits_at_the_lower_elevation_limit(z_m: float) -> None:
    cam, other = _cam("a", 0.0, 0.0, z_m=z_m), _cam("b", 3.0, 0.0, z_m=z_m)
    d = min_baseline(cam, other, P)
    elev = math.atan2(P.band_z_m - z_m, d - other.radius_m)  # the band's near edge, seen from cam
    assert elev == pytest.approx(cam.elev_min_rad + P.elev_margin_rad)


def test_at_the_maximum_baseline_the_body_is_min_band_px_wide() -> None:
    cam, other = _cam("a", 0.0, 0.0), _cam("b", 3.0, 0.0)
    d = max_baseline(cam, other, P)
    width_px = 2.0 * math.asin(other.radius_m / d) * cam.width_px / (2.0 * math.pi)
    assert width_px == pytest.approx(P.min_band_px)
    ptz = PlanCamera("p", np.zeros(2), 0.0, SIGMA, False, width_px=0)
    assert max_baseline(cam, ptz, P) == math.inf  # a bodiless camera without a panorama: neither ranges the other


def test_at_the_head_range_the_head_top_sits_at_the_upper_elevation_limit() -> None:
    cam = _cam("a", 0.0, 0.0)
    d = head_min_range(cam, 1.9, P.elev_margin_rad)
    assert math.atan2(1.9 - cam.z_m, d) == pytest.approx(cam.elev_max_rad - P.elev_margin_rad)
    assert head_min_range(cam, 1.0, P.elev_margin_rad) == 0.0  # a head below the camera is always in view


def test_predicted_error_is_least_beside_the_target_and_scales_with_the_bearing_error() -> None:
    sc = _scene()
    # Colinear behind the target (tiny parallax) vs. across from it: Fig. 4's map.
    xy = np.array([[6.5, 3.0], [4.0, 5.5]])
    err = predicted_error(xy, sc)
    assert err[1] < err[0]
    sharper = Scene(
        cam=PlanCamera("r", sc.cam.xy, 0.18, SIGMA / 2, True, width_px=1080), main=sc.main, tgt=sc.tgt,
        others=sc.others, people=sc.people, fixed=sc.fixed,
    )  # fmt: skip
    assert predicted_error(xy, sharper) == pytest.approx(err / 2)


def test_feasible_keeps_the_robot_in_the_room_clear_of_people_and_off_the_line_of_sight() -> None:
    sc = _scene()
    xy = np.array([
        [4.0, 5.4],  # across from the target, clear of everything
        [8.2, 3.0],  # outside the room
        [7.9, 5.9],  # inside but within the wall margin
        [4.0, 3.5],  # on the target's toes
        [6.0, 3.0],  # the target stands between it and the main camera
    ])  # fmt: skip
    assert feasible(xy, sc, P).tolist() == [True, False, False, False, False]
    # Without the transient checks (where people are now) only the room and the bodies count.
    assert feasible(xy[3:4], sc, P, transient=False).tolist() == [True]


def test_moving_pays_only_when_the_goal_finds_the_target_more_often() -> None:
    sc = _scene(fixed=1)
    goal = np.array([4.0, 5.4])
    gain, cost, blind_s = move_payoff(sc, P, goal, 0.05, found(0.6, P.found_m), others_err=math.inf)
    assert blind_s == pytest.approx(math.hypot(*(goal - sc.cam.xy)) / P.speed_mps + P.settle_cost_s)
    assert gain > 0 and cost > 0  # one other camera only: the target is lost while the robot drives
    no_gain, _, _ = move_payoff(sc, P, goal, 0.6, found(0.6, P.found_m), others_err=math.inf)
    assert no_gain == pytest.approx(0.0)
    covered = _scene(fixed=2)
    assert math.isinf(others_error(sc)) and math.isfinite(others_error(covered))
    _, cost2, _ = move_payoff(covered, P, goal, 0.05, found(0.6, P.found_m), others_err=others_error(covered))
    assert cost2 == 0.0  # two other cameras still pair up on everyone meanwhile
