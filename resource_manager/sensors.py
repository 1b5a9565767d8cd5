"""The sensor registry: everything the manager knows of each sensor, in one place.

Per sensor it owns what the sensor said it is (its SensorInfo), whether its liveliness token is there
(presence), its recent frames (:class:`~resource_manager.ingest.buffers.Ingest`'s buffers and the irregular-message
counters) and its measured frame timing (:class:`~resource_manager.ingest.schedule.FrameTiming`). The stages read
it: the pose solver and the PTZ allocator the SensorInfo, the scheduler the timing, alignment the frames. Only
:class:`~resource_manager.fusion.Fusion` writes it, through the methods below.

Memory is bounded by one figure, ``capacity`` (sensors): at most that many sensors hold frames and timing, and at
most :data:`PRESENCE_PER_SENSOR` times it liveliness entries (a gone sensor's entry is kept, to drop its late frames
and report it absent, until room is needed).
"""

from __future__ import annotations

from collections.abc import Iterator

from common.schema import MAX_SENSORS, Features, SensorInfo
from resource_manager.ingest.buffers import Ingest, IngestCounters, SensorBuffer
from resource_manager.ingest.schedule import FrameTiming

__all__ = ["PRESENCE_PER_SENSOR", "SensorRegistry"]

PRESENCE_PER_SENSOR = 4
"""Liveliness entries kept per sensor slot: tokens come and go (a flapping link, ids tried by a stranger) more
often than sensors send frames, and an entry is one flag."""


class SensorRegistry:
    """SensorInfo, presence, frame buffers and frame timing of every sensor the manager has heard of.

    Args:
        buffer_frames: most frames kept per sensor.
        clock_step_ns: a frame with a higher seq this much behind the newest restarts the sensor's buffer.
        max_wait_ns: the scheduler's longest wait (bounds a frame's measured delay, :meth:`FrameTiming.note`).
        capacity: most sensors holding frames (bounded memory: ids nobody announced cannot grow it without limit).
    """

    def __init__(self, buffer_frames: int, clock_step_ns: int, max_wait_ns: int, capacity: int = MAX_SENSORS) -> None:
        self.capacity = capacity
        self.max_wait_ns = max_wait_ns
        self.infos: dict[str, SensorInfo] = {}
        """What each sensor said it is (whichever arrived last; kept after it leaves)."""
        self.present: dict[str, bool] = {}
        """Liveliness: sensor id -> alive. A sensor never mentioned counts as present."""
        self.frames = Ingest(buffer_frames, clock_step_ns)
        """Each sensor's recent frames, sorted by capture stamp, and the irregular-message counters."""
        self.timing: dict[str, FrameTiming] = {}
        """Each sensor's measured frame period, delay and jitter (read by the scheduler)."""
        self.received = 0
        """Frames offered so far, every sensor's (forgotten sensors' too)."""

    # -- reads ----------------------------------------------------------------------------------------------------
    def is_present(self, sensor_id: str) -> bool:
        """False only for a sensor whose liveliness token went."""
        return self.present.get(sensor_id, True)

    @property
    def buffers(self) -> dict[str, SensorBuffer]:
        return self.frames.buffers

    @property
    def counters(self) -> IngestCounters:
        return self.frames.counters

    def present_buffers(self) -> Iterator[tuple[str, SensorBuffer]]:
        """The frame buffers of the sensors still present."""
        return ((sid, buf) for sid, buf in self.frames.buffers.items() if self.is_present(sid))

    def known(self, also: set[str] | None = None) -> list[str]:
        """Every sensor heard of: by its SensorInfo or its frames (plus ``also``, e.g. the pose overrides)."""
        return sorted(set(self.frames.buffers) | set(self.infos) | (also or set()))

    def alive(self) -> set[str]:
        """Sensors whose liveliness token is there."""
        return {sid for sid, alive in self.present.items() if alive}

    def absent(self) -> list[str]:
        """Sensors seen before whose liveliness token is gone."""
        return sorted(sid for sid, alive in self.present.items() if not alive)

    def in_use(self) -> list[str]:
        """The sensors the watermark waits for: present ones with frames, and declared ones whose first frame is
        still to come."""
        with_frames = {sid for sid, buf in self.frames.buffers.items() if buf.newest_stamp() is not None}
        return [sid for sid in sorted(with_frames | self.infos.keys()) if self.is_present(sid)]

    # -- writes ---------------------------------------------------------------------------------------------------
    def _timing(self, sensor_id: str) -> FrameTiming:
        s = self.timing.get(sensor_id)
        if s is None:
            s = self.timing[sensor_id] = FrameTiming()
        return s

    def declare(self, info: SensorInfo) -> None:
        """Take a SensorInfo. Whichever arrives last wins: the manager's shell passes only what the sensor's own
        queryable confirmed (resource_manager/ingest/infos.py); its stamp is not compared (a forged one from 2262
        would otherwise shadow every real SensorInfo after it). Its fps is the period until frames measure one."""
        self.infos[info.sensor_id] = info
        self._timing(info.sensor_id).declared_period_ns = int(1e9 / info.fps) if info.fps > 0 else 0

    def came(self, sensor_id: str) -> None:
        """Its liveliness token appeared (ignored when the liveliness entries are full of present sensors)."""
        limit = PRESENCE_PER_SENSOR * self.capacity
        if sensor_id not in self.present and len(self.present) >= limit:
            # Bounded memory under liveliness churn: forget sensors already gone first.
            for gone in [k for k, v in self.present.items() if not v]:
                del self.present[gone]
            if len(self.present) >= limit:
                return
        self.present[sensor_id] = True

    def went(self, sensor_id: str) -> bool:
        """Its liveliness token went: it is marked absent and its frames and timing forgotten. Returns whether it
        was known at all (by presence, frames or SensorInfo)."""
        if sensor_id not in self.present and sensor_id not in self.frames.buffers and sensor_id not in self.infos:
            return False
        self.present[sensor_id] = False
        self.forget(sensor_id)
        return True

    def file(self, frame: Features, arrival_ns: int) -> None:
        """File one Features message that arrived at ``arrival_ns`` (dropped, and counted, when its sensor is gone
        or the registry is full)."""
        sid = frame.sensor_id
        if not self.is_present(sid) or (sid not in self.frames.buffers and len(self.frames.buffers) >= self.capacity):
            self.frames.counters.dropped += 1
            return
        kind = self.frames.add(frame)
        self.received += 1
        processing_ns = int(frame.processing_ms * 1e6)
        arrival = arrival_ns or frame.stamp_ns + processing_ns
        self._timing(sid).arrived(kind, frame.stamp_ns, arrival, processing_ns, self.max_wait_ns)

    def fused(self, t_ns: int) -> None:
        """An instant was fused: frames stamped at or before it are late from now on."""
        self.frames.last_fusion_ns = t_ns

    def trim(self, keep_from_ns: int, forget_before_ns: int) -> None:
        """Free frames no later instant can need (before ``keep_from_ns``), and forget a sensor that never said
        what it is, is not known present and sent nothing since ``forget_before_ns`` (free its slot)."""
        self.frames.trim(keep_from_ns)
        for sid, buf in list(self.frames.buffers.items()):
            newest = buf.newest_stamp()
            if sid not in self.infos and not self.present.get(sid) and (newest is None or newest < forget_before_ns):
                self.forget(sid)

    def forget(self, sensor_id: str) -> None:
        """Drop a sensor's frames and timing (its SensorInfo and presence stay: it may come back)."""
        self.frames.forget(sensor_id)
        self.timing.pop(sensor_id, None)
