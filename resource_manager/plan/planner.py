"""View planning for mobile cameras (paper, "Error Characteristics and View Planning", Eqs. 4-6, Fig. 4).

For each mobile camera with a known pose, pick the person it should help
localise, take the other camera of that person's pair as the main camera O1,
and place the mobile camera O2 where the error map of Fig. 4 (model M1,
:func:`common.error_model.normalised_error_xy`) is minimal relative to the
current target -- unconstrained, B ≈ 2√(D1 R) and cos φ1 = 3BD1/(2D1²+B²)
(Eq. 4) -- among the places where the system keeps working:

* **Where the system keeps working** (:mod:`resource_manager.plan.checks`): both
  bodies' bands in each other's view (minimum and maximum baseline, Eq. 3), the
  person's head in view and D2 >= D1/2, the room, clearance on the drive and at
  the goal, and the line of sight to the main camera's body.
* **Hysteresis**: a new goal only when its predicted error is below
  (1 - ``gain_frac``) times, and ``min_gain_m`` below, that of the goal held (or
  of where the robot stands, before any goal; judged without the constraints that
  depend on where people are now: someone walking by is no reason to leave), and
  not within ``settle_ns`` of the last new goal (or of the
  first plan for that camera) unless the held one -- or where the robot stands --
  became infeasible, so the robot can settle, relearn its background and be
  re-calibrated. The held goal is re-published every period (a repeat:
  the simulated world and :func:`sim.world.goals_from_plans` ignore it),
  also while nobody is tracked, until the robot gets there.
* **Cost of moving**: while the robot drives and settles, its views count for
  nothing (:mod:`resource_manager.views.settling`); on a site where the people it
  helps have no other pair then, a move is made only when the found
  person-seconds it gains over ``horizon_s`` exceed those lost on the way
  (:func:`~resource_manager.plan.checks.move_payoff`, ``found_m``).
* **One robot at a time**: while another robot drives or relearns its
  background (:meth:`ViewPlanner.driving`), a robot standing in a usable place
  waits.

The candidates are a grid (``grid_step_m``) over the room (or around the target; the map is smooth and flat
near its minimum, docs/geometry.md §2.3); among near-equal ones the shorter drive wins (``travel_frac_per_m``).

Assignment: each mobile camera takes the confirmed track with the largest predicted error among those not yet
taken, nearest first when equal; two mobile cameras never take the same person.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field, replace

import numpy as np

from common.arrays import FloatArray
from common.schema import MAX_METRES
from resource_manager.plan.checks import feasible, found, move_payoff, others_error, predicted_error
from resource_manager.plan.scene import (
    PlanCamera,
    PlanGoal,
    PlannerParams,
    PlanTarget,
    Scene,
    plan_camera,
)

__all__ = ["PlanCamera", "PlanGoal", "PlanTarget", "PlannerParams", "ViewPlanner", "plan_camera"]

logger = logging.getLogger(__name__)


@dataclass(slots=True)
class _Held:
    xy: tuple[float, float]
    track_id: str
    issued_ns: int
    arrived_ns: int | None = None
    """When the robot's pose first came within ``min_move_m`` of the goal."""
    last: PlanGoal | None = None
    """The goal as last published."""


