"""Every track's measurement update of one tick at once: the floor filter and the head height.

The blobs assigned to the tracks are gathered from the tick's :class:`~resource_manager.views.blobs.Views` by
index arrays (:class:`Slots`: one slot per view of each track, in order of sensor ids), so that the arithmetic runs
once per tick on arrays rather than once per track and view:

* :func:`fuse`: the iterated EKF of :mod:`.motion` with each view's bearing and, where the camera sees the feet,
  its floor distance, and the size-ratio lines along near-colinear pairs' baselines (:mod:`.lines`), all
  gathered by :func:`observations` (which :meth:`.filter.TrackFilter.fused_without_each` also updates each track
  with, without each view in turn);
* :func:`fuse_heights`: the head-top heights the views imply at each track's updated distance (scalar Kalman
  updates, view after view).

Pure: states in, states out; :class:`~.tracker.Tracker` writes them into its tracks.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, TypeVar

import numpy as np
import numpy.typing as npt

from common.arrays import FloatArray, IntArray
from resource_manager.track.lines import size_ratio_lines
from resource_manager.track.motion import (
    MIN_RANGE_M,
    ObservationBatch,
    core_share,
    quadratic_form,
    update_many,
)
from resource_manager.track.observe import bearing_var, cut_bearing, feet_ln
from resource_manager.views.blobs import Views

__all__ = ["Slots", "fuse", "fuse_heights", "observations"]

_Scalar = TypeVar("_Scalar", bound=np.generic)
HALF = 0.5
"""A floor distance less likely than this to show the feet is left out (its bearing stays)."""


@dataclass(frozen=True, slots=True)
class Slots:
    """Tracks' assigned blobs as indices into the tick's :class:`Views`: the ``slot[e]``-th blob assigned to track
    ``track[e]`` is the blob (entry) ``blob[e]``, of its view ``view[e]``."""

    track: IntArray
    slot: IntArray
    view: IntArray
    blob: IntArray
    shape: tuple[int, int]
    """(tracks, most slots of any)."""

    @staticmethod
    def of(assigned: Sequence[Sequence[tuple[str, int]]], views: Views) -> Slots:
        """The slots of each track's assigned (sensor id, blob index in its view), in that order."""
        rows = views.rows
        flat = [(k, c, rows[sid], j) for k, got in enumerate(assigned) for c, (sid, j) in enumerate(got)]
        idx = np.array(flat, dtype=np.int64).reshape(-1, 4)
        view = idx[:, 2]
        width = max((len(got) for got in assigned), default=0)
        return Slots(idx[:, 0], idx[:, 1], view, views.offsets[view] + idx[:, 3], (len(assigned), width))

    def per_slot(self, values: npt.NDArray[_Scalar], fill: float = 0.0) -> npt.NDArray[_Scalar]:
        """(k, w, ...) per-slot array of ``values`` (one per entry), ``fill`` in the empty slots."""
        out = np.full((*self.shape, *values.shape[1:]), fill, dtype=values.dtype)
        out[self.track, self.slot] = values
        return out

    def used(self) -> npt.NDArray[np.bool_]:
        """(k, w) which slots hold a blob."""
        out = np.zeros(self.shape, dtype=bool)
        out[self.track, self.slot] = True
        return out


