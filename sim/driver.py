"""The driver of the simulated robots: the manager's view plans (``plan/*``) become the world's goals.

Two places turn plans into goals, by this module's one rule: a simulated camera's source, as the
plans arrive (:class:`PlanFollower`, handed to the node as what follows its plans), and the
ground-truth writer after a run, from the recorded plans (:func:`goals_from_plans`). Both give
the same trajectories, because the world applies goals from their issue time in canonical order
(:meth:`sim.world.World.set_goal`).
"""

from __future__ import annotations

import math
import threading
from collections.abc import Iterable

from common.schema import ViewPlan
from common.site import SiteConfig
from sim.world import SAME_GOAL_M, Goal, World, world_time_s

__all__ = ["PlanFollower", "goals_from_plans"]


class PlanFollower:
    """Takes view plans on any thread; hands their goals to the world before the next render.

    Args:
        world: the simulated world the source renders.
        site: the site (which cameras are mobile).
        epoch_ns: world time 0 on the node clock.
    """

    def __init__(self, world: World, site: SiteConfig, epoch_ns: int) -> None:
        self.world = world
        self.site = site
        self.epoch_ns = epoch_ns
        self._goals: list[tuple[str, float, float, float]] = []
        self._lock = threading.Lock()
        self.goals_applied = 0

    def follow(self, plan: ViewPlan) -> None:
        """Queue a view plan's goal (thread-safe); applied by :meth:`apply`."""
        self.add_goal(plan.sensor_id, plan.goal_x_m, plan.goal_y_m, plan.stamp_ns)

    def add_goal(self, sensor_id: str, x_m: float, y_m: float, issued_ns: int) -> None:
        """Queue a goal for ``sensor_id`` issued at ``issued_ns`` on the node clock (thread-safe)."""
        with self._lock:
            self._goals.append((sensor_id, x_m, y_m, (issued_ns - self.epoch_ns) / 1e9))

    def apply(self) -> None:
        """Give the world the goals queued so far (plans for a camera it does not move are ignored)."""
        with self._lock:
            goals, self._goals = self._goals, []
        for sensor_id, x, y, issued_s in goals:
            cam = next((c for c in self.site.camera if c.id == sensor_id), None)
            if cam is None or not cam.mobile:
                continue  # a plan for a camera this world does not move
            self.world.set_goal(sensor_id, x, y, issued_s)
            self.goals_applied += 1


def goals_from_plans(plans: Iterable[ViewPlan], epoch_ns: int) -> list[Goal]:
    """Run-time goals from the manager's view plans, the one way every process turns plans into goals.

    Plans are taken in (stamp_ns, sensor_id, seq) order; a plan becomes
    ``Goal(sensor_id, goal_x_m, goal_y_m, issued_s=(stamp_ns - epoch_ns) / 1e9)`` unless the previous goal of
    the same sensor is within ``SAME_GOAL_M`` of it (a re-published plan is not a new goal). Sim nodes apply the goals
    as plans arrive; the ground-truth writer applies the recorded ones after the run: both get the same
    trajectories.
    """
    goals: list[Goal] = []
    last: dict[str, tuple[float, float]] = {}
    for plan in sorted(plans, key=lambda p: (p.stamp_ns, p.sensor_id, p.seq)):
        xy = (float(plan.goal_x_m), float(plan.goal_y_m))
        prev = last.get(plan.sensor_id)
        if prev is not None and math.dist(prev, xy) < SAME_GOAL_M:
            continue
        last[plan.sensor_id] = xy
        goals.append(Goal(plan.sensor_id, xy[0], xy[1], max(0.0, world_time_s(plan.stamp_ns, epoch_ns))))
    return goals
