"""Stage 3c: split a blob that holds people the 2D tracks saw apart a moment ago.

People who walk in a tight group keep merging into one blob: one head stands
a little in front of the other, the far head is a step on the slope of the
near one's top profile, and no valley between the heads is deep enough for
:func:`sensor_node.segmentation.head_splits.split_at_heads`. But a moment earlier they were
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

A far person who walked in with the group (never alone, so no confirmed
track) or whose track was lost while merged has no prediction. Given one
tracked head in the blob, their head still shows as a bump of the top
profile beside the tracked one (:func:`_head_bumps`: a round local top,
lower and no wider than the tracked head, a dip between the two, and their
own shoulders well below it on the far side); each bump is one more
candidate, cut and checked exactly like a prediction. On the six site
(``benchmarks/bench_node_quality.py``, world seeds 5, 9, 3, 11, 21) this
found 0.8-1.3 % more people and left 1.5-2.5 % fewer people merged with
someone whose head is apart from theirs, at the cost of 0.01-0.04 more
extra blobs per frame (four cameras): a ghost or a ragged arm beside a
person can still pass for a far head.

Only pixels decide where the cut goes; the tracks only say that a cut is
worth looking for (the measured bearings are the parts' heads, never the
predictions). Work is the blob's top profile, on the blobs that hold a
prediction.
"""

from __future__ import annotations

import itertools

import numpy as np
import numpy.typing as npt

from sensor_node.config import PipelineSettings
from sensor_node.segmentation.blobs import RawBlob
from sensor_node.segmentation.head_splits import blob_part, has_head, ok_part, top_profile

__all__ = ["split_by_tracks"]


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


BUMP_DROP_HEADS = 2.0
"""Rows a far head's bump rises above the far person's own shoulders beside it, in widths of the bump
(its columns ``HEAD_DIP_PX`` below its top): a head is ~1.5 times as tall as wide, and a neck
follows. A near person's shoulder beside a ragged edge or a ghost drops about its own width."""

HEAD_SEARCH_PX = 4
"""Columns on each side of a track's prediction in which its head (the highest column) is looked for."""

ROUND_MIN_COLS = 2
"""Columns by which a far head's bump widens from its top row to ``HEAD_DIP_PX`` rows below it (a
head is round; a near person's shoulder beside a far body is a flat step that ends abruptly)."""

SHOULDER_GAP_FRAC = 0.5
"""Least gap between a far head's bump and the tracked head, in widths of the tracked head: the near
person's shoulder spans about that much beside their head (a bump there is that shoulder)."""

BUMP_REACH_PX = 4
"""Columns beyond a bump's edge in which its drop to the far person's shoulders is looked for (the
first may still be the side of the head)."""

BUMP_SHOULDER_COLS = 3
"""Of the ``BUMP_REACH_PX`` columns, how many must lie that far below the bump (shoulders are wider
than the head; a ragged arm or the blob's end is not)."""

SPLIT_MIN_HEADS = 2
"""Heads (predicted, or found as bumps of the top) a blob must hold to be split: one head is one person."""


def _cut_between(top: npt.NDArray[np.int64], a: float, b: float) -> int | None:
    """Boundary column c (the right part starts at c) between predicted head columns a < b, or None."""
    ia, ib = max(round(a), 0), min(round(b), top.size - 1)
    if ib <= ia + 1:
        return None  # no column between the heads to cut at
    seg = top[ia : ib + 1]
    v = int(np.argmax(seg[1:-1])) + 1
    left_min, right_min = int(seg[:v].min()), int(seg[v + 1 :].min())
    if int(seg[v]) - VALLEY_MIN_PX >= max(left_min, right_min):
        # A valley: of its deepest columns (a flat floor: the near one's shoulder), only the one
        # next to the side whose head is lower (the far one) goes with it.
        if left_min > right_min:
            return ia + v + 1
        return ia + int(np.flatnonzero(seg[1:-1] == seg[v]).max()) + 1
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


def _extent(top: list[int], p: int) -> tuple[int, int]:
    """Columns [a, b] around ``p`` whose top lies from ``top[p]`` to ``HEAD_DIP_PX`` rows below it (a
    far head's extent ends where the near person's higher profile begins)."""
    t = top[p]
    a = b = p
    while a > 0 and t <= top[a - 1] <= t + HEAD_DIP_PX:
        a -= 1
    while b + 1 < len(top) and t <= top[b + 1] <= t + HEAD_DIP_PX:
        b += 1
    return a, b


def _local_tops(top: list[int], image_top: int) -> list[tuple[int, int]]:
    """The runs of equal top (first and last column) that are local tops below ``image_top``: the profile
    is lower on both sides (a step beside a near shoulder is too often that shoulder).

    One pass over plain ints: a blob's profile is a few dozen columns, too short for array operations
    to pay their fixed cost.
    """
    out: list[tuple[int, int]] = []
    n, c = len(top), 0
    while c < n:
        t, e = top[c], c
        while e + 1 < n and top[e + 1] == t:
            e += 1
        if t > image_top and (c == 0 or top[c - 1] > t) and (e == n - 1 or top[e + 1] > t):
            out.append((c, e))
        c = e + 1
    return out