def fuse(
    xs: FloatArray,
    ps: FloatArray,
    slots: Slots,
    views: Views,
    *,
    outlier: tuple[float, float],
    **options: Any,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """States ``xs`` (k, 4) and covariances ``ps`` (k, 4, 4) updated with the blobs of their ``slots``
    (:func:`observations`, with ``options``; :func:`.motion.update_many`).

    Returns:
        (x, P, the weight (k, w) of each slot's blob: low for an outlier).
    """
    batch = observations(xs, ps, slots, views, outlier=outlier, **options)
    return update_many(xs, ps, batch, outlier)


def observations(
    xs: FloatArray,
    ps: FloatArray,
    slots: Slots,
    views: Views,
    *,
    position_weight: FloatArray,
    outlier: tuple[float, float],
    width_rel_sigma: float,
    line_views: int,
    feet_cut: FloatArray | None = None,
    cut_reach_m: FloatArray | None = None,
    cover_near_m: FloatArray | None = None,
) -> ObservationBatch:
    """The blobs of the ``slots`` as observations of the tracks predicted at ``xs`` (k, 4) with covariances ``ps``
    (k, 4, 4).

    Args:
        position_weight: (s,) each view's share of a new frame's information (its variances are divided by it: a
            tick between two frames sees an interpolation of frames already used).
        outlier: (probability, scale) of the observations' outlier component.
        width_rel_sigma: the relative width error of the size-ratio method.
        line_views: the size-ratio pairs are taken among each track's first this many views (0: none).
        feet_cut: (s, k) probability that view ``s``'s box of track ``k`` ends above the feet (someone nearer or a
            camera's body hides them: :func:`.observe.feet_cut_prob`); None: ``outlier``'s alone.
        cut_reach_m: (s, k) the farthest floor distance such a cut box can read
            (:attr:`.observe.Visibility.cut_reach_m`); None: unbounded.
        cover_near_m: (s, k) where view ``s``'s blobs merge people who overlap, the floor distance of the nearest cover
            of track ``k``'s feet, at whose foot a blob that took it in ends (:attr:`.observe.Visibility.cover_near_m`;
            0 or None: none).
    """
    view, blob = slots.view, slots.blob
    # Each assigned blob as an observation of its track: its bearing and, where the camera sees the feet, its
    # floor distance (motion.ObservationBatch.padded's rows).
    obs = np.full((len(view), 6), math.nan)
    obs[:, :2] = origin = views.origin[view]
    weight = position_weight[view]
    dist = np.hypot(xs[slots.track, 0] - origin[:, 0], xs[slots.track, 1] - origin[:, 1])
    bearing, cut_var = cut_bearing(views.bearing_rad[blob], views.width_rad[blob], views.side_cut[blob], dist)
    obs[:, 2] = bearing
    obs[:, 3] = (bearing_var(views, view, dist) + cut_var) / weight
    has = np.isfinite(views.mono_range_m[blob])
    obs[has, 4] = views.mono_range_m[blob[has]]
    feet_var = views.mono_sigma_m[blob[has]] ** 2 + views.sigma_xy_m[view[has]] ** 2 + views.point_var_m2[view[has]]
    obs[has, 5] = feet_var / weight[has]
    if feet_cut is not None and has.any():
        # A box cut above the feet puts the person farther than they are (a blob that took a nearer person in,
        # nearer). Judged against the prediction, a distance more likely cut than not is left out, the others
        # weigh by the chance that they show the feet (the bearings cannot contradict a cut box where two cameras
        # look along one line, and a precise distance, however down-weighted, would still drag the track).
        track = slots.track[has]
        unit = (xs[track, :2] - origin[has]) / np.maximum(dist[has], MIN_RANGE_M)[:, None]
        var = quadratic_form(unit, ps[track, :2, :2], unit) + obs[has, 5]
        reach = None if cut_reach_m is None else cut_reach_m[view[has], track]
        near = None if cover_near_m is None else cover_near_m[view[has], track]
        nu = obs[has, 4] - dist[has]
        ln_feet, ln_cut = feet_ln(nu, var, dist[has], feet_cut[view[has], track], outlier, reach=reach, near=near)
        p_feet = np.exp(ln_feet - np.logaddexp(ln_feet, ln_cut))
        obs[has, 5] /= np.maximum(p_feet, HALF)
        obs[np.flatnonzero(has)[p_feet < HALF], 4] = math.nan
    k = slots.shape[0]
    line_rows, line_valid = np.zeros((k, 0, 4)), np.zeros((k, 0), dtype=bool)
    if line_views > 0:
        first = slice(0, line_views)
        # A box the picture's side cuts has no whole width to use (0: no line).
        width = np.where(views.side_cut[blob] != 0, 0.0, views.width_rad[blob])
        line_rows, line_valid = size_ratio_lines(
            slots.per_slot(origin)[:, first],
            slots.per_slot(np.column_stack([bearing, width]))[:, first],
            slots.used()[:, first],
            width_rel_sigma,
        )
    return ObservationBatch.padded(slots.per_slot(obs), slots.used(), line_rows, line_valid)


def fuse_heights(
    xy: FloatArray,
    height_m: FloatArray,
    height_var: FloatArray,
    slots: Slots,
    views: Views,
    *,
    outlier: tuple[float, float] | None = None,
) -> tuple[FloatArray, FloatArray]:
    """Head-top heights ``height_m`` (k,) and their variances ``height_var`` of tracks at ``xy`` (k, 2) after the
    heights their slots' blobs imply (scalar Kalman updates, slot after slot).

    ``outlier``: (probability, scale) of a height off by several sigmas (raised arms, a box that took in someone
    else, a blob given to the wrong track), as the views' scores model it: a height likelier such an outlier than
    not is left out, and one that may be is weighed by the chance that it is not."""
    view, blob = slots.view, slots.blob
    at = xy[slots.track]
    d = np.hypot(at[:, 0] - views.origin[view, 0], at[:, 1] - views.origin[view, 1])
    tan_top = np.tan(views.top_elev_rad[blob])
    z = slots.per_slot(views.z_m[view] + d * tan_top)
    var = slots.per_slot((d * views.sigma_rad[view] * (1.0 + tan_top * tan_top)) ** 2 + views.point_var_m2[view])
    # A head cut by the picture's top gives a lower bound only: left out.
    use = slots.used() & ~slots.per_slot(views.top_cut[blob])
    for c in range(slots.shape[1]):
        meas_var = var[:, c]
        used = use[:, c]
        if outlier is not None:
            p_core = core_share((z[:, c] - height_m) ** 2 / (height_var + var[:, c]), 1, outlier)
            used = used & (p_core >= HALF)
            meas_var = meas_var / np.maximum(p_core, HALF)
        k = height_var / (height_var + meas_var)
        height_m = np.where(used, height_m + k * (z[:, c] - height_m), height_m)
        height_var = np.where(used, height_var * (1.0 - k), height_var)
    return height_m, height_var
