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
a spike), and pass the blob checks (pixels, width, height). A
blob cut by the top of the image (a near person whose head is above the view)
has no heads to split at there.
"""

from __future__ import annotations

import itertools
from typing import Any

import numpy as np
import numpy.typing as npt

from sensor_node.blobs import RawBlob, roi
from sensor_node.config import PipelineSettings

__all__ = ["split_at_heads", "top_profile"]

Mask = npt.NDArray[Any]

HEAD_MIN_COLS = 3
"""Least width of a head (columns at ``split_dip_px`` below its top): narrower is a spike of noise."""

HEAD_MAX_FRAC = 0.85
"""Largest width of a head relative to its part: a flat top is an arm, a shoulder or a ghost, not a head."""

SPLIT_MIN_WIDTH_FRAC = 0.3
"""Least width of a split part relative to the widest part (an arm or shoulder is narrower)."""


def top_profile(mask: npt.NDArray[np.bool_]) -> npt.NDArray[np.int64]:
    """First set row of each column of a blob mask (the mask's height where a column is empty)."""
    h = mask.shape[0]
    any_set = mask.any(axis=0)
    return np.where(any_set, mask.argmax(axis=0), h).astype(np.int64)


def _peaks(top: npt.NDArray[np.int64], radius: int) -> list[int]:
    """Columns that are the highest point (lowest row) within ``radius`` columns; one per plateau."""
    w = top.size
    padded = np.concatenate([np.full(radius, np.iinfo(np.int64).max), top, np.full(radius, np.iinfo(np.int64).max)])
    windows = np.lib.stride_tricks.sliding_window_view(padded, 2 * radius + 1)
    is_peak = top <= windows.min(axis=1)
    out: list[int] = []
    c = 0
    while c < w:
        if is_peak[c]:
            e = c
            while e + 1 < w and top[e + 1] == top[c]:
                e += 1
            # A plateau is a peak only if the profile falls away on both sides (not a flat valley floor).
            if (c == 0 or top[c - 1] > top[c]) and (e == w - 1 or top[e + 1] > top[c]):
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


def _has_head(top: npt.NDArray[np.int64], dip_px: int) -> bool:
    """True if a part's profile rises to a head: at ``dip_px`` below its highest point it is at least
    ``HEAD_MIN_COLS`` and at most ``HEAD_MAX_FRAC`` of the part wide (not a spike, not a flat top)."""
    p = int(np.argmin(top))
    above = top <= top[p] + dip_px
    a = p
    while a > 0 and above[a - 1]:
        a -= 1
    b = p
    while b + 1 < top.size and above[b + 1]:
        b += 1
    cols = b - a + 1
    return HEAD_MIN_COLS <= cols <= HEAD_MAX_FRAC * top.size


def split_at_heads(blob: RawBlob, moving: Mask, settings: PipelineSettings, width_px: int) -> list[RawBlob]:
    """The blob's people, one blob each (``[blob]`` when it holds one).

    Args:
        blob: a validated blob.
        moving: (H, W) frame-difference mask of the frame (for the parts' motion fractions).
        settings: ``split_dip_px`` and the blob checks.
        width_px: image width (blob columns wrap on a panorama).
    """
    dip = settings.split_dip_px
    if dip <= 0 or blob.w < 2 * settings.min_blob_width_px:
        return [blob]
    top = top_profile(blob.mask)
    cuts = _cuts(top, dip, max(2, settings.min_blob_width_px // 2), 1 - blob.v0)
    if not cuts:
        return [blob]
    edges = [0, *cuts, blob.w]
    widest = max(b - a for a, b in itertools.pairwise(edges))
    parts: list[RawBlob] = []
    for a, b in itertools.pairwise(edges):
        if b - a < SPLIT_MIN_WIDTH_FRAC * widest or not _has_head(top[a:b], dip):
            return [blob]  # a bump, not a person: keep the blob whole
        part = _part(blob, a, b, moving, width_px)
        if part is None:
            continue
        if part.area_px < settings.min_blob_px or part.h < settings.min_blob_height_px:
            continue
        if part.w < settings.min_blob_width_px:
            continue
        parts.append(part)
    return parts or [blob]


def _part(blob: RawBlob, a: int, b: int, moving: Mask, width_px: int) -> RawBlob | None:
    """Columns [a, b) of a blob as a blob of its own, trimmed to its pixels."""
    sub = blob.mask[:, a:b]
    rows = np.flatnonzero(sub.any(axis=1))
    cols = np.flatnonzero(sub.any(axis=0))
    if rows.size == 0:
        return None
    r0, r1, c0, c1 = int(rows[0]), int(rows[-1]), int(cols[0]), int(cols[-1])
    mask = sub[r0 : r1 + 1, c0 : c1 + 1]
    u0, v0, w, h = (blob.u0 + a + c0) % width_px, blob.v0 + r0, c1 - c0 + 1, r1 - r0 + 1
    area = int(np.count_nonzero(mask))
    moving_px = int(np.count_nonzero(np.asarray(roi(moving, u0, v0, w, h))[mask]))
    return RawBlob(u0, v0, w, h, mask, area, area / float(w * h), moving_px / max(area, 1))