def _head_bumps(
    top: npt.NDArray[np.int64], preds: npt.NDArray[np.float64], image_top: int, empty: int
) -> npt.NDArray[np.float64]:
    """Columns of far heads seen as bumps on the side of a tracked person's profile.

    A far person half hidden behind a near one whose track is in the blob shows as a narrow peak of
    the top profile beside the near one's shoulders: lower than the tracked head, no wider than it
    (at ``HEAD_DIP_PX`` below each top), round (``ROUND_MIN_COLS``), parted from the tracked head
    by a dip of at least ``VALLEY_MIN_PX`` rows below its top, and ``BUMP_DROP_HEADS`` of its
    widths above ``BUMP_SHOULDER_COLS`` of the ``BUMP_REACH_PX`` columns just outside it on the side
    away from the tracked head (the far person's own shoulders, changed pixels). A near person's shoulder is
    a flat or wider plateau, and its arm beside it is one ragged column. Bumps are only candidates:
    the cut next to one must pass the same part checks as a cut between two tracks.
    """
    found: list[tuple[int, int, int]] = []
    vals, pl = top.tolist(), preds.tolist()
    for c, e in _local_tops(vals, image_top):
        p, tp = (c + e) // 2, vals[c]
        near_f = min(pl, key=lambda q: abs(q - p))
        if abs(near_f - p) < MIN_SEPARATION_PX:
            continue
        near = round(near_f)
        lo = max(near - HEAD_SEARCH_PX, 0)
        search = vals[lo : near + HEAD_SEARCH_PX + 1]
        head = lo + search.index(min(search))  # the first highest column, as argmin
        if vals[head] <= image_top:
            continue  # the tracked person's head is above the view: their shoulders are its top
        if tp <= vals[head]:
            continue  # as high as the tracked head: not a head behind it
        a, b = _extent(vals, p)
        ha, hb = _extent(vals, head)
        if a - hb < SHOULDER_GAP_FRAC * (hb - ha + 1) and ha - b < SHOULDER_GAP_FRAC * (hb - ha + 1):
            continue  # on the tracked head's own slope, or where its shoulder is
        if b - a > hb - ha or b - a + 1 < e - c + 1 + ROUND_MIN_COLS:
            continue  # wider than the tracked head, or flat-topped: a shoulder
        # From its top towards the tracked head, the profile must dip before it rises above the top.
        inward = top[e + 1 : head + 1] if p < near else top[head:c][::-1]
        rise = np.flatnonzero(inward < tp)
        if int(inward[: rise[0] if rise.size else inward.size].max(initial=tp)) < tp + VALLEY_MIN_PX:
            continue  # no dip between it and the tracked head: a ripple on the near one's shoulder
        outer = top[b + 1 : b + 1 + BUMP_REACH_PX] if p > near else top[max(a - BUMP_REACH_PX, 0) : a]
        outer = outer[outer < empty]  # changed columns only (not the blob's edge)
        if int(np.count_nonzero(outer >= tp + BUMP_DROP_HEADS * (b - a + 1))) >= BUMP_SHOULDER_COLS:
            found.append((tp, a, b))
    # One candidate per bump: its highest run (a run on its slope spans part of the same columns),
    # placed at the middle of its width (the run at its top may be an edge pixel).
    out: list[float] = []
    taken: list[tuple[int, int]] = []
    for _, a, b in sorted(found):
        if all(b < x or a > y for x, y in taken):
            taken.append((a, b))
            out.append((a + b) / 2.0)
    return np.asarray(out, np.float64)


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
    blob: RawBlob,
    predicted_u: list[float],
    settings: PipelineSettings,
    width_px: int,
    *,
    top: npt.NDArray[np.int64] | None = None,
) -> list[RawBlob]:
    """The blob cut between the predicted head columns of the tracks inside it (``[blob]`` if none).

    Args:
        blob: a blob (after :func:`sensor_node.segmentation.head_splits.split_at_heads`).
        predicted_u: predicted head columns of the confirmed 2D tracks (image columns).
        settings: the blob checks.
        width_px: image width (blob columns wrap on a panorama).
        top: the blob's :func:`~sensor_node.segmentation.head_splits.top_profile`, if known (None: computed).
    """
    if not predicted_u or blob.w < 2 * settings.min_blob_width_px:
        return [blob]
    rel = (np.asarray(predicted_u, np.float64) - blob.u0) % width_px
    inside = rel[(rel >= 0.0) & (rel <= blob.w - 1)]
    if inside.size == 0:
        return [blob]
    if top is None:
        top = top_profile(blob.mask)
    inside = np.sort(np.concatenate([inside, _head_bumps(top, inside, -blob.v0, blob.mask.shape[0])]))
    if inside.size < SPLIT_MIN_HEADS:
        return [blob]
    # Predictions closer than MIN_SEPARATION_PX: one occludes the other; keep one of them.
    preds = [float(inside[0])]
    for p in inside[1:].tolist():
        if p - preds[-1] >= MIN_SEPARATION_PX:
            preds.append(p)
    if len(preds) < SPLIT_MIN_HEADS:
        return [blob]
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
    parts = [p for x, y in itertools.pairwise(edges) if (p := blob_part(blob, x, y, width_px)) is not None]
    return parts if len(parts) > 1 else [blob]
