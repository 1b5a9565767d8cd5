"""The size-ratio method's measurements along near-colinear pairs' baselines (Eq. 2), for the filter.

Where two of a person's views and the person are nearly colinear, bearings say little about where along the
baseline the person is; the size-ratio method (Eq. 2) says it from the two blob widths: each such pair gives a
measurement along its baseline, fused with the bearings (its error, 2 eps D1 D2 / B with eps the relative width
error, against theirs, D / sin phi0: the crossover of docs/geometry.md §3 is then the point where each counts as
much as the other, not a switch).

Pairs whose bearings both lie within :data:`~common.geometry.MAX_SIZE_RATIO_OFFSET_RAD` of their baseline's line
qualify (with many cameras, pairs among the first few of them by sensor id); a blob wider than one person
(a merged group) gives no width to use. Every pair of every track is worked out at once, with arrays.
"""

from __future__ import annotations

import math

import numpy as np

from common.arrays import BoolArray, FloatArray, pairs_of
from common.geometry import MAX_SIZE_RATIO_OFFSET_RAD, MIN_RAYS, MIN_SIZE_RATIO_DEN
from resource_manager.stereo.localize import MAX_PERSON_WIDTH_M

__all__ = ["size_ratio_lines"]


def size_ratio_lines(
    origin: FloatArray, blob: FloatArray, used: BoolArray, width_rel_sigma: float
) -> tuple[FloatArray, BoolArray]:
    """Each track's line observations from the blobs assigned to it, pairs taken in order of slots.

    Args:
        origin: (k, w, 2) the camera of each track's slots (its views in order of sensor id).
        blob: (k, w, 2) the bearing and angular width of the blob in each slot.
        used: (k, w) which slots hold a view.
        width_rel_sigma: the relative width error eps.

    Returns:
        (k, l, 4) rows of direction x, y, value and variance (the
        :class:`~resource_manager.track.motion.LineObservation` of each, as
        :meth:`~resource_manager.track.motion.ObservationBatch.padded` takes them), and (k, l) which are there.
    """
    k, width = used.shape
    if width < MIN_RAYS:  # no pair of views
        return np.zeros((k, 0, 4)), np.zeros((k, 0), dtype=bool)
    ia, ib = pairs_of(width)
    ray = np.stack([np.cos(blob[:, :, 0]), np.sin(blob[:, :, 0])], axis=2)  # each blob's bearing as a vector
    oa, wa, wb = origin[:, ia], blob[:, ia, 1], blob[:, ib, 1]
    base = origin[:, ib] - oa
    length = np.hypot(base[:, :, 0], base[:, :, 1])
    ok = used[:, ia] & used[:, ib] & (length > 0)
    u = base / np.where(ok, length, 1.0)[:, :, None]
    # Each bearing's angle with the baseline's line, by its sine and cosine with the baseline's direction.
    ra, rb = ray[:, ia], ray[:, ib]
    sin_a, cos_a = (
        ra[:, :, 0] * u[:, :, 1] - ra[:, :, 1] * u[:, :, 0],
        ra[:, :, 0] * u[:, :, 0] + ra[:, :, 1] * u[:, :, 1],
    )
    sin_b, cos_b = (
        rb[:, :, 0] * u[:, :, 1] - rb[:, :, 1] * u[:, :, 0],
        rb[:, :, 0] * u[:, :, 0] + rb[:, :, 1] * u[:, :, 1],
    )
    ok &= np.maximum(np.abs(sin_a), np.abs(sin_b)) < math.sin(MAX_SIZE_RATIO_OFFSET_RAD)
    # Eq. (2): the cosines' signs say whether the person is between the cameras or beyond one of them.
    c1 = np.where(cos_a > 0, 1.0, -1.0)
    c2 = np.where(cos_b < 0, 1.0, -1.0)
    w1, w2 = np.sin(wa / 2), np.sin(wb / 2)
    ok &= (w1 > 0) & (w2 > 0)
    den = w1 * c1 + w2 * c2
    ok &= np.abs(den) >= MIN_SIZE_RATIO_DEN
    den = np.where(ok, den, 1.0)
    d1 = length * w2 * c2 / den * c1
    d2 = length * w1 * c1 / den * c2
    ok &= (d1 > 0) & (d2 > 0)
    # A blob wider than one person at its distance (a merged group) gives no width to use.
    ok &= ~(_wide(d1, wa) | _wide(d2, wb))
    sigma = 2.0 * width_rel_sigma * d1 * d2 / np.where(ok, length, 1.0)
    value = u[:, :, 0] * oa[:, :, 0] + u[:, :, 1] * oa[:, :, 1] + c1 * d1
    # Each track's lines moved to its first slots, in order.
    count = ok.sum(axis=1)
    rows = np.zeros((k, int(count.max(initial=0)), 4))
    valid = np.zeros(rows.shape[:2], dtype=bool)
    track, pair = np.nonzero(ok)
    slot = (np.cumsum(ok, axis=1) - 1)[track, pair]
    rows[track, slot] = np.stack(
        [u[track, pair, 0], u[track, pair, 1], value[track, pair], sigma[track, pair] ** 2], axis=1
    )
    valid[track, slot] = True
    return rows, valid


def _wide(distance_m: FloatArray, width_rad: FloatArray) -> BoolArray:
    """Whether blobs of angular widths ``width_rad`` are plainly wider than one person at ``distance_m``
    (:func:`~resource_manager.stereo.localize.wide_blob`)."""
    return np.asarray(2.0 * distance_m * np.tan(0.5 * width_rad) > MAX_PERSON_WIDTH_M, dtype=bool)
