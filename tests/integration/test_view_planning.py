"""View planning closed loop through the real network (issue 6, item 8).

A router, the two simulated panoramic nodes of ``deploy/sites/planning.toml``
(a surveyed tripod and a robot located by mutual calibration, both rendering
pixels) and the manager run as processes on loopback. The robot starts on the
line through the tripod and the person (triangulation degenerates). The
manager's planner sends it a goal on ``plan/robot``; the robot node's simulated
world drives it there. The test, and only the test, scores the manager's
tracks against the simulator's ground truth (the world with the same goals):
after the move, scored from the moment the robot stops, the person is placed
(a reported track within 0.3 m) far more of the time than before it, reported
tracks are centimetres off, and so are most right after the stop; the goal
keeps the bands in view (minimum baseline) and the manager knows the robot's
pose all along.
"""

from __future__ import annotations

import math
import re
import statistics
import sys
import threading
import time
from pathlib import Path
from typing import Any

import pytest

from common.codec import decode
from common.keys import Keys
from common.schema import ManagerStatus, TrackSet, ViewPlan
from common.site import load_site
from sim.driver import goals_from_plans
from sim.render.bodies import band_z_range
from sim.world import World
from tests.support import client_session, wait_for, wait_for_liveliness

pytestmark = pytest.mark.integration

REPO = Path(__file__).resolve().parents[2]
SITE = REPO / "deploy" / "sites" / "planning.toml"
NODES = REPO / "deploy" / "nodes" / "planning"
PREFIX = "itest-plan"
MID = "mgr-plan"
AFTER_S = 6.0
"""Seconds of tracks scored from the moment the robot stops at its goal."""
EARLY_S = 2.0
"""The first seconds after the stop, when the robot's node relearns its background and its pose re-converges:
the manager leaves its views out until then (resource_manager/settling.py), so no track is off there either."""
START_RADIUS_M = 0.3
"""'Before': the true robot still within this of where it started."""
PLACED_M = 0.3
"""The person is placed at an instant when a reported track is within this of them."""


def _config(src: Path, dest: Path, endpoint: str, state: Path | None = None) -> Path:
    """A copy of a planning-site process config on the test's router and prefix, paths made absolute."""
    text = src.read_text()
    text = re.sub(r'(?m)^prefix = "[^"]*"', f'prefix = "{PREFIX}"', text)
    text = re.sub(r"(?m)^connect = \[.*\]", f'connect = ["{endpoint}"]', text)
    text = re.sub(r'(?m)^site = "[^"]*"', f'site = "{SITE.as_posix()}"', text)
    text = re.sub(r'(?m)^id = "mgr1"', f'id = "{MID}"', text)
    if state is not None:
        text = re.sub(r'(?m)^state_dir = "[^"]*"', f'state_dir = "{state.as_posix()}"', text)
    dest.write_text(text)
    return dest


class Collector:
    """Everything the manager publishes that the test scores (callbacks only append)."""

    def __init__(self, session: Any, keys: Keys) -> None:
        self.lock = threading.Lock()
        self.tracksets: list[TrackSet] = []
        self.plans: list[ViewPlan] = []
        self.statuses: list[ManagerStatus] = []
        self.subs = [
            session.declare_subscriber(keys.tracks(), lambda s: self._add(self.tracksets, s, TrackSet)),
            session.declare_subscriber(keys.all_plans, lambda s: self._add(self.plans, s, ViewPlan)),
            session.declare_subscriber(keys.manager_status(MID), lambda s: self._add(self.statuses, s, ManagerStatus)),
        ]

    def _add(self, into: list[Any], sample: Any, kind: type) -> None:
        msg = decode(sample.payload.to_bytes(), kind)
        with self.lock:
            into.append(msg)

    def snapshot(self) -> tuple[list[TrackSet], list[ViewPlan], list[ManagerStatus]]:
        with self.lock:
            return list(self.tracksets), list(self.plans), list(self.statuses)

    def close(self) -> None:
        for s in self.subs:
            s.undeclare()


def _stop_time(world: World, sensor_id: str, from_s: float) -> float:
    """World time at which the robot stops at its last goal (0.1 s resolution)."""
    last: tuple[float, float] | None = None
    for k in range(600):
        t = from_s + 0.1 * k
        p = next(q for q in world.platforms_at(t) if q.sensor_id == sensor_id)
        if last is not None and math.dist((p.x_m, p.y_m), last) < 1e-6:
            return t - 0.1
        last = (p.x_m, p.y_m)
    raise AssertionError(f"{sensor_id} never stops after t = {from_s:.1f} s")


