"""The frame contract: what a camera, real or simulated, hands to a sensor node.

A :class:`FrameSource` is read by the node's capture thread: :meth:`FrameSource.read`
blocks until the next frame, stamps it on the node's NTP-corrected clock at capture,
and returns None only when the source has ended or the node is stopping. A PTZ
camera's frame carries where its head pointed at capture (:class:`PtzPose`), so the
pipeline casts its rays from that pose.

Sources that deliver frames on a fixed schedule (image folders, detection files,
the simulator) take their slots from a :class:`Pacer`.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol

import numpy.typing as npt

from common.errors import SourceError
from common.schema import SourceState

__all__ = ["Clock", "Frame", "FrameSource", "Pacer", "PtzPose"]

Clock = Callable[[], int]
"""Returns Unix ns on the node's (NTP-corrected) clock."""


@dataclass(frozen=True, slots=True)
class PtzPose:
    """Where a PTZ head points."""

    pan_rad: float
    """World azimuth of the optical axis (counter-clockwise from +x)."""
    tilt_rad: float
    """Elevation of the optical axis, > 0 up."""
    zoom: float
    moving: bool = False


@dataclass(frozen=True, slots=True)
class Frame:
    """One captured frame."""

    index: int
    """0-based frame counter of the source (for detection files: file frame - 1)."""
    stamp_ns: int
    """Capture time on the node's NTP-corrected clock."""
    image: npt.NDArray[Any] | None = None
    """BGR image (None for image-less sources)."""
    payload: Any = None
    """Image-less sources: what was read (e.g. the frame's detections)."""
    skipped: int = 0
    """Frames the source itself skipped before this one (it was late)."""
    ptz: PtzPose | None = None
    """A PTZ camera's head pose at capture (None: a fixed camera)."""


class FrameSource(Protocol):
    """What the node's capture thread reads."""

    state: SourceState
    message: str

    def read(self, stop: threading.Event) -> Frame | None:
        """Block until the next frame; None when the source ended or ``stop`` is set."""
        ...

    def close(self) -> None: ...


class Pacer:
    """Frame slots k at times ``epoch + k / fps`` on a clock: wait for the next, skipping missed ones.

    Args:
        fps: slots per second.
        clock: the node clock.
        epoch_ns: time of slot 0.
        max_late_ns: a slot at most this late is still served (late); an older one is skipped
            to the current slot (0: always jump to the slot at or after now).
    """

    def __init__(self, fps: float, clock: Clock, epoch_ns: int, max_late_ns: int = 0) -> None:
        if fps <= 0:
            raise SourceError(f"frame rate must be > 0, got {fps}")
        self.period_ns = round(1e9 / fps)
        self.clock = clock
        self.epoch_ns = epoch_ns
        self.max_late_ns = max_late_ns
        self.next_k = 0

    def wait(self, stop: threading.Event) -> tuple[int, int, int] | None:
        """Sleep until the next slot; return (k, slot stamp ns, slots skipped), or None if stopped."""
        now = self.clock()
        k = self.next_k
        if self.epoch_ns + k * self.period_ns < now - self.max_late_ns:
            k = max(k, -((self.epoch_ns - now) // self.period_ns))  # ceil((now - epoch) / period)
        skipped = k - self.next_k if self.next_k > 0 else 0
        stamp = self.epoch_ns + k * self.period_ns
        delay = (stamp - now) / 1e9
        if delay > 0 and stop.wait(delay):
            return None
        self.next_k = k + 1
        return k, stamp, skipped
