"""Every camera's blobs at the fusion instant, in world terms, in one set of arrays: what every manager stage reads.

:func:`~resource_manager.views.build.build_views` builds one :class:`Views` per tick: one row per view (camera),
one entry per blob of every view, view after view in order of sensor ids. Stereo matching, the tracker's
assignment and update, and births read it as it is: a view's blobs are the entries
``offsets[i]:offsets[i + 1]``, and some of the tick's blobs (the unexplained ones, those sure enough to start a
person) are a :class:`Subset`, index arrays into the same arrays (no blob is copied into another object).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, TypeVar, cast

import numpy as np
import numpy.typing as npt

from common.angles import TWO_PI
from common.arrays import BoolArray, FloatArray, IntArray

__all__ = ["ImageBounds", "Subset", "Views", "stack_histograms"]

_A = TypeVar("_A", bound=npt.NDArray[Any])

MIN_DEPTH_M = 1e-6
"""A point must be at least this far in front of a perspective camera (m) to project into its picture."""


@dataclass(frozen=True, slots=True)
class ImageBounds:
    """Where a perspective camera's picture is: its ideal (distortion-free) projection and image size.

    Distortion is left out on purpose: a strong lens model folds far-off points back into the image, and the
    ideal projection of a point in view lies within a few pixels of the image rectangle anyway.
    """

    k: FloatArray
    """(3, 3) intrinsics."""
    r: FloatArray
    """(3, 3) world -> camera rotation."""
    t: FloatArray
    """(3,) world -> camera translation (m)."""
    width_px: int
    height_px: int
    _projection: FloatArray = field(init=False, repr=False, compare=False)
    """(4, 3) world points (homogeneous rows) -> (u w, v w, w), w the depth: K [R | t], transposed."""

    def __post_init__(self) -> None:
        rt = np.column_stack([np.asarray(self.r, dtype=np.float64), np.asarray(self.t, dtype=np.float64)])
        object.__setattr__(self, "_projection", (np.asarray(self.k, dtype=np.float64) @ rt).T.copy())

    def inside(self, xyz: FloatArray, margin_px: float = 0.0) -> npt.NDArray[np.bool_]:
        """(n,) whether world points (n, 3) project into the picture (in front of the camera)."""
        pts = np.asarray(xyz, dtype=np.float64).reshape(-1, 3)
        uvw = pts @ self._projection[:3] + self._projection[3]
        w = uvw[:, 2]  # K's last row is (0, 0, 1): the depth
        front = w > MIN_DEPTH_M
        z = np.where(front, w, 1.0)
        u = uvw[:, 0] / z
        v = uvw[:, 1] / z
        m = margin_px
        return np.asarray(
            front & (u >= -m) & (u <= self.width_px + m) & (v >= -m) & (v <= self.height_px + m), dtype=bool
        )


@dataclass(frozen=True, slots=True)
class Subset:
    """Some of a tick's blobs, view by view: index arrays into a :class:`Views` (:meth:`Views.subset`)."""

    rows: IntArray
    """(r,) the views that have blobs in the subset (every view for :meth:`Views.every`), in order."""
    offsets: IntArray
    """(r + 1,) view ``rows[i]``'s blobs are ``entries[offsets[i]:offsets[i + 1]]``."""
    entries: IntArray
    """(k,) the blobs (entries of the views' per-blob arrays), view after view."""
    row_of: IntArray
    """(k,) the position in ``rows`` of each blob's view."""
    whole: bool = False
    """Every blob of every view, in order (:meth:`Views.every`): the views' arrays are read as they are."""

    @property
    def counts(self) -> IntArray:
        """(r,) blobs of each view in the subset."""
        return np.diff(self.offsets)

    def take(self, per_blob: _A) -> _A:
        """The values of the subset's blobs, of a per-blob array (m, ...) of the views."""
        return per_blob if self.whole else cast(_A, per_blob[self.entries])

    def pick(self, per_view: _A) -> _A:
        """The values of the subset's views, of a per-view array (s, ...) of the views."""
        return per_view if self.whole else cast(_A, per_view[self.rows])

    def part(self, i: int) -> IntArray:
        """The blobs of view ``rows[i]``."""
        return self.entries[self.offsets[i] : self.offsets[i + 1]]

    def split(self, a: FloatArray) -> list[FloatArray]:
        """(n, k) per-blob columns ``a`` cut into each view's (n, k_i)."""
        return [a[:, self.offsets[i] : self.offsets[i + 1]] for i in range(len(self.rows))]


