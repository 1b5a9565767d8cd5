"""Stage 4: head extraction (paper, "Head extraction and blob representation").

The bearing of a whole blob moves with arms and legs; the head is almost
symmetric from every viewpoint, usually visible and easy to separate from the
background. So the bearing reported for a blob is its head's: the topmost part
of the blob with a fixed height:width ratio (3:2 in the paper). The exact head
height does not matter much since only its bearing is used.

Head width is taken from the blob's topmost rows (the crown of the head), the
head box is then ``head_ratio`` times as tall, and the head column is the
centroid of the blob pixels inside that box -- a sub-pixel estimate, robust to
a ragged silhouette edge.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

__all__ = ["Head", "extract_head"]


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


def extract_head(mask: npt.NDArray[np.bool_], head_ratio: float = 1.5) -> Head:
    """Find the head of a blob given its (h, w) pixel mask.

    Args:
        mask: blob pixels inside its bounding box (at least one pixel set).
        head_ratio: head height / head width (paper: 3:2 = 1.5).
    """
    rows = np.flatnonzero(mask.any(axis=1))
    if rows.size == 0:
        raise ValueError("extract_head needs a non-empty blob mask")
    top = int(rows[0])
    h = int(rows[-1]) - top + 1
    # Crown rows: about the top tenth of the body, at least 2 rows; their extents give the head width.
    k = max(2, min(h, round(0.1 * h)))
    crown = mask[top : top + k]
    width = crown.shape[1]
    first = crown.argmax(axis=1)
    last = width - 1 - crown[:, ::-1].argmax(axis=1)
    filled = crown[np.arange(crown.shape[0]), first]
    widths = sorted((last - first + 1)[filled].tolist())
    head_w = max(2, int(widths[len(widths) // 2]))
    head_h = max(2, min(h, round(head_ratio * head_w)))
    region = mask[top : top + head_h]
    # Per-row pixel centroids, averaged over the rows that are head-wide (a shoulder row that
    # slipped into the box would pull the centroid towards the body).
    counts = region.sum(axis=1)
    ok = (counts > 0) & (counts <= max(1.5 * head_w, 2))
    if not ok.any():
        ok = counts > 0
    row_u = (region[ok] @ np.arange(width, dtype=np.float64)) / counts[ok]
    row_v = np.flatnonzero(ok)
    return Head(
        u_px=float(row_u.sum()) / row_u.size,
        v_px=float(row_v.sum()) / row_v.size + top,
        top_px=top,
        width_px=head_w,
        height_px=head_h,
    )
