"""Walking people for the simulated world: a deterministic, incremental crowd simulation.

Every person is stepped at a fixed ``DT_S`` from t = 0, all together (so people
avoid each other), and the states are kept so any time can be sampled again.
Random decisions (the next waypoint, whether to pause and for how long) are
drawn from a generator seeded by ``(seed, person, decision number)``, never from
a shared stream, so the simulation is a pure function of the site, the seed and
the camera platforms' trajectories: every process computes the same crowd.

Behaviour (the issue's "realistic paths"):

* walking speed per person in ``person_speed_mps``; acceleration and turn rate
  are bounded, so paths turn smoothly;
* ``random`` paths: waypoints across the room (so paths cross), with pauses
  (``pause_prob``); ``rectangle``: the paper's Fig. 7 path, a known rectangle
  with six turn points where the walker stops briefly, people spaced along it and
  walking in alternating directions; ``line``: back and forth along the segment
  from (x0, y0) to (x1, y1) of ``rectangle``;
* ``enter_leave``: people come in and go out through the door (on the wall y = 0)
  and stay outside for a while;
* people steer around each other and around camera platforms, and can never
  overlap a platform (a hard constraint).

When a mobile platform's trajectory changes (a goal given at run time), the
caller invalidates the states after the goal's issue time with
:meth:`WalkerSim.invalidate_from`; they are recomputed from the last checkpoint.
"""

from __future__ import annotations

import math
import random
import threading
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from common.angles import angle_diff, wrap_angle
from common.errors import ConfigError
from common.site import WorldSpec
from sim.people import Door, WalkerLook, make_look

__all__ = ["DT_S", "WalkerSample", "WalkerSim"]

DT_S = 0.05
"""Simulation step (s); samples between steps are interpolated."""
CHECKPOINT_STEPS = 20
KEEP_S = 300.0
"""Frames kept for direct sampling behind the newest simulated time (older ones are re-simulated)."""
SPARSE_CHECKPOINT_S = 30.0
"""Spacing of the checkpoints kept from before the window."""
OLD_SEGMENT_S = 10.0
MAX_CATCH_UP_S = 4 * 3600.0
"""Most world time simulated in one go; beyond it the epoch must be wrong."""
PERSON_RADIUS_M = 0.28
"""Clearance a person keeps from a platform's surface (half shoulder width + a little)."""
PERSON_GAP_M = 0.5
"""Closest two people's centres come (shoulder to shoulder)."""
MAX_PUSH_M = 0.03
"""Most a person is displaced per step to keep clear of someone else (bounded, so nobody jumps)."""
ACCEL_MPS2 = 1.2
TURN_RATE_RADPS = 2.6
STRIDE_M = 1.4
"""Distance walked per full gait cycle (two steps)."""
ARRIVE_M = 0.3
STUCK_S = 25.0
"""A walker that has not reached its target after this long picks another."""

AVOID_RANGE_M = 1.6
"""People steer away from others closer than this, the more the nearer and the more ahead."""
VEER_RANGE_M = 1.5
"""...and round a platform whose surface is closer than this on their way."""
PASS_MARGIN_M = 0.15
"""A platform is on a person's way when its centre is within its radius + PERSON_RADIUS_M + this of it."""
KEEP_CLEAR_M = 0.25
"""A person closer than this to a platform's clearance steps away from it."""
SAME_SPOT_M = 1e-6
"""Two centres closer than this are at one spot: no direction between them."""
START_SPACING_M = 0.9
"""People placed in the room at the start stand at least this far apart."""
ROUTE_ENDS = 2
"""A route of two points is walked back and forth; a longer one, round."""
JUMP_M = 0.5
"""A move this large between two simulation steps is a jump (entering from outside): not interpolated."""
FLAG_TRUE = 0.5
"""The state arrays hold flags as 0.0 / 1.0: above this is true."""
HALF = 0.5
"""A sample takes the flags of the nearer of its two steps."""

_WALK, _PAUSE, _OUTSIDE = 0, 1, 2
_WANDER, _ENTER, _EXIT_IN, _EXIT_OUT, _ROUTE = 0, 1, 2, 3, 4

