"""Ghost tests of the background model: the surface beside a still region, and undoing a wrong absorption.

Used by :mod:`sensor_node.background.model` (stage 2). A *ghost* is a changed region
where something that was in the background left (a person who stood still
while the model was learnt). The helpers:

* :func:`surround_deviation` -- how far the frame and the model inside a still
  region are from the surface beside it: a hole shows in the frame what
  continues on both sides, while the model still holds whoever left;
  :func:`start_up_hole` judges a region changed since the model was young by it, and
  :func:`hole_columns` each column of one that holds both a hole and the one walking out of it;
* :class:`UnderGhosts` -- the model as it was under absorbed ghosts, put back
  where the frame shows it again (the absorption was a mistake: someone in
  front of a narrow bright window looks like a ghost of the window).
"""

from __future__ import annotations

import logging

import cv2
import numpy as np
import numpy.typing as npt

from common.arrays import BoolArray, Float32Array, FloatArray, Mask
from sensor_node.components import components

__all__ = ["UnderGhosts", "hole_columns", "start_up_hole", "surround_deviation"]

logger = logging.getLogger(__name__)


SIDE_PX = 8
"""Columns either side of a still region whose unchanged model pixels stand for the surface around it."""

SURROUND_GHOST = 0.5
"""A still region whose frame is this much closer (grey-level deviation ratio) to the surface beside it than
the model is, is a ghost: a hole left by someone who walked away."""

SURROUND_MIN_DEV = 15.0
"""Mean grey-level deviation from the surface beside a still region that is a clear departure (the model
holds someone there, or the frame does); below it, the surface continues."""

SIDE_MIN_PX = 3
"""Fewest unchanged pixels beside a still region on one row for their mean to stand for the surface there."""

MIN_COLUMN_PX = 5
"""Fewest pixels of a region in one column (on rows with side pixels) for :func:`hole_columns` to judge it."""

RESTORE_FRAMES = 90
"""Frames (6 s at 15 fps) for which the model from under an absorbed ghost is kept for putting back."""

RESTORE_MATCH = 0.7
"""Fraction of a still region over an absorbed ghost that must match the model from before for it to be put back."""

_K5 = np.ones((5, 5), np.uint8)


def _beside(
    grey: Mask, bg: Mask, fg: Mask, mask: npt.NDArray[np.bool_], origin: tuple[int, int]
) -> tuple[Float32Array, Float32Array, BoolArray, BoolArray, FloatArray]:
    """A still region's box widened by ``SIDE_PX`` on both sides (wrapping round the panorama): the frame and
    the model there as floats, the region's pixels, the rows with ``SIDE_MIN_PX`` unchanged pixels beside it
    (clear of its edge), and the model's mean over those pixels on each of those rows (the surface there)."""
    x, y = origin
    h, w = mask.shape
    cols = np.arange(x - SIDE_PX, x + w + SIDE_PX) % grey.shape[1]
    rows = slice(y, y + h)
    g = grey[rows][:, cols].astype(np.float32)
    b = bg[rows][:, cols].astype(np.float32)
    inside = np.zeros(g.shape, bool)
    inside[:, SIDE_PX : SIDE_PX + w] = mask
    side = (fg[rows][:, cols] == 0) & ~cv2.dilate(inside.astype(np.uint8), _K5).astype(bool)
    n_side = side.sum(axis=1)
    ok = n_side >= SIDE_MIN_PX
    side_mean = (b * side).sum(axis=1)[ok] / n_side[ok]
    return g, b, inside, ok, side_mean


