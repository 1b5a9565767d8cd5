"""Connected regions of a binary mask, with their boxes and areas (used by grouping and the ghost tests)."""

from __future__ import annotations

from typing import Any

import cv2
import numpy as np
import numpy.typing as npt

__all__ = ["components"]

Mask = npt.NDArray[Any]


def components(mask: Mask) -> tuple[int, Mask, npt.NDArray[np.int32]]:
    """The 8-connected regions of a mask: what ``cv2.connectedComponentsWithStats(mask, connectivity=8)``
    returns (count, labels, stats: left, top, width, height, area; the background's row left zero).

    OpenCV's statistics pass costs several times its labelling (0.27 against 0.04 ms on a reduced
    panorama mask); each region's box comes instead from its outer contour and its area from its
    labels inside that box.
    """
    n, labels = cv2.connectedComponents(mask, connectivity=8, ltype=cv2.CV_32S)
    stats = np.zeros((n, 5), np.int32)
    if n <= 1:
        return n, labels, stats
    contours, hierarchy = cv2.findContours(mask, cv2.RETR_CCOMP, cv2.CHAIN_APPROX_SIMPLE)
    outer = [c for c, h in zip(contours, hierarchy[0].tolist(), strict=True) if h[3] < 0]  # not a hole's
    for contour in outer:
        x, y = contour[0, 0].tolist()
        stats[labels[y, x], :4] = cv2.boundingRect(contour)
    if n > MANY_REGIONS:
        stats[:, 4] = np.bincount(labels.ravel(), minlength=n)
    else:
        for k in range(1, n):
            u, v, w, h = stats[k, :4].tolist()
            stats[k, 4] = np.count_nonzero(labels[v : v + h, u : u + w] == k)
    stats[0] = 0
    return n, labels, stats


MANY_REGIONS = 12
"""Regions beyond which areas come from one count over the whole label image, not one per region's box."""
