"""The simulated world: room, camera platforms and people as a pure function of time.

A :class:`World` is built from a site file (``[world]`` and ``[[camera]]``) and
answers "where is everything at world time t?" for any t >= 0:

* the room: ``room_x_m`` x ``room_y_m`` with walls ``wall_height_m`` high, the
  floor at z = 0, x and y along two walls, and a door in the wall y = 0;
* camera platforms (:meth:`World.platforms_at`): every ``[[camera]]`` with its
  body -- a white cylinder of radius R (0.18 m on the paper's robots) and known
  height with a coloured marking band, carrying the camera on its axis at
  ``height_m``. Static platforms stay put; mobile robots drive their waypoint
  loop at ``max_speed_mps``, or, once given a goal (:meth:`World.set_goal`),
  drive straight to it at that speed and stop. A robot base is holonomic: its
  heading (the camera's sensor frame) stays at ``yaw_deg``;
* people (:meth:`World.people_at`), walking as described in :mod:`sim.walkers`.

World time t = (capture_stamp_ns - epoch_ns) / 1e9, with the common epoch set by
the launcher. Everything here is deterministic: the same site, seed, goals and
t give the same answer in every process. Goals take effect from their
``issued_s`` (world time), so every process that receives the same goal messages
computes the same trajectories, whenever they arrive.

Ground truth (:meth:`World.ground_truth`, :func:`write_gt_csv`) is for scoring
only: the pipeline sees pixels. In ``gt.csv`` ``z_m`` is the person's height
(the top of the head above the floor), which the pipeline estimates from the
top of the blob.
"""

from __future__ import annotations

import logging
import math
import os
import threading
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import msgspec

from common.angles import angle_diff
from common.errors import ConfigError
from common.site import CameraSpec, SiteConfig, WorldSpec
from sim.people import Door, WalkerLook
from sim.robots import ROBOT_CLEARANCE_M, RobotMotion, stop_short
from sim.walkers import WalkerSim

__all__ = [
    "SEED_ENV",
    "Goal",
    "GroundTruth",
    "PersonState",
    "PlatformState",
    "World",
    "sensor_bearing",
    "site_with_seed",
    "site_with_seed_from_env",
    "world_time_s",
    "write_gt_csv",
]

logger = logging.getLogger(__name__)

RGB = tuple[int, int, int]
ROBOT_WALL_CLEARANCE_M = 0.05
SEED_ENV = "PANOSTEREO_SEED"
"""Environment variable that overrides the site's seed (``panostereo demo --seed N`` sets it for every process)."""
SAME_GOAL_M = 0.01
"""A goal within this distance of the same robot's previous one is a repeat (a re-published plan)."""


@dataclass(frozen=True, slots=True)
class Goal:
    """A run-time goal for a mobile robot: drive to (x, y) from world time ``issued_s``."""

    sensor_id: str
    x_m: float
    y_m: float
    issued_s: float


@dataclass(frozen=True, slots=True)
class PersonState:
    """One person at one instant."""

    person_id: int
    """Identity, 1..N (the ``id`` column of gt.csv)."""
    x_m: float
    y_m: float
    height_m: float
    """Top of the head above the floor."""
    heading_rad: float
    """Walking direction, counter-clockwise from world +x."""
    present: bool
    """Inside the room (False while outside the door)."""
    body_width_m: float
    """Shoulder width."""
    shirt_rgb: RGB
    pants_rgb: RGB
    skin_rgb: RGB
    hair_rgb: RGB
    shoe_rgb: RGB
    speed_mps: float
    gait_phase_rad: float
    """Phase of the walking cycle (legs and arms swing with it)."""


@dataclass(frozen=True, slots=True)
class PlatformState:
    """A camera and its body at one instant (true pose)."""

    sensor_id: str
    kind: str
    """``panoramic`` or ``ptz``."""
    x_m: float
    y_m: float
    yaw_rad: float
    """Heading of the camera's sensor frame (world bearing of panorama column 0)."""
    z_m: float
    """Camera (optical centre) height above the floor."""
    radius_m: float
    """Radius of the white cylindrical body (0: no body)."""
    body_height_m: float
    band_rgb: RGB
    """Colour of the marking band that identifies the body."""
    mobile: bool


