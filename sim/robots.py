"""Trajectories of the camera platforms: a waypoint loop (or parked), overridden by run-time goals.

A platform drives its loop -- its start position, then its waypoints, and back
-- at ``max_speed_mps`` (a static camera never moves). A goal issued at world
time t0 sends it from wherever it is at t0 straight to the goal at that speed,
where it stops; later goals chain from where the earlier ones had taken it.
A robot stops short of another platform in its way (:func:`stop_short`): of
where that one is when the goal is issued, and of where its own latest goal
takes it. The world replays all goals in (issue time, sensor, x, y) order, so
the trajectories are a pure function of the goal set, whenever and in whatever
order each goal becomes known.
"""

from __future__ import annotations

import bisect
import math

from common.site import CameraSpec

__all__ = ["ROBOT_CLEARANCE_M", "RobotMotion", "stop_short"]

ROBOT_CLEARANCE_M = 0.1
"""Gap a driving robot keeps from another platform's body."""

AT_GOAL_M = 1e-9
"""A drive (or waypoint loop) shorter than this goes nowhere."""
EMPTY_SEGMENT_M = 1e-12
"""A waypoint segment shorter than this is passed at once."""


class RobotMotion:
    """Trajectory of one platform: waypoint loop (or parked), overridden by goals from their issue time."""

    def __init__(self, cam: CameraSpec) -> None:
        self.start = (cam.x_m, cam.y_m)
        self.speed = cam.max_speed_mps if cam.mobile else 0.0
        loop = [self.start, *((float(p[0]), float(p[1])) for p in cam.waypoints)] if cam.mobile else [self.start]
        self.loop = loop
        self.seg_len = [math.dist(loop[i], loop[(i + 1) % len(loop)]) for i in range(len(loop))]
        self.loop_len = sum(self.seg_len)
        self.radius_m = cam.body_radius_m
        self.goal_t: list[float] = []
        self.goals: list[tuple[float, tuple[float, float], tuple[float, float]]] = []
        """(issued_s, from_xy, to_xy) in issue order."""

    def _loop_xy(self, t_s: float) -> tuple[float, float]:
        if self.loop_len <= AT_GOAL_M or self.speed <= 0.0:
            return self.start
        s = (self.speed * max(t_s, 0.0)) % self.loop_len
        for i, seg in enumerate(self.seg_len):
            if s <= seg or i == len(self.seg_len) - 1:
                a, b = self.loop[i], self.loop[(i + 1) % len(self.loop)]
                f = 0.0 if seg <= EMPTY_SEGMENT_M else min(s / seg, 1.0)
                return (a[0] + f * (b[0] - a[0]), a[1] + f * (b[1] - a[1]))
            s -= seg
        return self.start  # pragma: no cover - the loop above always returns

    def xy(self, t_s: float) -> tuple[float, float]:
        """Where the platform is at world time ``t_s``."""
        k = bisect.bisect_right(self.goal_t, t_s) - 1
        if k < 0:
            return self._loop_xy(t_s)
        issued, a, b = self.goals[k]
        d = math.dist(a, b)
        f = 1.0 if d <= AT_GOAL_M else min(1.0, self.speed * (t_s - issued) / d)
        return (a[0] + f * (b[0] - a[0]), a[1] + f * (b[1] - a[1]))

    def destination(self, t_s: float) -> tuple[float, float] | None:
        """Where the latest goal issued by ``t_s`` takes it (None: no goal yet)."""
        k = bisect.bisect_right(self.goal_t, t_s) - 1
        return None if k < 0 else self.goals[k][2]

    def append_goal(self, issued_s: float, to_xy: tuple[float, float]) -> None:
        """Drive from wherever it is at ``issued_s`` to ``to_xy`` (goals must come in issue order)."""
        self.goals.append((issued_s, self.xy(issued_s), to_xy))
        self.goal_t.append(issued_s)

    def clear_goals(self) -> None:
        self.goals.clear()
        self.goal_t.clear()


def stop_short(
    start_xy: tuple[float, float], goal_xy: tuple[float, float], blockers: list[tuple[float, float, float]]
) -> tuple[float, float]:
    """The goal, or the point where the straight drive to it first touches a blocker (x, y, keep-out radius).

    A robot has a bumper: it stops before it would touch another platform (where
    that one is, or is heading), and it never drives deeper into one it already touches.
    """
    sx, sy = start_xy
    dx, dy = goal_xy[0] - sx, goal_xy[1] - sy
    length = math.hypot(dx, dy)
    if length < AT_GOAL_M:
        return goal_xy
    ux, uy = dx / length, dy / length
    stop = length
    for cx, cy, keep in blockers:
        ox, oy = sx - cx, sy - cy
        b = ox * ux + oy * uy
        c = ox * ox + oy * oy - keep * keep
        if c <= 0.0:  # already touching: only moving away is allowed
            if b < 0.0:
                stop = 0.0
            continue
        disc = b * b - c
        if disc <= 0.0 or b >= 0.0:
            continue  # passes clear, or the blocker is behind
        entry = -b - math.sqrt(disc)
        stop = min(stop, max(0.0, entry - 0.01))
    return (sx + ux * stop, sy + uy * stop)
