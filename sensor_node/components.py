"""Connected regions of a binary mask, with their boxes and areas (used by grouping and the ghost tests)."""

from __future__ import annotations

import bisect
from typing import cast

import cv2
import numpy as np
import numpy.typing as npt

from common.arrays import Mask

__all__ = ["ColumnRuns", "components", "packed_components"]


def components(mask: Mask) -> tuple[int, Mask, npt.NDArray[np.int32]]:
    """The 8-connected regions of a mask: what ``cv2.connectedComponentsWithStats(mask, connectivity=8)``
    returns (count, labels, stats: left, top, width, height, area; the background's row left zero).

    Labels are 16-bit where they fit: OpenCV's statistics pass is several times faster with them than with
    32-bit labels (``benchmarks/NOTES.md``). Regions of an 8-connected labelling touch not even at a
    corner, so a mask has at most one per 2 x 2 block of pixels.
    """
    height, width = mask.shape[:2]
    ltype = cv2.CV_16U if ((height + 1) // 2) * ((width + 1) // 2) < np.iinfo(np.uint16).max else cv2.CV_32S
    n, labels, stats, _ = cv2.connectedComponentsWithStats(mask, connectivity=8, ltype=ltype)
    stats[0] = 0
    return n, labels, cast("npt.NDArray[np.int32]", stats)


class ColumnRuns:
    """A mask's columns that hold set pixels, in runs set side by side (:meth:`pack`), and the way back.

    Runs at least ``2 * margin + 2`` empty columns apart are packed with ``margin`` empty columns on each
    side (the first run from the mask's first column, the last to its last, so the mask's edges stay
    edges); each run is shifted by an even number of columns. Labelling scans the packed mask's pixels
    only; its regions are the mask's, and in the same order: 8-connected labelling assigns labels block by
    block of 2 x 2 pixels, in raster order of the blocks, which even shifts keep.

    Args:
        mask: 8-bit, set pixels nonzero.
        margin: empty columns kept beside each run (a filter applied to the packed mask then sees what it
            would see in the mask within ``margin`` columns of each run).
    """

    __slots__ = ("runs", "starts")

    def __init__(self, mask: Mask, margin: int) -> None:
        cols = np.flatnonzero(cv2.reduce(mask, 0, cv2.REDUCE_SUM, dtype=cv2.CV_32S).ravel())
        breaks = np.flatnonzero(np.diff(cols) > 2 * margin + 2).tolist() if cols.size else []
        firsts = [int(cols[0]), *(int(cols[b + 1]) for b in breaks)] if cols.size else []
        lasts = [*(int(cols[b]) for b in breaks), int(cols[-1])] if cols.size else []
        self.runs: list[tuple[int, int, int]] = []
        """(first mask column, first packed column, columns) of each run."""
        packed = 0
        for i, (first, last) in enumerate(zip(firsts, lasts, strict=True)):
            a = 0 if i == 0 else first - margin
            b = mask.shape[1] if i == len(firsts) - 1 else last + 1 + margin
            a -= (a - packed) % 2
            self.runs.append((a, packed, b - a))
            packed += b - a
        self.starts = [p for _, p, _ in self.runs]

    @property
    def apart(self) -> bool:
        """More than one run: packing leaves columns out."""
        return len(self.runs) > 1

    def pack(self, mask: Mask) -> Mask:
        """The runs' columns of ``mask`` (this mask, or one of its size) side by side."""
        return np.concatenate([mask[:, a : a + n] for a, _, n in self.runs], axis=1)

    def unpack(self, packed_col: int) -> int:
        """The mask column of a packed one (within a run)."""
        a, p, _ = self.runs[bisect.bisect_right(self.starts, packed_col) - 1]
        return packed_col + a - p


def packed_components(mask: Mask) -> tuple[int, npt.NDArray[np.int32]]:
    """:func:`components`' count and statistics (in ``mask``'s coordinates), labelling the columns that hold
    set pixels only (:class:`ColumnRuns`): a mask of a few regions far apart costs a fraction."""
    runs = ColumnRuns(mask, 1)
    if not runs.apart:
        n, _, stats = components(mask)
        return n, stats
    n, _, stats = components(runs.pack(mask))
    for k in range(1, n):
        stats[k, 0] = runs.unpack(int(stats[k, 0]))
    return n, stats