@dataclass(frozen=True, slots=True)
class GroundTruth:
    """Everything's true state at one instant (for scoring, never for the pipeline)."""

    t_s: float
    people: tuple[PersonState, ...]
    """Only the people present in the room."""
    platforms: tuple[PlatformState, ...]


class World:
    """The simulated site as a pure function of (site, seed, goals, t).

    Args:
        spec: the ``[world]`` table.
        cameras: the ``[[camera]]`` tables (true placements).
        seed: the site seed (textures, people, paths).
        goals: run-time goals already known.
    """

    def __init__(self, spec: WorldSpec, cameras: Sequence[CameraSpec], seed: int, goals: Iterable[Goal] = ()) -> None:
        self.spec = spec
        self.cameras = tuple(cameras)
        self.seed = int(seed)
        for cam in self.cameras:
            if not (0.0 <= cam.x_m <= spec.room_x_m and 0.0 <= cam.y_m <= spec.room_y_m):
                raise ConfigError(
                    f"camera {cam.id!r}: position ({cam.x_m}, {cam.y_m}) must be inside the room "
                    f"[0, {spec.room_x_m}] x [0, {spec.room_y_m}]"
                )
        door_w = min(1.2, 0.5 * spec.room_x_m)
        x1 = spec.room_x_m - min(1.0, 0.15 * spec.room_x_m)
        self.door = Door(x0_m=x1 - door_w, x1_m=x1, height_m=min(2.1, 0.9 * spec.wall_height_m))
        self._motion = {cam.id: RobotMotion(cam) for cam in self.cameras}
        self._goals: list[Goal] = []
        self._goal_set: set[Goal] = set()
        self._applied_key: tuple[float, str, float, float] | None = None
        self._last_target: dict[str, tuple[float, float]] = {}
        self._lock = threading.Lock()
        self._walkers = WalkerSim(spec, self.seed, self._obstacles, self.door)
        for g in goals:
            self.set_goal(g.sensor_id, g.x_m, g.y_m, g.issued_s)

    @classmethod
    def from_site(cls, site: SiteConfig, goals: Iterable[Goal] = ()) -> World:
        """The world a site file describes."""
        return cls(site.world, site.camera, site.site.seed, goals)

    # -- room ----------------------------------------------------------------------------------------
    @property
    def room_x_m(self) -> float:
        return self.spec.room_x_m

    @property
    def room_y_m(self) -> float:
        return self.spec.room_y_m

    @property
    def wall_height_m(self) -> float:
        return self.spec.wall_height_m

    @property
    def looks(self) -> list[WalkerLook]:
        """Every person's fixed appearance (index i = person_id i + 1)."""
        return self._walkers.looks

    # -- platforms -----------------------------------------------------------------------------------
    def _obstacles(self, t_s: float) -> list[tuple[float, float, float]]:
        out = []
        for cam in self.cameras:
            if cam.kind == "ptz" and cam.body_radius_m <= 0.0:
                continue  # wall-mounted: not in anyone's way
            x, y = self._motion[cam.id].xy(t_s)
            out.append((x, y, max(cam.body_radius_m, 0.25)))
        return out

    def platforms_at(self, t_s: float) -> list[PlatformState]:
        """Every camera with its body and true pose at world time ``t_s``."""
        out = []
        with self._lock:
            for cam in self.cameras:
                x, y = self._motion[cam.id].xy(t_s)
                out.append(
                    PlatformState(
                        sensor_id=cam.id,
                        kind=cam.kind,
                        x_m=x,
                        y_m=y,
                        yaw_rad=cam.yaw_rad,
                        z_m=cam.height_m,
                        radius_m=cam.body_radius_m,
                        body_height_m=cam.body_height_m,
                        band_rgb=(int(cam.band_rgb[0]), int(cam.band_rgb[1]), int(cam.band_rgb[2])),
                        mobile=cam.mobile,
                    )
                )
        return out

    def platform_at(self, sensor_id: str, t_s: float) -> PlatformState:
        """One platform's state; ConfigError for an unknown id."""
        for p in self.platforms_at(t_s):
            if p.sensor_id == sensor_id:
                return p
        raise ConfigError(f"no camera {sensor_id!r} in the world (cameras: {', '.join(c.id for c in self.cameras)})")

    # -- goals ---------------------------------------------------------------------------------------
    @property
    def goals(self) -> tuple[Goal, ...]:
        """The goals given so far, in the order they were set."""
        return tuple(self._goals)

    def set_goal(self, sensor_id: str, x_m: float, y_m: float, issued_s: float) -> Goal:
        """Send a mobile robot to (x, y) from world time ``issued_s`` at its ``max_speed_mps``.

        The goal is clamped into the room (the body stays clear of the walls).
        Goals take effect in canonical (issue time, sensor, x, y) order, so the
        trajectories do not depend on when or in which order the calls are made.
        A goal within 1 cm of the same robot's previous goal is a repeat (a
        re-published plan) and changes nothing, as in :func:`goals_from_plans`.
        The robot stops short of any other platform in its way (where it is at
        the issue time, and where its latest goal takes it).

        Returns:
            The goal as applied (after clamping).

        Raises:
            ConfigError: unknown sensor, a camera that is not mobile, or a non-finite goal.
        """
        cam = next((c for c in self.cameras if c.id == sensor_id), None)
        if cam is None:
            raise ConfigError(f"goal for unknown sensor {sensor_id!r}")
        if not cam.mobile:
            raise ConfigError(f"goal for {sensor_id!r}: the camera is not mobile")
        if not all(math.isfinite(v) for v in (x_m, y_m, issued_s)):
            raise ConfigError(f"goal for {sensor_id!r} must be finite, got ({x_m}, {y_m}) at {issued_s}")
        c = cam.body_radius_m + ROBOT_WALL_CLEARANCE_M
        gx = min(max(x_m, c), self.spec.room_x_m - c)
        gy = min(max(y_m, c), self.spec.room_y_m - c)
        if (gx, gy) != (x_m, y_m):
            logger.warning(
                "goal for %s clamped into the room: (%.2f, %.2f) -> (%.2f, %.2f)", sensor_id, x_m, y_m, gx, gy
            )
        goal = Goal(sensor_id=sensor_id, x_m=gx, y_m=gy, issued_s=max(0.0, float(issued_s)))
        with self._lock:
            if goal in self._goal_set:
                return goal  # already applied: giving the same goal twice changes nothing
            self._goals.append(goal)
            self._goal_set.add(goal)
            if self._applied_key is None or _goal_key(goal) > self._applied_key:
                changed = self._apply_goal(goal)  # the usual case: goals arrive in time order
            else:
                self._replay_goals()  # a late goal: rebuild everything in canonical order
                changed = True
        if changed:
            self._walkers.invalidate_from(goal.issued_s)
        return goal

    def _apply_goal(self, g: Goal) -> bool:
        """Append one goal (the latest in canonical order); False when it repeats the robot's previous goal."""
        self._applied_key = _goal_key(g)
        prev = self._last_target.get(g.sensor_id)
        if prev is not None and math.dist(prev, (g.x_m, g.y_m)) < SAME_GOAL_M:
            return False  # a re-published plan: not a new goal
        self._last_target[g.sensor_id] = (g.x_m, g.y_m)
        me = self._motion[g.sensor_id]
        blockers = []
        for cam in self.cameras:
            other = self._motion[cam.id]
            if cam.id == g.sensor_id or (cam.kind == "ptz" and cam.body_radius_m <= 0.0):
                continue
            keep = me.radius_m + max(cam.body_radius_m, 0.1) + ROBOT_CLEARANCE_M
            blockers.append((*other.xy(g.issued_s), keep))
            dest = other.destination(g.issued_s)
            if dest is not None:
                blockers.append((*dest, keep))
        me.append_goal(g.issued_s, stop_short(me.xy(g.issued_s), (g.x_m, g.y_m), blockers))
        return True

    def _replay_goals(self) -> None:
        """Rebuild every robot's trajectory from all goals, in canonical (issue time, sensor, x, y) order."""
        for motion in self._motion.values():
            motion.clear_goals()
        self._last_target = {}
        self._applied_key = None
        for g in sorted(self._goals, key=_goal_key):
            self._apply_goal(g)

    def with_goals(self, goals: Iterable[Goal]) -> World:
        """A new world with these goals added to the ones already set."""
        return World(self.spec, self.cameras, self.seed, [*self._goals, *goals])

    # -- people --------------------------------------------------------------------------------------
    def people_at(self, t_s: float) -> list[PersonState]:
        """Every person (present or not) at world time ``t_s``."""
        s = self._walkers.sample(t_s)
        out = []
        for i, look in enumerate(self._walkers.looks):
            out.append(
                PersonState(
                    person_id=look.person_id,
                    x_m=float(s.x_m[i]),
                    y_m=float(s.y_m[i]),
                    height_m=look.height_m,
                    heading_rad=float(s.heading_rad[i]),
                    present=bool(s.present[i]),
                    body_width_m=look.body_width_m,
                    shirt_rgb=look.shirt_rgb,
                    pants_rgb=look.pants_rgb,
                    skin_rgb=look.skin_rgb,
                    hair_rgb=look.hair_rgb,
                    shoe_rgb=look.shoe_rgb,
                    speed_mps=float(s.speed_mps[i]),
                    gait_phase_rad=float(s.gait_phase_rad[i]),
                )
            )
        return out

    def ground_truth(self, t_s: float) -> GroundTruth:
        """Present people and all platforms at world time ``t_s``."""
        people = tuple(p for p in self.people_at(t_s) if p.present)
        return GroundTruth(t_s=float(t_s), people=people, platforms=tuple(self.platforms_at(t_s)))


