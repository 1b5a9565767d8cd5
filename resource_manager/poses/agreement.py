"""Whether each camera's blobs still agree with where the other cameras put the people (a camera bumped or moved).

Every fusion tick, for each camera's view: the published tracks that at least two *other* cameras localised
(their positions do not rest on this camera) are the people it should see. Each of its blobs is a bearing ray from
its centre; the blob's residual is the floor distance from that ray to the nearest such person in front of it.
Over the last ``window_s`` the median residual of the blobs that found a person within ``gate_m`` is the camera's
agreement; a camera whose median exceeds ``disagree_m`` (with at least ``min_blobs`` blobs) is reported as
disagreeing: its pose is no longer what its calibration says, and ``panostereo calib refine`` with a recording of
the site fixes it. Blobs that find no person within the gate are counted apart (``unexplained``): clutter, or a
camera turned so far that its blobs point at no one.

Pure: reads the views and the published tracks, changes neither.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from common.schema import SensorAgreement, Track
from resource_manager.views.blobs import ViewBlobs

__all__ = ["Agreement", "AgreementParams"]

MIN_OTHER_CAMERAS = 2
"""A track counts for a camera when at least this many other cameras localised it."""


@dataclass(frozen=True, slots=True)
class AgreementParams:
    window_s: float = 10.0
    """The residual is the median over this many seconds of blobs."""
    gate_m: float = 2.0
    """A blob whose ray passes further than this from every person explains none (counted as unexplained)."""
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

    def update(self, t_ns: int, views: Mapping[str, ViewBlobs], tracks: Sequence[Track]) -> None:
        """Add one tick's blobs (see the module docstring)."""
        p = self.params
        for sid, view in views.items():
            n = view.bearing_rad.size
            if n == 0:
                continue
            others = [t for t in tracks if sum(1 for s in t.sensors if s != sid) >= MIN_OTHER_CAMERAS]
            if not others:
                continue
            pts = np.array([(t.x_m, t.y_m) for t in others], dtype=np.float64) - view.origin_xy
            dirs = np.column_stack([np.cos(view.bearing_rad), np.sin(view.bearing_rad)])
            along = dirs @ pts.T  # (blobs, people)
            across = np.abs(dirs[:, 0:1] * pts[None, :, 1] - dirs[:, 1:2] * pts[None, :, 0])
            across = np.where(along > 0, across, np.inf)
            best = across.min(axis=1)
            h = self._hist.setdefault(sid, _History())
            for d in best:
                if d <= p.gate_m:
                    h.residuals.append((t_ns, float(d)))
                else:
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
            if n + u == 0:
                continue
            med = float(np.median([d for _, d in h.residuals])) if n else math.inf
            out.append(
                SensorAgreement(
                    sensor_id=sid,
                    residual_m=min(med, 1e4),
                    blobs=n,
                    unexplained_frac=u / (n + u),
                    disagrees=n + u >= self.params.min_blobs and med > self.params.disagree_m,
                )
            )
        out.sort(key=lambda a: -a.residual_m)
        return out
