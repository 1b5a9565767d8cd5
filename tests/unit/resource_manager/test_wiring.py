"""The manager's stages from its config: each setting reaches its stage, in the stage's units (ns, rad)."""

from __future__ import annotations

import math
from pathlib import Path

import msgspec
import numpy as np
import pytest

from common.area import rectangle
from resource_manager import wiring
from resource_manager.config import ManagerConfig, load_manager_config
from resource_manager.stereo.matchers import get_matcher

CONFIG = """
[manager]
id = "m1"
max_extrapolation_ms = 150
stale_ms = 2500
latency_ms = 80
rate_hz = 20
matcher = "{matcher}"

[match]
feet_sigma_deg = {feet_sigma_deg}
max_range_m = 12.0

[[pose]]
id = "wall1"
x_m = 1.0
y_m = 2.0
z_m = 2.4
yaw_deg = 270

[planner]
period_s = 0.25
settle_s = 3.0
elev_margin_deg = 2.0
{room}

[ptz]
hfov_deg = 50.0
min_tilt_deg = -45.0
"""


def _config(tmp_path: Path, *, matcher: str = "greedy", feet_sigma_deg: float = 1.5, room: str = "") -> ManagerConfig:
    path = tmp_path / "m.toml"
    path.write_text(CONFIG.format(matcher=matcher, feet_sigma_deg=feet_sigma_deg, room=room))
    return load_manager_config(path)


def test_times_reach_the_stages_in_nanoseconds(tmp_path: Path) -> None:
    cfg = _config(tmp_path)
    align = wiring.align_params(cfg)
    assert (align.max_extrapolation_ns, align.stale_ns) == (150_000_000, 2_500_000_000)
    sched = wiring.schedule(cfg, wiring.sensor_registry(cfg)).params
    assert (sched.max_wait_ns, sched.min_interval_ns) == (80_000_000, 50_000_000)  # 20 Hz at most
    planner = wiring.view_planner(cfg).params
    assert (planner.period_ns, planner.settle_ns) == (250_000_000, 3_000_000_000)


def test_angles_reach_the_stages_in_radians(tmp_path: Path) -> None:
    cfg = _config(tmp_path)
    assert wiring.view_planner(cfg).params.elev_margin_rad == pytest.approx(math.radians(2.0))
    ptz = wiring.ptz_allocator(cfg, wiring.sensor_registry(cfg)).params
    assert ptz.hfov_rad == pytest.approx(math.radians(50.0)) and ptz.min_tilt_rad == pytest.approx(-math.pi / 4)
    feet = wiring.feet_model(cfg)
    assert feet is not None and feet.sigma_elev_rad == pytest.approx(math.radians(1.5)) and feet.max_range_m == 12.0


def test_a_pose_override_is_a_surveyed_pose_with_its_yaw_wrapped(tmp_path: Path) -> None:
    pose = wiring.pose_solver(cfg := _config(tmp_path), wiring.sensor_registry(cfg)).overrides["wall1"]
    assert (pose.x_m, pose.y_m, pose.z_m, pose.source) == (1.0, 2.0, 2.4, "surveyed")
    assert pose.yaw_rad == pytest.approx(-math.pi / 2)  # 270 deg is -90 deg


@pytest.mark.parametrize(("room", "expected"), [("", None), ("room = [0, 0, 8, 6]", (0.0, 0.0, 8.0, 6.0))])
def test_the_room_reaches_the_planner(tmp_path: Path, room: str, expected: tuple[float, ...] | None) -> None:
    cfg = _config(tmp_path, room=room)
    assert wiring.view_planner(cfg).params.room == expected
    assert wiring.scene(cfg).max_range_m == 12.0


def test_the_sites_area_reaches_the_tracker_and_bounds_the_planners_goals(tmp_path: Path) -> None:
    cfg = msgspec.structs.replace(_config(tmp_path), area=rectangle(-1.0, 0.0, 7.0, 5.0))
    scene = wiring.scene(cfg)
    assert scene.area is not None and scene.area.bounds == (-1.0, 0.0, 7.0, 5.0)
    assert wiring.view_planner(cfg).params.room == (-1.0, 0.0, 7.0, 5.0)


def test_a_zone_manager_follows_people_within_two_bands_of_its_zone(tmp_path: Path) -> None:
    """The zone x in [3, 7] of the site's area x in [-1, 7], band 0.5 m: people are followed from x = 2 on."""
    manager = msgspec.structs.replace(
        _config(tmp_path).manager,
        zone="east",
        zone_polygon=[[3.0, 0.0], [7.0, 0.0], [7.0, 5.0], [3.0, 5.0]],
        zone_band_m=0.5,
    )
    cfg = msgspec.structs.replace(_config(tmp_path), manager=manager, area=rectangle(-1.0, 0.0, 7.0, 5.0))
    area = wiring.scene(cfg).area
    assert area is not None
    assert area.contains(np.array([[2.1, 2.0], [1.9, 2.0], [7.5, 2.0]])).tolist() == [True, False, False]
    assert area.bounds == (2.0, 0.0, 7.0, 5.0)
    assert wiring.view_planner(cfg).params.room == (-1.0, 0.0, 7.0, 5.0)  # the planner still has the whole site


def test_no_feet_model_without_a_feet_sigma(tmp_path: Path) -> None:
    assert wiring.feet_model(_config(tmp_path, feet_sigma_deg=0.0)) is None


@pytest.mark.parametrize("matcher", ["greedy", "global"])
def test_the_tracker_births_with_the_configured_matcher(tmp_path: Path, matcher: str) -> None:
    births = wiring.tracker(_config(tmp_path, matcher=matcher), lambda: "t").birth_params
    assert type(births.matcher) is type(get_matcher(matcher))
    assert births.match.max_range_m == 12.0
