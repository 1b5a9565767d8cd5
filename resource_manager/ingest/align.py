"""Alignment: every sensor's blobs at one common fusion instant T.

The paper synchronises its two platforms "by using network time protocol (NTP)
and by data interpolation in order to avoid the time/motion delay of moving
objects in two images". Each blob is matched across the two frames that
bracket T by the node's 2D track id (``local_id``) and its bearing, width and
top elevation are interpolated linearly (bearings along the shorter arc). A
blob present in only one of the two frames, or a sensor whose newest frame is
just before T, is extrapolated (or held) for at most ``max_extrapolation_ns``;
a sensor with nothing within ``stale_ns`` of T sits out the tick.

Sightings of other robots (Eq. 3) are interpolated the same way, keyed by the
sighted robot's id.

The result is one :class:`Aligned` per tick: the blobs of every sensor in one
set of arrays, sensor after sensor, still in each sensor's frame. The views
stage (:func:`resource_manager.views.build.build_views`) turns it into the
tick's world-frame :class:`~resource_manager.views.blobs.Views` once the poses
are known.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass, field

import numpy as np

from common.angles import angle_diff, interp_angle, wrap_angle
from common.arrays import FloatArray, IntArray
from common.schema import Blob, Features, Sighting
from resource_manager.config import ManagerSection, default_of
from resource_manager.ingest.buffers import SensorBuffer

__all__ = ["ALIGNED_COLUMNS", "AlignParams", "Aligned", "AlignedSighting", "align"]

ALIGNED_COLUMNS = 9
"""Columns of :attr:`Aligned.values`: bearing, width, top and bottom elevations (rad), bottom and top rows of the
box (px), confidence, left and right columns of the box (px)."""


@dataclass(frozen=True, slots=True)
class AlignParams:
    """``[manager]``'s alignment limits in ns (defaulted and documented in
    :class:`resource_manager.config.ManagerSection`)."""

    max_extrapolation_ns: int = int(default_of(ManagerSection, "max_extrapolation_ms") * 1e6)
    stale_ns: int = int(default_of(ManagerSection, "stale_ms") * 1e6)
    max_gap_ns: int = int(default_of(ManagerSection, "max_gap_ms") * 1e6)


@dataclass(frozen=True, slots=True)
class AlignedSighting:
    target_id: str
    left_rad: float
    right_rad: float
    body_radius_m: float


@dataclass(frozen=True, slots=True)
class Aligned:
    """Every sensor's blobs (and sightings) at the fusion instant, each in its sensor's frame: the blobs of all the
    sensors in one set of arrays, sensor after sensor (sensor ``i``'s are entries ``offsets[i]:offsets[i + 1]``)."""

    t_ns: int
    sensor_ids: tuple[str, ...]
    """The sensors aligned, in the order given (one that sits the tick out is not among them)."""
    modes: tuple[str, ...]
    """Each sensor's alignment: interpolated | extrapolated | held."""
    offsets: IntArray
    """(s + 1,) where each sensor's blobs start, and the end."""
    values: FloatArray
    """(m, :data:`ALIGNED_COLUMNS`) per blob: bearing (sensor-frame azimuth), angular width, top and bottom
    elevations (rad; the bottom NaN where the feet are not visible), the rows of its box's bottom and top edges (px;
    -1: unknown; a box cut by the image's lower border does not show the feet, whatever the node says, and one
    whose top is row 0 has its head cut), the node's confidence (a detector's score; the lower of the two
    frames'), and the columns of its box's left and right edges (px; over two frames the outermost: a box cut by
    the picture's side in either is not the person's whole width)."""
    local_id: IntArray
    """(m,) the nodes' 2D track ids."""
    hist: list[list[float]]
    """(m,) each blob's colour histogram (the frozen message's list, not copied; empty: none)."""
    sightings: dict[str, list[AlignedSighting]] = field(default_factory=dict)
    """Each sensor's sightings of other robots (empty when not asked for)."""

    @property
    def counts(self) -> IntArray:
        """(s,) blobs of each sensor."""
        return np.diff(self.offsets)

    @property
    def bearing_rad(self) -> FloatArray:
        return self.values[:, 0]

    @property
    def width_rad(self) -> FloatArray:
        return self.values[:, 1]

    @property
    def top_elev_rad(self) -> FloatArray:
        return self.values[:, 2]


@dataclass(slots=True)
class _Columns:
    """The blobs aligned so far, one flat row of :data:`ALIGNED_COLUMNS` floats each (a Python list: one is
    appended per blob, sensor and tick; the arrays are made once per tick)."""

    values: list[float] = field(default_factory=list)
    local_id: list[int] = field(default_factory=list)
    hist: list[list[float]] = field(default_factory=list)

    def add(self, b0: Blob | None, t0: int, b1: Blob | None, t1: int, t: int) -> None:
        """The blob at ``t`` from its two frames (or its one)."""
        if b0 is not None and b1 is not None:
            # interp_linear / interp_angle (common.clock) written out with the fraction computed once: this runs
            # for every blob of every sensor on every tick.
            f = (t - t0) / (t1 - t0) if t1 != t0 else 1.0
            bearing0 = b0.bearing_rad
            step = angle_diff(b1.bearing_rad, bearing0)
            width0, top0, bottom0 = b0.width_rad, b0.top_elev_rad, b0.bottom_elev_rad
            v0, v1 = b0.bbox_v_px, b1.bbox_v_px
            self.values.extend(
                (
                    wrap_angle(bearing0 + step * f),
                    max(0.0, width0 + (b1.width_rad - width0) * f),
                    top0 + (b1.top_elev_rad - top0) * f,
                    bottom0 + (b1.bottom_elev_rad - bottom0) * f if b0.feet_visible and b1.feet_visible else math.nan,
                    max(v0 + b0.bbox_h_px, v1 + b1.bbox_h_px),
                    min(v0, v1),
                    min(b0.confidence, b1.confidence),
                    min(b0.bbox_u_px, b1.bbox_u_px),
                    max(b0.bbox_u_px + b0.bbox_w_px, b1.bbox_u_px + b1.bbox_w_px),
                )
            )
            self.local_id.append(b1.local_id)
            self.hist.append(b1.hist if abs(t1 - t) <= abs(t - t0) else b0.hist)
            return
        b = b1 if b1 is not None else b0
        assert b is not None
        self.values.extend(
            (
                b.bearing_rad,
                b.width_rad,
                b.top_elev_rad,
                b.bottom_elev_rad if b.feet_visible else math.nan,
                b.bbox_v_px + b.bbox_h_px,
                b.bbox_v_px,
                b.confidence,
                b.bbox_u_px,
                b.bbox_u_px + b.bbox_w_px,
            )
        )
        self.local_id.append(b.local_id)
        self.hist.append(b.hist)


def _sighting_at(s0: Sighting | None, t0: int, s1: Sighting | None, t1: int, t: int) -> AlignedSighting:
    if s0 is not None and s1 is not None:
        return AlignedSighting(
            target_id=s1.target_id,
            left_rad=interp_angle(t0, s0.left_rad, t1, s1.left_rad, t),
            right_rad=interp_angle(t0, s0.right_rad, t1, s1.right_rad, t),
            body_radius_m=s1.body_radius_m,
        )
    s = s1 if s1 is not None else s0
    assert s is not None
    return AlignedSighting(s.target_id, s.left_rad, s.right_rad, s.body_radius_m)


def _pair(
    out: _Columns, f0: Features, f1: Features, t: int, max_one_sided_ns: int, *, want_s: bool
) -> list[AlignedSighting]:
    """Interpolate (or extrapolate) between two frames into ``out``; one-sided blobs only near their own frame.
    Returns the sightings."""
    t0, t1 = f0.stamp_ns, f1.stamp_ns
    by0 = {b.local_id: b for b in f0.blobs}
    by1 = {b.local_id: b for b in f1.blobs}
    # A blob in one frame only (the person appeared, left, or the node's 2D track changed id) is taken
    # from its own frame only when that frame is the nearer one: otherwise, at low frame rates, the
    # same person would be there twice (old id from one frame, new id from the other) -- a ghost.
    near1 = abs(t1 - t) <= abs(t - t0)
    for lid, b1 in by1.items():
        b0 = by0.get(lid)
        if b0 is not None:
            out.add(b0, t0, b1, t1, t)
        elif abs(t1 - t) <= max_one_sided_ns and near1:
            out.add(None, t0, b1, t1, t)
    for lid, b0 in by0.items():
        if lid not in by1 and abs(t - t0) <= max_one_sided_ns and t1 > t and not near1:
            out.add(b0, t0, None, t1, t)
    if not want_s:
        return []
    s0 = {s.target_id: s for s in f0.sightings if s.target_id}
    s1 = {s.target_id: s for s in f1.sightings if s.target_id}
    sightings = [_sighting_at(s0.get(k), t0, s, t1, t) for k, s in s1.items()]
    sightings += [_sighting_at(s, t0, None, t1, t) for k, s in s0.items() if k not in s1 and t1 > t]
    return sightings


def align(sensors: Iterable[tuple[str, SensorBuffer, AlignParams]], t_ns: int, *, sightings: bool = True) -> Aligned:
    """Every sensor's blobs and sightings at ``t_ns``; a sensor that must sit this tick out is left out.

    Args:
        sensors: (sensor id, its frames sorted by stamp, its extrapolation, staleness and gap limits) of each.
        t_ns: the fusion instant.
        sightings: False skips the sightings (every pose is surveyed: mutual calibration has nothing to do).
    """
    out = _Columns()
    sids: list[str] = []
    modes: list[str] = []
    ends = [0]
    seen: dict[str, list[AlignedSighting]] = {}
    for sid, buf, params in sensors:
        got = _align(out, buf, t_ns, params, sightings)
        if got is None:
            continue
        sids.append(sid)
        modes.append(got[0])
        seen[sid] = got[1]
        ends.append(len(out.local_id))
    return Aligned(
        t_ns=t_ns,
        sensor_ids=tuple(sids),
        modes=tuple(modes),
        offsets=np.array(ends, dtype=np.int64),
        values=np.array(out.values, dtype=np.float64).reshape(-1, ALIGNED_COLUMNS),
        local_id=np.array(out.local_id, dtype=np.int64),
        hist=out.hist,
        sightings=seen,
    )


def _past(
    out: _Columns, buf: SensorBuffer, before: Features, t_ns: int, params: AlignParams, *, want_s: bool
) -> tuple[str, list[AlignedSighting]] | None:
    """The blobs at ``t_ns`` from the frames up to ``before``, the nearest frame (none after it is nearer)."""
    half = params.max_extrapolation_ns
    if t_ns - before.stamp_ns > half:
        return None
    prev = buf.previous(before)
    if prev is not None and before.stamp_ns - prev.stamp_ns <= params.max_gap_ns:
        # Short constant-rate extrapolation past the newest frame, blob by blob.
        return "extrapolated", _pair(out, prev, before, t_ns, half, want_s=want_s)
    for b in before.blobs:
        out.add(b, before.stamp_ns, None, 0, t_ns)
    return "held", [_sighting_at(s, before.stamp_ns, None, 0, t_ns) for s in before.sightings if s.target_id and want_s]


def _align(
    out: _Columns, buf: SensorBuffer, t_ns: int, params: AlignParams, want_s: bool
) -> tuple[str, list[AlignedSighting]] | None:
    """One sensor's blobs at ``t_ns`` into ``out``; its mode and sightings, or None (nothing added) if it must sit
    this tick out."""
    newest = buf.newest_stamp()
    if newest is None or t_ns - newest > params.stale_ns:
        return None
    before, after = buf.bracket(t_ns)
    half = params.max_extrapolation_ns
    if before is not None and after is not None and after.stamp_ns - before.stamp_ns <= params.max_gap_ns:
        return "interpolated", _pair(
            out, before, after, t_ns, max(half, (after.stamp_ns - before.stamp_ns)), want_s=want_s
        )
    if before is not None and (after is None or t_ns - before.stamp_ns <= after.stamp_ns - t_ns):
        return _past(out, buf, before, t_ns, params, want_s=want_s)
    if after is not None and after.stamp_ns - t_ns <= half:
        for b in after.blobs:
            out.add(None, 0, b, after.stamp_ns, t_ns)
        return "held", [
            _sighting_at(None, 0, s, after.stamp_ns, t_ns) for s in after.sightings if s.target_id and want_s
        ]
    return None
