"""One track's state: the record only :mod:`resource_manager.track` writes.

Other stages (planning, PTZ, publishing) read it; none changes it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from common.schema import Method, TrackState

__all__ = ["TrackRecord"]

FloatArray = npt.NDArray[np.float64]


@dataclass(slots=True, eq=False)
class TrackRecord:
    """One person being followed: a floor filter, a head height, an existence probability and what identifies
    them in each view."""

    serial: int
    """Unique per tracker, in order of birth."""
    x: FloatArray
    """(4,) x, y (m) and vx, vy (m/s) on the floor."""
    p: FloatArray
    """(4, 4) covariance of ``x``."""
    t_ns: int
    """Instant of ``x``."""
    born_ns: int
    logodds: float
    """Existence: ln(p / (1 - p)) of the probability that this is a person."""
    height_m: float
    """Head-top height above the floor."""
    height_var: float
    """Its variance (m²)."""
    track_id: str = ""
    """``{manager}-{n}`` once confirmed; "" before."""
    confirmed: bool = False
    """Existence reached ``p_confirm`` once: the track is published."""
    detected: bool = False
    """Some view detected the person at the latest tick."""
    hits: int = 0
    """Ticks at which some view detected the person."""
    misses: int = 0
    """Ticks since the last detection."""
    method: Method = "predicted"
    sensors: tuple[str, ...] = ()
    """The camera pair the error model ranks best among the views that detected the person (or the one view)."""
    predicted_error_m: float = 0.0
    """That pair's predicted position error (the error model)."""
    links: dict[str, int] = field(default_factory=dict)
    """sensor id -> the node's 2D track id of the blob last assigned to this track there."""
    looks: dict[str, FloatArray] = field(default_factory=dict)
    """sensor id -> running mean of the square-rooted colour histograms of this track's blobs in that view."""
    look_s: dict[str, float] = field(default_factory=dict)
    """sensor id -> seconds of evidence in that look."""

    @property
    def xy(self) -> FloatArray:
        return self.x[:2]

    @property
    def existence(self) -> float:
        return 1.0 / (1.0 + math.exp(-self.logodds))

    @property
    def published(self) -> bool:
        """Confirmed once and, now, more likely there than not (a confirmed track whose person has gone unseen is
        kept, unpublished, until it ends, so that it keeps its id if they reappear). The manager reports it while
        its position is placed too (:meth:`~resource_manager.track.tracker.Tracker.reported`)."""
        return self.confirmed and self.logodds >= 0.0

    @property
    def state(self) -> TrackState:
        if not self.confirmed:
            return "tentative"
        return "confirmed" if self.detected else "coasting"

    @property
    def position_sigma_m(self) -> float:
        """1-sigma position error in the worst direction."""
        a, b, c = float(self.p[0, 0]), float(self.p[0, 1]), float(self.p[1, 1])
        return math.sqrt(max(0.5 * (a + c) + math.hypot(0.5 * (a - c), b), 0.0))
