"""The simulated world: deterministic, physically plausible people and robots, goals, ground truth."""

from __future__ import annotations

import csv
import itertools
import math
from pathlib import Path

import msgspec
import numpy as np
import pytest

from common.errors import ConfigError
from common.site import CameraSpec, SiteConfig, SiteSection, WorldSpec, load_site
from sim.world import (
    Goal,
    World,
    sensor_bearing,
    site_with_seed_from_env,
    write_gt_csv,
)

REPO = Path(__file__).resolve().parents[3]
SITES = REPO / "deploy" / "sites"


def _site(**world: object) -> SiteConfig:
    cams = [
        CameraSpec(id="r1", x_m=2.0, y_m=2.0, mobile=True, pose="mutual", max_speed_mps=0.5),
        CameraSpec(id="r2", x_m=5.5, y_m=3.5, mobile=True, pose="mutual", waypoints=[[5.5, 1.5], [6.5, 1.5]]),
        CameraSpec(id="post", x_m=4.0, y_m=5.0, body_height_m=1.0, height_m=1.2),
    ]
    spec = msgspec.convert({"room_x_m": 8.0, "room_y_m": 6.0, "people": 5, **world}, WorldSpec)
    return SiteConfig(site=SiteSection(name="t", seed=3), world=spec, camera=cams)


def _track(world: World, t_end: float, dt: float) -> dict[str, np.ndarray]:
    """People sampled every dt: arrays (T, N) of x, y, present, speed."""
    rows = [world.people_at(t) for t in np.arange(0.0, t_end, dt)]
    return {
        "x": np.array([[p.x_m for p in r] for r in rows]),
        "y": np.array([[p.y_m for p in r] for r in rows]),
        "present": np.array([[p.present for p in r] for r in rows]),
        "speed": np.array([[p.speed_mps for p in r] for r in rows]),
    }


@pytest.mark.parametrize("name", ["demo", "paper1", "paper2", "six", "crowd"])
def test_every_site_file_loads_and_builds_a_world(name: str) -> None:
    site = load_site(SITES / f"{name}.toml")
    world = World.from_site(site)
    assert len(world.people_at(1.0)) == site.world.people
    assert {p.sensor_id for p in world.platforms_at(1.0)} == {c.id for c in site.camera}


def test_same_seed_same_world_whatever_the_sampling_order() -> None:
    a, b = World.from_site(_site()), World.from_site(_site())
    late = a.people_at(37.3)  # jump straight there
    for t in np.arange(0.0, 37.3, 1.0):
        b.people_at(float(t))  # walk there in steps
    assert b.people_at(37.3) == late
    other = World.from_site(msgspec.structs.replace(_site(), site=SiteSection(name="t", seed=4)))
    assert other.people_at(37.3) != late


def test_people_walk_like_people() -> None:
    site = _site(people=6, pause_prob=0.5)
    world = World.from_site(site)
    tr = _track(world, 90.0, 0.1)
    assert tr["present"].all()
    step = np.hypot(np.diff(tr["x"], axis=0), np.diff(tr["y"], axis=0)) / 0.1
    assert step.max() <= 1.5 + 0.35  # walking speed range, plus the bounded shove when crowded
    assert (tr["speed"] <= 1.5 + 1e-9).all()
    assert np.median(step[step > 0.2]) > 0.45
    paused = tr["speed"] < 0.05
    assert paused.any(axis=0).sum() >= 3  # people do stop now and then
    assert (paused.mean(axis=0) < 0.5).all()  # ... but nobody stands around most of the time
    lo, hi = site.world.person_height_m
    assert all(lo <= p.height_m <= hi for p in world.people_at(0.0))
    assert len({p.shirt_rgb for p in world.people_at(0.0)}) == 6  # distinct clothing
    # In the room, clear of the walls, never through a platform, never through each other.
    assert tr["x"].min() >= 0.2 and tr["x"].max() <= 7.8 and tr["y"].min() >= 0.2 and tr["y"].max() <= 5.8
    for k in range(0, tr["x"].shape[0], 5):
        for pl in world.platforms_at(k * 0.1):
            d = np.hypot(tr["x"][k] - pl.x_m, tr["y"][k] - pl.y_m)
            assert d.min() >= pl.radius_m + 0.25
        for i, j in itertools.combinations(range(6), 2):
            assert math.hypot(tr["x"][k, i] - tr["x"][k, j], tr["y"][k, i] - tr["y"][k, j]) > 0.4
    # Paths cross: people visit most of the room, not a corner each.
    for i in range(6):
        assert np.ptp(tr["x"][:, i]) > 2.5 or np.ptp(tr["y"][:, i]) > 2.0


