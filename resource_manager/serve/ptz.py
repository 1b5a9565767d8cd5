"""PTZ allocation: many user agents share the PTZ cameras through the manager (paper, Conclusion; [8]).

An agent asks (query on ``manager/{id}/ptz/{agent}``) for a view of a track with a
priority. The priority is the agent's identity's, not its word: a request asking
more than the agent's cap (``[ptz] max_priority``, by agent id; ``default_max_priority``
for the rest, equal for all unless configured) is clipped to it, so an agent can
take a camera from another only if the site gave it a higher cap. The manager
assigns a free PTZ camera of known pose that can see the
person (within range, tilt within limits), nearest first; when every such camera
is taken, a request of strictly higher (clipped) priority preempts the
lowest-priority holder. A refusal says only what the asker may know: never who
holds a camera nor at what priority. While assigned, each tick the camera gets a PtzCommand pointing it at
the person: pan = azimuth from the camera to the track, tilt = elevation of
``aim_height_frac`` of the person's height, zoom so that ``target_width_m``
fills the field of view. The reply always says which camera or why none.

A hold is a lease, not a gift. It ends on release, preemption, when the track
ends, when the agent's liveliness token goes (exit, crash, partition:
:meth:`PtzAllocator.agent_gone`), or when its lease runs out: ``lease_s`` after
the agent's last request for it (an agent keeping a view asks again before
then). Requests arrive as :class:`PtzAsk` (the agent named by the request's
key, never by its payload alone) and are answered in the fusion tick, the one
thread that changes the allocation.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field

from common.schema import PtzRequest, SensorInfo
from resource_manager.config import PtzSection, default_of

__all__ = ["Assignment", "PtzAim", "PtzAllocator", "PtzAnswer", "PtzAsk", "PtzParams", "PtzTarget"]

MIN_AIM_DISTANCE_M = 1e-3
"""A person this close to a PTZ camera's axis foot (m) gives it no pan to aim at."""


@dataclass(frozen=True, slots=True)
class PtzParams:
    """``[ptz]`` in the allocator's units (rad); each knob is documented, and defaulted, in
    :class:`resource_manager.config.PtzSection`."""

    max_range_m: float = default_of(PtzSection, "max_range_m")
    aim_height_frac: float = default_of(PtzSection, "aim_height_frac")
    target_width_m: float = default_of(PtzSection, "target_width_m")
    hfov_rad: float = math.radians(default_of(PtzSection, "hfov_deg"))
    max_zoom: float = default_of(PtzSection, "max_zoom")
    min_tilt_rad: float = math.radians(default_of(PtzSection, "min_tilt_deg"))
    max_tilt_rad: float = math.radians(default_of(PtzSection, "max_tilt_deg"))
    lease_s: float = default_of(PtzSection, "lease_s")
    max_priority: Mapping[str, int] = field(default_factory=dict)
    """Agent id -> the highest priority its requests get (higher asks are clipped to it)."""
    default_max_priority: int = default_of(PtzSection, "default_max_priority")

    def cap(self, agent_id: str) -> int:
        """The highest priority ``agent_id``'s requests get."""
        return self.max_priority.get(agent_id, self.default_max_priority)


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
    expires_ns: int = 2**63 - 1
    """The hold ends at this instant unless renewed."""


@dataclass(frozen=True, slots=True)
class PtzAsk:
    """A PTZ request as the manager's shell received it."""

    request: PtzRequest
    agent_id: str
    """The agent its key names (the shell refused it if the payload named another)."""
    arrival_ns: int
    """When it arrived, on the manager's clock (the agent's own stamp is not trusted)."""
    token: int
    """The shell's handle of the query to answer."""


