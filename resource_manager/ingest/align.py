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
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

from common.angles import angle_diff, interp_angle, wrap_angle
from common.schema import Blob, Features, Sighting
from resource_manager.config import ManagerSection, default_of
from resource_manager.ingest.buffers import SensorBuffer

__all__ = ["AlignParams", "AlignedBlob", "AlignedSighting", "AlignedView", "align_sensor"]


@dataclass(frozen=True, slots=True)
class AlignParams:
    """``[manager]``'s alignment limits in ns (defaulted and documented in
    :class:`resource_manager.config.ManagerSection`)."""

    max_extrapolation_ns: int = int(default_of(ManagerSection, "max_extrapolation_ms") * 1e6)
    stale_ns: int = int(default_of(ManagerSection, "stale_ms") * 1e6)
    max_gap_ns: int = int(default_of(ManagerSection, "max_gap_ms") * 1e6)


class AlignedBlob(NamedTuple):
    """One blob at the fusion instant (immutable; a NamedTuple: one is built per blob, sensor and tick, and a
    frozen dataclass's __init__ costs several times more)."""

    local_id: int
    bearing_rad: float
    """Sensor-frame azimuth at the fusion instant."""
    width_rad: float
    top_elev_rad: float
    bottom_elev_rad: float
    hist: list[float]
    feet_visible: bool
    bottom_px: float = -1.0
    """Image row of the blob's bottom edge (bbox_v + bbox_h; -1: unknown): a box cut by the image's lower
    border does not show the feet, whatever the node says."""
    top_px: float = -1.0
    """Image row of the blob's top edge (-1: unknown): 0 means the head is cut by the upper border."""
    confidence: float = 1.0
    """The node's confidence in the blob (a detector's score): the lower of the two frames'."""


@dataclass(frozen=True, slots=True)
class AlignedSighting:
    target_id: str
    left_rad: float
    right_rad: float
    body_radius_m: float


@dataclass(frozen=True, slots=True)
class AlignedView:
    """One sensor's observations at the fusion instant."""

    sensor_id: str
    t_ns: int
    blobs: list[AlignedBlob]
    sightings: list[AlignedSighting]
    mode: str
    """interpolated | extrapolated | held."""


def _blob_at(b0: Blob | None, t0: int, b1: Blob | None, t1: int, t: int) -> AlignedBlob:
    if b0 is not None and b1 is not None:
        # interp_linear / interp_angle (common.clock) written out with the fraction computed once, and the
        # tuple built positionally: this runs for every blob of every sensor on every tick.
        f = (t - t0) / (t1 - t0) if t1 != t0 else 1.0
        bearing0 = b0.bearing_rad
        step = angle_diff(b1.bearing_rad, bearing0)
        width0, top0, bottom0 = b0.width_rad, b0.top_elev_rad, b0.bottom_elev_rad
        v0, v1 = b0.bbox_v_px, b1.bbox_v_px
        return AlignedBlob(
            b1.local_id,
            wrap_angle(bearing0 + step * f),
            max(0.0, width0 + (b1.width_rad - width0) * f),
            top0 + (b1.top_elev_rad - top0) * f,
            bottom0 + (b1.bottom_elev_rad - bottom0) * f,
            b1.hist if abs(t1 - t) <= abs(t - t0) else b0.hist,  # the frozen message's list: not copied
            b0.feet_visible and b1.feet_visible,
            max(v0 + b0.bbox_h_px, v1 + b1.bbox_h_px),
            min(v0, v1),
            min(b0.confidence, b1.confidence),
        )
    b = b1 if b1 is not None else b0
    assert b is not None
    return AlignedBlob(
        b.local_id,
        b.bearing_rad,
        b.width_rad,
        b.top_elev_rad,
        b.bottom_elev_rad,
        b.hist,
        b.feet_visible,
        b.bbox_v_px + b.bbox_h_px,
        b.bbox_v_px,
        b.confidence,
    )


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
    f0: Features, f1: Features, t: int, max_one_sided_ns: int, want_s: bool = True
) -> tuple[list[AlignedBlob], list[AlignedSighting]]:
    """Interpolate (or extrapolate) between two frames; one-sided blobs only near their own frame."""
    t0, t1 = f0.stamp_ns, f1.stamp_ns
    by0 = {b.local_id: b for b in f0.blobs}
    by1 = {b.local_id: b for b in f1.blobs}
    blobs: list[AlignedBlob] = []
    # A blob in one frame only (the person appeared, left, or the node's 2D track changed id) is taken
    # from its own frame only when that frame is the nearer one: otherwise, at low frame rates, the
    # same person would be there twice (old id from one frame, new id from the other) -- a ghost.
    near1 = abs(t1 - t) <= abs(t - t0)
    for lid, b1 in by1.items():
        b0 = by0.get(lid)
        if b0 is not None:
            blobs.append(_blob_at(b0, t0, b1, t1, t))
        elif abs(t1 - t) <= max_one_sided_ns and near1:
            blobs.append(_blob_at(None, t0, b1, t1, t))
    for lid, b0 in by0.items():
        if lid not in by1 and abs(t - t0) <= max_one_sided_ns and t1 > t and not near1:
            blobs.append(_blob_at(b0, t0, None, t1, t))
    if not want_s:
        return blobs, []
    s0 = {s.target_id: s for s in f0.sightings if s.target_id}
    s1 = {s.target_id: s for s in f1.sightings if s.target_id}
    sightings = [_sighting_at(s0.get(k), t0, s, t1, t) for k, s in s1.items()]
    sightings += [_sighting_at(s, t0, None, t1, t) for k, s in s0.items() if k not in s1 and t1 > t]
    return blobs, sightings


