"""People in a merged group: a fix from a track's own rays and the extents of the blobs it shares.

When people walk close together most cameras see one blob for two or three of them: the support step gives that
blob to one track and lets the others *share* it (:meth:`~resource_manager.association.Associator.support`). A
track left with one camera of its own and only shared blobs elsewhere has no stereo pair, yet it is far from
unobserved: its own blob gives a sharp bearing, and every shared blob says the person lies within that blob's
angular extent. This stage turns that into a floor fix by least squares on bearing rays
(:func:`common.geometry.intersect_rays`):

* each own view: the blob's head bearing with the view's sigma (inflated for a head cut by the panorama's top
  border: :data:`CUT_SIGMA_FACTOR`);
* each shared view: the track's predicted bearing clamped into the blob's extent (head bearing ± its
  width, less half a person's width at the predicted distance: the head may be at either edge of the
  blob), with a sigma of a quarter of that extent. While the prediction lies inside the extent, the shared
  view only holds the position along the own ray where the prediction has it; when the prediction drifts
  out of the blob, it is pulled back to the blob's edge.

The fix keeps a confirmed track on its person through the 1-3 s its group stays merged, instead of coasting off
and dying (then being reborn under a new id). It is used only for a confirmed track whose own blob continues the
node's 2D track it followed (same local id), only for ``group_coast_s`` after its last stereo fix, and only
inside the motion gate.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from common.errors import GeometryError
from common.geometry import intersect_rays
from resource_manager.localize import Measurement, wide_blob
from resource_manager.match import ViewBlobs

__all__ = ["CUT_SIGMA_FACTOR", "HOLD_MIN_HITS", "PERSON_HALF_WIDTH_M", "group_fix", "hidden_in_group"]

FloatArray = npt.NDArray[np.float64]
PERSON_HALF_WIDTH_M = 0.2
"""Half a person's body width (m): a blob explains its people within its extent less this at each edge."""
HOLD_MIN_HITS = 40
"""A track is held in its group (:func:`hidden_in_group`) only after this many fixes (4 s at 10 Hz): the ghosts
of the first seconds (crossing rays, a background learnt with someone in it) are never held. Replays of five six
recordings (seeds 5, 9, 21, 3, 11), holding with the mates' velocity: mean MOTA 0.940 without the hold, 0.937
holding from 1 fix, 0.944 from 40; held in place (no velocity) from 40: 0.947."""
CUT_SIGMA_FACTOR = 3.0
"""Bearing sigma factor of a blob whose head is cut by the top border (a close person: head bearing 1-2 px off)."""


def _bearing_sigma(v: ViewBlobs, i: int) -> float:
    cut = v.top_cut is not None and bool(v.top_cut[i])
    return v.sigma_rad * (CUT_SIGMA_FACTOR if cut else 1.0)


def group_fix(
    pred_xy: FloatArray,
    own: dict[str, int],
    shared: dict[str, int],
    views: dict[str, ViewBlobs],
    *,
    min_sigma_m: float = 0.02,
) -> Measurement | None:
    """A floor fix from the own blobs' rays and the shared blobs' extents (see the module doc).

    Args:
        pred_xy: (2,) the track's predicted position.
        own: sensor id -> index of the track's own blob there (at least one).
        shared: sensor id -> index of a blob it shares with a neighbour.
        views: every view of the tick.

    Returns:
        The fix (method ``least_squares``, ``blobs`` = the own views only), or None with no own view, fewer
        than two views, a shared blob no wider than one person at the predicted distance (then it is the
        neighbour's alone, not a group this track hides in), or rays that do not meet.
    """
    if not own or len(own) + len(shared) < 2:
        return None
    px, py = float(pred_xy[0]), float(pred_xy[1])
    origins: list[FloatArray] = []
    bearings: list[float] = []
    sigmas: list[float] = []
    for sid, i in own.items():
        v = views[sid]
        origins.append(v.origin_xy)
        bearings.append(float(v.bearing_rad[i]))
        sigmas.append(_bearing_sigma(v, i))
    for sid, i in shared.items():
        v = views[sid]
        dx, dy = px - float(v.origin_xy[0]), py - float(v.origin_xy[1])
        dist = max(math.hypot(dx, dy), 0.3)
        if not wide_blob(v, i, dist):
            return None  # one person's blob: the neighbour's alone, not a group this track hides in
        pred = math.atan2(dy, dx)
        head = float(v.bearing_rad[i])
        half = max(float(v.width_rad[i]) - math.atan(PERSON_HALF_WIDTH_M / dist), 0.0)
        off = math.remainder(pred - head, 2.0 * math.pi)
        origins.append(v.origin_xy)
        bearings.append(head + min(max(off, -half), half))
        sigmas.append(max(0.5 * half, _bearing_sigma(v, i)))
    try:
        fix = intersect_rays(np.array(origins), np.array(bearings), np.array(sigmas))
    except GeometryError:
        return None
    xy = np.asarray(fix.xy, dtype=np.float64)
    if not np.all(np.isfinite(xy)):
        return None
    cov = np.asarray(fix.cov, dtype=np.float64) + min_sigma_m**2 * np.eye(2)
    return Measurement(
        xy=xy,
        cov=cov,
        height_m=0.0,
        method="least_squares",
        sensors=tuple(own) + tuple(shared),
        predicted_error_m=math.sqrt(max(float(np.trace(cov)), 0.0)),
        blobs=tuple(own.items()),
    )


def hidden_in_group(
    pred_xy: FloatArray, own: dict[str, int], shared: dict[str, int], views: dict[str, ViewBlobs]
) -> bool:
    """Whether a track without a fix is plausibly hidden in a merged group at its predicted position.

    Every blob that supports it (own or shared, at least two views) holds its predicted bearing within about the
    blob's width, and at least one shared blob is wider than one person there. Then the track is held where it
    was last seen (the caller drops its velocity) instead of coasting off, dying and being reborn under a new id
    when the group splits.
    """
    if len(own) + len(shared) < 2:
        return False
    px, py = float(pred_xy[0]), float(pred_xy[1])
    wide = False
    for sid, i in {**own, **shared}.items():
        v = views[sid]
        dx, dy = px - float(v.origin_xy[0]), py - float(v.origin_xy[1])
        off = abs(math.remainder(math.atan2(dy, dx) - float(v.bearing_rad[i]), 2.0 * math.pi))
        if off > float(v.width_rad[i]) + 4.0 * v.sigma_rad:
            return False
        wide = wide or (sid in shared and wide_blob(v, i, max(math.hypot(dx, dy), 0.3)))
    return wide
