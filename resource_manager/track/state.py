"""One track's identity: the record only :mod:`resource_manager.track` writes.

A track's state (where the person is, how sure, how tall: :mod:`.filter`) lives with every other track's in one
filter; the record keeps who the person is: the id once confirmed, what they look like in each view, which of
each node's 2D tracks they are, and the counters the life cycle reads. Other stages read
:class:`~resource_manager.track.tracker.TrackSnapshot` values; none changes a record.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from common.arrays import FloatArray
from common.schema import Method, TrackState

__all__ = ["TrackRecord"]


@dataclass(slots=True, eq=False)
class TrackRecord:
    """One person being followed: their id, looks and counters (their state is in the filter)."""

    serial: int
    """Unique per tracker, in order of birth."""
    born_ns: int
    """Instant of the first detection."""
    first_xy: FloatArray = field(default_factory=lambda: np.zeros(2))
    """Where the person was first placed (re-identification compares it with where a lost track could be)."""
    track_id: str = ""
    """``{manager}-{n}`` once confirmed; "" before."""
    confirmed: bool = False
    """Existence reached ``p_confirm`` once: the track is published."""
    adopted: str = ""
    """While tentative: the id of another manager's track of the same person (a standby's leader's), taken at
    confirmation if no other track has it (resource_manager/serve/adopt.py)."""
    detected: bool = False
    """Some view detected the person at the latest tick."""
    seen_ns: int = 0
    """The latest instant some view detected the person."""
    hits: int = 0
    """Ticks at which some view detected the person."""
    misses: int = 0
    """Ticks since the last detection."""
    method: Method = "predicted"
    sensors: tuple[str, ...] = ()
    """The camera pair the error model ranks best among the views that detected the person (or the one view)."""
    views: tuple[str, ...] = ()
    """The cameras whose blobs were assigned to the person at the latest tick (none: no view detected them)."""
    predicted_error_m: float = 0.0
    """That pair's predicted position error (the error model)."""
    links: dict[str, int] = field(default_factory=dict)
    """sensor id -> the node's 2D track id of the blob last assigned to this track there."""
    looks: dict[str, FloatArray] = field(default_factory=dict)
    """sensor id -> running mean of the square-rooted colour histograms of this track's blobs in that view."""
    look_s: dict[str, float] = field(default_factory=dict)
    """sensor id -> seconds of evidence in that look."""

    def state(self) -> TrackState:
        if not self.confirmed:
            return "tentative"
        return "confirmed" if self.detected else "coasting"
