"""Ingest: bounded per-sensor frame buffers, ordered by capture time.

Messages arrive over the network late, twice, out of order, or from a sender
whose clock was just stepped by NTP. The buffer keeps each sensor's frames
sorted by ``stamp_ns`` so that alignment (:mod:`resource_manager.ingest.align`) can
always find the two frames that bracket the fusion instant, whatever the
arrival order:

* *duplicate*: a frame with a stamp (or seq) already held is counted and ignored;
* *out of order*: a frame older than the newest held is counted and inserted
  in its place (it can still bracket a later fusion instant);
* *late*: a frame whose stamp is already behind the last fusion instant is
  counted; it is kept only as a lower bracket;
* *clock step*: a frame with a higher seq but a stamp far behind the newest
  means the sender's clock moved back; the sensor's buffer restarts from it
  (otherwise every later frame would look out of order until the clock caught up);
* *overflow*: beyond ``capacity`` frames the oldest go (counted as dropped).

None of these touches the tracks: a sensor without usable frames simply sits
out a tick.
"""

from __future__ import annotations

import bisect
import logging
from dataclasses import dataclass, field

from common.ratelog import SenderLog
from common.schema import Features

__all__ = ["Ingest", "IngestCounters", "SensorBuffer"]

logger = logging.getLogger(__name__)


@dataclass(slots=True)
class IngestCounters:
    """How many messages of each irregular kind were seen (for ManagerStatus)."""

    accepted: int = 0
    late: int = 0
    duplicate: int = 0
    out_of_order: int = 0
    dropped: int = 0
    """Frames pushed out of a full buffer or refused as too old."""
    clock_steps: int = 0


@dataclass(slots=True)
class SensorBuffer:
    """One sensor's recent frames, sorted by capture stamp."""

    capacity: int
    stamps: list[int] = field(default_factory=list)
    frames: list[Features] = field(default_factory=list)
    max_seq: int = -1

    def newest_stamp(self) -> int | None:
        return self.stamps[-1] if self.stamps else None

    def clear(self) -> None:
        self.stamps.clear()
        self.frames.clear()
        self.max_seq = -1

    def bracket(self, t_ns: int) -> tuple[Features | None, Features | None]:
        """The latest frame at or before ``t_ns`` and the earliest after it."""
        i = bisect.bisect_right(self.stamps, t_ns)
        before = self.frames[i - 1] if i > 0 else None
        after = self.frames[i] if i < len(self.frames) else None
        return before, after

    def previous(self, frame: Features) -> Features | None:
        """The frame just before ``frame`` (for extrapolation)."""
        i = bisect.bisect_left(self.stamps, frame.stamp_ns)
        return self.frames[i - 1] if i > 0 else None

    def trim_before(self, t_ns: int) -> int:
        """Drop frames not needed to bracket instants >= ``t_ns`` (keep one at or before it)."""
        i = bisect.bisect_right(self.stamps, t_ns) - 2
        if i <= 0:
            return 0
        del self.stamps[:i]
        del self.frames[:i]
        return i


class Ingest:
    """Per-sensor buffers plus the irregular-message counters.

    Args:
        capacity: most frames kept per sensor.
        clock_step_ns: a frame with a higher seq whose stamp is this much behind
            the newest held frame restarts that sensor's buffer.
    """

    def __init__(self, capacity: int = 64, clock_step_ns: int = 1_500_000_000) -> None:
        self.capacity = capacity
        self.clock_step_ns = clock_step_ns
        self.buffers: dict[str, SensorBuffer] = {}
        self.counters = IngestCounters()
        self.last_fusion_ns = 0
        self._log = SenderLog(logger)
        """Clock steps are said once a second per sensor (a sender alternating stamps cannot flood the log)."""

    def add(self, msg: Features) -> str:
        """File one Features message; return what it was: accepted|duplicate|out_of_order|late|clock_step."""
        buf = self.buffers.get(msg.sensor_id)
        if buf is None:
            buf = self.buffers[msg.sensor_id] = SensorBuffer(self.capacity)
        newest = buf.newest_stamp()
        kind = "accepted"
        stepped = newest is not None and msg.stamp_ns < newest and msg.seq > buf.max_seq
        if newest is not None and stepped and newest - msg.stamp_ns >= self.clock_step_ns:
            self._log.log(
                logging.WARNING,
                msg.sensor_id,
                "sensor %s: clock stepped back by %.3f s (seq %d after %d); restarting its buffer",
                msg.sensor_id,
                (newest - msg.stamp_ns) / 1e9,
                msg.seq,
                buf.max_seq,
            )
            self.counters.clock_steps += 1
            buf.clear()
            kind = "clock_step"
        i = bisect.bisect_left(buf.stamps, msg.stamp_ns)
        if i < len(buf.stamps) and buf.stamps[i] == msg.stamp_ns:
            self.counters.duplicate += 1
            return "duplicate"
        if kind == "accepted" and newest is not None and msg.stamp_ns < newest:
            kind = "out_of_order"
            self.counters.out_of_order += 1
        if msg.stamp_ns <= self.last_fusion_ns and kind != "clock_step":
            self.counters.late += 1
            if kind == "accepted":
                kind = "late"
            if i == 0 and len(buf.stamps) >= self.capacity:
                self.counters.dropped += 1
                return kind
        buf.stamps.insert(i, msg.stamp_ns)
        buf.frames.insert(i, msg)
        buf.max_seq = max(buf.max_seq, msg.seq)
        self.counters.accepted += 1
        while len(buf.stamps) > self.capacity:
            del buf.stamps[0]
            del buf.frames[0]
            self.counters.dropped += 1
        return kind

    def forget(self, sensor_id: str) -> None:
        """Drop a sensor's buffer (it left: liveliness DELETE)."""
        self.buffers.pop(sensor_id, None)

    def trim(self, keep_from_ns: int) -> None:
        """Free frames no later fusion instant can need."""
        for buf in self.buffers.values():
            buf.trim_before(keep_from_ns)