def test_headings_turn_smoothly() -> None:
    world = World.from_site(_site())
    h = np.array([[p.heading_rad for p in world.people_at(t)] for t in np.arange(0.0, 40.0, 0.05)])
    dh = np.abs((np.diff(h, axis=0) + math.pi) % (2 * math.pi) - math.pi) / 0.05
    assert dh.max() < 3.0  # rad/s: no instantaneous about-turns


def test_rectangle_paths_follow_the_known_rectangle_in_opposite_directions() -> None:
    site = load_site(SITES / "paper2.toml")
    world = World.from_site(site)
    x0, y0, x1, y1 = site.world.rectangle
    tr = _track(world, 60.0, 0.2)
    # Distance to the rectangle's outline stays small (corners are rounded by the turn rate).
    dx = np.maximum(np.maximum(x0 - tr["x"], tr["x"] - x1), 0.0)
    dy = np.maximum(np.maximum(y0 - tr["y"], tr["y"] - y1), 0.0)
    inside = np.minimum(np.minimum(tr["x"] - x0, x1 - tr["x"]), np.minimum(tr["y"] - y0, y1 - tr["y"]))
    off = np.where((dx > 0) | (dy > 0), np.hypot(dx, dy), np.maximum(inside, 0.0))
    assert np.percentile(off, 95) < 0.4
    # Angular progress about the centre: one walks counter-clockwise, the other clockwise.
    cx, cy = (x0 + x1) / 2, (y0 + y1) / 2
    ang = np.unwrap(np.arctan2(tr["y"] - cy, tr["x"] - cx), axis=0)
    turns = (ang[-1] - ang[0]) / (2 * math.pi)
    assert turns[0] > 0.8 and turns[1] < -0.8
    start = world.people_at(0.0)
    assert math.hypot(start[0].x_m - start[1].x_m, start[0].y_m - start[1].y_m) > 2.0


def test_people_enter_and_leave_through_the_door() -> None:
    world = World.from_site(_site(people=4, enter_leave=True))
    tr = _track(world, 150.0, 0.25)
    absent = ~tr["present"]
    assert absent.any(axis=0).sum() >= 3
    came_back = [(np.diff(tr["present"][:, i].astype(int)) == 1).any() for i in range(4)]
    assert sum(came_back) >= 3
    # Where people appear or disappear, they are at the door.
    for i in range(4):
        for k in np.flatnonzero(np.diff(tr["present"][:, i].astype(int)) != 0):
            x = tr["x"][k + 1, i]
            assert world.door.x0_m - 0.1 <= x <= world.door.x1_m + 0.1


def test_robots_loop_their_waypoints_and_static_ones_stay() -> None:
    world = World.from_site(_site())
    r2 = [world.platform_at("r2", t) for t in np.arange(0.0, 30.0, 0.5)]
    xy = np.array([(p.x_m, p.y_m) for p in r2])
    assert np.hypot(*np.diff(xy, axis=0).T).max() <= 0.5 * 0.5 + 1e-9  # max_speed 0.5 m/s over 0.5 s
    assert np.ptp(xy[:, 1]) > 1.5
    post = {(p.x_m, p.y_m) for p in (world.platform_at("post", t) for t in (0.0, 10.0, 99.0))}
    assert post == {(4.0, 5.0)}
    assert world.platform_at("r1", 50.0).x_m == 2.0  # mobile but no waypoints: parked


