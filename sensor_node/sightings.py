"""Stage 7: sightings of the other robots' bodies, for mutual calibration (Eq. 3).

Each robot is a white cylinder of known radius R with a coloured marking band
(paper, "Dynamic Mutual Calibration": a body "with a distinctive appearance").
In the panorama:

1. **Find and identify**: pixels of each known body's band colour (hue within
   a tolerance, saturated, not dark) below the horizon; the widest run of
   columns holding them (the panorama wraps) is a candidate, accepted if it
   has ``band_min_px`` pixels and a band-like shape (rows:columns). The band
   colour names the robot (``[[body]]`` list).
2. **Occluding boundaries, sub-pixel**: across the band rows, the colour
   gradient magnitude |dI/du| (summed over channels, averaged over rows) peaks
   where the silhouette's edge is; a parabola through the peak and its two
   neighbours places it to a fraction of a pixel. Averaging over the rows
   beats the per-pixel noise, and the gradient peak is where the edge is
   whatever the (unknown) background level.
3. **Eq. (3)**: alpha = angle between the two boundary rays; B = R / sin(alpha/2)
   (exact for tangent rays); bearing = circular mean of the two boundaries
   (the paper's beta).

:func:`is_body_blob` tells the pipeline which motion blobs are a robot that
moves, so bodies are never reported as people; :class:`LeftPlaces` keeps where a
robot that stood in the background model drove off from, so its hole is not either.
"""

from __future__ import annotations

import colorsys
import math
from dataclasses import dataclass

import cv2
import numpy as np
import numpy.typing as npt

from common.angles import wrap_angle
from common.arrays import Image
from common.cameras import CylindricalCamera
from common.errors import GeometryError
from common.geometry import baseline_exact, sighting_bearing
from common.schema import Sighting
from sensor_node.config import BodySpec, PipelineSettings
from sensor_node.segmentation.blobs import roi
from sensor_node.unwarp import PanoFrame

__all__ = ["BandFinder", "BodySighting", "LeftPlaces", "drove_off", "is_body_blob"]


@dataclass(frozen=True, slots=True)
class BodySighting:
    """One robot body found in the panorama."""

    sighting: Sighting
    """The wire form (bearings in the sensor frame)."""
    left_col: float
    """Sub-pixel column of the boundary with the lower column (may exceed W across the seam)."""
    right_col: float
    band_rows: tuple[int, int]
    """First and last row of the band."""
    top_row: float = -math.inf
    """Row above which nothing of this robot can be (body, mast and camera head): a blob reaching
    higher is a person, not the robot."""


def _hue_ranges(rgb: list[int], tol_deg: float) -> list[tuple[int, int]]:
    """OpenCV hue intervals (0..179) within ``tol_deg`` of the colour's hue (split at the wrap)."""
    h, _, _ = colorsys.rgb_to_hsv(*(c / 255.0 for c in rgb))
    c = h * 180.0  # OpenCV hue: degrees / 2
    t = tol_deg / 4.0
    lo, hi = c - t, c + t
    if lo < 0:
        return [(0, math.floor(hi)), (math.ceil(lo + 180), MAX_HUE)]
    if hi > MAX_HUE:
        return [(math.ceil(lo), MAX_HUE), (0, math.floor(hi - 180))]
    return [(math.ceil(lo), math.floor(hi))]


def _runs(cols: npt.NDArray[np.bool_], wrap: bool) -> list[tuple[int, int]]:
    """(start, length) of runs of True; a run crossing the seam starts near W and wraps."""
    w = cols.size
    idx = np.flatnonzero(np.diff(np.concatenate([[0], cols.astype(np.int8), [0]])))
    runs = [(int(a), int(b - a)) for a, b in zip(idx[0::2], idx[1::2], strict=True)]
    if wrap and len(runs) > 1 and runs[0][0] == 0 and runs[-1][0] + runs[-1][1] == w:
        first, last = runs[0], runs[-1]
        runs = [(last[0], last[1] + first[1]), *runs[1:-1]]
    return runs