@dataclass(slots=True)
class ViewPlanner:
    params: PlannerParams = field(default_factory=PlannerParams)
    last_ns: int = 0
    held: dict[str, _Held] = field(default_factory=dict)
    """The goal each mobile camera was last sent (re-published until a better one)."""
    goals_issued: int = 0
    """New goals (not repeats) so far."""
    ref_avg: dict[tuple[str, str], tuple[float, int]] = field(default_factory=dict)
    """Per (mobile camera, track): the chance the person is found where the robot stands (averaged), when."""
    first_ns: dict[str, int] = field(default_factory=dict)
    """When each mobile camera was first planned for (its first goal waits ``settle_ns`` from then)."""

    def note_arrivals(self, positions: dict[str, FloatArray], t_ns: int) -> None:
        """Record when each robot sent to a goal first came within ``min_move_m`` of it (by ``positions``).

        Called once per tick with the cameras' poses, before :meth:`driving` and :meth:`en_route` are asked.
        """
        lim = self.params.min_move_m
        for sid, h in self.held.items():
            xy = positions.get(sid)
            if h.arrived_ns is None and xy is not None and math.dist(tuple(map(float, xy[:2])), h.xy) <= lim:
                h.arrived_ns = t_ns

    def driving(self, positions: dict[str, FloatArray], t_ns: int) -> frozenset[str]:
        """The mobile cameras (with a pose in ``positions``) this planner set moving that cannot detect anyone yet.

        From a new goal until ``relearn_ns`` after the robot reached it (:meth:`note_arrivals`), its node sees
        the world move and relearns its background: its empty blob lists say nothing about where people
        are, and must not count as "seen nothing there" against the other cameras' detections.
        """
        return frozenset(
            sid
            for sid, h in self.held.items()
            if sid in positions and (h.arrived_ns is None or t_ns - h.arrived_ns < self.params.relearn_ns)
        )

    def en_route(self, positions: dict[str, FloatArray]) -> frozenset[str]:
        """The mobile cameras sent to a goal they have not reached yet (by their pose in ``positions``)."""
        lim = self.params.min_move_m
        return frozenset(
            sid
            for sid, h in self.held.items()
            if sid in positions
            and h.arrived_ns is None
            and math.dist((float(positions[sid][0]), float(positions[sid][1])), h.xy) > lim
        )

    def _fixed(self, c: PlanCamera) -> PlanCamera:
        held = self.held.get(c.sensor_id) if c.mobile else None
        return c if held is None else replace(c, xy=np.asarray(held.xy))

    def plan(
        self, t_ns: int, cameras: list[PlanCamera], targets: list[PlanTarget], force: bool = False
    ) -> list[PlanGoal]:
        """Goals for the mobile cameras (at most once per period unless ``force``)."""
        if not self.params.enabled or (not targets and not self.held):
            return []
        if not force and t_ns - self.last_ns < self.params.period_ns:
            return []
        self.last_ns = t_ns
        live = {t.track_id for t in targets}
        self.ref_avg = {k: v for k, v in self.ref_avg.items() if k[1] in live}
        if not targets:
            # Nobody tracked now (a two-camera site while its robot drives): a robot still on its way keeps
            # its goal, re-published as it was.
            return [h.last for h in self.held.values() if h.arrived_ns is None and h.last is not None]
        by_id = {c.sensor_id: c for c in cameras}
        taken: set[str] = set()
        out: list[PlanGoal] = []
        positions = {c.sensor_id: c.xy for c in cameras}
        for cam in sorted((c for c in cameras if c.mobile), key=lambda c: c.sensor_id):
            if cam.radius_m <= 0:
                continue
            held = self.held.get(cam.sensor_id)
            order = sorted(
                (t for t in targets if t.track_id not in taken),
                key=lambda t: (
                    held is None or t.track_id != held.track_id,
                    -t.predicted_error_m,
                    float(np.hypot(*(t.xy - cam.xy))),
                ),
            )
            rest = [c for c in cameras if c.sensor_id != cam.sensor_id]
            fixed = [self._fixed(c) for c in rest]
            # Where the other robots are going counts as well as where they are.
            others = rest + [f for c, f in zip(rest, fixed, strict=True) if f is not c]
            self.note_arrivals(positions, t_ns)
            busy = self.driving(positions, t_ns) - {cam.sensor_id}  # including goals sent this instant
            for tgt in order:
                partners = [by_id[s] for s in tgt.sensors if s in by_id and s != cam.sensor_id] or rest
                if not partners:
                    continue
                main = min(partners, key=lambda c: float(np.hypot(*(c.xy - tgt.xy))))
                scene = Scene(cam, main, tgt, others, targets, fixed, bool(busy))
                goal = self._goal(t_ns, scene)
                if goal is None:
                    continue
                taken.add(tgt.track_id)
                out.append(goal)
                break
        return out

    # -- one camera ---------------------------------------------------------------------------------
    def _goal(self, t_ns: int, sc: Scene) -> PlanGoal | None:
        p = self.params
        cam, main, tgt = sc.cam, sc.main, sc.tgt
        d1 = float(np.hypot(*(tgt.xy - main.xy)))
        if d1 <= 2 * cam.radius_m:
            return None
        xy = self._grid(tgt.xy, d1)
        err = predicted_error(xy, sc)
        ok = feasible(xy, sc, p)
        travel = 1.0 + p.travel_frac_per_m * np.hypot(*(xy - cam.xy).T)
        i = int(np.argmin(np.where(ok, err * travel, np.inf)))
        best_xy, best_err = xy[i], float(err[i]) if ok[i] else math.inf
        here = cam.xy[None, :]
        now_err = float(predicted_error(here, sc)[0])
        held = self.held.get(cam.sensor_id)
        if held is not None:
            h = np.asarray(held.xy)[None, :]
            held_ok = bool(feasible(h, sc, p, drive=False, transient=False)[0])
            ref_xy, ref_err = h[0], float(predicted_error(h, sc)[0]) if held_ok else math.inf
        else:
            here_ok = bool(feasible(here, sc, p, drive=False, transient=False, bands=not cam.ranged)[0])
            ref_xy, ref_err = cam.xy, now_err if here_ok else math.inf
        since = t_ns - (held.issued_ns if held is not None else self.first_ns.setdefault(cam.sensor_id, t_ns))
        settling = (since < p.settle_ns or sc.others_busy) and math.isfinite(ref_err)
        better = math.isfinite(best_err) and (
            not math.isfinite(ref_err)
            or (best_err < (1.0 - p.gain_frac) * ref_err and best_err < ref_err - p.min_gain_m)
        )
        far = float(np.hypot(*(best_xy - ref_xy))) >= p.min_move_m
        worth = self._worth(t_ns, sc, best_xy, best_err, ref_err)
        if better and far and worth and not settling:
            self.held[cam.sensor_id] = _Held((float(best_xy[0]), float(best_xy[1])), tgt.track_id, t_ns)
            self.goals_issued += 1
            logger.info(
                "plan %s: goal (%.2f, %.2f) for %s with %s, predicted error %.3f m (was %.3f m here, %.3f m held)",
                cam.sensor_id, best_xy[0], best_xy[1], tgt.track_id, main.sensor_id, best_err, now_err, ref_err,
            )  # fmt: skip
            goal_xy, goal_err = best_xy, best_err
        elif held is not None:
            if held.track_id != tgt.track_id:
                self.held[cam.sensor_id] = _Held(held.xy, tgt.track_id, held.issued_ns, held.arrived_ns)
            goal_xy, goal_err = np.asarray(held.xy), ref_err
        else:
            return None  # where it stands is good enough: no goal yet
        if float(np.hypot(*(goal_xy - cam.xy))) < p.min_move_m:
            now_err = goal_err  # arrived (the pose estimate's noise is below min_move_m)
        v1, v2 = tgt.xy - main.xy, goal_xy - main.xy
        phi1 = abs(math.atan2(v1[0] * v2[1] - v1[1] * v2[0], float(v1 @ v2)))
        goal = PlanGoal(
            sensor_id=cam.sensor_id,
            partner_id=main.sensor_id,
            track_id=tgt.track_id,
            goal_xy=(float(goal_xy[0]), float(goal_xy[1])),
            baseline_m=float(np.hypot(*v2)),
            phi1_rad=float(phi1),
            predicted_error_m=min(goal_err, MAX_METRES),
            current_error_m=min(now_err, MAX_METRES),
        )
        self.held[cam.sensor_id].last = goal
        return goal

    def _worth(self, t_ns: int, sc: Scene, goal_xy: FloatArray, goal_err: float, ref_err: float) -> bool:
        """Is the move worth what it costs (:func:`~resource_manager.plan.checks.move_payoff`)?

        The target's chance of being found where the robot stands (``ref_err``) is averaged over
        ``persist_s`` first: someone crossing the line between two cameras soon leaves it.
        """
        p = self.params
        cam = sc.cam
        if not math.isfinite(ref_err):
            return True  # it cannot stay there
        key = (cam.sensor_id, sc.tgt.track_id)
        # A new target starts as found (no evidence yet that it is lost where the robot stands).
        avg, since = self.ref_avg.get(key, (1.0, t_ns))
        a = 1.0 - math.exp(-max(t_ns - since, 0) / 1e9 / max(p.persist_s, 1e-3))
        others_err = others_error(sc)
        here = avg + a * (found(min(ref_err, others_err), p.found_m) - avg)  # or the others' best pair
        self.ref_avg[key] = (here, t_ns)
        if p.found_m <= 0:
            return True
        gain, cost, blind_s = move_payoff(sc, p, goal_xy, goal_err, here, others_err=others_err)
        logger.debug(
            "plan %s: a move gains %.1f found s, loses %.1f (%.1f s blind)", cam.sensor_id, gain, cost, blind_s
        )
        return gain > cost + p.min_found_gain_s

    def _grid(self, centre: FloatArray, d1: float) -> FloatArray:
        step = self.params.grid_step_m
        room = self.params.room
        if room is not None:
            m = self.params.margin_m
            x0, y0, x1, y1 = room[0] + m, room[1] + m, room[2] - m, room[3] - m
        else:
            half = d1 + 3.0
            x0, y0, x1, y1 = centre[0] - half, centre[1] - half, centre[0] + half, centre[1] + half
        xs = np.clip(np.round(np.arange(x0, x1 + 1e-9, step), 6), x0, x1)
        ys = np.clip(np.round(np.arange(y0, y1 + 1e-9, step), 6), y0, y1)
        gx, gy = np.meshgrid(xs, ys)
        return np.stack([gx.ravel(), gy.ravel()], axis=1)
