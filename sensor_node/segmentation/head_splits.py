"""Stage 3b: split a blob that holds several people, at the valleys between their heads.

Grouping merges connected and nearby regions (paper), so two people who walk
side by side, or a person beside a ghost, become one blob whose single "head"
(:mod:`sensor_node.head`) lies somewhere between them: a bearing error of half
a body width. The paper's own cue separates them again: a head is the topmost
part of a person, so each person is a peak of the blob's *top profile* (the
first changed row of each column). Two peaks with a valley between them that
dips at least ``split_dip_px`` rows below the lower peak are two objects; the
blob is cut at the valley's deepest column and each part keeps its own pixels.

A shoulder or a raised arm is also a bump on the profile, but a narrow one
beside a much wider body: a part must be at least ``SPLIT_MIN_WIDTH_FRAC`` as
wide as the widest part, rise to a head (narrower than its body, wider than
a spike), and pass the blob checks (pixels, width, height). A part parted at an
(almost) empty column, or narrower than ``NARROW_PART_FRAC`` of the widest, must
also have a head narrower than the body below it: an arm swung clear of the
body is a strip as wide all the way down, even where its top is ragged. A
blob cut by the top of the image (a near person whose head is above the view)
has no heads to split at there.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable
from typing import cast

import cv2
import numpy as np
import numpy.typing as npt
from scipy import ndimage

from sensor_node.config import PipelineSettings
from sensor_node.segmentation.blobs import RawBlob

__all__ = ["blob_part", "has_head", "ok_part", "split_at_heads", "top_profile"]


HEAD_MIN_COLS = 3
"""Least width of a head (columns at ``split_dip_px`` below its top): narrower is a spike of noise."""

HEAD_MAX_FRAC = 0.85
"""Largest width of a head relative to its part: a flat top is an arm, a shoulder or a ghost, not a head."""

SPLIT_MIN_WIDTH_FRAC = 0.15
"""Least width of a split part relative to the widest part. Parts under ``NARROW_PART_FRAC`` must also
have a head narrower than their body, which tells a far person beside a near one (0.3 of their width
or less, e.g. arms out) from an arm; 0.3 without that test lost such people (six seed 5: 0.2 % fewer
found, ``benchmarks/bench_node_quality.py``)."""

HEAD_BODY_FRAC = 0.75
"""Largest width of a head relative to the body below it (people: ~0.3-0.5; an arm: ~1)."""

NARROW_PART_FRAC = 0.5
"""A part of a head-valley split narrower than this fraction of the widest part must have a head
narrower than its body (an arm is a strip; a person's body is wider than the head)."""

GAP_MAX_PX = 1
"""Changed pixels a column may hold and still be a gap of the vertical projection profile (a noise speck)."""

GAP_MIN_WIDTH_FRAC = 0.6
"""A part parted at a gap stands alone without a head if at least this wide relative to the widest part."""

GAP_HEAD_DIP_PX = 8
"""Rows below a part's top at which its head is measured when parting at gaps with ``split_dip_px`` 0."""

BODY_MIN_ROWS = 3
"""Fewest rows of a part's body (2.5 to 5 head widths below its top) to compare its width with the head's:
with fewer (a part cut off by the image's edge), the head is not held against it."""

UNCUT_EDGES = 2
"""Edges of a blob in one part (its first column and its end): no cut left to weigh."""


def top_profile(mask: npt.NDArray[np.bool_]) -> npt.NDArray[np.int64]:
    """First set row of each column of a blob mask (the mask's height where a column is empty)."""
    h = mask.shape[0]
    any_set = mask.any(axis=0)
    return np.where(any_set, mask.argmax(axis=0), h).astype(np.int64)


def _peaks(top: npt.NDArray[np.int64], radius: int) -> list[int]:
    """Columns that are the highest point (lowest row) within ``radius`` columns; one per plateau."""
    w = top.size
    lowest = ndimage.minimum_filter1d(top, 2 * radius + 1, mode="constant", cval=np.iinfo(np.int64).max)
    is_peak: list[bool] = (top <= lowest).tolist()
    t: list[int] = top.tolist()  # plain ints: the loop reads them one by one
    out: list[int] = []
    c = 0
    while c < w:
        if is_peak[c]:
            e = c
            while e + 1 < w and t[e + 1] == t[c]:
                e += 1
            # A plateau is a peak only if the profile falls away on both sides (not a flat valley floor).
            if (c == 0 or t[c - 1] > t[c]) and (e == w - 1 or t[e + 1] > t[c]):
                out.append((c + e) // 2)
            c = e + 1
        else:
            c += 1
    return out


def _cuts(top: npt.NDArray[np.int64], dip_px: int, radius: int, cut_above: int) -> list[int]:
    """Columns to cut at: the deepest column between consecutive peaks that dips ``dip_px`` below both.

    Peaks at rows < ``cut_above`` run out of the image (a near person's head above the view): their
    profile is shoulders and arms, not heads, so they split nothing.
    """
    # Quick exit (most blobs hold one person): no column dips dip_px below the highest point on
    # each side of it -- a necessary condition for any valley between two peaks.
    left = np.minimum.accumulate(top)
    right = np.minimum.accumulate(top[::-1])[::-1]
    if int((top - np.maximum(left, right)).max()) < dip_px:
        return []
    peaks = [p for p in _peaks(top, radius) if top[p] >= cut_above]
    cuts: list[int] = []
    keep = peaks[:1]
    for p in peaks[1:]:
        a = keep[-1]
        seg = top[a : p + 1]
        v = a + int(np.argmax(seg))
        if int(top[v]) - max(int(top[a]), int(top[p])) >= dip_px:
            cuts.append(v)
            keep.append(p)
        elif top[p] < top[a]:
            keep[-1] = p  # the same object: carry on from its higher point
    return cuts


def has_head(top: npt.NDArray[np.int64], dip_px: int, mask: npt.NDArray[np.bool_] | None = None) -> bool:
    """True if a part's profile rises to a head: at ``dip_px`` below its highest point it is at least
    ``HEAD_MIN_COLS`` and at most ``HEAD_MAX_FRAC`` of the part wide (not a spike, not a flat top).

    Given the part's pixels (``mask``, the columns of ``top``), the head must also be narrower than
    the body below it (at most ``HEAD_BODY_FRAC`` of the part's median row width from 2.5 to 5 head
    widths below its top): an arm or a leg is a strip as wide all the way down, whose ragged top
    passes the profile test.
    """
    p = int(np.argmin(top))
    above = top <= top[p] + dip_px
    a = p
    while a > 0 and above[a - 1]:
        a -= 1
    b = p
    while b + 1 < top.size and above[b + 1]:
        b += 1
    cols = b - a + 1
    if not HEAD_MIN_COLS <= cols <= HEAD_MAX_FRAC * top.size:
        return False
    if mask is None:
        return True
    t0 = int(top[p])
    counts = np.count_nonzero(mask[t0 + round(2.5 * cols) : t0 + 5 * cols], axis=1)
    counts = counts[counts > 0]
    return counts.size < BODY_MIN_ROWS or cols <= HEAD_BODY_FRAC * _median(counts)


def _median(values: npt.NDArray[np.intp]) -> float:
    """np.median of a short array, without its fixed cost (about 20 us, several calls a frame)."""
    s = np.sort(values)
    m = s.size // 2
    return float(s[m]) if s.size % 2 else 0.5 * float(s[m - 1] + s[m])


def _column_counts(mask: npt.NDArray[np.bool_]) -> npt.NDArray[np.int32]:
    """Set pixels per column of a blob mask: OpenCV's column sum over the mask's bytes (a fraction of
    ``np.count_nonzero(mask, axis=0)``'s time on a blob's few dozen columns)."""
    if mask.size == 0:
        return np.zeros(mask.shape[1], np.int32)
    counts = cv2.reduce(mask.view(np.uint8), 0, cv2.REDUCE_SUM, dtype=cv2.CV_32S).ravel()
    return cast("npt.NDArray[np.int32]", counts)


def _gaps(col_px: npt.NDArray[np.int32], gap_cols: int) -> list[int]:
    """Cut columns at the gaps of a blob's vertical projection profile.

    A gap is a run of at least ``gap_cols`` columns with at most ``GAP_MAX_PX`` changed pixels
    (grouping joined regions up to ``merge_gap_px`` apart, and a noise speck may sit in between);
    the cut is the gap's middle column.
    """
    if gap_cols <= 0:
        return []
    low = col_px <= GAP_MAX_PX
    if not low[1:-1].any():
        return []
    cuts: list[int] = []
    flags: list[bool] = low.tolist()  # plain bools: the loop reads them one by one
    c, w = 0, len(flags)
    while c < w:
        if not flags[c]:
            c += 1
            continue
        e = c
        while e + 1 < w and flags[e + 1]:
            e += 1
        if c > 0 and e < w - 1 and e - c + 1 >= gap_cols:
            cuts.append((c + e + 1) // 2)
        c = e + 1
    return cuts


def ok_part(blob: RawBlob, a: int, b: int, settings: PipelineSettings) -> bool:
    """Columns [a, b) of a blob hold enough of an object to stand alone (the blob checks)."""
    sub = blob.mask[:, a:b]
    rows = np.flatnonzero(sub.any(axis=1))
    if rows.size == 0:
        return False
    cols = np.flatnonzero(sub.any(axis=0))
    area = int(np.count_nonzero(sub))
    return (
        area >= settings.min_blob_px
        and int(rows[-1] - rows[0]) + 1 >= settings.min_blob_height_px
        and int(cols[-1] - cols[0]) + 1 >= settings.min_blob_width_px
    )


def _merge_weak(edges: list[int], ok: Callable[[int, int], bool]) -> list[int]:
    """Drop cuts until every part [edges[i], edges[i+1]) is ``ok``: a weak part joins its narrower neighbour."""
    edges = list(edges)
    while len(edges) > UNCUT_EDGES:
        weak = [i for i in range(len(edges) - 1) if not ok(edges[i], edges[i + 1])]
        if not weak:
            break
        i = weak[0]
        if i == 0:
            del edges[1]
        elif i == len(edges) - 2:
            del edges[-2]
        else:  # join the neighbour it is closer to in width (the smaller of the two joins)
            left, right = edges[i] - edges[i - 1], edges[i + 2] - edges[i + 1]
            del edges[i if left <= right else i + 1]
    return edges


def split_at_heads(
    blob: RawBlob, settings: PipelineSettings, width_px: int, *, top: npt.NDArray[np.int64] | None = None
) -> list[RawBlob]:
    """The blob's objects, one blob each (``[blob]`` when it holds one).

    First at the gaps of the vertical projection profile (``split_gap_cols``): grouping joined
    regions that do not touch; each side that passes the blob checks and rises to a head (or is
    wide) stands alone, a fragment or a narrow flat-topped strip (an arm swung clear of the body)
    joins its neighbour. Then each part at the valleys between heads (``split_dip_px``):
    a cut is kept only if the parts on both sides are wide enough, rise to a head and pass the blob
    checks; otherwise the weak part joins its neighbour (one bump does not undo the other cuts).

    Args:
        blob: a validated blob.
        settings: ``split_gap_cols``, ``split_dip_px`` and the blob checks.
        width_px: image width (blob columns wrap on a panorama).
        top: the blob's :func:`top_profile`, if known (None: computed when needed).
    """
    dip = settings.split_dip_px
    if blob.w < 2 * settings.min_blob_width_px:
        return [blob]
    col_px = _column_counts(blob.mask)  # changed pixels per column: gaps, part widths, dips
    gaps = _gaps(col_px, settings.split_gap_cols)
    if top is None:
        top = top_profile(blob.mask) if gaps or dip > 0 else np.zeros(0, np.int64)
    head_dip = dip if dip > 0 else GAP_HEAD_DIP_PX

    # The widest part between gaps (only parts between gaps read it).
    widest = (
        max(int(np.count_nonzero(col_px[a:b] > GAP_MAX_PX)) for a, b in itertools.pairwise([0, *gaps, blob.w]))
        if gaps
        else 0
    )

    def ok_gap(a: int, b: int) -> bool:
        # A part of its own passes the blob checks and rises to a head, or is wide (a ghost, a bag),
        # or its top is the image's top row (a near person's head above the view). A narrow strip
        # with a flat top -- an arm swung clear of the body -- stays with its neighbour.
        if not ok_part(blob, a, b, settings):
            return False
        cols = col_px[a:b] > GAP_MAX_PX
        t = top[a:b][cols]
        if t.size == 0:
            return False
        return (
            blob.v0 + int(t.min()) == 0
            or t.size >= GAP_MIN_WIDTH_FRAC * widest
            or has_head(t, head_dip, blob.mask[:, a:b][:, cols])
        )

    edges = _merge_weak([0, *gaps, blob.w], ok_gap) if gaps else [0, blob.w]
    if dip > 0:
        edges = _split_at_dips(blob, edges, col_px, top, settings)
    if len(edges) == UNCUT_EDGES:
        return [blob]
    parts = [p for a, b in itertools.pairwise(edges) if (p := blob_part(blob, a, b, width_px)) is not None]
    return parts or [blob]


def _split_at_dips(
    blob: RawBlob,
    edges: list[int],
    col_px: npt.NDArray[np.int32],
    top: npt.NDArray[np.int64],
    settings: PipelineSettings,
) -> list[int]:
    """The ``edges`` of a blob's parts, each part cut further at the valleys between heads (``split_dip_px``)
    where both sides stand as parts of their own.

    Args:
        blob: the blob.
        edges: its parts' edges so far (its first column, the cuts, its end).
        col_px: its changed pixels per column.
        top: its :func:`top_profile`.
        settings: ``split_dip_px`` and the blob checks.
    """
    dip = settings.split_dip_px
    radius = max(2, settings.min_blob_width_px // 2)
    fine: list[int] = [0]
    for a, b in itertools.pairwise(edges):
        if b - a < 2 * settings.min_blob_width_px:
            fine.append(b)
            continue
        cuts = [a + c for c in _cuts(top[a:b], dip, radius, 1 - blob.v0)]
        sub = [a, *cuts, b]
        widest = max(y - x for x, y in itertools.pairwise(sub))

        def ok(x: int, y: int, widest: int = widest) -> bool:
            # A side parted at an (almost) empty column, or much narrower than the widest, must
            # have a head narrower than its body (an arm swung clear of the body is a strip).
            strip = (
                y - x < NARROW_PART_FRAC * widest
                or (x > 0 and col_px[x] <= GAP_MAX_PX)
                or (y < blob.w and col_px[y] <= GAP_MAX_PX)
            )
            return (
                y - x >= SPLIT_MIN_WIDTH_FRAC * widest
                and has_head(top[x:y], dip, blob.mask[:, x:y] if strip else None)
                and ok_part(blob, x, y, settings)
            )

        fine.extend(_merge_weak(sub, ok)[1:])
    return fine


def blob_part(blob: RawBlob, a: int, b: int, width_px: int) -> RawBlob | None:
    """Columns [a, b) of a blob as a blob of its own, trimmed to its pixels (end columns of a speck dropped)."""
    sub = blob.mask[:, a:b]
    counts = _column_counts(sub)
    cols = np.flatnonzero(counts > GAP_MAX_PX)  # trimmed of specks left in a gap at its ends
    if cols.size == 0:
        cols = np.flatnonzero(counts)
    if cols.size == 0:
        return None
    c0, c1 = int(cols[0]), int(cols[-1])
    sub = sub[:, c0 : c1 + 1]
    rows = np.flatnonzero(sub.any(axis=1))
    r0, r1 = int(rows[0]), int(rows[-1])
    mask = sub[r0 : r1 + 1]
    u0, v0, w, h = (blob.u0 + a + c0) % width_px, blob.v0 + r0, c1 - c0 + 1, r1 - r0 + 1
    area = int(np.count_nonzero(mask))
    return RawBlob(u0, v0, w, h, mask, area, area / float(w * h))