def write_gt_csv(world: World, path: str | Path, fps: float, duration_s: float) -> int:
    """Write the people's ground truth as ``frame,id,x_m,y_m,z_m``; returns the number of rows.

    Frame k (1-based) is world time (k - 1) / fps; only people present in the
    room are listed; ``z_m`` is the person's height (top of the head).

    Raises:
        ConfigError: non-positive fps or negative duration.
    """
    if not (fps > 0 and math.isfinite(fps)) or not (duration_s >= 0 and math.isfinite(duration_s)):
        raise ConfigError(f"write_gt_csv: need fps > 0 and duration_s >= 0, got fps={fps}, duration_s={duration_s}")
    n_frames = math.floor(duration_s * fps + 1e-9)
    lines = ["frame,id,x_m,y_m,z_m"]
    for k in range(1, n_frames + 1):
        for p in world.people_at((k - 1) / fps):
            if p.present:
                lines.append(f"{k},{p.person_id},{p.x_m:.4f},{p.y_m:.4f},{p.height_m:.4f}")
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return len(lines) - 1


def sensor_bearing(platform: PlatformState, x_m: float, y_m: float) -> float:
    """Sensor-frame bearing (rad, wrapped to [-pi, pi)) of a world point seen from a platform."""
    return angle_diff(math.atan2(y_m - platform.y_m, x_m - platform.x_m), platform.yaw_rad)


