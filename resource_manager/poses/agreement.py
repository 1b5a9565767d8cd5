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

*Its own residual in place.* How close a camera in place comes depends on the site (its distance from the people,
its detector, how well the others place them): a few centimetres on one site, 0.15 m on another. So each camera's
residual is also compared with its own: over its first ``settle_s`` of full windows (while it agreed), the largest
residual it showed (90th percentile, ``settled_m``). A camera whose residual has since grown past
``grown_ratio`` times that, and by at least ``grown_min_m``, for a whole window (a bump lasts; a crowd that passes
the camera's worst side does not), was moved while the manager ran, even where the move
leaves it under ``disagree_m`` (a turn the shift partly undoes). The people a bumped camera helps place move with
it, so the others' residuals grow a little too: growth names a camera only where it grew by at least
``GROWN_SHARE`` of the most any camera grew. A camera that disagreed from the start has no residual of its own and
is judged by ``disagree_m`` alone.

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
    settle_s: float = 30.0
    """A camera's own residual in place is learned over this long once its first window is full."""
    grown_ratio: float = 2.0
    """A camera whose residual has grown past this many times its own in place..."""
    grown_min_m: float = 0.05
    """...and by at least this much (a camera in place wanders by a few centimetres between windows) has moved."""


SETTLE_SAMPLE_S = 1.0
"""While a camera's own residual is learned, its window's residual is sampled at most this often."""
GROWN_SHARE = 0.5
"""A camera is named for a grown residual only where it grew by at least this share of the most any camera grew."""
SETTLED_QUANTILE = 90.0
"""A camera's own residual in place is this percentile of its window residuals while it was learned."""


@dataclass(slots=True)
class _History:
    residuals: deque[tuple[int, float]] = field(default_factory=deque)
    unexplained: deque[int] = field(default_factory=deque)
    first_ns: int | None = None
    """Its first residual."""
    first_full_ns: int | None = None
    """When its window first held ``min_blobs`` blobs a full window after its first residual."""
    samples: list[float] = field(default_factory=list)
    """Its window residuals while its own is learned (while it agreed)."""
    sampled_ns: int = 0
    settled_m: float | None = None
    """Its own residual in place, once learned."""
    grown_since_ns: int | None = None
    """Since when its residual has been grown past its own (None: it is not)."""


class Agreement:
    """Per camera, the residuals of its blobs against the others' people over a sliding window."""

    def __init__(self, params: AgreementParams | None = None) -> None:
        self.params = params or AgreementParams()
        self._hist: dict[str, _History] = {}
        self._t_ns = 0

    def update(self, t_ns: int, views: Views, people: Sequence[TrackSnapshot]) -> None:
        """Add one tick's blobs against its published people (see the module docstring)."""
        p = self.params
        self._t_ns = t_ns
        if people and views.n:
            self._add(t_ns, views, people)
        oldest = t_ns - int(p.window_s * 1e9)
        for h in self._hist.values():
            while h.residuals and h.residuals[0][0] < oldest:
                h.residuals.popleft()
            while h.unexplained and h.unexplained[0] < oldest:
                h.unexplained.popleft()
            self._settle(h, t_ns)

    def _settle(self, h: _History, t_ns: int) -> None:
        """Learn a camera's own residual over its first ``settle_s`` of full windows, then follow whether its
        residual has grown past it, and since when (see the module docstring); at most every ``SETTLE_SAMPLE_S``."""
        p = self.params
        if h.first_ns is None and h.residuals:
            h.first_ns = h.residuals[0][0]
        if h.first_ns is None or len(h.residuals) < p.min_blobs or t_ns - h.sampled_ns < SETTLE_SAMPLE_S * 1e9:
            return
        if h.first_full_ns is None:
            if t_ns - h.first_ns < p.window_s * 1e9:
                return
            h.first_full_ns = t_ns
        h.sampled_ns = t_ns
        med = float(np.median([d for _, d in h.residuals]))
        if h.settled_m is None:
            if med <= p.disagree_m:
                h.samples.append(med)
            if t_ns - h.first_full_ns >= p.settle_s * 1e9:
                # Nothing learned (it disagreed all along): the absolute threshold alone judges it, for good.
                h.settled_m = float(np.percentile(h.samples, SETTLED_QUANTILE)) if h.samples else np.inf
                h.samples = []
            return
        if self._grown(med, h.settled_m):
            h.grown_since_ns = t_ns if h.grown_since_ns is None else h.grown_since_ns
        else:
            h.grown_since_ns = None

    def _grown(self, residual_m: float, own_m: float) -> bool:
        """Whether a residual has grown past a camera's own in place (see the module docstring)."""
        p = self.params
        return residual_m > max(p.grown_ratio * own_m, own_m + p.grown_min_m)

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
        p = self.params
        rows = []
        for sid, h in self._hist.items():
            n, u = len(h.residuals), len(h.unexplained)
            if n == 0:
                continue
            med = float(np.median([d for _, d in h.residuals]))
            own = h.settled_m if h.settled_m is not None and np.isfinite(h.settled_m) else None
            grown = (
                own is not None
                and h.grown_since_ns is not None
                and self._t_ns - h.grown_since_ns >= p.window_s * 1e9
                and self._grown(med, own)
            )
            rows.append((sid, med, n, u, own, med - own if grown and own is not None else 0.0))
        # The people a bumped camera helps place move with it, so the others' residuals grow a little too; the
        # camera that moved grows most. Growth names a camera only where it is comparable to the largest.
        most = max((r[5] for r in rows), default=0.0)
        out = [
            SensorAgreement(
                sensor_id=sid,
                residual_m=med,
                blobs=n,
                unexplained_frac=u / n,
                disagrees=n >= p.min_blobs and (med > p.disagree_m or (excess > 0 and excess >= GROWN_SHARE * most)),
                settled_m=own,
            )
            for sid, med, n, u, own, excess in rows
        ]
        out.sort(key=lambda a: -a.residual_m)
        return out