def test_goal_drives_the_robot_at_bounded_speed_and_is_order_independent() -> None:
    world = World.from_site(_site())
    world.set_goal("r1", 5.0, 2.0, issued_s=10.0)
    assert (world.platform_at("r1", 9.9).x_m, world.platform_at("r1", 9.9).y_m) == (2.0, 2.0)
    mid = world.platform_at("r1", 14.0)
    assert mid.x_m == pytest.approx(2.0 + 0.5 * 4.0) and mid.y_m == pytest.approx(2.0)
    end = world.platform_at("r1", 30.0)
    assert (end.x_m, end.y_m) == pytest.approx((5.0, 2.0))
    assert end.yaw_rad == world.platform_at("r1", 0.0).yaw_rad  # holonomic base: heading kept
    # The same goals given in another order, or late, give the same trajectories and people.
    goals = [Goal("r1", 5.0, 2.0, 10.0), Goal("r1", 3.0, 4.0, 12.0), Goal("r2", 1.0, 1.0, 5.0)]
    a = World.from_site(_site(), goals)
    b = World.from_site(_site())
    before = b.people_at(40.0)  # computed before the goals were known
    for g in reversed(goals):
        b.set_goal(g.sensor_id, g.x_m, g.y_m, g.issued_s)
    for t in (11.0, 13.0, 20.0, 40.0):
        assert a.platforms_at(t) == b.platforms_at(t)
        assert a.people_at(t) == b.people_at(t)
    assert b.people_at(40.0) != before  # people re-routed around the robots' new paths
    assert a.with_goals([]).platforms_at(20.0) == a.platforms_at(20.0)


def test_goal_is_clamped_into_the_room_and_bad_goals_are_rejected() -> None:
    world = World.from_site(_site())
    g = world.set_goal("r1", -3.0, 99.0, 1.0)
    assert (g.x_m, g.y_m) == pytest.approx((0.23, 6.0 - 0.23))
    with pytest.raises(ConfigError, match="not mobile"):
        world.set_goal("post", 1.0, 1.0, 0.0)
    with pytest.raises(ConfigError, match="unknown sensor"):
        world.set_goal("nope", 1.0, 1.0, 0.0)
    with pytest.raises(ConfigError, match="finite"):
        world.set_goal("r1", math.nan, 1.0, 0.0)


def test_camera_outside_the_room_is_a_config_error() -> None:
    site = _site()
    bad = msgspec.structs.replace(site, camera=[CameraSpec(id="x", x_m=9.0, y_m=1.0)])
    with pytest.raises(ConfigError, match="inside the room"):
        World.from_site(bad)


def test_gt_csv_lists_present_people_per_frame(tmp_path: Path) -> None:
    world = World.from_site(_site(people=3, enter_leave=True))
    path = tmp_path / "gt.csv"
    n = write_gt_csv(world, path, fps=5.0, duration_s=40.0)
    with path.open() as f:
        rows = list(csv.DictReader(f))
    assert list(rows[0]) == ["frame", "id", "x_m", "y_m", "z_m"]
    assert len(rows) == n
    frames = {int(r["frame"]) for r in rows}
    assert min(frames) == 1 and max(frames) <= 200
    for r in rows[::17]:
        t = (int(r["frame"]) - 1) / 5.0
        p = world.people_at(t)[int(r["id"]) - 1]
        assert p.present
        assert (float(r["x_m"]), float(r["y_m"]), float(r["z_m"])) == pytest.approx(
            (p.x_m, p.y_m, p.height_m), abs=1e-4
        )
    total_present = sum(sum(p.present for p in world.people_at((k - 1) / 5.0)) for k in range(1, 201))
    assert n == total_present < 3 * 200  # some people were outside for a while
    gt = world.ground_truth(12.0)
    assert all(p.present for p in gt.people) and len(gt.platforms) == 3
    with pytest.raises(ConfigError):
        write_gt_csv(world, path, fps=0.0, duration_s=1.0)


def test_sensor_bearing_is_relative_to_the_camera_heading() -> None:
    world = World.from_site(load_site(SITES / "demo.toml"))
    pl = world.platform_at("pano2", 0.0)  # yaw 200 deg
    b = sensor_bearing(pl, pl.x_m + 1.0, pl.y_m)
    assert b == pytest.approx(math.radians(-200.0 + 360.0))


def test_old_times_are_recomputed_after_the_kept_window(monkeypatch: pytest.MonkeyPatch) -> None:
    import sim.walkers

    ref = World.from_site(_site())
    expect = [ref.people_at(float(t)) for t in np.arange(0.0, 80.0, 3.1)]
    monkeypatch.setattr(sim.walkers, "KEEP_S", 10.0)
    small = World.from_site(_site())
    small.people_at(80.0)  # frames before ~70 s are dropped, checkpoints thinned
    assert [small.people_at(float(t)) for t in np.arange(0.0, 80.0, 3.1)] == expect
    small.set_goal("r1", 6.0, 1.0, 20.0)
    ref.set_goal("r1", 6.0, 1.0, 20.0)
    assert small.people_at(50.0) == ref.people_at(50.0)


