"""View planning for mobile cameras (paper, "Error Characteristics and View Planning", Eqs. 4-6, Fig. 4).

For each mobile camera with a known pose, pick the person it should help
localise, take the other camera of that person's pair as the main camera O1,
and place the mobile camera O2 where the error map of Fig. 4 is minimal
relative to the current target: B ≈ 2√(D1 R), cos φ1 = 3BD1/(2D1²+B²)
(:func:`common.error_model.optimal_positions_world`, model M1). Of the two
symmetric optima the one nearer the robot wins; the goal is clipped to the
room. As the person moves, the goal moves: the sensor nodes drive the robots
there (closed loop).

Assignment: each mobile camera takes the confirmed track with the largest
predicted error among those it is not already the best for, nearest first when
equal; two mobile cameras never take the same person.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np
import numpy.typing as npt

from common.error_model import OptimalConfig, m1_error, optimal_configuration
from common.errors import GeometryError

__all__ = ["PlanGoal", "PlannerParams", "ViewPlanner"]

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True, slots=True)
class PlannerParams:
    enabled: bool = True
    period_ns: int = 500_000_000
    room: tuple[float, float, float, float] | None = None
    margin_m: float = 0.4
    min_move_m: float = 0.15


@dataclass(frozen=True, slots=True)
class PlanGoal:
    sensor_id: str
    partner_id: str
    track_id: str
    goal_xy: tuple[float, float]
    baseline_m: float
    phi1_rad: float
    predicted_error_m: float
    current_error_m: float


@dataclass(frozen=True, slots=True)
class PlanTarget:
    """What the planner needs of a track."""

    track_id: str
    xy: FloatArray
    predicted_error_m: float
    sensors: tuple[str, ...]


@dataclass(frozen=True, slots=True)
class PlanCamera:
    sensor_id: str
    xy: FloatArray
    radius_m: float
    """Body radius R used by Eq. 3 (the error model's baseline term)."""
    sigma_rad: float
    mobile: bool


@dataclass(slots=True)
class ViewPlanner:
    params: PlannerParams = field(default_factory=PlannerParams)
    last_ns: int = 0
    last_goal: dict[str, tuple[float, float]] = field(default_factory=dict)

    def _clip(self, xy: FloatArray) -> FloatArray:
        room = self.params.room
        if room is None:
            return xy
        m = self.params.margin_m
        return np.array([min(max(xy[0], room[0] + m), room[2] - m), min(max(xy[1], room[1] + m), room[3] - m)])

    def plan(
        self, t_ns: int, cameras: list[PlanCamera], targets: list[PlanTarget], force: bool = False
    ) -> list[PlanGoal]:
        """Goals for the mobile cameras (at most once per period unless ``force``)."""
        if not self.params.enabled or not targets:
            return []
        if not force and t_ns - self.last_ns < self.params.period_ns:
            return []
        self.last_ns = t_ns
        by_id = {c.sensor_id: c for c in cameras}
        taken: set[str] = set()
        out: list[PlanGoal] = []
        for cam in sorted((c for c in cameras if c.mobile), key=lambda c: c.sensor_id):
            if cam.radius_m <= 0:
                continue
            order = sorted(
                (t for t in targets if t.track_id not in taken),
                key=lambda t: (-t.predicted_error_m, float(np.hypot(*(t.xy - cam.xy)))),
            )
            for tgt in order:
                partners = [by_id[s] for s in tgt.sensors if s in by_id and s != cam.sensor_id]
                if not partners:
                    partners = [c for c in cameras if c.sensor_id != cam.sensor_id]
                if not partners:
                    continue
                main = min(partners, key=lambda c: float(np.hypot(*(c.xy - tgt.xy))))
                goal = self._goal(cam, main, tgt)
                if goal is None:
                    continue
                taken.add(tgt.track_id)
                prev = self.last_goal.get(cam.sensor_id)
                if (
                    prev is not None
                    and math.hypot(goal.goal_xy[0] - prev[0], goal.goal_xy[1] - prev[1]) < self.params.min_move_m
                ):
                    goal = PlanGoal(
                        goal.sensor_id, goal.partner_id, goal.track_id, prev, goal.baseline_m, goal.phi1_rad,
                        goal.predicted_error_m, goal.current_error_m,
                    )  # fmt: skip
                self.last_goal[cam.sensor_id] = goal.goal_xy
                out.append(goal)
                break
        return out

    def _goal(self, cam: PlanCamera, main: PlanCamera, tgt: PlanTarget) -> PlanGoal | None:
        d1 = float(np.hypot(*(tgt.xy - main.xy)))
        if d1 <= 1e-6:
            return None
        try:
            cfg = _optimal(round(d1, 2), round(cam.radius_m, 3))
        except GeometryError:
            return None
        # Fig. 4's frame (O1 at the origin, T on +x) -> world.
        c, s = (tgt.xy - main.xy) / d1
        rot = np.array([[c, -s], [s, c]])
        p_a = main.xy + rot @ np.asarray(cfg.o2_xy_pair[0])
        p_b = main.xy + rot @ np.asarray(cfg.o2_xy_pair[1])
        goal = min((p_a, p_b), key=lambda p: float(np.hypot(*(p - cam.xy))))
        goal = self._clip(np.asarray(goal, dtype=np.float64))
        sigma = cam.sigma_rad
        try:
            at_goal = float(m1_error(main.xy, goal, tgt.xy, cam.radius_m, sigma, baseline_known=False))
            now = float(m1_error(main.xy, cam.xy, tgt.xy, cam.radius_m, sigma, baseline_known=False))
        except GeometryError:
            return None
        if not math.isfinite(at_goal):
            at_goal = cfg.normalised_error * d1 * sigma
        if not math.isfinite(now):
            now = 1e5
        return PlanGoal(
            sensor_id=cam.sensor_id,
            partner_id=main.sensor_id,
            track_id=tgt.track_id,
            goal_xy=(float(goal[0]), float(goal[1])),
            baseline_m=float(np.hypot(*(goal - main.xy))),
            phi1_rad=float(cfg.phi1_rad),
            predicted_error_m=min(at_goal, 1e5),
            current_error_m=min(now, 1e5),
        )


@lru_cache(maxsize=4096)
def _optimal(d1_m: float, radius_m: float) -> OptimalConfig:
    """Fig. 4's optimum for (D1, R), cached (D1 rounded to 1 cm: the map is flat near its minimum)."""
    return optimal_configuration(d1_m, radius_m)
