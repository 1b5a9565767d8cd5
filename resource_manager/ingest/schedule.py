"""When to fuse: the watermark of the sensors' frames, not a fixed delay behind the clock.

An instant ``t`` can be fused once every sensor in use has sent a frame at or after ``t`` (then each sensor's
blobs are interpolated to ``t`` between two real frames), or once a sensor is so late that waiting longer would
hold everyone back: its next frame has missed the deadline its own recent frames predict (a margin over the
latest they came past their expected time, at most ``max_wait``). The instant fused is the newest one that every
sensor still on time has reached: the minimum of their newest frame stamps (the watermark of stream processors).
Sensors that send frames at one instant (a dataset's cameras) are fused exactly at their frame instants;
unsynchronised ones at the pace of the slowest, interpolated. A sensor that has said what it is but sent no frame
yet (the network starting, a camera joining) is waited for like one whose first frame is due: at most ``max_wait``
from the first instant it holds back, and not again until it sends one; otherwise the first frames of a site's
cameras, arriving one by one, would be fused one camera at a time.

The same rule runs in dataset time (``panostereo evaluate-site``, every frame arriving at its own stamp) and live
(:mod:`resource_manager.node`, frames arriving over the network), so the two fuse the same instants.

``fixed`` mode is the older rule, kept to compare against and for sites that want a steady cadence: fuse
``now - max_wait`` on a timer, whether or not the frames arrived long ago.

Every fusion also records where the capture -> fusion time went (:class:`TickLatency`): the node's processing of
the frame the instant waited for last, its transport, and the wait for the watermark after it arrived.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from typing import Literal

__all__ = ["FrameTiming", "ScheduleParams", "Scheduler", "TickLatency"]

Mode = Literal["watermark", "fixed"]

MIN_ALLOWANCE_NS = 20_000_000
"""The least a sensor is waited for past its expected next frame (20 ms): a host's scheduling and a LAN hop
jitter by a few ms even when every frame so far came on time."""
WAIT_MARGIN = 1.5
"""A sensor is waited for this many times the latest any of its recent frames came past its expected time."""
WINDOW_FRAMES = 32
"""How many recent frames that lateness is taken over (a sample large enough to hold the occasional spike)."""
WARMUP_FRAMES = 8
"""Until this many frames have measured it, a sensor is waited for the longest (``max_wait``)."""
SMOOTHING = 0.05
"""Weight of each new frame in a sensor's running period, delay and jitter figures (a memory of ~20 frames)."""
DROP_PERIODS = 1.5
"""Stamps further apart than this many periods are dropped frames between, not the period."""

PERIOD_FRAMES = 2
"""A measured period needs two frames; until then the declared one (SensorInfo fps) stands."""


@dataclass(frozen=True, slots=True)
class ScheduleParams:
    mode: Mode
    max_wait_ns: int
    """Watermark: the most a late sensor is waited for past its expected frame. Fixed: the delay behind now."""
    min_interval_ns: int
    """At most one fusion per this (the configured maximum tick rate)."""