def _goal_key(g: Goal) -> tuple[float, str, float, float]:
    return (g.issued_s, g.sensor_id, g.x_m, g.y_m)


def world_time_s(stamp_ns: int, epoch_ns: int) -> float:
    """World time of a capture stamp: (stamp - epoch) / 1e9 seconds."""
    return (int(stamp_ns) - int(epoch_ns)) / 1e9


def site_with_seed_from_env(site: SiteConfig, env: Mapping[str, str] | None = None) -> SiteConfig:
    """The site with its seed replaced by ``PANOSTEREO_SEED`` when that is set (every sim process and the
    ground-truth writer call this, so they all simulate the same world).

    Raises:
        ConfigError: the variable is set but is not an integer.
    """
    raw = (os.environ if env is None else env).get(SEED_ENV, "").strip()
    if not raw:
        return site
    try:
        seed = int(raw)
    except ValueError as err:
        raise ConfigError(f"{SEED_ENV} must be an integer, got {raw!r}") from err
    return site_with_seed(site, seed)


def site_with_seed(site: SiteConfig, seed: int | None) -> SiteConfig:
    """The site with its world seed replaced by ``seed`` (None: unchanged)."""
    if seed is None:
        return site
    return msgspec.structs.replace(site, site=msgspec.structs.replace(site.site, seed=int(seed)))