Obstacles = Callable[[float], Sequence[tuple[float, float, float]]]
"""World time -> platforms as (x_m, y_m, radius_m)."""


@dataclass(frozen=True, slots=True)
class WalkerSample:
    """All people at one instant (arrays of length N, person i = ``looks[i]``)."""

    x_m: npt.NDArray[np.float64]
    y_m: npt.NDArray[np.float64]
    heading_rad: npt.NDArray[np.float64]
    speed_mps: npt.NDArray[np.float64]
    gait_phase_rad: npt.NDArray[np.float64]
    present: npt.NDArray[np.bool_]


class _Walker:
    """Mutable dynamic state of one person (scalar fields, copied into checkpoints)."""

    __slots__ = (
        "heading", "leg_start", "mode", "ndec", "phase", "route_dir", "route_idx", "speed",
        "timer", "tkind", "tx", "ty", "wander_left", "x", "y",
    )  # fmt: skip

    def __init__(self) -> None:
        self.x = self.y = self.heading = self.speed = self.phase = 0.0
        self.tx = self.ty = self.timer = self.leg_start = 0.0
        self.mode = _WALK
        self.tkind = _WANDER
        self.ndec = self.wander_left = self.route_idx = 0
        self.route_dir = 1

    def snapshot(self) -> tuple[float | int, ...]:
        return tuple(getattr(self, k) for k in self.__slots__)

    def restore(self, snap: tuple[float | int, ...]) -> None:
        for k, v in zip(self.__slots__, snap, strict=True):
            setattr(self, k, v)


