"""The views of one tick stacked into arrays: every per-view and per-blob quantity the track stages score with.

A tick has a dozen views with a dozen blobs each. Working on them one view at a time costs a few dozen small array
operations per view; stacked (one row per view, one entry per blob of every view, in view order) the same
arithmetic runs once per tick. :class:`ViewStack` is built once per tick (and once for the unexplained blobs of
births) and read by :mod:`.observe`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from common.angles import TWO_PI
from common.arrays import FloatArray, IntArray
from resource_manager.track.motion import MIN_RANGE_M
from resource_manager.views.blobs import ViewBlobs

__all__ = ["Spread", "ViewStack"]


@dataclass(frozen=True, slots=True)
class Spread:
    """Variances (m²) of a camera's measured points around a person: across its rays, and along them (feet)."""

    cross_var: float
    range_var: float


@dataclass(frozen=True, slots=True)
class ViewStack:
    """Several views' blobs along one axis (view after view), with each view's own quantities per row."""

    views: tuple[ViewBlobs, ...]
    """Each row's view, for its camera's own quantities (sensor id, picture, field of view); its blobs in the stack
    are entries ``offsets[i]:offsets[i + 1]`` (in a :meth:`subset`, only some of the view's)."""
    rows: dict[str, int]
    """sensor id -> its view's row."""
    offsets: IntArray
    """(s + 1,) view ``i``'s blobs are entries ``offsets[i]:offsets[i + 1]``."""
    view_of: IntArray
    """(m,) the view (row) of each blob."""
    origin: FloatArray
    """(s, 2) optical centres on the floor."""
    z_m: FloatArray
    """(s,) optical centre heights."""
    sigma_rad: FloatArray
    """(s,) bearing errors."""
    sigma_xy_m: FloatArray
    """(s,) the cameras' own position errors."""
    cross_var: FloatArray
    """(s,) :attr:`Spread.cross_var` of each view."""
    range_var: FloatArray
    """(s,) :attr:`Spread.range_var` of each view."""
    fov_width_rad: FloatArray
    """(s,) horizontal extent of each view's bearings."""
    body_radius_m: FloatArray
    """(s,) each camera's body radius (0: none): the bodies hide people from the other cameras."""
    bearing_rad: FloatArray
    """(m,) the blobs' world azimuths."""
    width_rad: FloatArray
    """(m,) their angular widths."""
    top_elev_rad: FloatArray
    """(m,) elevations of the blob tops."""
    top_cut: npt.NDArray[np.bool_]
    """(m,) blobs whose head-top height is only a lower bound."""
    mono_range_m: FloatArray
    """(m,) floor distances from the feet (NaN: none)."""
    mono_sigma_m: FloatArray
    """(m,) their 1-sigma (NaN: none)."""
    local_id: IntArray
    """(m,) the nodes' 2D track ids."""
    hist_bins: IntArray
    """(s,) the size of each view's colour histograms (0: it sends none)."""
    hist_sqrt: dict[int, FloatArray]
    """Histogram size -> (m, size) square-rooted histograms of the blobs whose view has that size (0 elsewhere)."""

    @property
    def n_views(self) -> int:
        return len(self.views)

    @property
    def counts(self) -> IntArray:
        """(s,) blobs of each row in the stack."""
        return np.diff(self.offsets)

    @staticmethod
    def of(views: Sequence[ViewBlobs], spreads: Sequence[Spread]) -> ViewStack:
        """The stack of ``views``, each with its spread of points around a person."""
        counts = np.array([v.n for v in views], dtype=np.int64)
        offsets = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)

        def cat(get: str, fill: float) -> FloatArray:
            parts = [
                np.full(v.n, fill) if getattr(v, get) is None else np.asarray(getattr(v, get), dtype=np.float64)
                for v in views
            ]
            return np.concatenate(parts) if parts else np.zeros(0)

        ranges = [_ranges(v) for v in views]
        bins = [0 if v.hist_sqrt is None else int(v.hist_sqrt.shape[1]) for v in views]
        hists: dict[int, FloatArray] = {}
        sizes = sorted(set(bins) - {0})
        if len(sizes) == 1 and min(bins) > 0:  # every view with histograms of one size: the usual case
            hists[sizes[0]] = np.concatenate([v.hist_sqrt for v in views if v.hist_sqrt is not None])
        else:
            for size in sizes:
                hists[size] = np.zeros((int(offsets[-1]), size))
                for i, v in enumerate(views):
                    if bins[i] == size and v.hist_sqrt is not None:
                        hists[size][offsets[i] : offsets[i + 1]] = v.hist_sqrt
        return ViewStack(
            views=tuple(views),
            rows={v.sensor_id: i for i, v in enumerate(views)},
            offsets=offsets,
            view_of=np.repeat(np.arange(len(views), dtype=np.int64), counts),
            origin=np.array([v.origin_xy for v in views], dtype=np.float64).reshape(-1, 2),
            z_m=np.array([v.z_m for v in views], dtype=np.float64),
            sigma_rad=np.array([v.sigma_rad for v in views], dtype=np.float64),
            sigma_xy_m=np.array([v.sigma_xy_m for v in views], dtype=np.float64),
            cross_var=np.array([s.cross_var for s in spreads], dtype=np.float64),
            range_var=np.array([s.range_var for s in spreads], dtype=np.float64),
            fov_width_rad=np.array([fov_width(v) for v in views], dtype=np.float64),
            body_radius_m=np.array([v.body_radius_m for v in views], dtype=np.float64),
            bearing_rad=cat("bearing_rad", 0.0),
            width_rad=cat("width_rad", 0.0),
            top_elev_rad=cat("top_elev_rad", 0.0),
            top_cut=cat("top_cut", 0.0) > 0,
            mono_range_m=np.concatenate([r for r, _ in ranges]) if ranges else np.zeros(0),
            mono_sigma_m=np.concatenate([s for _, s in ranges]) if ranges else np.zeros(0),
            local_id=np.concatenate([v.local_id for v in views]).astype(np.int64) if views else np.zeros(0, np.int64),
            hist_bins=np.array(bins, dtype=np.int64),
            hist_sqrt=hists,
        )

    def subset(self, rows: Sequence[int], blobs: Sequence[Sequence[int]]) -> ViewStack:
        """The stack of some of its views with some of their blobs: the views of ``rows`` with only their blobs
        ``blobs`` (indices in each view), taken from these arrays (no view is copied)."""
        counts = np.array([len(b) for b in blobs], dtype=np.int64)
        row = np.asarray(rows, dtype=np.int64)
        pick = np.array([self.offsets[r] + j for r, b in zip(rows, blobs, strict=True) for j in b], dtype=np.int64)
        views = [self.views[r] for r in rows]
        return ViewStack(
            views=tuple(views),
            rows={v.sensor_id: i for i, v in enumerate(views)},
            offsets=np.concatenate([[0], np.cumsum(counts)]).astype(np.int64),
            view_of=np.repeat(np.arange(len(views), dtype=np.int64), counts),
            origin=self.origin[row],
            z_m=self.z_m[row],
            sigma_rad=self.sigma_rad[row],
            sigma_xy_m=self.sigma_xy_m[row],
            cross_var=self.cross_var[row],
            range_var=self.range_var[row],
            fov_width_rad=self.fov_width_rad[row],
            body_radius_m=self.body_radius_m[row],
            bearing_rad=self.bearing_rad[pick],
            width_rad=self.width_rad[pick],
            top_elev_rad=self.top_elev_rad[pick],
            top_cut=self.top_cut[pick],
            mono_range_m=self.mono_range_m[pick],
            mono_sigma_m=self.mono_sigma_m[pick],
            local_id=self.local_id[pick],
            hist_bins=self.hist_bins[row],
            hist_sqrt={size: h[pick] for size, h in self.hist_sqrt.items()},
        )

    def bearing_var(self, rows: IntArray, dist: FloatArray) -> FloatArray:
        """Bearing variance of a person at ``dist`` from the camera of view ``rows`` (each element its own): the
        sensor's and its yaw's, its position's and the spread of the point seen around the person."""
        d = np.maximum(dist, MIN_RANGE_M)
        spread = self.cross_var[rows] + self.sigma_xy_m[rows] ** 2
        return np.asarray(self.sigma_rad[rows] ** 2 + spread / (d * d), dtype=np.float64)

    def split(self, a: FloatArray) -> list[FloatArray]:
        """(n, m) per-blob columns ``a`` cut into each view's (n, m_i)."""
        return [a[:, self.offsets[i] : self.offsets[i + 1]] for i in range(self.n_views)]


def _ranges(v: ViewBlobs) -> tuple[FloatArray, FloatArray]:
    """A view's feet distances and their sigmas (NaN: none)."""
    if v.mono_range_m is None or v.mono_sigma_m is None:
        return np.full(v.n, math.nan), np.full(v.n, math.nan)
    return np.asarray(v.mono_range_m, dtype=np.float64), np.asarray(v.mono_sigma_m, dtype=np.float64)


def fov_width(v: ViewBlobs) -> float:
    """Horizontal extent of the view's bearings (rad)."""
    return TWO_PI if v.fov is None else min(2.0 * v.fov[1], TWO_PI)
