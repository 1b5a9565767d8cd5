"""Whether each camera's blobs still agree with where the other cameras put the people (a camera bumped or moved).

Every fusion tick, for each camera's view:

* *Who checks it.* The published tracks that the blobs of at least two *other* cameras placed at this tick are the
  people it is checked against: their positions do not rest on this camera.
* *Whom a blob shows.* Each blob is a bearing ray from the camera's centre. Where the camera gives the blob's feet
  distance, only the people near that distance along the ray (``RANGE_SIGMAS`` of its spread) can be the one it
  shows: a ray through a crowd passes near somebody, its feet near one person. The published person nearest the
  ray among those, in front of the camera, is the one it shows.
* *Its residual.* Where that is a checked person, the residual is their floor distance from the ray. Where it is a
  person this camera itself helped place, the blob tests nothing and is left out. A blob that finds nobody within
  ``gate_m`` counts as ``gate_m`` and as unexplained (clutter, someone nobody else sees, or a camera turned so far
  that its rays point at no one), unless its feet put it where fewer than two other cameras look: nobody the
  others place can stand there, so finding nobody says nothing. A camera with no checked person at a tick adds
  nothing then.

Over the last ``window_s`` the median is the camera's residual. A camera whose residual exceeds ``disagree_m``
(with at least ``min_blobs`` blobs) is reported as disagreeing: its pose is no longer what its calibration says,
and ``panostereo calib refine`` with a recording of the site fixes it. A camera in place keeps most of its rays
within a person's width of the people the others place, whatever clutter it also sees; a camera turned by a few
degrees puts most of them a metre off, or next to the wrong person.

Pure: reads the views and the published tracks, changes neither.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from common.schema import SensorAgreement
from resource_manager.track.model import HEAD_HEIGHT_M
from resource_manager.track.observe import seen_by
from resource_manager.track.tracker import TrackSnapshot
from resource_manager.views.blobs import Views

__all__ = ["Agreement", "AgreementParams"]

MIN_OTHER_CAMERAS = 2
"""A person checks a camera when the blobs of at least this many other cameras placed them."""
RANGE_SIGMAS = 3.0
"""A blob's feet distance rules out the people further than this many of its sigmas along its ray."""


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
    height_m: float = HEAD_HEIGHT_M
    """How tall a person is taken to be where a blob's feet put them (who else could see them there)."""


@dataclass(slots=True)
class _History:
    residuals: deque[tuple[int, float]] = field(default_factory=deque)
    unexplained: deque[int] = field(default_factory=deque)


class Agreement:
    """Per camera, the residuals of its blobs against the others' people over a sliding window."""

    def __init__(self, params: AgreementParams | None = None) -> None:
        self.params = params or AgreementParams()
        self._hist: dict[str, _History] = {}

    def update(self, t_ns: int, views: Views, people: Sequence[TrackSnapshot]) -> None:
        """Add one tick's blobs against its published people (see the module docstring)."""
        p = self.params
        if people and views.n:
            self._add(t_ns, views, people)
        oldest = t_ns - int(p.window_s * 1e9)
        for h in self._hist.values():
            while h.residuals and h.residuals[0][0] < oldest:
                h.residuals.popleft()
            while h.unexplained and h.unexplained[0] < oldest:
                h.unexplained.popleft()

    def _add(self, t_ns: int, views: Views, people: Sequence[TrackSnapshot]) -> None:
        p = self.params
        xy = np.array([tr.xy for tr in people], dtype=np.float64).reshape(-1, 2)
        dirs = np.column_stack([np.cos(views.bearing_rad), np.sin(views.bearing_rad)])
        # Feet distance, where given: only the people near it along the ray can be the one a blob shows; and finding
        # nobody says something only where two other cameras look.
        rng = views.mono_range_m
        ranged = np.flatnonzero(np.isfinite(rng))
        others_look = np.full(views.n, MIN_OTHER_CAMERAS)
        if ranged.size:
            feet = views.origin[views.view_of[ranged]] + dirs[ranged] * rng[ranged, None]
            seen = seen_by(views, feet, p.height_m, np.inf)
            others_look[ranged] = seen.sum(axis=0) - seen[views.view_of[ranged], np.arange(ranged.size)]
        for row, sid in enumerate(views.sensor_ids):
            span = views.span(row)
            if span.start == span.stop:
                continue
            checks = np.array([sum(1 for s in tr.views if s != sid) >= MIN_OTHER_CAMERAS for tr in people])
            if not checks.any():
                continue
            pts = xy - views.origin[row]
            d = dirs[span]
            along = d @ pts.T  # (blobs, people)
            across = np.abs(d[:, 0:1] * pts[None, :, 1] - d[:, 1:2] * pts[None, :, 0])
            r = rng[span, None]
            near = np.where(np.isfinite(r), np.abs(along - r) <= RANGE_SIGMAS * views.mono_sigma_m[span, None], True)
            off = np.where((along > 0) & near, across, np.inf)
            nearest = off.argmin(axis=1)
            best = off[np.arange(len(off)), nearest]
            checkable = others_look[span] >= MIN_OTHER_CAMERAS
            h = self._hist.setdefault(sid, _History())
            for dist, who, ok in zip(best.tolist(), nearest.tolist(), checkable.tolist(), strict=True):
                if dist <= p.gate_m:
                    if checks[who]:
                        h.residuals.append((t_ns, dist))
                elif ok:
                    h.residuals.append((t_ns, p.gate_m))
                    h.unexplained.append(t_ns)

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