@dataclass(frozen=True, slots=True)
class Views:
    """Every camera's blobs at the fusion instant in world terms: per-view arrays (s,) and per-blob arrays (m,), the
    blobs view after view (see the module docstring)."""

    sensor_ids: tuple[str, ...]
    """Each view's camera, in order of sensor ids."""
    offsets: IntArray
    """(s + 1,) view ``i``'s blobs are entries ``offsets[i]:offsets[i + 1]``."""
    # -- per view ---------------------------------------------------------------------------------------------
    origin: FloatArray
    """(s, 2) optical centres on the floor plane."""
    z_m: FloatArray
    """(s,) heights of the optical centres."""
    sigma_rad: FloatArray
    """(s,) 1-sigma bearing errors (the sensor's, plus its pose's yaw error)."""
    sigma_xy_m: FloatArray
    """(s,) 1-sigma errors of the cameras' own floor positions (mutual calibration; 0: surveyed)."""
    point_var_m2: FloatArray
    """(s,) variance of each camera's measured point around a person's floor position, across its rays and along
    them (feet): what the sensor states (``point_sigma_m``), else the site's default."""
    period_s: FloatArray
    """(s,) frame periods (0: unknown): successive ticks between two frames see the same evidence."""
    body_radius_m: FloatArray
    """(s,) radius of each camera's body (a robot, a post): a cylinder from the floor up to the camera, which hides
    what stands behind it from the other cameras (0: none)."""
    blobs_merge: BoolArray
    """(s,) whether each camera's blobs are foreground segments, which merge people who overlap in its picture (a
    blob's bottom may be a nearer person's feet), rather than one box per person."""
    shared_detector: tuple[str, ...]
    """Each view's multi-view detector (its boxes are that detector's floor detections drawn into its picture: the
    views that name it find or miss a person together, covered or not); "": the camera's own detector."""
    fov: tuple[tuple[float, float] | None, ...]
    """(world azimuth of the optical axis, half width) of each perspective camera; None: 360 deg (panoramic)."""
    image: tuple[ImageBounds | None, ...]
    """Each perspective camera's projection, to tell whether a floor position is in its picture (None: panoramic)."""
    hist_bins: IntArray
    """(s,) the size of each view's colour histograms (0: it sends none)."""
    # -- per blob ---------------------------------------------------------------------------------------------
    bearing_rad: FloatArray
    """(m,) world azimuths of the heads."""
    width_rad: FloatArray
    """(m,) angular widths."""
    top_elev_rad: FloatArray
    """(m,) elevations of the blob tops."""
    bottom_elev_rad: FloatArray
    """(m,) elevations of the blob bottoms (feet), NaN where the feet are not visible."""
    top_cut: BoolArray
    """(m,) blobs whose top touches the image's upper border (a person close to the camera): their head-top height
    is only a lower bound."""
    side_cut: FloatArray
    """(m,) +1 or -1 for a blob whose box the picture's side cuts (a perspective camera's left or right border):
    the way (the sign of a world-bearing change) in which the person goes on beyond the picture, so that the box's
    centre is not theirs and its width is only part of theirs; 0: whole."""
    mono_range_m: FloatArray
    """(m,) floor distance of each blob from its feet elevation (:mod:`~resource_manager.views.mono`), NaN where
    the camera gives none."""
    mono_sigma_m: FloatArray
    """(m,) 1-sigma of ``mono_range_m`` (NaN: none)."""
    local_id: IntArray
    """(m,) the nodes' 2D track ids."""
    confidence: FloatArray
    """(m,) the node's confidence in each blob (a detector's score; 1: sure): a low one may update a track but
    never starts one."""
    hist_sqrt: dict[int, FloatArray]
    """Histogram size -> (m, size) square roots of the L1-normalised colour histograms of the blobs whose view has
    that size (0 elsewhere)."""
    # -- derived ----------------------------------------------------------------------------------------------
    rows: dict[str, int] = field(init=False)
    """sensor id -> its view's row."""
    view_of: IntArray = field(init=False)
    """(m,) the view (row) of each blob."""
    fov_width_rad: FloatArray = field(init=False)
    """(s,) horizontal extent of each view's bearings."""
    shared_groups: dict[str, IntArray] = field(init=False)
    """Each multi-view detector's name -> the rows of its views (:attr:`shared_detector`), in order of names."""

    def __post_init__(self) -> None:
        counts = np.diff(self.offsets)
        object.__setattr__(self, "rows", {sid: i for i, sid in enumerate(self.sensor_ids)})
        object.__setattr__(self, "view_of", np.repeat(np.arange(len(self.sensor_ids), dtype=np.int64), counts))
        widths = [TWO_PI if f is None else min(2.0 * f[1], TWO_PI) for f in self.fov]
        object.__setattr__(self, "fov_width_rad", np.array(widths, dtype=np.float64))
        names = sorted(set(self.shared_detector) - {""})
        groups = {n: np.array([v for v, d in enumerate(self.shared_detector) if d == n], dtype=np.int64) for n in names}
        object.__setattr__(self, "shared_groups", groups)

    @property
    def n_views(self) -> int:
        return len(self.sensor_ids)

    @property
    def n(self) -> int:
        """Blobs of every view."""
        return int(self.offsets[-1])

    @property
    def counts(self) -> IntArray:
        """(s,) blobs of each view."""
        return np.diff(self.offsets)

    def span(self, row: int) -> slice:
        """View ``row``'s blobs."""
        return slice(int(self.offsets[row]), int(self.offsets[row + 1]))

    def entry(self, sensor_id: str, blob: int) -> int:
        """The entry of blob ``blob`` (its index in its view) of view ``sensor_id``."""
        return self.offsets.item(self.rows[sensor_id]) + blob

    def hist_of(self, entry: int) -> FloatArray | None:
        """The square-rooted histogram of one blob (None: its view sends none)."""
        bins = self.hist_bins.item(self.view_of.item(entry))
        return self.hist_sqrt[bins][entry] if bins else None

    def every(self) -> Subset:
        """Every blob, every view (with or without blobs)."""
        return Subset(
            np.arange(self.n_views, dtype=np.int64), self.offsets, np.arange(self.n, dtype=np.int64), self.view_of, True
        )

    def subset(self, blobs: BoolArray) -> Subset:
        """The blobs ``blobs`` says (an (m,) mask), in their views (only the views with some), in order."""
        entries = np.flatnonzero(blobs).astype(np.int64)
        view = self.view_of[entries]
        rows, counts = np.unique(view, return_counts=True)
        offsets = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
        return Subset(rows.astype(np.int64), offsets, entries, np.repeat(np.arange(len(rows), dtype=np.int64), counts))

    @staticmethod
    def empty() -> Views:
        """No view."""
        none = np.zeros(0)
        return Views(
            sensor_ids=(),
            offsets=np.zeros(1, dtype=np.int64),
            origin=np.zeros((0, 2)),
            z_m=none,
            sigma_rad=none,
            sigma_xy_m=none,
            point_var_m2=none,
            period_s=none,
            body_radius_m=none,
            blobs_merge=np.zeros(0, dtype=bool),
            shared_detector=(),
            fov=(),
            image=(),
            hist_bins=np.zeros(0, dtype=np.int64),
            bearing_rad=none,
            width_rad=none,
            top_elev_rad=none,
            bottom_elev_rad=none,
            top_cut=np.zeros(0, dtype=bool),
            side_cut=none,
            mono_range_m=none,
            mono_sigma_m=none,
            local_id=np.zeros(0, dtype=np.int64),
            confidence=none,
            hist_sqrt={},
        )


def stack_histograms(
    per_view: Sequence[FloatArray | None], offsets: IntArray
) -> tuple[IntArray, dict[int, FloatArray]]:
    """Each view's histogram size (0: none) and, per size, the (m, size) histograms of the views of that size (0
    elsewhere), from each view's (n_i, size) histograms (None: it sends none)."""
    bins = [0 if h is None else int(h.shape[1]) for h in per_view]
    hists: dict[int, FloatArray] = {}
    total = int(offsets[-1])
    for size in sorted(set(bins) - {0}):
        hists[size] = np.zeros((total, size))
        for i, h in enumerate(per_view):
            if bins[i] == size and h is not None:
                hists[size][offsets[i] : offsets[i + 1]] = h
    return np.array(bins, dtype=np.int64), hists
