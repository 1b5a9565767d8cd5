"""When to fuse: the watermark of the sensors' frames, not a fixed delay behind the clock.

An instant ``t`` can be fused once every sensor in use has sent a frame at or after ``t`` (then each sensor's
blobs are interpolated to ``t`` between two real frames), or once a sensor is so late that waiting longer would
hold everyone back: its next frame is overdue by more than its frame period plus ``allowance``. The instant fused
is the newest one that every sensor still on time has reached: the minimum of their newest frame stamps (the
watermark of stream processors). Sensors that send frames at one instant (a dataset's cameras) are fused exactly
at their frame instants; unsynchronised ones at the pace of the slowest, interpolated.

The same rule runs in dataset time (``panostereo evaluate-site``, every frame arriving at its own stamp) and live
(:mod:`resource_manager.node`, frames arriving over the network), so the two fuse the same instants.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

__all__ = ["Watermark"]


@dataclass(frozen=True, slots=True)
class Watermark:
    """Which instant to fuse next, from each sensor's newest frame stamp and frame period."""

    allowance_ns: int
    """How long past its expected next frame a sensor is waited for (delivery and jitter)."""
    min_interval_ns: int
    """At most one fusion per this (the configured maximum tick rate)."""

    def instant(self, newest: Mapping[str, int], periods: Mapping[str, int], now_ns: int, last_ns: int) -> int | None:
        """The instant to fuse now, or None while nothing new can be fused.

        Args:
            newest: sensor id -> stamp of its newest frame (sensors in use only).
            periods: sensor id -> its frame period (0: unknown, then it is waited for ``allowance_ns``).
            now_ns: the manager's clock (in dataset time: the newest arrival).
            last_ns: the instant fused last (0: none yet).
        """
        if not newest:
            return None
        on_time = [stamp for sid, stamp in newest.items() if now_ns <= stamp + periods.get(sid, 0) + self.allowance_ns]
        # Everyone late (a network stall): fuse what is there, up to the newest frame any of them sent.
        t = min(on_time) if on_time else max(newest.values())
        t = min(t, now_ns)
        if t <= last_ns or (last_ns and t - last_ns < self.min_interval_ns):
            return None
        return t
