"""PTZ allocation: many user agents share the PTZ cameras through the manager (paper, Conclusion; [8]).

An agent asks (query on ``manager/{id}/ptz``) for a view of a track with a
priority. The manager assigns a free PTZ camera of known pose that can see the
person (within range, tilt within limits), nearest first; when every such camera
is taken, a request of strictly higher priority preempts the lowest-priority
holder. While assigned, each tick the camera gets a PtzCommand pointing it at
the person: pan = azimuth from the camera to the track, tilt = elevation of
``aim_height_frac`` of the person's height, zoom so that ``target_width_m``
fills the field of view. An assignment ends on release, preemption, or when the
track ends; the reply always says which camera or why none.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from common.schema import SensorInfo

__all__ = ["Assignment", "PtzAim", "PtzAllocator", "PtzParams", "PtzTarget"]


@dataclass(frozen=True, slots=True)
class PtzParams:
    max_range_m: float = 25.0
    aim_height_frac: float = 0.85
    target_width_m: float = 1.5
    hfov_rad: float = math.radians(60.0)
    max_zoom: float = 10.0
    min_tilt_rad: float = math.radians(-80.0)
    max_tilt_rad: float = math.radians(60.0)


@dataclass(frozen=True, slots=True)
class PtzTarget:
    track_id: str
    x_m: float
    y_m: float
    height_m: float


@dataclass(frozen=True, slots=True)
class Assignment:
    sensor_id: str
    agent_id: str
    track_id: str
    priority: int
    since_ns: int


@dataclass(frozen=True, slots=True)
class PtzAim:
    sensor_id: str
    track_id: str
    pan_rad: float
    tilt_rad: float
    zoom: float


@dataclass(slots=True)
class _Cam:
    sensor_id: str
    x_m: float
    y_m: float
    z_m: float


@dataclass(slots=True)
class PtzAllocator:
    params: PtzParams = field(default_factory=PtzParams)
    cameras: dict[str, _Cam] = field(default_factory=dict)
    assignments: dict[str, Assignment] = field(default_factory=dict)
    """PTZ sensor id -> who holds it."""
    ended: list[tuple[Assignment, str]] = field(default_factory=list)
    """Assignments ended since the last tick, with the reason (for logs)."""

    def update_info(self, info: SensorInfo) -> None:
        if info.kind != "ptz":
            return
        if info.pose is None:
            self.cameras.pop(info.sensor_id, None)
            return
        p = info.pose
        self.cameras[info.sensor_id] = _Cam(info.sensor_id, p.x_m, p.y_m, p.z_m)

    def forget(self, sensor_id: str) -> None:
        self.cameras.pop(sensor_id, None)
        a = self.assignments.pop(sensor_id, None)
        if a is not None:
            self.ended.append((a, "camera left"))

    def aim(self, sensor_id: str, target: PtzTarget) -> PtzAim | None:
        """Pan/tilt/zoom that centre the person, or None if out of reach."""
        cam = self.cameras.get(sensor_id)
        if cam is None:
            return None
        dx, dy = target.x_m - cam.x_m, target.y_m - cam.y_m
        dist = math.hypot(dx, dy)
        if dist > self.params.max_range_m or dist < 1e-3:
            return None
        aim_z = (target.height_m if target.height_m > 0 else 1.7) * self.params.aim_height_frac
        tilt = math.atan2(aim_z - cam.z_m, dist)
        if not self.params.min_tilt_rad <= tilt <= self.params.max_tilt_rad:
            return None
        fov_needed = 2.0 * math.atan2(self.params.target_width_m / 2.0, dist)
        zoom = min(max(math.tan(self.params.hfov_rad / 2) / math.tan(fov_needed / 2), 1.0), self.params.max_zoom)
        return PtzAim(sensor_id, target.track_id, math.atan2(dy, dx), tilt, zoom)

    def acquire(
        self, agent_id: str, target: PtzTarget | None, track_id: str, priority: int, t_ns: int
    ) -> tuple[str, str]:
        """Assign a camera; return (sensor_id, "") or ("", reason)."""
        if target is None:
            return "", f"no current track {track_id!r}"
        for sid, a in self.assignments.items():
            if a.agent_id == agent_id and a.track_id == track_id:
                if a.priority != priority:
                    self.assignments[sid] = Assignment(sid, agent_id, track_id, priority, a.since_ns)
                return sid, ""
        if not self.cameras:
            return "", "no PTZ camera with a known pose is online"
        able = [sid for sid in self.cameras if self.aim(sid, target) is not None]
        if not able:
            return "", f"no PTZ camera can see track {track_id!r} (out of range or tilt limits)"

        def dist(sid: str) -> float:
            c = self.cameras[sid]
            return math.hypot(c.x_m - target.x_m, c.y_m - target.y_m)

        free = sorted((s for s in able if s not in self.assignments), key=dist)
        if free:
            self.assignments[free[0]] = Assignment(free[0], agent_id, track_id, priority, t_ns)
            return free[0], ""
        weakest = min(able, key=lambda s: (self.assignments[s].priority, -self.assignments[s].since_ns))
        held = self.assignments[weakest]
        if held.priority < priority:
            self.ended.append((held, f"preempted by {agent_id} (priority {priority} > {held.priority})"))
            self.assignments[weakest] = Assignment(weakest, agent_id, track_id, priority, t_ns)
            return weakest, ""
        return "", (
            f"all {len(able)} PTZ camera(s) that can see track {track_id!r} are held at priority >= {priority}"
            f" (lowest: {held.agent_id} at {held.priority})"
        )

    def release(self, agent_id: str, track_id: str) -> tuple[str, str]:
        """Release the agent's camera for the track; return (sensor_id, "") or ("", reason)."""
        for sid, a in list(self.assignments.items()):
            if a.agent_id == agent_id and a.track_id == track_id:
                del self.assignments[sid]
                self.ended.append((a, "released"))
                return sid, ""
        return "", f"{agent_id} holds no PTZ camera for track {track_id!r}"

    def tick(self, targets: dict[str, PtzTarget]) -> list[PtzAim]:
        """Drop assignments whose track ended; aim every assigned camera."""
        out: list[PtzAim] = []
        for sid, a in list(self.assignments.items()):
            tgt = targets.get(a.track_id)
            if tgt is None:
                del self.assignments[sid]
                self.ended.append((a, "track ended"))
                continue
            aim = self.aim(sid, tgt)
            if aim is not None:
                out.append(aim)
        return out