def surround_deviation(
    grey: Mask, bg: Mask, fg: Mask, mask: npt.NDArray[np.bool_], origin: tuple[int, int]
) -> tuple[float, float]:
    """How far the frame and the model inside a still region are from the background beside it.

    Row by row (walls, floors and their edges run across a panorama's rows), the
    mean grey level of the region's pixels -- in the current frame and in the
    model -- is compared with the mean of the model's unchanged pixels up to
    ``SIDE_PX`` columns left and right of the region on that row (wrapping). A
    hole left by someone who walked away shows, in the frame, the surface that
    continues on both sides (small frame deviation) while the model still holds
    the person (large model deviation); a person who stands still is the reverse.

    Args:
        grey: the frame (H, W) uint8.
        bg: the model (H, W) uint8.
        fg: the changed pixels (255) of the frame.
        mask: the region inside its bounding box.
        origin: (column, row) of the box's top-left corner.

    Returns:
        (frame deviation, model deviation): pixel-weighted mean absolute grey-level
        differences over the rows that have both region and side pixels (0, 0 if none).
    """
    g, b, inside, sided, side_mean = _beside(grey, bg, fg, mask, origin)
    n_in = inside.sum(axis=1)
    ok = (n_in > 0) & sided
    if not ok.any():
        return 0.0, 0.0
    side_mean = side_mean[ok[sided]]
    weight = n_in[ok].astype(np.float32)
    cur_mean = (g * inside).sum(axis=1)[ok] / weight
    bg_mean = (b * inside).sum(axis=1)[ok] / weight
    total = float(weight.sum())
    dev_cur = float((np.abs(cur_mean - side_mean) * weight).sum()) / total
    dev_bg = float((np.abs(bg_mean - side_mean) * weight).sum()) / total
    return dev_cur, dev_bg


def hole_columns(
    grey: Mask, bg: Mask, fg: Mask, mask: npt.NDArray[np.bool_], origin: tuple[int, int]
) -> npt.NDArray[np.bool_]:
    """The columns of a still region (in its box) that are a start-up hole, each judged on its own.

    Someone who stood while the model was learnt and walks off is beside their hole for a while: the
    still inside of them (a plain shirt does not change from frame to frame) and the hole behind them
    make one region, which is neither a hole nor a person as a whole. Column by column they part: in
    the hole's columns the frame continues the surface beside the region and the model departs from
    it; in the person's the reverse. Each column's frame and model deviations are the mean absolute
    grey-level differences of its region pixels from the row's side surface (as
    :func:`surround_deviation`). Only a clear hole counts (the model departs by ``SURROUND_MIN_DEV``, the
    frame is ``SURROUND_GHOST`` as close): a column where neither departs is the edge of whoever stands
    there, not a hole (:func:`start_up_hole`'s undecided case is for whole regions).

    Args: as :func:`surround_deviation`.

    Returns:
        One flag per column of the box: a hole there (False where no row has side pixels to compare).
    """
    g, b, inside, ok, side_mean = _beside(grey, bg, fg, mask, origin)
    w = mask.shape[1]
    out = np.zeros(w, bool)
    if not ok.any():
        return out
    ins = inside[ok][:, SIDE_PX : SIDE_PX + w]
    n_col = ins.sum(axis=0)
    have = n_col >= MIN_COLUMN_PX
    if not have.any():
        return out
    dev_cur = (np.abs(g[ok][:, SIDE_PX : SIDE_PX + w] - side_mean[:, None]) * ins).sum(axis=0)
    dev_bg = (np.abs(b[ok][:, SIDE_PX : SIDE_PX + w] - side_mean[:, None]) * ins).sum(axis=0)
    dev_cur = dev_cur / np.maximum(n_col, 1)
    dev_bg = dev_bg / np.maximum(n_col, 1)
    out[:] = have & (dev_bg >= SURROUND_MIN_DEV) & (dev_cur <= SURROUND_GHOST * dev_bg)
    return out


def start_up_hole(dev_cur: float, dev_bg: float) -> bool:
    """A region changed ever since the background model was young is a start-up hole, by the surface beside it.

    Args:
        dev_cur: how far the frame inside the region is from the surface beside it.
        dev_bg: how far the model is (both from :func:`surround_deviation`).

    A hole: the model departs clearly (``SURROUND_MIN_DEV``) and the frame is
    twice as close (``SURROUND_GHOST``: someone stood through the warm-up and
    left), or the frame continues the surface and the model is not twice as
    close. The latter is the remnant of a hole where the one who left looks like
    the surface around: a grey shirt held where the frame now shows the bright
    corner of the ceiling, at the edge of both (ceiling beside it on one side,
    wall on the other); the surface decides nothing, and a region changed since
    the model was young is then more likely a hole than someone who came in just
    then and stands. Someone who does departs from the surface clearly while the
    model does not -- or both do (a shirt in front of a poster): no hole.
    """
    frame_closer = dev_bg >= SURROUND_MIN_DEV and dev_cur <= SURROUND_GHOST * dev_bg
    undecided = dev_cur < SURROUND_MIN_DEV and dev_bg >= SURROUND_GHOST * dev_cur
    return frame_closer or undecided


