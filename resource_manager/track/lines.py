"""The size-ratio method's measurements along near-colinear pairs' baselines (Eq. 2), for the filter.

Where two of a person's views and the person are nearly colinear, bearings say little about where along the
baseline the person is; the size-ratio method (Eq. 2) says it from the two blob widths: each such pair gives a
measurement along its baseline, fused with the bearings (its error, 2 eps D1 D2 / B with eps the relative width
error, against theirs, D / sin phi0: the crossover of notes/geometry.md §3 is then the point where each counts as
much as the other, not a switch).

Pairs whose bearings both lie within :data:`~common.geometry.MAX_SIZE_RATIO_OFFSET_RAD` of their baseline's line
qualify (with many cameras, pairs among the first ``max_views`` of them by sensor id); a blob wider than one person
(a merged group) gives no width to use. Few pairs ever qualify: every pair of every track is screened at once with
arrays, and only those that may qualify are worked out one by one.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from common.errors import GeometryError
from common.geometry import MAX_SIZE_RATIO_OFFSET_RAD, size_ratio
from resource_manager.stereo.localize import wide_blob
from resource_manager.track.motion import LineObservation
from resource_manager.views.blobs import ViewBlobs

__all__ = ["size_ratio_lines"]

FloatArray = npt.NDArray[np.float64]
SCREEN_MARGIN_RAD = 1e-9
"""The array screen keeps pairs this much beyond the limit too: its rounding differs from the exact test's."""


def size_ratio_lines(
    views: dict[str, ViewBlobs], blobs: list[dict[str, int]], width_rel_sigma: float, max_views: int
) -> list[list[LineObservation]]:
    """Each track's line observations from the blobs assigned to it (``blobs``: per track, sensor id -> blob),
    pairs taken in order of sensor ids; ``width_rel_sigma``: the relative width error eps."""
    out: list[list[LineObservation]] = [[] for _ in blobs]
    sids = sorted(views)
    if len(sids) < 2 or not blobs:
        return out
    column = {s: c for c, s in enumerate(sids)}
    origin = np.array([views[s].origin_xy for s in sids], dtype=np.float64)
    chosen = [sorted(by_sid)[:max_views] for by_sid in blobs]
    width = max(len(c) for c in chosen)
    if width < 2:
        return out
    cam = np.zeros((len(blobs), width), dtype=np.int64)
    bearing = np.zeros((len(blobs), width))
    used = np.zeros((len(blobs), width), dtype=bool)
    for k, (by_sid, ids) in enumerate(zip(blobs, chosen, strict=True)):
        for c, sid in enumerate(ids):
            cam[k, c] = column[sid]
            bearing[k, c] = views[sid].bearing_rad[by_sid[sid]]
            used[k, c] = True
    ia, ib = np.triu_indices(width, 1)  # the order of itertools.combinations
    base = origin[cam[:, ib]] - origin[cam[:, ia]]
    psi = np.arctan2(base[:, :, 1], base[:, :, 0])
    off = np.maximum(_off_line(bearing[:, ia] - psi), _off_line(bearing[:, ib] - psi))
    maybe = used[:, ia] & used[:, ib] & (off < MAX_SIZE_RATIO_OFFSET_RAD + SCREEN_MARGIN_RAD)
    for k, q in zip(*np.nonzero(maybe), strict=True):
        sa, sb = chosen[k][ia[q]], chosen[k][ib[q]]
        line = _line(views[sa], blobs[k][sa], views[sb], blobs[k][sb], width_rel_sigma)
        if line is not None:
            out[k].append(line)
    return out


def _line(va: ViewBlobs, ia: int, vb: ViewBlobs, ib: int, eps: float) -> LineObservation | None:
    """The size-ratio measurement of blobs ``ia`` of ``va`` and ``ib`` of ``vb`` along their baseline, if the pair
    qualifies."""
    ta, tb = float(va.bearing_rad[ia]), float(vb.bearing_rad[ib])
    base = vb.origin_xy - va.origin_xy
    length = float(np.hypot(*base))
    if length <= 0:
        return None
    psi = math.atan2(float(base[1]), float(base[0]))
    if max(_off_line_f(ta - psi), _off_line_f(tb - psi)) >= MAX_SIZE_RATIO_OFFSET_RAD:
        return None
    c1 = 1.0 if abs(math.remainder(ta - psi, 2 * math.pi)) < math.pi / 2 else -1.0
    c2 = 1.0 if abs(math.remainder(tb - psi - math.pi, 2 * math.pi)) < math.pi / 2 else -1.0
    wa, wb = float(va.width_rad[ia]), float(vb.width_rad[ib])
    try:
        d1, d2 = size_ratio(length, math.sin(wa / 2), math.sin(wb / 2), c1, c2)
    except GeometryError:
        return None
    if wide_blob(va, ia, d1) or wide_blob(vb, ib, d2):
        return None
    u = base / length
    sigma = 2.0 * eps * d1 * d2 / length
    return LineObservation((float(u[0]), float(u[1])), float(u @ va.origin_xy) + c1 * d1, sigma * sigma)


def _off_line_f(angle_rad: float) -> float:
    """Angle between a direction and a line (either way along it), in [0, pi/2]."""
    a = abs(math.remainder(angle_rad, math.pi))
    return min(a, math.pi - a)


def _off_line(angle_rad: FloatArray) -> FloatArray:
    """:func:`_off_line_f` of many angles."""
    a = np.remainder(angle_rad, math.pi)
    return np.asarray(np.minimum(a, math.pi - a), dtype=np.float64)
