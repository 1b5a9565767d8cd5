"""The simulated PTZ head: bounded slew rates, clamped tilt and zoom, shortest-way pan."""

from __future__ import annotations

import math

import pytest

from sim.ptz_head import SimulatedPtz


def test_slews_at_bounded_rates_and_arrives() -> None:
    now = [0]
    head = SimulatedPtz(0.0, 0.0, 1.0, lambda: now[0], pan_rate=math.radians(90), tilt_rate=math.radians(45))
    assert not head.pose(0).moving
    head.command(math.radians(90), math.radians(-20), 3.0)
    half = head.pose(500_000_000)
    assert half.moving and half.pan_rad == pytest.approx(math.radians(45))
    assert half.tilt_rad == pytest.approx(math.radians(-20))  # 0.5 s at 45 deg/s covers 20 deg
    done = head.pose(2_000_000_000)
    assert not done.moving and done.pan_rad == pytest.approx(math.radians(90)) and done.zoom == pytest.approx(3.0)


def test_pan_goes_the_short_way_and_limits_hold() -> None:
    now = [0]
    head = SimulatedPtz(math.radians(170), 0.0, 1.0, lambda: now[0], pan_rate=math.radians(10))
    head.command(math.radians(-170), math.radians(89), 100.0)
    p = head.pose(1_000_000_000)
    assert p.pan_rad == pytest.approx(math.radians(180), abs=1e-9) or p.pan_rad == pytest.approx(-math.pi, abs=1e-9)
    end = head.pose(60_000_000_000)
    assert end.pan_rad == pytest.approx(math.radians(-170))
    assert end.tilt_rad == pytest.approx(math.radians(80)) and end.zoom == pytest.approx(30.0)
    assert head.commands == 1
