"""Is a fix the track's? Checks of step 2 that refuse fixes belonging to someone else or to nobody.

* :func:`views_agreeing`: the cameras supporting the track whose blob points at the fix (a ghost of two other
  people's rays has the other cameras looking elsewhere);
* :func:`owned_elsewhere`: a coasting track's grown gate reaches the neighbour's fix; a track measured more
  recently that explains it better keeps it.
"""

from __future__ import annotations

import math

from resource_manager.localize import Measurement
from resource_manager.match import ViewBlobs
from resource_manager.mono import range_mismatch
from resource_manager.track import Tracker, TrackRecord

__all__ = ["OWNER_MIN_MISSES", "owned_elsewhere", "views_agreeing"]

OWNER_MIN_MISSES = 3
"""A track that missed this many ticks in a row (its gate has grown) yields fixes nearer a measured track."""


def views_agreeing(
    meas: Measurement, sup: dict[str, int], views: dict[str, ViewBlobs], k: float, mono_k: float
) -> tuple[list[str], int]:
    """Supporting cameras whose blob points at the measurement, and how many point elsewhere.

    A blob points at it when its bearing is within ``k`` sigmas (plus 0.25 m of lateral slack) and its feet, where
    known, within ``mono_k`` sigmas of the distance (:func:`~resource_manager.mono.range_mismatch`).
    """
    x, y = float(meas.xy[0]), float(meas.xy[1])
    agree: list[str] = []
    against = 0
    for sid, i in sup.items():  # plain floats: a handful of views, numpy per element would cost more
        v = views[sid]
        dx, dy = x - float(v.origin_xy[0]), y - float(v.origin_xy[1])
        dist = max(math.hypot(dx, dy), 0.3)
        off = math.remainder(float(v.bearing_rad[i]) - math.atan2(dy, dx), 2 * math.pi)
        if abs(off) < k * v.sigma_rad + 0.25 / dist and range_mismatch(v, i, meas.xy) < mono_k:
            agree.append(sid)
        else:
            against += 1
    return agree, against


def owned_elsewhere(tracker: Tracker, tr: TrackRecord, meas: Measurement, tracks: list[TrackRecord]) -> bool:
    """Whether another track measured more recently than ``tr`` is nearer (Mahalanobis) to the fix.

    A coasting track's gate keeps growing; without this it takes the fix of the person next to it (the
    neighbour's own, active track loses it, and ids swap when the two walk apart).
    """
    if tr.misses < OWNER_MIN_MISSES:
        return False  # its gate is still about as tight as its neighbours'
    d_tr = tracker.gate_distance(tr, meas)
    x, y = float(meas.xy[0]), float(meas.xy[1])
    for u in tracks:
        if u is tr or not u.confirmed:
            continue
        if u.misses >= tr.misses:
            continue
        if abs(float(u.x[0]) - x) > 1.5 or abs(float(u.x[1]) - y) > 1.5:
            continue
        if tracker.gate_distance(u, meas) < d_tr:
            return True
    return False
