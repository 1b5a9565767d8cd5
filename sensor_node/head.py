"""Stage 4: head extraction (paper, "Head extraction and blob representation").

The bearing of a whole blob moves with arms and legs; the head is almost
symmetric from every viewpoint, usually visible and easy to separate from the
background. So the bearing reported for a blob is its head's: the topmost part
of the blob with a fixed height:width ratio (3:2 in the paper). The exact head
height does not matter much since only its bearing is used.

Head width is taken from the blob's topmost rows (the crown of the head), the
head box is then ``head_ratio`` times as tall, and the head column is the
centroid of the blob pixels inside that box -- a sub-pixel estimate, robust to
a ragged silhouette edge. Given the difference to the background, the head
column comes instead from the two ends of each of the box's upper rows, each
placed to sub-pixel precision from its partly covered edge pixels: the
thresholded mask rounds ends to whole pixels and loses more of a faint edge
(a face near the wall's brightness) than of a contrasted one (hair), a bias of
0.3 px on the rendered sites (``benchmarks/bench_node_quality.py``).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

__all__ = ["DiffRows", "Head", "extract_head"]


@dataclass(frozen=True, slots=True)
class Head:
    """The head part of one blob, in the blob box's pixel coordinates (pixel centres at integers)."""

    u_px: float
    """Centroid column of the head pixels (sub-pixel)."""
    v_px: float
    """Centroid row of the head pixels."""
    top_px: int
    """First row of the head (the blob's top row)."""
    width_px: int
    height_px: int


DiffRows = Callable[[int, int], npt.NDArray[np.float32]]
"""``diff(r0, r1)``: rows [r0, r1) of the signed difference frame - background over the blob's box
widened by one column each side, shape (r1 - r0, w + 2)."""


def extract_head(mask: npt.NDArray[np.bool_], head_ratio: float = 1.5, diff: DiffRows | None = None) -> Head:
    """Find the head of a blob given its (h, w) pixel mask.

    Args:
        mask: blob pixels inside its bounding box (at least one pixel set).
        head_ratio: head height / head width (paper: 3:2 = 1.5).
        diff: optional rows of the signed difference to the background (:data:`DiffRows`): the
            head column then comes from each of the top ``HEAD_EDGE_ROWS`` head rows' ends placed
            to sub-pixel precision from the partly covered edge pixels (:func:`_row_edges`), not
            from the thresholded mask's whole pixels.
    """
    height, width = mask.shape
    if height and mask[0].any() and mask[-1].any():
        top, h = 0, height  # a box trimmed to its pixels (every blob's)
    else:
        rows = np.flatnonzero(mask.any(axis=1))
        if rows.size == 0:
            raise ValueError("extract_head needs a non-empty blob mask")
        top = int(rows[0])
        h = int(rows[-1]) - top + 1
    # Crown rows: about the top tenth of the body, at least 2 rows; their extents give the head width.
    k = max(2, min(h, round(0.1 * h)))
    crown = mask[top : top + k]
    first = crown.argmax(axis=1)
    last = width - 1 - crown[:, ::-1].argmax(axis=1)
    widths = sorted((last - first + 1)[crown.any(axis=1)].tolist())
    head_w = max(2, widths[len(widths) // 2])
    head_h = max(2, min(h, round(head_ratio * head_w)))
    region = mask[top : top + head_h]
    # Per-row pixel centroids, averaged over the rows that are head-wide (a shoulder row that
    # slipped into the box would pull the centroid towards the body). The head's few dozen rows
    # as plain ints: cheaper than a handful of array operations on them.
    counts: list[int] = np.count_nonzero(region, axis=1).tolist()
    most = max(1.5 * head_w, 2)
    row_v = [v for v, n in enumerate(counts) if 0 < n <= most] or [v for v, n in enumerate(counts) if n > 0]
    if diff is not None and HEAD_EDGE_ROWS > 0:
        # The crown half: hair all round, so the same contrast on both sides (the face, often
        # close to the wall's brightness, is lower down and on one side only).
        edge_v = row_v[: max(1, math.ceil(HEAD_EDGE_ROWS * head_h))]
        v0, v1 = edge_v[0], edge_v[-1] + 1
        d = diff(top + v0, top + v1)
        if v1 - v0 == len(edge_v):  # consecutive rows (most heads): slices, not gathers
            row_u = _row_edges(region[v0:v1], d)
        else:
            row_u = _row_edges(region[edge_v], d[[v - v0 for v in edge_v]])
    else:
        row_u = (region[row_v] @ np.arange(width, dtype=np.float64)) / np.asarray(counts)[row_v]
    return Head(
        u_px=float(row_u.sum()) / row_u.size,
        v_px=sum(row_v) / len(row_v) + top,
        top_px=top,
        width_px=head_w,
        height_px=head_h,
    )


HEAD_EDGE_ROWS = 0.5
"""Fraction of the head box's rows (from the top) whose sub-pixel edges give the head column."""


def _row_edges(rows: npt.NDArray[np.bool_], diff: npt.NDArray[np.float32]) -> npt.NDArray[np.float64]:
    """Sub-pixel centre of each row's silhouette from its two ends and their partly covered pixels.

    A sensor pixel on the silhouette's edge integrates object and background, so its difference
    to the background is the covered fraction of the inside's: alpha = d(edge) / d(inside), clipped
    to [0, 1]. The left end of a run starting at column l is then ``l - 0.5 + (1 - alpha_l) -
    alpha_{l-1}`` (column l partly covered, column l - 1 below the threshold but partly covered),
    and likewise on the right. The thresholded mask alone rounds each end to a whole pixel, and
    on the side where the contrast is lower it drops more of the edge: a bias towards the
    contrasted side of the head (hair against a pale wall).

    Args:
        rows: (n, w) mask rows (each with at least one pixel set).
        diff: (n, w + 2) signed frame - background differences, one extra column each side.
    """
    w = rows.shape[1]
    firsts = rows.argmax(axis=1).tolist()
    lasts = (w - 1 - rows[:, ::-1].argmax(axis=1)).tolist()
    out = np.empty(len(firsts), np.float64)
    # A few rows per head: plain floats beat a dozen array operations on (n, 4) arrays here.
    for i, (row, first, last) in enumerate(zip(diff.tolist(), firsts, lasts, strict=True)):
        # diff column = mask column + 1; inside references: the pixel next to each end inwards.
        ref_l, ref_r = row[min(first + 1, last) + 1], row[max(last - 1, first) + 1]
        left, right = first - 0.5, last + 0.5
        if abs(ref_l) >= 1.0:  # no contrast to scale by: whole pixels
            a, b = row[first + 1] / ref_l, row[first] / ref_l
            left += 1.0 - (0.0 if a < 0.0 else min(a, 1.0)) - (0.0 if b < 0.0 else min(b, 1.0))
        if abs(ref_r) >= 1.0:
            a, b = row[last + 1] / ref_r, row[last + 2] / ref_r
            right -= 1.0 - (0.0 if a < 0.0 else min(a, 1.0)) - (0.0 if b < 0.0 else min(b, 1.0))
        out[i] = (left + right) / 2.0
    return out