def test_a_wrong_epoch_is_reported_not_simulated() -> None:
    with pytest.raises(ConfigError, match="epoch"):
        World.from_site(_site()).people_at(1.7e9)


def test_seed_from_environment() -> None:
    site = _site()
    assert site_with_seed_from_env(site, {}) is site
    assert site_with_seed_from_env(site, {"PANOSTEREO_SEED": " 42 "}).site.seed == 42
    with pytest.raises(ConfigError, match="PANOSTEREO_SEED"):
        site_with_seed_from_env(site, {"PANOSTEREO_SEED": "x"})


def test_the_same_goal_twice_changes_nothing() -> None:
    a = World.from_site(_site())
    a.set_goal("r1", 5.0, 2.0, 3.0)
    a.people_at(20.0)
    a.set_goal("r1", 5.0, 2.0, 3.0)
    assert a.goals == (Goal("r1", 5.0, 2.0, 3.0),)
    assert len(a._walkers._frames) > 300  # nothing was invalidated


def test_line_paths_go_back_and_forth_between_the_end_points() -> None:
    world = World.from_site(_site(people=1, paths="line", rectangle=[1.0, 4.0, 7.0, 4.5]))
    tr = _track(world, 60.0, 0.2)
    x, y = tr["x"][:, 0], tr["y"][:, 0]
    # On the segment (within a turning radius) and reaching both ends.
    d = np.abs(0.5 * (x - 1.0) - 6.0 * (y - 4.0)) / math.hypot(6.0, 0.5)
    assert np.percentile(d, 95) < 0.3
    assert np.hypot(x - 1.0, y - 4.0).min() < 0.35 and np.hypot(x - 7.0, y - 4.5).min() < 0.35
    turns = np.sum(np.diff(np.sign(np.diff(x))) != 0)
    assert turns >= 4


def test_robots_stop_short_of_other_platforms_whatever_the_goal_order() -> None:
    goals = [Goal("r1", 4.0, 3.0, 5.0), Goal("r2", 4.0, 3.0, 5.0), Goal("r1", 4.0, 4.9, 30.0)]
    a = World.from_site(_site(), goals)
    b = World.from_site(_site())
    for g in reversed(goals):
        b.set_goal(g.sensor_id, g.x_m, g.y_m, g.issued_s)
    for t in (10.0, 25.0, 40.0, 60.0):
        assert a.platforms_at(t) == b.platforms_at(t)
    for t in np.arange(0.0, 60.0, 0.5):
        pls = [p for p in a.platforms_at(float(t)) if p.radius_m > 0]
        for p, q in itertools.combinations(pls, 2):
            assert math.hypot(p.x_m - q.x_m, p.y_m - q.y_m) >= p.radius_m + q.radius_m + 0.05
    r1, r2 = a.platform_at("r1", 25.0), a.platform_at("r2", 25.0)
    assert (r1.x_m, r1.y_m) == pytest.approx((4.0, 3.0))  # first by sensor id at a tie: it gets there
    assert math.hypot(r2.x_m - 4.0, r2.y_m - 3.0) == pytest.approx(0.18 + 0.18 + 0.1, abs=0.02)
    post = a.platform_at("post", 60.0)  # r1's last goal is inside the post: it stops at its bumper
    r1 = a.platform_at("r1", 60.0)
    assert math.hypot(r1.x_m - post.x_m, r1.y_m - post.y_m) == pytest.approx(0.18 + 0.18 + 0.1, abs=0.02)


def test_repeated_plans_are_not_new_goals() -> None:
    once = World.from_site(_site(), [Goal("r1", 5.0, 2.0, 3.0)])
    many = World.from_site(_site())
    for k in range(200):  # a plan re-published at 10 Hz
        many.set_goal("r1", 5.0 + 0.001 * (k % 3), 2.0, 3.0 + 0.1 * k)
    for t in (3.0, 5.0, 9.0, 30.0):
        assert many.platforms_at(t) == once.platforms_at(t)
    late = World.from_site(_site())
    late.set_goal("r1", 5.0, 2.0, 8.0)
    late.set_goal("r1", 3.0, 4.0, 5.0)  # arrives late: now the 8 s goal is no longer a repeat
    ordered = World.from_site(_site(), [Goal("r1", 3.0, 4.0, 5.0), Goal("r1", 5.0, 2.0, 8.0)])
    for t in (6.0, 9.0, 30.0):
        assert late.platforms_at(t) == ordered.platforms_at(t)