class UnderGhosts:
    """The background model as it was under absorbed ghosts, put back where the frame shows it again.

    A still region wrongly taken for a ghost (a person standing in front of a
    narrow bright window: the model's outline there is the window's, the
    frame's is flat) is painted into the model; when the person walks on, the
    window reappears as a changed, still region with its outline in the frame:
    a paused person to the ghost test, reported for up to ``still_keep_frames``.
    Keeping what the absorption overwrote (for ``RESTORE_FRAMES``: someone
    wrongly absorbed walks on soon, and an old copy must not come back with
    whoever stands there much later) lets a still region that the frame matches
    again (``RESTORE_MATCH`` of its pixels) get it back at once.
    """

    def __init__(self, shape: tuple[int, int]) -> None:
        self._under = np.zeros(shape, np.float32)
        self._under_u8 = np.zeros(shape, np.uint8)
        """``_under`` as 8-bit grey levels, for matching frames (updated where ``keep`` writes)."""
        self._mask = np.zeros(shape, np.uint8)
        self._frame = np.zeros(shape, np.int32)
        self._newest = -RESTORE_FRAMES - 1
        """Frame of the latest ``keep``: once it is ``RESTORE_FRAMES`` old, nothing is kept."""

    def expired(self, frame: int) -> bool:
        """Everything kept is older than ``RESTORE_FRAMES`` at ``frame``: nothing can be put back any more."""
        return self._newest < frame - RESTORE_FRAMES

    def keep(
        self, origin: tuple[int, int], take: npt.NDArray[np.bool_], sub: npt.NDArray[np.float32], frame: int
    ) -> None:
        """Remember the model ``sub`` (box at ``origin`` = (column, row)) on ``take`` before it is overwritten."""
        x0, y0 = origin
        h, w = take.shape
        box = (slice(y0, y0 + h), slice(x0, x0 + w))
        first = take & (self._mask[box] == 0)  # the model from before the first absorption
        self._under[box][first] = sub[first]
        self._under_u8[box] = cv2.convertScaleAbs(self._under[box])
        self._frame[box][first] = frame
        self._mask[box][take] = 255
        self._newest = max(self._newest, frame)

    def restore(
        self, grey: Mask, still: Mask, bg: npt.NDArray[np.float32], *, frame: int, match_level: int, least_px: int
    ) -> tuple[Mask | None, int]:
        """Put the kept model back into ``bg`` (in place) on still regions that the frame matches again.

        Args:
            grey: the frame.
            still: its changed, not moving pixels (255).
            bg: the float background model, updated in place.
            frame: the model's frame count now.
            match_level: grey levels within which a frame pixel matches the kept model (``fg_threshold``).
            least_px: the least region (pixels) tested: a whole object, not a few pixels of a passing shirt.

        Returns:
            255 where the model was put back (None if nowhere), and how many regions were. Returns at
            once (no image work) when everything kept has expired.
        """
        if self.expired(frame):
            return None, 0
        # Everything is done in the box of what is kept (a few regions of a large image); what is too old
        # to put back is forgotten.
        mx, my, mw, mh = cv2.boundingRect(self._mask)
        if mw == 0:
            return None, 0
        kept = (slice(my, my + mh), slice(mx, mx + mw))
        self._mask[kept][self._frame[kept] < frame - RESTORE_FRAMES] = 0
        cand = cv2.bitwise_and(still[kept], self._mask[kept])
        if cv2.countNonZero(cand) < least_px:
            return None, 0
        n, labels, stats = components(cand)
        done: Mask | None = None
        regions = 0
        for k in range(1, n):
            x, y, w, h, area = (int(v) for v in stats[k])
            if area < least_px:
                continue
            comp = labels[y : y + h, x : x + w] == k
            x, y = x + mx, y + my
            box = (slice(y, y + h), slice(x, x + w))
            near = cv2.absdiff(grey[box], self._under_u8[box]) <= match_level
            if np.count_nonzero(near[comp]) < RESTORE_MATCH * area:
                continue
            bg[box][comp] = self._under[box][comp]
            self._mask[box][comp] = 0
            if done is None:
                done = np.zeros_like(self._mask)
            done[box][comp] = 255
            regions += 1
            logger.debug("background under a ghost of %d px at column %d put back (the frame shows it)", area, x)
        return done, regions