class WalkerSim:
    """People walking in the room; :meth:`sample` gives their state at any time >= 0.

    Args:
        spec: the ``[world]`` table (room, people, speeds, heights, paths).
        seed: the site seed.
        obstacles: platforms at a given time, as (x, y, radius); people keep clear of them.
        door: the door people enter and leave by.
    """

    def __init__(self, spec: WorldSpec, seed: int, obstacles: Obstacles, door: Door) -> None:
        self.spec = spec
        self.seed = int(seed)
        self.door = door
        self._obstacles = obstacles
        self._lock = threading.Lock()
        n = spec.people
        self.looks: list[WalkerLook] = [make_look(spec, self.seed, i) for i in range(n)]
        self._walkers = [_Walker() for _ in range(n)]
        self._route = self._route_points()
        self._init_walkers()
        self._base = 0
        """Step number of ``_frames[0]``."""
        self._frames: list[npt.NDArray[np.float64]] = [self._record(self._walkers)]
        self._old: tuple[int, list[npt.NDArray[np.float64]]] = (0, [])
        self._checkpoints: dict[int, list[tuple[float | int, ...]]] = {0: [w.snapshot() for w in self._walkers]}

    # -- set-up -------------------------------------------------------------------------------------
    def _rng(self, person: int, decision: int) -> random.Random:
        return random.Random(f"walker:{self.seed}:{person}:{decision}")

    def _route_points(self) -> list[tuple[float, float]]:
        x0, y0, x1, y1 = self.spec.rectangle
        if self.spec.paths == "line":
            return [(x0, y0), (x1, y1)]
        if self.spec.paths != "rectangle":
            return []
        # Six turn points (the paper's Fig. 7a shows six clusters): the corners and the middles of the long sides.
        if abs(x1 - x0) >= abs(y1 - y0):
            xm = 0.5 * (x0 + x1)
            return [(x0, y0), (xm, y0), (x1, y0), (x1, y1), (xm, y1), (x0, y1)]
        ym = 0.5 * (y0 + y1)
        return [(x0, y0), (x1, y0), (x1, ym), (x1, y1), (x0, y1), (x0, ym)]

    def _clear_of(self, x: float, y: float, t_s: float, margin_m: float) -> bool:
        return all(math.hypot(x - ox, y - oy) >= r + margin_m for ox, oy, r in self._obstacles(t_s))

    def _random_target(self, i: int, w: _Walker, t_s: float, rng: random.Random) -> tuple[float, float]:
        m = max(self.spec.margin_m, 0.3)
        xs, ys = self.spec.room_x_m, self.spec.room_y_m
        best = (xs / 2, ys / 2)
        for _ in range(40):
            x, y = rng.uniform(m, max(m, xs - m)), rng.uniform(m, max(m, ys - m))
            best = (x, y)
            if math.hypot(x - w.x, y - w.y) >= min(2.0, 0.4 * max(xs, ys)) and self._clear_of(x, y, t_s, m):
                break
        return best

    def _init_walkers(self) -> None:
        n = len(self._walkers)
        placed: list[tuple[float, float]] = []
        for i, w in enumerate(self._walkers):
            rng = self._rng(i, 0)
            w.ndec = 1
            if self._route:
                npts = len(self._route)
                w.route_dir = 1 if i % 2 == 0 else -1
                w.route_idx = round(i * npts / max(n, 1)) % npts
                w.x, w.y = self._route[w.route_idx]
                w.tkind = _ROUTE
                w.route_idx = (w.route_idx + w.route_dir) % npts
                w.tx, w.ty = self._route[w.route_idx]
            elif self.spec.enter_leave and i % 2 == 1:
                w.mode, w.tkind = _OUTSIDE, _ENTER
                w.x, w.y = self.door.outside_xy
                w.timer = 1.0 + 4.0 * i / max(n, 1) + rng.uniform(0.0, 2.0)
            else:
                m = max(self.spec.margin_m, 0.3)
                for _ in range(60):
                    w.x = rng.uniform(m, self.spec.room_x_m - m)
                    w.y = rng.uniform(m, self.spec.room_y_m - m)
                    if self._clear_of(w.x, w.y, 0.0, m) and all(
                        math.hypot(w.x - px, w.y - py) > START_SPACING_M for px, py in placed
                    ):
                        break
                w.tx, w.ty = self._random_target(i, w, 0.0, rng)
                w.wander_left = rng.randint(4, 8)
            placed.append((w.x, w.y))
            w.heading = math.atan2(w.ty - w.y, w.tx - w.x) if w.mode != _OUTSIDE else math.pi / 2
            w.speed = 0.0 if w.mode == _OUTSIDE else self.looks[i].speed_mps * 0.5

    # -- stepping -----------------------------------------------------------------------------------
    @staticmethod
    def _record(walkers: list[_Walker]) -> npt.NDArray[np.float64]:
        rows = [
            (w.x, w.y, w.heading, w.speed, w.phase, float(w.mode != _OUTSIDE and w.y > 0.0), float(w.mode != _OUTSIDE))
            for w in walkers
        ]
        return np.asarray(rows, dtype=np.float64).reshape(len(walkers), 7)

    def _arrive(self, i: int, w: _Walker, t_s: float) -> None:
        rng = self._rng(i, w.ndec)
        w.ndec += 1
        w.leg_start = t_s
        if w.tkind == _ROUTE:
            npts = len(self._route)
            if npts == ROUTE_ENDS:
                w.route_idx = 1 - w.route_idx
            else:
                w.route_idx = (w.route_idx + w.route_dir) % npts
            w.tx, w.ty = self._route[w.route_idx]
            w.mode, w.timer = _PAUSE, t_s + rng.uniform(0.6, 1.5)
            return
        if w.tkind == _EXIT_IN:
            w.tkind = _EXIT_OUT
            w.tx, w.ty = self.door.outside_xy
            return
        if w.tkind == _EXIT_OUT:
            w.mode, w.timer, w.speed = _OUTSIDE, t_s + rng.uniform(3.0, 12.0), 0.0
            return
        if w.tkind == _ENTER:
            w.tkind = _WANDER
            w.wander_left = rng.randint(4, 8)
        elif self.spec.enter_leave:
            w.wander_left -= 1
            if w.wander_left <= 0:
                w.tkind = _EXIT_IN
                w.tx, w.ty = self.door.inside_xy
                return
        if rng.random() < self.spec.pause_prob:
            w.mode, w.timer = _PAUSE, t_s + rng.uniform(1.0, 4.0)
        w.tx, w.ty = self._random_target(i, w, t_s, rng)

    def _steer(
        self, i: int, w: _Walker, others: npt.NDArray[np.float64], obst: Sequence[tuple[float, float, float]]
    ) -> float:
        """Desired heading: toward the target, bent around people and platforms ahead."""
        tx, ty = w.tx, w.ty
        if w.tkind == _EXIT_OUT and w.y > 0.0 and not (self.door.x0_m + 0.3 <= w.x <= self.door.x1_m - 0.3):
            tx, ty = self.door.inside_xy[0], 0.3  # pushed aside at the door: line up with the doorway first
        dx, dy = tx - w.x, ty - w.y
        dist = math.hypot(dx, dy) or 1e-9
        gx, gy = dx / dist, dy / dist
        hx, hy = math.cos(w.heading), math.sin(w.heading)
        px = py = 0.0
        for j in range(others.shape[0]):
            if j == i or others[j, 6] < FLAG_TRUE:
                continue
            rx, ry = others[j, 0] - w.x, others[j, 1] - w.y
            d = math.hypot(rx, ry)
            if d > AVOID_RANGE_M or d < SAME_SPOT_M:
                continue
            ux, uy = rx / d, ry / d
            ahead = max(0.0, ux * hx + uy * hy)
            k = (AVOID_RANGE_M - d) / AVOID_RANGE_M * (0.4 + ahead)
            px -= ux * k * 1.2
            py -= uy * k * 1.2
            px += uy * k * ahead * 0.9  # sidestep: keep the other person on the left
            py -= ux * k * ahead * 0.9
        for ox, oy, r in obst:
            rx, ry = ox - w.x, oy - w.y
            d = math.hypot(rx, ry)
            gap = d - r - PERSON_RADIUS_M
            if gap > VEER_RANGE_M or d < SAME_SPOT_M:
                continue
            ux, uy = rx / d, ry / d
            along = rx * gx + ry * gy  # how far ahead on the way to the target
            lateral = ux * gy - uy * gx  # > 0: the platform is to the right of the way
            beside = abs(rx * gy - ry * gx)  # distance of its centre from the straight way
            if along > 0.0 and along < dist + r and beside < r + PERSON_RADIUS_M + PASS_MARGIN_M:
                # On a collision course: veer round it, on the side away from its centre.
                k = (VEER_RANGE_M - max(gap, 0.0)) / VEER_RANGE_M * 2.0
                side = 1.0 if lateral > 0 else -1.0  # +1: veer left (counter-clockwise), away from it
                px -= side * uy * k
                py += side * ux * k
            if gap < KEEP_CLEAR_M:
                k = (KEEP_CLEAR_M - max(gap, 0.0)) / KEEP_CLEAR_M * 1.5  # too close: step away
                px -= ux * k
                py -= uy * k
        return math.atan2(gy + py, gx + px)

    def _crowding(self, i: int, w: _Walker, others: npt.NDArray[np.float64]) -> float:
        """Speed factor: slow down behind or in front of someone close ahead."""
        hx, hy = math.cos(w.heading), math.sin(w.heading)
        k = 1.0
        for j in range(others.shape[0]):
            if j == i or others[j, 6] < FLAG_TRUE:
                continue
            rx, ry = others[j, 0] - w.x, others[j, 1] - w.y
            d = math.hypot(rx, ry)
            if d < 1.0 and rx * hx + ry * hy > 0.7 * d:
                k = min(k, max(0.2, (d - PERSON_GAP_M) / (1.0 - PERSON_GAP_M)))
        return k

    def _constrain(
        self, i: int, w: _Walker, others: npt.NDArray[np.float64], obst: Sequence[tuple[float, float, float]]
    ) -> None:
        # People do not walk through each other: step out of anyone closer than PERSON_GAP_M (both do,
        # against the other's position at the start of the step, so each corrects half the overlap).
        for j in range(others.shape[0]):
            if j == i or others[j, 6] < FLAG_TRUE or w.mode == _OUTSIDE:
                continue
            rx, ry = w.x - others[j, 0], w.y - others[j, 1]
            d = math.hypot(rx, ry)
            if d < PERSON_GAP_M:
                if d < SAME_SPOT_M:
                    rx, ry, d = (1.0, 0.0, 1.0) if i < j else (-1.0, 0.0, 1.0)
                push = min(0.5 * (PERSON_GAP_M - d), MAX_PUSH_M)
                w.x += rx / d * push
                w.y += ry / d * push
        xs, ys = self.spec.room_x_m, self.spec.room_y_m
        wall = 0.25
        in_doorway = self.door.x0_m + wall <= w.x <= self.door.x1_m - wall
        if w.tkind in (_ENTER, _EXIT_IN, _EXIT_OUT) and (in_doorway or w.y < 0.0):
            # Through the door: the wall y = 0 has a gap here; behind it, stay in the corridor.
            if w.y < wall:
                w.x = min(max(w.x, self.door.x0_m + wall), self.door.x1_m - wall)
            w.y = max(w.y, self.door.outside_xy[1] - 0.2)
        else:
            w.y = max(w.y, wall)
        w.x = min(max(w.x, wall), xs - wall)
        w.y = min(w.y, ys - wall)
        for ox, oy, r in obst:
            rx, ry = w.x - ox, w.y - oy
            d = math.hypot(rx, ry)
            need = r + PERSON_RADIUS_M
            if d < need:
                if d < SAME_SPOT_M:
                    rx, ry, d = 1.0, 0.0, 1.0
                w.x, w.y = ox + rx / d * need, oy + ry / d * need

    def _step_one(
        self,
        i: int,
        w: _Walker,
        t_s: float,
        others: npt.NDArray[np.float64],
        obst: Sequence[tuple[float, float, float]],
    ) -> None:
        if w.mode == _OUTSIDE:
            if t_s >= w.timer:
                w.mode, w.tkind, w.leg_start = _WALK, _ENTER, t_s
                w.x, w.y = self.door.outside_xy
                w.heading, w.speed = math.pi / 2, 0.5 * self.looks[i].speed_mps
                w.tx, w.ty = self.door.inside_xy
            return
        pref = self.looks[i].speed_mps
        want = self._steer(i, w, others, obst)
        err = angle_diff(want, w.heading)
        rate = TURN_RATE_RADPS * (0.5 if w.mode == _PAUSE else 1.0)
        w.heading = wrap_angle(w.heading + max(-rate * DT_S, min(rate * DT_S, err)))
        if w.mode == _PAUSE:
            v_goal = 0.0
            if t_s >= w.timer:
                w.mode, w.leg_start = _WALK, t_s
        else:
            dist = math.hypot(w.tx - w.x, w.ty - w.y)
            v_goal = pref * max(0.25, math.cos(min(abs(err), math.pi / 2))) * self._crowding(i, w, others)
            v_goal = min(v_goal, max(0.3, dist * 1.5)) if w.tkind == _ROUTE else v_goal
        dv = max(-ACCEL_MPS2 * DT_S, min(ACCEL_MPS2 * DT_S, v_goal - w.speed))
        w.speed = max(0.0, w.speed + dv)
        w.x += w.speed * math.cos(w.heading) * DT_S
        w.y += w.speed * math.sin(w.heading) * DT_S
        w.phase += 2.0 * math.pi * w.speed * DT_S / STRIDE_M
        self._constrain(i, w, others, obst)
        if w.mode == _WALK:
            if math.hypot(w.tx - w.x, w.ty - w.y) < ARRIVE_M:
                self._arrive(i, w, t_s)
            elif t_s - w.leg_start > STUCK_S or not self._clear_of(w.tx, w.ty, t_s, PERSON_RADIUS_M):
                self._arrive(i, w, t_s)  # blocked (e.g. a robot parked on the target): go elsewhere

    def _step_all(self, walkers: list[_Walker], k: int, others: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
        """Advance everyone from step k to k + 1; returns the record of step k + 1."""
        t_s = k * DT_S
        obst = [o for o in self._obstacles(t_s) if o[2] > 0.0]
        for i, w in enumerate(walkers):
            self._step_one(i, w, t_s, others, obst)
        return self._record(walkers)

    def _advance_to(self, step: int) -> None:
        """Simulate the live state up to ``step``, keeping a window of frames and sparse checkpoints."""
        frontier = self._base + len(self._frames) - 1
        if (step - frontier) * DT_S > MAX_CATCH_UP_S:
            raise ConfigError(
                f"world time {step * DT_S:.0f} s is more than {MAX_CATCH_UP_S:.0f} s ahead of the simulation "
                f"({frontier * DT_S:.0f} s): is the common epoch set (PANOSTEREO_EPOCH_NS / [source] epoch_ns)?"
            )
        while frontier < step:
            self._frames.append(self._step_all(self._walkers, frontier, self._frames[-1]))
            frontier += 1
            if frontier % CHECKPOINT_STEPS == 0:
                self._checkpoints[frontier] = [w.snapshot() for w in self._walkers]
        # Bound memory: frames older than KEEP_S are dropped (recomputed from a checkpoint if asked
        # for again); older checkpoints thin out to one every SPARSE_CHECKPOINT_S.
        drop = len(self._frames) - round(KEEP_S / DT_S)
        if drop > 2 * CHECKPOINT_STEPS:
            drop -= drop % CHECKPOINT_STEPS
            del self._frames[:drop]
            self._base += drop
            sparse = round(SPARSE_CHECKPOINT_S / DT_S)
            for k in [k for k in self._checkpoints if k < self._base and k % sparse]:
                del self._checkpoints[k]

    def _old_pair(self, k0: int) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
        """Frames k0 and k0 + 1 from before the kept window: re-simulated from a checkpoint (cached)."""
        seg_start, seg = self._old
        if not (seg_start <= k0 and k0 + 1 < seg_start + len(seg)):
            cp = max(k for k in self._checkpoints if k <= k0)
            walkers = [_Walker() for _ in self._walkers]
            for w, snap in zip(walkers, self._checkpoints[cp], strict=True):
                w.restore(snap)
            seg = [self._record(walkers)]
            for k in range(cp, max(k0 + 1, cp + round(OLD_SEGMENT_S / DT_S))):
                seg.append(self._step_all(walkers, k, seg[-1]))
            seg_start = cp
            self._old = (seg_start, seg)
        return seg[k0 - seg_start], seg[k0 + 1 - seg_start]

    # -- public -------------------------------------------------------------------------------------
    def invalidate_from(self, t_s: float) -> None:
        """Forget states after ``t_s`` (the platforms' trajectories changed from then on)."""
        with self._lock:
            step = max(0, math.floor(t_s / DT_S))
            self._old = (0, [])
            cp = max(k for k in self._checkpoints if k <= step)
            if cp >= self._base + len(self._frames) - 1:
                return
            for w, snap in zip(self._walkers, self._checkpoints[cp], strict=True):
                w.restore(snap)
            if cp >= self._base:
                del self._frames[cp - self._base + 1 :]
            else:
                self._frames, self._base = [self._record(self._walkers)], cp
            for k in [k for k in self._checkpoints if k > cp]:
                del self._checkpoints[k]

    def sample(self, t_s: float) -> WalkerSample:
        """Everyone's state at world time ``t_s`` (clamped at 0), interpolated between steps.

        Raises:
            ConfigError: ``t_s`` is implausibly far ahead (more than ``MAX_CATCH_UP_S`` beyond what has
                been simulated), which means the world-time epoch is wrong.
        """
        pos = max(0.0, float(t_s)) / DT_S
        k0 = math.floor(pos)
        frac = pos - k0
        with self._lock:
            self._advance_to(k0 + 1)
            if k0 >= self._base:
                a, b = self._frames[k0 - self._base], self._frames[k0 + 1 - self._base]
            else:
                a, b = self._old_pair(k0)
        dh = wrap_angle(b[:, 2] - a[:, 2])
        heading = wrap_angle(a[:, 2] + frac * dh)
        # A jump (entering through the door from outside) is not interpolated.
        jump = np.hypot(b[:, 0] - a[:, 0], b[:, 1] - a[:, 1]) > JUMP_M
        f = np.where(jump, 0.0, frac)
        return WalkerSample(
            x_m=a[:, 0] + f * (b[:, 0] - a[:, 0]),
            y_m=a[:, 1] + f * (b[:, 1] - a[:, 1]),
            heading_rad=heading,
            speed_mps=a[:, 3] + f * (b[:, 3] - a[:, 3]),
            gait_phase_rad=a[:, 4] + f * (b[:, 4] - a[:, 4]),
            present=(a[:, 5] if frac < HALF else b[:, 5]) > FLAG_TRUE,
        )