def align_sensor(
    buf: SensorBuffer, sensor_id: str, t_ns: int, params: AlignParams, sightings: bool = True
) -> AlignedView | None:
    """The sensor's blobs and sightings at ``t_ns``, or None if it must sit this tick out.

    Args:
        buf: the sensor's frames, sorted by stamp.
        sensor_id: for the result.
        t_ns: the fusion instant.
        params: extrapolation, staleness and gap limits.
        sightings: False skips the sightings (every pose is surveyed: mutual calibration has nothing to do).
    """
    return _align(buf, sensor_id, t_ns, params, sightings)


def _past(
    buf: SensorBuffer, before: Features, sensor_id: str, t_ns: int, params: AlignParams, *, want_s: bool
) -> AlignedView | None:
    """The blobs at ``t_ns`` from the frames up to ``before``, the nearest frame (none after it is nearer)."""
    half = params.max_extrapolation_ns
    if t_ns - before.stamp_ns > half:
        return None
    prev = buf.previous(before)
    if prev is not None and before.stamp_ns - prev.stamp_ns <= params.max_gap_ns:
        # Short constant-rate extrapolation past the newest frame, blob by blob.
        blobs, sightings = _pair(prev, before, t_ns, half, want_s)
        return AlignedView(sensor_id, t_ns, blobs, sightings, "extrapolated")
    return AlignedView(
        sensor_id,
        t_ns,
        [_blob_at(b, before.stamp_ns, None, 0, t_ns) for b in before.blobs],
        [_sighting_at(s, before.stamp_ns, None, 0, t_ns) for s in before.sightings if s.target_id and want_s],
        "held",
    )


def _align(buf: SensorBuffer, sensor_id: str, t_ns: int, params: AlignParams, want_s: bool) -> AlignedView | None:
    newest = buf.newest_stamp()
    if newest is None or t_ns - newest > params.stale_ns:
        return None
    before, after = buf.bracket(t_ns)
    half = params.max_extrapolation_ns
    if before is not None and after is not None and after.stamp_ns - before.stamp_ns <= params.max_gap_ns:
        blobs, sightings = _pair(before, after, t_ns, max(half, (after.stamp_ns - before.stamp_ns)), want_s)
        return AlignedView(sensor_id, t_ns, blobs, sightings, "interpolated")
    if before is not None and (after is None or t_ns - before.stamp_ns <= after.stamp_ns - t_ns):
        return _past(buf, before, sensor_id, t_ns, params, want_s=want_s)
    if after is not None and after.stamp_ns - t_ns <= half:
        return AlignedView(
            sensor_id,
            t_ns,
            [_blob_at(None, 0, b, after.stamp_ns, t_ns) for b in after.blobs],
            [_sighting_at(None, 0, s, after.stamp_ns, t_ns) for s in after.sightings if s.target_id and want_s],
            "held",
        )
    return None