@dataclass(frozen=True, slots=True)
class PtzAnswer:
    """What to reply to one :class:`PtzAsk`."""

    token: int
    request: PtzRequest
    sensor_id: str
    """The camera, or "" with ``reason``."""
    reason: str
    lease_s: float
    """How long the hold lasts unless renewed (0 when nothing is held)."""


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
    infos: Mapping[str, SensorInfo] = field(default_factory=dict)
    """Every sensor's SensorInfo, read from the manager's sensor registry (:mod:`resource_manager.sensors`)."""
    present: Mapping[str, bool] = field(default_factory=dict)
    """...and its liveliness (sensor id -> alive; a sensor never mentioned counts as present)."""
    assignments: dict[str, Assignment] = field(default_factory=dict)
    """PTZ sensor id -> who holds it."""
    ended: list[tuple[Assignment, str]] = field(default_factory=list)
    """Assignments ended since :meth:`take_ended`, with the reason (for logs)."""

    def _camera(self, sensor_id: str) -> _Cam | None:
        """The PTZ camera ``sensor_id`` if it is present and its pose known."""
        info = self.infos.get(sensor_id)
        if info is None or info.kind != "ptz" or info.pose is None or not self.present.get(sensor_id, True):
            return None
        return _Cam(sensor_id, info.pose.x_m, info.pose.y_m, info.pose.z_m)

    @property
    def cameras(self) -> dict[str, _Cam]:
        """The PTZ cameras present with a known pose."""
        return {sid: cam for sid in self.infos if (cam := self._camera(sid)) is not None}

    def take_ended(self) -> list[tuple[Assignment, str]]:
        """The holds ended since the last call, with the reason."""
        out, self.ended = self.ended, []
        return out

    def forget(self, sensor_id: str) -> None:
        """The camera left: its hold ends."""
        a = self.assignments.pop(sensor_id, None)
        if a is not None:
            self.ended.append((a, "camera left"))

    def aim(self, sensor_id: str, target: PtzTarget) -> PtzAim | None:
        """Pan/tilt/zoom that centre the person, or None if out of reach."""
        cam = self._camera(sensor_id)
        if cam is None:
            return None
        dx, dy = target.x_m - cam.x_m, target.y_m - cam.y_m
        dist = math.hypot(dx, dy)
        if dist > self.params.max_range_m or dist < MIN_AIM_DISTANCE_M:
            return None
        aim_z = target.height_m * self.params.aim_height_frac
        tilt = math.atan2(aim_z - cam.z_m, dist)
        if not self.params.min_tilt_rad <= tilt <= self.params.max_tilt_rad:
            return None
        fov_needed = 2.0 * math.atan2(self.params.target_width_m / 2.0, dist)
        zoom = min(max(math.tan(self.params.hfov_rad / 2) / math.tan(fov_needed / 2), 1.0), self.params.max_zoom)
        return PtzAim(sensor_id, target.track_id, math.atan2(dy, dx), tilt, zoom)

    def lease_ns(self, asked_s: float) -> int:
        """The lease a request gets: what it asked for, at most ``params.lease_s`` (0: the default)."""
        lease = self.params.lease_s if asked_s <= 0 else min(asked_s, self.params.lease_s)
        return int(lease * 1e9)

    def answer(self, ask: PtzAsk, target: PtzTarget | None) -> PtzAnswer:
        """Apply one request (acquire, renew or release) and say what to reply."""
        req = ask.request
        if req.action == "acquire":
            lease = self.lease_ns(req.lease_s)
            cap = self.params.cap(ask.agent_id)
            priority = min(req.priority, cap)
            sid, reason = self.acquire(ask.agent_id, target, req.track_id, priority, ask.arrival_ns, lease_ns=lease)
            if priority < req.priority:
                # The asker may know its own cap: it explains a refusal, or a hold weaker than asked.
                reason = f"{reason}; " if reason else ""
                reason += f"priority {req.priority} clipped to {cap}, this agent's cap"
            return PtzAnswer(ask.token, req, sid, reason, lease / 1e9 if sid else 0.0)
        sid, reason = self.release(ask.agent_id, req.track_id)
        return PtzAnswer(ask.token, req, sid, reason, 0.0)

    def agent_gone(self, agent_id: str) -> None:
        """The agent's liveliness token went: every hold of it ends."""
        for sid, a in list(self.assignments.items()):
            if a.agent_id == agent_id:
                del self.assignments[sid]
                self.ended.append((a, "agent left (its liveliness token went)"))

    def acquire(
        self,
        agent_id: str,
        target: PtzTarget | None,
        track_id: str,
        priority: int,
        t_ns: int,
        *,
        lease_ns: int | None = None,
    ) -> tuple[str, str]:
        """Assign a camera (or renew the agent's hold of it); return (sensor_id, "") or ("", reason)."""
        if target is None:
            return "", f"no current track {track_id!r}"
        expires = t_ns + (self.lease_ns(0.0) if lease_ns is None else lease_ns)
        for sid, a in self.assignments.items():
            if a.agent_id == agent_id and a.track_id == track_id:
                self.assignments[sid] = Assignment(sid, agent_id, track_id, priority, a.since_ns, expires)
                return sid, ""
        return self._assign(agent_id, target, track_id, priority, (t_ns, expires))

    def _assign(
        self, agent_id: str, target: PtzTarget, track_id: str, priority: int, span_ns: tuple[int, int]
    ) -> tuple[str, str]:
        """A camera for an agent that holds none for the track: the nearest free one that can see the person, or
        the weakest held one if the agent's priority is higher."""
        t_ns, expires = span_ns
        cameras = self.cameras
        if not cameras:
            return "", "no PTZ camera with a known pose is online"
        able = [sid for sid in cameras if self.aim(sid, target) is not None]
        if not able:
            return "", f"no PTZ camera can see track {track_id!r} (out of range or tilt limits)"

        def dist(sid: str) -> float:
            c = cameras[sid]
            return math.hypot(c.x_m - target.x_m, c.y_m - target.y_m)

        free = sorted((s for s in able if s not in self.assignments), key=dist)
        if free:
            self.assignments[free[0]] = Assignment(free[0], agent_id, track_id, priority, t_ns, expires)
            return free[0], ""
        weakest = min(able, key=lambda s: (self.assignments[s].priority, -self.assignments[s].since_ns))
        held = self.assignments[weakest]
        if held.priority < priority:
            self.ended.append((held, f"preempted by {agent_id} (priority {priority} > {held.priority})"))
            self.assignments[weakest] = Assignment(weakest, agent_id, track_id, priority, t_ns, expires)
            return weakest, ""
        # Who holds the cameras, and at what priority, is not the asker's business.
        return "", f"every PTZ camera that can see track {track_id!r} is held at priority {priority} or above"

    def release(self, agent_id: str, track_id: str) -> tuple[str, str]:
        """Release the agent's camera for the track; return (sensor_id, "") or ("", reason)."""
        for sid, a in list(self.assignments.items()):
            if a.agent_id == agent_id and a.track_id == track_id:
                del self.assignments[sid]
                self.ended.append((a, "released"))
                return sid, ""
        return "", f"{agent_id} holds no PTZ camera for track {track_id!r}"

    def tick(self, targets: dict[str, PtzTarget], t_ns: int | None = None) -> list[PtzAim]:
        """Drop assignments whose track ended or whose lease ran out by ``t_ns``; aim every assigned camera."""
        out: list[PtzAim] = []
        for sid, a in list(self.assignments.items()):
            if t_ns is not None and t_ns >= a.expires_ns:
                del self.assignments[sid]
                self.ended.append((a, "lease expired (not renewed)"))
                continue
            tgt = targets.get(a.track_id)
            if tgt is None:
                del self.assignments[sid]
                self.ended.append((a, "track ended"))
                continue
            aim = self.aim(sid, tgt)
            if aim is not None:
                out.append(aim)
        return out