@dataclass(slots=True)
class FrameTiming:
    """One sensor's measured frame timing, from its frames' capture stamps and arrival times."""

    declared_period_ns: int = 0
    """From its SensorInfo's fps (0: unknown); used until two frames measure it."""
    period_ns: float = 0.0
    period_dev_ns: float = 0.0
    delay_ns: float = 0.0
    """Capture -> arrival at the manager (node processing plus transport), running mean."""
    delay_dev_ns: float = 0.0
    """Its running mean absolute deviation (the jitter)."""
    lateness: deque[float] = field(default_factory=lambda: deque(maxlen=WINDOW_FRAMES))
    """How long after its expected time (the previous frame's stamp plus one period) each recent frame arrived:
    the delay and the period's jitter together, the way the deadline meets them."""
    newest_ns: int = 0
    """Stamp of its newest frame (0: none)."""
    arrival_ns: int = 0
    """When that frame arrived."""
    processing_ns: int = 0
    """The node's capture -> publish time of that frame."""
    frames: int = 0
    """Frames measured since its clock last stepped."""
    received: int = 0
    """Every frame offered, duplicates and all."""
    late: int = 0
    """Frames that arrived after their instant was fused (dropped from it)."""
    missed: int = 0
    """Deadlines this sensor missed: the others were fused without it."""
    missed_newest: int = 0
    """The newest stamp whose next frame's deadline was already counted as missed."""
    awaited_ns: int = 0
    """Before its first frame: when it first held an instant back (0: not yet)."""

    def period(self) -> float:
        return self.period_ns if self.frames >= PERIOD_FRAMES and self.period_ns > 0 else float(self.declared_period_ns)

    def allowance_ns(self, max_wait_ns: int) -> int:
        """How long past its expected next frame (newest + period) it is waited for: a margin over the latest its
        recent frames came, at least :data:`MIN_ALLOWANCE_NS`, at most ``max_wait_ns`` (and that long until
        enough frames have measured it)."""
        if len(self.lateness) < WARMUP_FRAMES:
            return max_wait_ns
        return int(min(max_wait_ns, max(MIN_ALLOWANCE_NS, WAIT_MARGIN * max(self.lateness))))

    def deadline_ns(self, max_wait_ns: int) -> int:
        """When waiting for its next frame stops (from this instant on it is late). Before its first frame: the
        longest wait from when it first held an instant back (until then, no deadline has started)."""
        if not self.newest_ns:
            return self.awaited_ns + max_wait_ns if self.awaited_ns else _NEVER
        return self.newest_ns + int(self.period()) + self.allowance_ns(max_wait_ns)

    def note(self, stamp_ns: int, arrival_ns: int, processing_ns: int, max_wait_ns: int) -> None:
        """A frame was filed (in order or not)."""
        bound = max_wait_ns + self.period()
        delay = float(min(max(arrival_ns - stamp_ns, -bound), bound))  # a stalled or skewed frame cannot swamp it
        if self.frames == 0:
            self.delay_ns = delay
        else:
            self.delay_dev_ns += SMOOTHING * (abs(delay - self.delay_ns) - self.delay_dev_ns)
            self.delay_ns += SMOOTHING * (delay - self.delay_ns)
        if stamp_ns > self.newest_ns:
            p = self.period()
            step = float(stamp_ns - self.newest_ns) if self.newest_ns else 0.0
            if not self.newest_ns:
                self.lateness.append(delay)
            elif p <= 0:
                self.period_ns = step
                self.lateness.append(delay)
            elif step <= DROP_PERIODS * p:  # the next frame, not one after a drop
                if self.period_ns <= 0:
                    self.period_ns = p
                self.lateness.append(float(min(arrival_ns - (self.newest_ns + p), bound)))
                self.period_dev_ns += SMOOTHING * (abs(step - self.period_ns) - self.period_dev_ns)
                self.period_ns += SMOOTHING * (step - self.period_ns)
            self.newest_ns = stamp_ns
            self.arrival_ns = arrival_ns
            self.processing_ns = processing_ns
        self.frames += 1

    def arrived(self, kind: str, stamp_ns: int, arrival_ns: int, processing_ns: int, max_wait_ns: int) -> None:
        """One frame was offered to the buffers; ``kind`` is what :meth:`Ingest.add` made of it."""
        self.received += 1
        if kind == "clock_step":
            self.restart()
        elif kind == "late":
            self.late += 1
        if kind != "duplicate":
            self.note(stamp_ns, arrival_ns, processing_ns, max_wait_ns)

    def restart(self) -> None:
        """The sender's clock stepped: its stamps so far say nothing of the next ones."""
        self.period_ns = self.period_dev_ns = self.delay_ns = self.delay_dev_ns = 0.0
        self.lateness.clear()
        self.newest_ns = self.arrival_ns = self.processing_ns = self.frames = self.missed_newest = 0
        self.awaited_ns = 0


_NEVER = 2**63 - 1
"""The deadline of a sensor not yet waited for."""


def _newest(s: FrameTiming) -> int:
    return s.newest_ns