def _peak(g: npt.NDArray[np.float64], lo: int, hi: int) -> float | None:
    """Sub-pixel argmax of g in [lo, hi] by a parabola through the peak and its neighbours."""
    lo, hi = max(lo, 1), min(hi, g.size - 2)
    if hi < lo:
        return None
    k = lo + int(np.argmax(g[lo : hi + 1]))
    a, b, c = float(g[k - 1]), float(g[k]), float(g[k + 1])
    den = a - 2 * b + c
    off = 0.5 * (a - c) / den if den < 0 else 0.0
    return k + max(-0.5, min(0.5, off))


class BandFinder:
    """Finds the known robot bodies in panoramas of one camera.

    Args:
        bodies: the ``[[body]]`` list (id, band colour, radius, height).
        camera: the panorama's cylindrical camera.
        settings: ``band_min_px`` and ``band_tolerance`` knobs.
    """

    def __init__(self, bodies: list[BodySpec], camera: CylindricalCamera, settings: PipelineSettings) -> None:
        self.bodies = bodies
        self.camera = camera
        self.settings = settings
        tol_deg = 360.0 * settings.band_tolerance
        self._ranges = [_hue_ranges(b.band_rgb, tol_deg) for b in bodies]
        # Bands are below the camera: search from the horizon down.
        self.row0 = max(0, min(camera.height_px - 1, math.floor(camera.v0_px)))

    def find(self, frame: PanoFrame) -> list[BodySighting]:
        """Every known body visible in this frame (at most one per body).

        The colour search runs on the frame's reduced colour panorama; the
        boundaries are measured on full-resolution colour around the band only.
        """
        if not self.bodies:
            return []
        s = frame.scale
        r0s = self.row0 // s
        hs, ws = frame.grey.shape[0] // s, frame.grey.shape[1] // s
        lower = frame.small_box(0, r0s, ws, hs - r0s)
        hsv = cv2.cvtColor(lower, cv2.COLOR_BGR2HSV)
        out = []
        for body, ranges in zip(self.bodies, self._ranges, strict=True):
            mask = None
            for h0, h1 in ranges:
                m = cv2.inRange(hsv, (h0, 90, 50), (h1, 255, 255))
                mask = m if mask is None else cv2.bitwise_or(mask, m)
            assert mask is not None
            found = self._measure(frame, lower, mask, r0s, body)
            if found is not None:
                out.append(found)
        return out

    def _measure(self, frame: PanoFrame, lower: Image, mask: Image, r0s: int, body: BodySpec) -> BodySighting | None:
        s = frame.scale
        width_s = mask.shape[1]
        per_col = cv2.reduce(mask, 0, cv2.REDUCE_SUM, dtype=cv2.CV_32S).ravel() // 255
        min_px = max(1, self.settings.band_min_px // (s * s))
        if int(per_col.sum()) < min_px:
            return None
        cands = []
        for u0, n in _runs(per_col >= 1, wrap=True):
            count = int(per_col[np.arange(u0, u0 + n) % width_s].sum())
            if count >= min_px:
                cands.append((count, u0, n))
        # Most band pixels first; the first run that looks like a band on a white body wins.
        for _, u0, n in sorted(cands, reverse=True):
            rows = self._validate(lower, mask, r0s, u0, n)
            if rows is not None:
                r0, r1 = rows[0] * s, rows[1] * s + s - 1
                return self._boundaries(frame, body, (u0 * s, n * s), (r0, r1))
        return None

    def _validate(self, lower: Image, mask: Image, r0s: int, u0: int, n: int) -> tuple[int, int] | None:
        """Band rows (r0, r1) of a candidate run in the reduced image, or None if it is not a band on a white body.

        ``lower`` and ``mask`` are the reduced image's rows from ``r0s`` down.
        """
        band = roi(mask, u0, 0, n, mask.shape[0])
        # Band rows: at least half the run's columns are band-coloured (ignores the mast, logos, noise).
        rows = np.flatnonzero(np.count_nonzero(band, axis=1) >= max(1, n // 2))
        if rows.size == 0:
            return None
        r0, r1 = int(rows[0]), int(rows[-1])
        cut = r1 == mask.shape[0] - 1
        # A band cut by the image's lower edge (a near body seen steeply) is a sliver: only its top
        # rows are in view, so only its upper bound on the shape applies.
        if not (cut or (r1 - r0 + 1) / n >= BAND_MIN_ASPECT) or (r1 - r0 + 1) / n > BAND_MAX_ASPECT:
            return None  # not band-shaped
        if not _white_beside(lower, u0, n, r0, r1):
            return None  # the band colour without the white body around it (e.g. a shirt)
        return r0 + r0s, r1 + r0s

    def _band_agrees(self, body: BodySpec, rows: tuple[int, int], dist_m: float, height_px: int) -> bool:
        """True if the band's elevation puts it at the Eq. 3 range (within ``BAND_RANGE_TOL``).

        The body's design is known: its band spans heights z0..z1. Seen from the
        camera at height z_c, the band's middle row at elevation e is at horizontal
        range (z_c - (z0 + z1)/2) / tan(-e) from the optical centre, to the body's
        surface -- plus R to its axis. A band-coloured shirt, or a band cut by the
        image edge (too narrow a run: an absurd range), fails this. A band at the
        camera's own height says nothing about the range and is accepted.
        """
        z0, z1 = body.band_range_m
        drop_m = self.camera.height_m - 0.5 * (z0 + z1)
        r0, r1 = rows
        if r1 >= height_px - 1:
            # The band runs out of the image: its middle row is not the band's middle.
            top = math.tan(-float(self.camera.elevation_from_row(r0 - 0.5)))
            return top <= 0.0 or dist_m <= (1.0 + BAND_RANGE_TOL) * ((self.camera.height_m - z1) / top + body.radius_m)
        tan_dn = math.tan(-float(self.camera.elevation_from_row(0.5 * (r0 + r1))))
        if abs(drop_m) < LEVEL_BAND_M or tan_dn * drop_m <= 0.0:
            return abs(drop_m) < LEVEL_BAND_M
        band_m = drop_m / tan_dn + body.radius_m
        return abs(dist_m - band_m) <= BAND_RANGE_TOL * band_m

    def _boundaries(
        self, frame: PanoFrame, body: BodySpec, run: tuple[int, int], rows: tuple[int, int]
    ) -> BodySighting | None:
        """Sub-pixel occluding boundaries of the body around a band (full-resolution ``run``), and Eq. (3)."""
        width = self.camera.width_px
        (u0, n), (r0, r1) = run, rows
        # Sub-pixel boundaries from the colour gradient across the band rows (inner rows only).
        pad = 3 + frame.scale
        inner0, inner1 = (r0 + 1, r1 - 1) if r1 - r0 >= TRIM_ROWS_FROM else (r0, r1)
        if inner1 - inner0 < SLIVER_ROWS:
            # A sliver of band (cut by the image edge): the white body right above it has the same
            # silhouette; measure over both.
            inner0 = max(0, inner1 - SLIVER_ROWS)
        strip = frame.colour(u0 - pad, inner0, n + 2 * pad, inner1 - inner0 + 1).astype(np.float32)
        # |step| summed over the channels, then averaged over the rows: the channels added one by one (a sum
        # over an axis of three costs several times more) and the rows' sum divided by their count, as a mean.
        step = strip[:, 1:] - strip[:, :-1]
        np.abs(step, out=step)
        per_row = step[..., 0] + step[..., 1]
        per_row += step[..., 2]
        grad = (per_row.sum(axis=0) / np.float32(per_row.shape[0])).astype(np.float64)
        # grad[j] is the step between strip columns j and j+1: the boundary at column u0 - pad + j + 0.5.
        left = _peak(grad, 1, pad + frame.scale)
        right = _peak(grad, pad + n - frame.scale - 2, pad + n + pad - 2)
        if left is None or right is None or right - left < MIN_BODY_COLS:
            return None
        left_col = u0 - pad + left + 0.5
        right_col = u0 - pad + right + 0.5
        b_left = self.camera.bearing_from_col(left_col % width)
        b_right = self.camera.bearing_from_col(right_col % width)
        alpha = (right_col - left_col) / self.camera.f_h_px
        try:
            dist = baseline_exact(b_left, b_right, body.radius_m)  # Eq. (3)
        except GeometryError:
            return None
        if not self._band_agrees(body, rows, dist, frame.grey.shape[0]):
            return None
        sighting = Sighting(
            target_id=body.id,
            left_rad=wrap_angle(b_left),
            right_rad=wrap_angle(b_right),
            alpha_rad=float(alpha),
            bearing_rad=wrap_angle(sighting_bearing(b_left, b_right)),
            distance_m=float(min(dist, 1e5)),
            body_radius_m=float(body.radius_m),
        )
        # The robot's highest point: its body top, or its camera head (taken at this camera's height,
        # robots carry theirs alike) plus a margin; seen from the body's near side at the Eq. 3 range.
        z_top = max(body.height_m, self.camera.height_m) + ROBOT_TOP_MARGIN_M
        near_m = max(dist - body.radius_m, 0.05)
        top_row = float(self.camera.row_from_elevation(math.atan((z_top - self.camera.height_m) / near_m)))
        return BodySighting(sighting, left_col, right_col, (r0, r1), top_row)


ROBOT_TOP_MARGIN_M = 0.15
"""How far above its camera (or body top) a robot may reach in the image (mast cap, head housing)."""

SLIVER_ROWS = 6
"""Fewest rows the boundaries are measured on; a shorter band is extended up into the white body."""

BAND_RANGE_TOL = 0.3
"""Largest relative disagreement between the Eq. 3 range and the band-elevation range of one sighting."""

MAX_HUE = 179
"""OpenCV's 8-bit hue runs 0..179 (degrees / 2)."""
BAND_MIN_ASPECT = 0.15
"""A band's rows over its columns: below this it is a line, not the marking band (unless cut by the image
edge). Lower: thinner bands (far or steeply seen bodies) count, so do stripes on shirts."""
BAND_MAX_ASPECT = 1.5
"""...above this it is a column (a pole, a person in the band's colour). Higher: the opposite."""
LEVEL_BAND_M = 0.05
"""A band within this height of the camera's own is level with it: its elevation says nothing of its range."""
TRIM_ROWS_FROM = 4
"""A band at least this many rows high loses its top and bottom rows (mixed pixels) for the boundaries."""
MIN_BODY_COLS = 2
"""Occluding boundaries closer than this (px) are no body: Eq. (3)'s angle would be noise."""
WHITE_MAX_SAT = 60
"""The body above and below the band is white: median saturation (0..255) below this..."""
WHITE_MIN_VALUE = 110
"""...and median value (0..255) above this. Raise the value or lower the saturation: only bright white
bodies count (a shaded body is missed); the opposite: pale walls and shirts pass."""
BODY_CONTRAST = 20.0
"""...and it differs from what is on both sides of it by more than this grey level somewhere (a white
body stands out from the room; a band-coloured shirt below a pale wall has the wall on both sides)."""


def _white_beside(small: Image, u0: int, n: int, r0: int, r1: int) -> bool:
    """True if the band sits on a white body: right above it (or, out of view, below) the image is
    bright and unsaturated over the band's columns, and differs from what is beside them (a band-
    coloured shirt below a pale wall has the same wall above it on both sides)."""
    height, width = small.shape[:2]
    c0, cw = u0 + n // 4, max(1, n // 2)
    side = max(1, n // 3)
    for a, b in ((r0 - 3, r0 - 1), (r1 + 2, r1 + 4)):
        if a < 0 or b > height:
            continue
        inside = np.ascontiguousarray(roi(small, c0 % width, a, cw, b - a))
        hsv = cv2.cvtColor(inside, cv2.COLOR_BGR2HSV).reshape(-1, 3)
        if not (_median(hsv[:, 1]) < WHITE_MAX_SAT and _median(hsv[:, 2]) > WHITE_MIN_VALUE):
            return False
        level = float(inside.mean())
        left = roi(small, (u0 - 1 - side) % width, a, side, b - a)
        right = roi(small, (u0 + n + 1) % width, a, side, b - a)
        return max(abs(level - float(left.mean())), abs(level - float(right.mean()))) > BODY_CONTRAST
    return False


def _median(values: Image) -> float:
    """np.median of a few dozen values, without its fixed cost (several times the sort's here)."""
    s = np.sort(values)
    m = s.size // 2
    return float(s[m]) if s.size % 2 else (float(s[m - 1]) + float(s[m])) / 2.0


DROVE_OFF_FRAC = 0.25
"""Share of the columns a body covered that it no longer covers when it has driven off (its sightings' noise
is a fraction of a pixel; lower: a smaller move counts)."""


def drove_off(was: BodySighting, now: BodySighting, width_px: int) -> bool:
    """True if the body sighted at ``was`` has moved so that ``now`` leaves ``DROVE_OFF_FRAC`` of its columns free.

    Sideways or towards or away from the camera alike: the columns of ``was`` that ``now`` does not cover.
    """
    span = was.right_col - was.left_col
    if span <= 0:
        return False
    was_mid, now_mid = 0.5 * (was.left_col + was.right_col), 0.5 * (now.left_col + now.right_col)
    unwrap = was_mid + math.remainder(now_mid - was_mid, width_px) - now_mid  # the same side of the seam
    lo, hi = now.left_col + unwrap, now.right_col + unwrap
    covered = max(0.0, min(hi, was.right_col) - max(lo, was.left_col))
    return span - covered >= DROVE_OFF_FRAC * span


class LeftPlaces:
    """Where known robot bodies that stood in a background model have driven off from, for a while.

    A robot standing in view while the model was learnt is in the model; when it drives off, its place is a
    hole the model knows nothing of, changed like someone standing there until the ghost tests absorb it (at
    the latest ``still_absorb_frames`` later). Its sightings say where it stood and that it left: a blob
    there no taller than the robot was is its hole (:func:`is_body_blob` against the old sighting), not a
    person. Where a body is first sighted after the model was learnt is taken for where it stood then
    (someone in front of it may have hidden it at first); if it came later, its old place holds no hole.

    Args:
        width_px: the panorama's width (columns wrap).
        settings: ``still_absorb_frames``.
    """

    def __init__(self, width_px: int, settings: PipelineSettings) -> None:
        self.width_px = width_px
        self.settings = settings
        self._stood: dict[str, BodySighting | None] = {}
        """Per body: where it stood in the current model; None once it drove off."""
        self._left: list[tuple[BodySighting, int]] = []
        """Places bodies drove off from, with the last frame their hole may still show."""

    def reset(self) -> None:
        """The model is learnt afresh: whoever stands in view then is in it."""
        self._stood, self._left = {}, []

    def update(self, sightings: list[BodySighting], frame: int) -> list[BodySighting]:
        """Follow one frame's sightings (of a learnt model); returns the places left lately (as sightings)."""
        for now in sightings:
            target = now.sighting.target_id
            if not target:
                continue
            if target not in self._stood:
                self._stood[target] = now
                continue
            was = self._stood[target]
            if was is not None and drove_off(was, now, self.width_px):
                self._left.append((was, frame + self.settings.still_absorb_frames))
                self._stood[target] = None  # it stands nowhere in this model any more
        self._left = [(b, last) for b, last in self._left if frame <= last]
        return [b for b, _ in self._left]


def is_body_blob(
    u0: int, w: int, width_px: int, sightings: list[BodySighting], *, margin_px: float = 3.0, v0: int | None = None
) -> bool:
    """True if a blob spanning columns [u0, u0 + w) (top row ``v0``) is mostly a sighted robot (the robot moved).

    A blob is the robot when at least 60 % of its columns lie within the body's
    boundaries (plus a margin), it is not much wider than the body (a person
    in front of a robot is wider than the robot's share of the blob), and it
    does not reach above the robot's top (a person walking behind or in front
    of a robot is as wide as it at a few metres, but taller).
    """
    for s in sightings:
        if v0 is not None and v0 < s.top_row - margin_px:
            continue
        lo, hi = s.left_col - margin_px, s.right_col + margin_px
        body_w = s.right_col - s.left_col
        if w > 1.6 * body_w + 2 * margin_px:
            continue
        for shift in (0, width_px, -width_px):
            a, b = u0 + shift, u0 + w + shift
            overlap = max(0.0, min(b, hi) - max(a, lo))
            if overlap >= 0.6 * w:
                return True
    return False
