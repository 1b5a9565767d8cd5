"""Connected regions of a binary mask, with their boxes and areas (used by grouping and the ghost tests)."""

from __future__ import annotations

from typing import Any, cast

import cv2
import numpy as np
import numpy.typing as npt

__all__ = ["components"]

Mask = npt.NDArray[Any]


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