@dataclass(frozen=True, slots=True)
class TickLatency:
    """Where the capture -> fusion time of one fused instant went (ns)."""

    t_ns: int
    node_ns: int
    """The node's processing of the frame the instant waited for last (capture -> publish)."""
    transport_ns: int
    """Its publish -> arrival at the manager."""
    wait_ns: int
    """Its arrival -> the fusion starting (waiting for the watermark, or the fixed delay)."""


class Scheduler:
    """Which instant to fuse next, from each sensor's measured frame timing (filed by the sensor registry; the
    scheduler only marks on it the waits and missed deadlines its rule counts)."""

    def __init__(self, params: ScheduleParams, sensors: Mapping[str, FrameTiming] | None = None) -> None:
        self.params = params
        self.sensors: Mapping[str, FrameTiming] = sensors if sensors is not None else {}
        """Each sensor's frame timing, read here and written by its owner (the manager's sensor registry,
        :mod:`resource_manager.sensors`)."""
        self.last: TickLatency | None = None
        """The latency split of the last instant :meth:`instant` returned."""

    def instant(self, in_use: Iterable[str], now_ns: int, last_ns: int) -> int | None:
        """The instant to fuse now, or None while nothing new can be fused.

        Args:
            in_use: the sensors to wait for (present: with frames, or declared and none yet).
            now_ns: the manager's clock (in dataset time: the newest arrival).
            last_ns: the instant fused last (0: none yet).
        """
        timings, awaited = self._split(in_use)
        if not timings:
            return None
        p = self.params
        if p.mode == "fixed":
            t = now_ns - p.max_wait_ns
            binding = min(timings, key=_newest)
        else:
            for s in awaited:
                if not s.awaited_ns:
                    s.awaited_ns = now_ns
            if any(now_ns < s.deadline_ns(p.max_wait_ns) for s in awaited):
                return None  # a sensor's first frame is still due: nothing is fused without it yet
            on_time = [s for s in timings if now_ns < s.deadline_ns(p.max_wait_ns)]
            # Everyone late (a network stall): fuse what is there, up to the newest frame any of them sent.
            binding = min(on_time, key=_newest) if on_time else max(timings, key=_newest)
            t = binding.newest_ns
        t = min(t, now_ns)
        if t <= last_ns or (last_ns and t - last_ns < p.min_interval_ns):
            return None
        if p.mode == "watermark":
            for s in timings:
                if s.missed_newest != s.newest_ns and now_ns >= s.deadline_ns(p.max_wait_ns):
                    s.missed += 1
                    s.missed_newest = s.newest_ns
        node = binding.processing_ns
        delivered = binding.arrival_ns - binding.newest_ns
        # Fixed mode fuses behind the newest frames: the frames at t arrived (t + delay) and then waited.
        arrived = binding.arrival_ns if t == binding.newest_ns else t + delivered
        self.last = TickLatency(t, node, max(0, delivered - node), max(0, now_ns - arrived))
        return t

    def until_due_ns(self, in_use: Iterable[str], now_ns: int, last_ns: int) -> int | None:
        """How long from ``now_ns`` until :meth:`instant` may answer without a new frame arriving (a sensor's
        deadline passing, or the fixed delay's next instant); None: only a new frame can make one due."""
        timings, awaited = self._split(in_use)
        if not timings:
            return None
        p = self.params
        if p.mode == "fixed":
            return max(0, last_ns + p.min_interval_ns + p.max_wait_ns - now_ns) if last_ns else 0
        due = [d for s in timings + awaited if now_ns < (d := s.deadline_ns(p.max_wait_ns)) < _NEVER]
        return min(due) - now_ns if due else None

    def _split(self, in_use: Iterable[str]) -> tuple[list[FrameTiming], list[FrameTiming]]:
        """The sensors in use with frames, and those declared that have sent none yet."""
        timings: list[FrameTiming] = []
        awaited: list[FrameTiming] = []
        for sid in in_use:
            s = self.sensors.get(sid)
            if s is not None:
                (timings if s.newest_ns else awaited).append(s)
        return timings, awaited
