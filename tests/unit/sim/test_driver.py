"""The simulated robots' driver: view plans become the world's goals, as they arrive or after a run."""

from __future__ import annotations

import pytest

from common.schema import ViewPlan
from common.site import load_site
from sim.driver import PlanFollower, goals_from_plans
from sim.world import Goal, World, world_time_s
from tests.support import REPO


def plan(seq: int, stamp_s: float, sid: str, x: float, y: float) -> ViewPlan:
    return ViewPlan(
        manager_id="m", seq=seq, stamp_ns=int(1e9 * (100.0 + stamp_s)), sensor_id=sid, partner_id="p",
        track_id="t1", goal_x_m=x, goal_y_m=y, baseline_m=2.0, phi1_rad=1.0, predicted_error_m=0.1,
        current_error_m=0.2,
    )  # fmt: skip


def test_goals_from_plans_order_and_dedup() -> None:
    plans = [plan(3, 12.0, "r1", 4.0, 2.0), plan(1, 10.0, "r1", 4.0, 2.0), plan(2, 11.0, "r1", 4.004, 2.0)]
    plans += [plan(4, 13.0, "r1", 5.0, 2.0), plan(5, 14.0, "r1", 4.0, 2.0), plan(1, 10.5, "r2", 1.0, 1.0)]
    goals = goals_from_plans(plans, epoch_ns=int(100e9))
    assert goals == [
        Goal("r1", 4.0, 2.0, 10.0),
        Goal("r2", 1.0, 1.0, 10.5),
        Goal("r1", 5.0, 2.0, 13.0),
        Goal("r1", 4.0, 2.0, 14.0),
    ]
    assert goals_from_plans(reversed(plans), epoch_ns=int(100e9)) == goals
    assert world_time_s(int(101.5e9), int(100e9)) == pytest.approx(1.5)


def test_a_follower_gives_the_world_the_goals_a_recording_would() -> None:
    """Plans followed live (in any order) and the same plans replayed after the run drive the same robots."""
    site = load_site(REPO / "deploy/sites/demo.toml")
    mobile = next(c.id for c in site.camera if c.mobile)
    fixed = next(c.id for c in site.camera if not c.mobile)
    plans = [plan(1, 2.0, mobile, 3.0, 2.0), plan(2, 6.0, mobile, 5.0, 3.0), plan(3, 4.0, fixed, 1.0, 1.0)]
    live = World.from_site(site)
    follower = PlanFollower(live, site, epoch_ns=int(100e9))
    for p in reversed(plans):
        follower.follow(p)
    assert live.goals == ()  # nothing until the source applies them, before its next render
    follower.apply()
    assert follower.goals_applied == 2  # the plan for a camera that does not move is ignored
    recorded = [p for p in plans if p.sensor_id == mobile]  # the demo keeps the mobile cameras' plans
    after = World.from_site(site, goals_from_plans(recorded, epoch_ns=int(100e9)))
    for t in (1.0, 3.0, 5.0, 9.0, 20.0):
        a, b = live.platform_at(mobile, t), after.platform_at(mobile, t)
        assert (a.x_m, a.y_m) == pytest.approx((b.x_m, b.y_m), abs=1e-9)
