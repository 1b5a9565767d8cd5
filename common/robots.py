"""Trajectories of the camera platforms: a waypoint loop (or parked), overridden by run-time goals.

A platform drives its loop -- its start position, then its waypoints, and back
-- at ``max_speed_mps`` (a static camera never moves). A goal issued at world
time t0 sends it from wherever it is at t0 straight to the goal at that speed,
where it stops; later goals chain from where the earlier ones had taken it.
Goals are kept sorted by (issue time, arrival order), so the trajectory is a
pure function of the goal set, whenever each goal becomes known.
"""

from __future__ import annotations

import bisect
import math

from common.site import CameraSpec

__all__ = ["RobotMotion"]


class RobotMotion:
    """Trajectory of one platform: waypoint loop (or parked), overridden by goals from their issue time."""

    def __init__(self, cam: CameraSpec) -> None:
        self.start = (cam.x_m, cam.y_m)
        self.speed = cam.max_speed_mps if cam.mobile else 0.0
        loop = [self.start, *((float(p[0]), float(p[1])) for p in cam.waypoints)] if cam.mobile else [self.start]
        self.loop = loop
        self.seg_len = [math.dist(loop[i], loop[(i + 1) % len(loop)]) for i in range(len(loop))]
        self.loop_len = sum(self.seg_len)
        self.goal_t: list[float] = []
        self.goals: list[tuple[float, float, tuple[float, float], tuple[float, float]]] = []
        """(issued_s, order, from_xy, to_xy) sorted by issue time."""

    def _loop_xy(self, t_s: float) -> tuple[float, float]:
        if self.loop_len <= 1e-9 or self.speed <= 0.0:
            return self.start
        s = (self.speed * max(t_s, 0.0)) % self.loop_len
        for i, seg in enumerate(self.seg_len):
            if s <= seg or i == len(self.seg_len) - 1:
                a, b = self.loop[i], self.loop[(i + 1) % len(self.loop)]
                f = 0.0 if seg <= 1e-12 else min(s / seg, 1.0)
                return (a[0] + f * (b[0] - a[0]), a[1] + f * (b[1] - a[1]))
            s -= seg
        return self.start  # pragma: no cover - the loop above always returns

    def xy(self, t_s: float) -> tuple[float, float]:
        k = bisect.bisect_right(self.goal_t, t_s) - 1
        if k < 0:
            return self._loop_xy(t_s)
        issued, _, a, b = self.goals[k]
        d = math.dist(a, b)
        f = 1.0 if d <= 1e-9 else min(1.0, self.speed * (t_s - issued) / d)
        return (a[0] + f * (b[0] - a[0]), a[1] + f * (b[1] - a[1]))

    def add_goal(self, issued_s: float, xy: tuple[float, float]) -> None:
        entry = (issued_s, len(self.goals), xy, xy)
        keys = [(g[0], g[1]) for g in self.goals]
        k = bisect.bisect_right(keys, (entry[0], entry[1]))
        self.goals.insert(k, entry)
        # Re-chain: every goal from k on starts where the robot was when it was issued.
        for j in range(k, len(self.goals)):
            issued, order, _, to = self.goals[j]
            self.goal_t = [g[0] for g in self.goals[:j]]
            self.goals[j] = (issued, order, self.xy(issued), to)
        self.goal_t = [g[0] for g in self.goals]