def test_planner_moves_robot_and_measured_error_falls(router: Any, spawn: Any, tmp_path: Path) -> None:
    site = load_site(SITE)
    start = site.camera_by_id("robot")
    keys = Keys(PREFIX)
    mgr_cfg = _config(NODES / "manager.toml", tmp_path / "manager.toml", router.endpoint, tmp_path / "state")
    node_cfgs = [_config(NODES / f"{n}.toml", tmp_path / f"{n}.toml", router.endpoint) for n in ("tripod", "robot")]
    epoch_ns = time.time_ns()
    env = {"PANOSTEREO_EPOCH_NS": str(epoch_ns), "PANOSTEREO_SEED": str(site.site.seed)}
    with client_session(router.endpoint) as session:
        got = Collector(session, keys)
        try:
            # --site: the manager fuses the planning site's sensor nodes (tripod, robot), as `panostereo up` has it.
            mgr = spawn([sys.executable, "-m", "resource_manager", "--config", mgr_cfg, "--site", SITE], env=env,
                        name="manager")  # fmt: skip
            for cfg in node_cfgs:
                spawn([sys.executable, "-m", "sensor_node", "--config", cfg], env=env, name=cfg.stem)
            wait_for_liveliness(session, keys.manager(MID), timeout_s=20)

            def world_now() -> tuple[World, list[ViewPlan]]:
                plans = [p for p in got.snapshot()[1] if p.sensor_id == "robot"]
                return World.from_site(site, goals_from_plans(plans, epoch_ns)), plans

            # A goal is sent (the robot stands on the tripod-person line: poor) ...
            wait_for(lambda: world_now()[1], 30, "a view plan for the robot")
            first_plan_s = (min(p.stamp_ns for p in world_now()[1]) - epoch_ns) / 1e9

            # ... the robot drives there and stops; then AFTER_S s of tracks are collected.
            def done() -> bool:
                world, _ = world_now()
                stop_s = _stop_time(world, "robot", first_plan_s)
                tracks = got.snapshot()[0]
                return bool(tracks) and (tracks[-1].stamp_ns - epoch_ns) / 1e9 > stop_s + AFTER_S

            wait_for(done, 35, "the robot to reach its goal and tracks after it", poll_s=0.5)
        finally:
            got.close()
    tracksets, plans, statuses = got.snapshot()
    plans = [p for p in plans if p.sensor_id == "robot"]
    world = World.from_site(site, goals_from_plans(plans, epoch_ns))
    goals = world.goals
    stop_s = _stop_time(world, "robot", first_plan_s)

    before: list[float] = []
    after: list[float] = []
    early: list[float] = []
    placed_before: list[bool] = []
    placed_after: list[bool] = []
    per_s: dict[int, list[float]] = {}
    for ts in tracksets:
        t_s = (ts.stamp_ns - epoch_ns) / 1e9
        truth = world.ground_truth(t_s)
        robot = next(p for p in truth.platforms if p.sensor_id == "robot")
        errs = [min(math.hypot(tr.x_m - p.x_m, tr.y_m - p.y_m) for p in truth.people) for tr in ts.tracks]
        placed = any(e < PLACED_M for e in errs)
        for err in errs:
            per_s.setdefault(int(t_s), []).append(err)
        if math.dist((robot.x_m, robot.y_m), (start.x_m, start.y_m)) < START_RADIUS_M:
            before += errs
            placed_before.append(placed)
        elif stop_s <= t_s <= stop_s + AFTER_S:
            after += errs
            placed_after.append(placed)
            if t_s < stop_s + EARLY_S:
                early += errs
    summary = (
        f"goals={[(round(g.x_m, 2), round(g.y_m, 2), round(g.issued_s, 1)) for g in goals]} stop={stop_s:.1f}s "
        f"before n={len(before)} mean={statistics.fmean(before) if before else -1:.3f} "
        f"after n={len(after)} mean={statistics.fmean(after) if after else -1:.3f} "
        f"early n={len(early)} max={max(early) if early else -1:.3f} "
        f"placed before {statistics.fmean(placed_before) if placed_before else -1:.2f} "
        f"after {statistics.fmean(placed_after) if placed_after else -1:.2f} per second (n, mean): "
        + " ".join(f"{k}:{len(v)},{statistics.fmean(v):.2f}" for k, v in sorted(per_s.items()))
    )
    assert len(placed_before) >= 10 and len(after) >= 20, summary
    # After the move the person is placed (a reported track within PLACED_M) far more of the time than before
    # it, when the tripod and the robot were near colinear: the manager then either reports a vague track off
    # along the line, or holds it unreported (vaguer than publish_sigma_m).
    assert statistics.fmean(placed_after) >= 0.5, summary
    assert statistics.fmean(placed_after) >= statistics.fmean(placed_before) + 0.25, summary
    assert statistics.median(after) < 0.15, summary
    # Right after the stop too: no track 1-2 m off while the robot's node relearns and its pose re-converges
    # (most of the reports then are within 0.3 m).
    assert early and statistics.median(early) < 0.3, summary

    # The goal keeps the robot where the system keeps working: the top of each body's band at least
    # 0.5 deg above the other camera's -15 deg limit (minimum baseline).
    tripod = site.camera_by_id("tripod")
    final = next(p for p in world.platforms_at(stop_s) if p.sensor_id == "robot")
    baseline = math.dist((final.x_m, final.y_m), (tripod.x_m, tripod.y_m))
    _, band_top_m = band_z_range(tripod.body_height_m)
    assert baseline - 0.18 > (1.1 - band_top_m) / math.tan(math.radians(14.5)), summary
    assert math.dist((final.x_m, final.y_m), (start.x_m, start.y_m)) > 1.0, summary
    # The move was planned for a gain at the instant it was planned (the placed shares above say it paid off;
    # the last plan's error is the person's at another place, not comparable with the first's).
    assert plans[0].predicted_error_m < plans[0].current_error_m, summary
    # Hysteresis: a handful of goals, not one per planning period.
    assert 1 <= len(goals) <= 3, summary

    # The manager knew the robot's pose from its first status with it to the end (mutual calibration held).
    since = next((i for i, s in enumerate(statuses) if any(p.sensor_id == "robot" for p in s.poses)), None)
    assert since is not None, f"the manager never knew the robot's pose: {summary}"
    for s in statuses[since:]:
        assert any(p.sensor_id == "robot" for p in s.poses), (s, summary)
        assert "robot" not in s.sensors_without_pose, (s, summary)
    assert (statuses[-1].stamp_ns - statuses[since].stamp_ns) / 1e9 > stop_s - first_plan_s, summary
    assert "pose of robot lost" not in mgr.log(), summary  # not even between two statuses
