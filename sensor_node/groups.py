"""Stage 3c: split a blob that holds people the 2D tracks saw apart a moment ago.

People who walk in a tight group keep merging into one blob: one head stands
a little in front of the other, the far head is a step on the slope of the
near one's top profile, and no valley between the heads is deep enough for
:func:`sensor_node.split.split_at_heads`. But a moment earlier they were
apart, and each had its own 2D track (:mod:`sensor_node.tracks2d`). When the
predicted head columns of two or more confirmed tracks fall inside one blob,
the blob is cut between each pair of neighbouring predictions:

* at the deepest column of the top profile between them when it is a valley
  (the profile rises again on both sides by ``VALLEY_MIN_PX``), else
* where the columns higher than the lower (far) head's top end: the far
  head comes out from behind the near one's edge there (the occlusion
  boundary), and the far part's top is the far head.

Each part must pass the blob checks (pixels, width, height), its top must
lie near its own track's predicted column (a part whose highest point is the
other person's head or neck edge is no head of its own), and it must rise to
a head (``HEAD_DIP_PX`` below its top it is narrower than the part: a
shoulder cut off its own body by a stale track is flat to the edge);
otherwise the cut is dropped. Tracks closer than ``MIN_SEPARATION_PX`` are
one person occluding the other: nothing can part them in the image.

Only pixels decide where the cut goes; the tracks only say that a cut is
worth looking for (the measured bearings are the parts' heads, never the
predictions). Work is the blob's top profile, on the few blobs that hold two
predictions.
"""

from __future__ import annotations

import itertools
from typing import Any

import numpy as np
import numpy.typing as npt

from sensor_node.blobs import RawBlob
from sensor_node.config import PipelineSettings
from sensor_node.split import blob_part, has_head, ok_part, top_profile

__all__ = ["split_by_tracks"]

Mask = npt.NDArray[Any]

MIN_SEPARATION_PX = 3.0
"""Least distance (columns) between two tracks' predicted head columns for a cut between them."""

VALLEY_MIN_PX = 2
"""Rows the top profile must rise on both sides of its deepest column between two predictions for
that column to be a valley (else the cut goes at the largest step)."""

HEAD_DIP_PX = 3
"""Rows below a part's top at which it must be a head: narrower than the part (a far head drops to its
own shoulders; a near one's shoulder cut off its body is flat to the edge)."""

TOP_NEAR_PX = 3.0
"""A part's highest column must lie this close to (or beyond, away from the cut) its track's prediction."""


def _cut_between(top: npt.NDArray[np.int64], a: float, b: float) -> int | None:
    """Boundary column c (the right part starts at c) between predicted head columns a < b, or None."""
    ia, ib = max(round(a), 0), min(round(b), top.size - 1)
    if ib - ia < 2:
        return None
    seg = top[ia : ib + 1]
    v = int(np.argmax(seg[1:-1])) + 1
    left_min, right_min = int(seg[:v].min()), int(seg[v + 1 :].min())
    if int(seg[v]) - VALLEY_MIN_PX >= max(left_min, right_min):
        # A valley: its deepest column goes with the side whose head is lower (the far one).
        return ia + v + (1 if left_min > right_min else 0)
    # No valley: the lower (far) head comes out from behind the near one. Cut where the columns
    # higher than the far head's top end, so the far part's top is the far head.
    ha, hb = int(top[max(ia - 1, 0) : ia + 2].min()), int(top[ib - 1 : ib + 2].min())
    if ha <= hb:
        higher = np.flatnonzero(seg < hb)
        c = ia + int(higher.max()) + 1 if higher.size else None
    else:
        higher = np.flatnonzero(seg < ha)
        c = ia + int(higher.min()) if higher.size else None
    return c if c is not None and 0 < c < top.size else None


def _top_near(top: npt.NDArray[np.int64], x: int, y: int, pred: float, side: int) -> bool:
    """The part [x, y)'s highest column lies near ``pred`` or beyond it, away from the cut.

    Args:
        side: -1 for a part left of a cut (its cut is at y), +1 right of a cut (at x), 0 both.
    """
    seg = top[x:y]
    best = np.flatnonzero(seg == seg.min()) + x
    for c in (best.min(), best.max()):
        if side <= 0 and c <= pred + TOP_NEAR_PX and (side < 0 or c >= pred - TOP_NEAR_PX):
            return True
        if side > 0 and c >= pred - TOP_NEAR_PX:
            return True
    return False


def split_by_tracks(
    blob: RawBlob, predicted_u: list[float], moving: Mask, settings: PipelineSettings, width_px: int
) -> list[RawBlob]:
    """The blob cut between the predicted head columns of the tracks inside it (``[blob]`` if none).

    Args:
        blob: a blob (after :func:`sensor_node.split.split_at_heads`).
        predicted_u: predicted head columns of the confirmed 2D tracks (image columns).
        moving: (H, W) frame-difference mask (for the parts' motion fractions).
        settings: the blob checks.
        width_px: image width (blob columns wrap on a panorama).
    """
    if len(predicted_u) < 2 or blob.w < 2 * settings.min_blob_width_px:
        return [blob]
    rel = (np.asarray(predicted_u, np.float64) - blob.u0) % width_px
    inside = np.sort(rel[(rel >= 0.0) & (rel <= blob.w - 1)])
    if inside.size < 2:
        return [blob]
    # Predictions closer than MIN_SEPARATION_PX: one occludes the other; keep one of them.
    preds = [float(inside[0])]
    for p in inside[1:].tolist():
        if p - preds[-1] >= MIN_SEPARATION_PX:
            preds.append(p)
    if len(preds) < 2:
        return [blob]
    top = top_profile(blob.mask)
    edges = [0]
    kept = [preds[0]]
    for b in preds[1:]:
        a = kept[-1]
        c = _cut_between(top, a, b)
        if c is None or c <= edges[-1]:
            continue
        if not (
            ok_part(blob, edges[-1], c, settings)
            and ok_part(blob, c, blob.w, settings)
            and _top_near(top, edges[-1], c, a, -1 if len(edges) == 1 else 0)
            and _top_near(top, c, blob.w, b, 1)
            and has_head(top[edges[-1] : c], HEAD_DIP_PX)
            and has_head(top[c:], HEAD_DIP_PX)
        ):
            continue
        edges.append(c)
        kept.append(b)
    if len(edges) == 1:
        return [blob]
    edges.append(blob.w)
    parts = [p for x, y in itertools.pairwise(edges) if (p := blob_part(blob, x, y, moving, width_px)) is not None]
    return parts if len(parts) > 1 else [blob]
