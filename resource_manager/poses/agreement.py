"""Whether each camera's blobs still agree with where the other cameras put the people (a camera bumped or moved).

Every fusion tick, for each camera's view: the published tracks that at least two *other* cameras localised
(their positions do not rest on this camera) are the people it should see. Each of its blobs is a bearing ray from
its centre; the blob's residual is the floor distance from that ray to the nearest such person in front of it.
A blob that finds no person within ``gate_m`` counts as ``gate_m`` (and as unexplained: clutter, someone the
others do not see, or a camera turned so far that its rays point at no one). Over the last ``window_s`` the median
is the camera's residual; a camera whose residual exceeds ``disagree_m`` (with at least ``min_blobs`` blobs) is
reported as disagreeing: its pose is no longer what its calibration says, and ``panostereo calib refine`` with a
recording of the site fixes it. A camera in place keeps most of its rays within a person's width of the people
the others place, whatever clutter it also sees; a camera turned by a few degrees puts most of them a metre off,
or next to the wrong person.

Pure: reads the views and the published tracks, changes neither.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from common.schema import SensorAgreement, Track
from resource_manager.views.blobs import Views

__all__ = ["Agreement", "AgreementParams"]

MIN_OTHER_CAMERAS = 2
"""A track counts for a camera when at least this many other cameras localised it."""


@dataclass(frozen=True, slots=True)
class AgreementParams:
    window_s: float = 10.0
    """The residual is the median over this many seconds of blobs."""
    gate_m: float = 1.0
    """A blob whose ray passes further than this from every person explains none: it counts as this far."""
    disagree_m: float = 0.5
    """A camera whose median residual exceeds this disagrees with the others (a person's width: a camera in
    place puts its rays well within it)."""
    min_blobs: int = 20
    """Fewer blobs in the window say nothing either way."""


@dataclass(slots=True)
class _History:
    residuals: deque[tuple[int, float]] = field(default_factory=deque)
    unexplained: deque[int] = field(default_factory=deque)


class Agreement:
    """Per camera, the residuals of its blobs against the others' people over a sliding window."""

    def __init__(self, params: AgreementParams | None = None) -> None:
        self.params = params or AgreementParams()
        self._hist: dict[str, _History] = {}

    def update(self, t_ns: int, views: Views, tracks: Sequence[Track]) -> None:
        """Add one tick's blobs (see the module docstring)."""
        p = self.params
        for row, sid in enumerate(views.sensor_ids):
            bearing = views.bearing_rad[views.span(row)]
            if bearing.size == 0:
                continue
            others = [t for t in tracks if sum(1 for s in t.sensors if s != sid) >= MIN_OTHER_CAMERAS]
            if not others:
                continue
            pts = np.array([(t.x_m, t.y_m) for t in others], dtype=np.float64) - views.origin[row]
            dirs = np.column_stack([np.cos(bearing), np.sin(bearing)])
            along = dirs @ pts.T  # (blobs, people)
            across = np.abs(dirs[:, 0:1] * pts[None, :, 1] - dirs[:, 1:2] * pts[None, :, 0])
            across = np.where(along > 0, across, np.inf)
            best = across.min(axis=1)
            h = self._hist.setdefault(sid, _History())
            for d in best:
                h.residuals.append((t_ns, min(float(d), p.gate_m)))
                if d > p.gate_m:
                    h.unexplained.append(t_ns)
        oldest = t_ns - int(p.window_s * 1e9)
        for h in self._hist.values():
            while h.residuals and h.residuals[0][0] < oldest:
                h.residuals.popleft()
            while h.unexplained and h.unexplained[0] < oldest:
                h.unexplained.popleft()

    def report(self) -> list[SensorAgreement]:
        """Every camera with blobs in the window, the worst first."""
        out = []
        for sid, h in self._hist.items():
            n, u = len(h.residuals), len(h.unexplained)
            if n == 0:
                continue
            med = float(np.median([d for _, d in h.residuals]))
            out.append(
                SensorAgreement(
                    sensor_id=sid,
                    residual_m=med,
                    blobs=n,
                    unexplained_frac=u / n,
                    disagrees=n >= self.params.min_blobs and med > self.params.disagree_m,
                )
            )
        out.sort(key=lambda a: -a.residual_m)
        return out
