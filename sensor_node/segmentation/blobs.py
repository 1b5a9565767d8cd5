"""Stage 3: group changed pixels into blobs (moving-object candidates) and validate them.

Paper: "The subtraction image ... is analyzed by a grouping algorithm that
generates blobs by merging connected and nearby regions ... Each of the
extracted moving object blobs is checked to determine that enough pixels in
the difference image have changed inside each region".

* connected regions of the foreground mask (8-connectivity); specks under
  ``min_component_px`` are noise;
* regions whose bounding boxes are within ``merge_gap_px`` (columns, rows) of
  each other merge into one blob -- a body split by clothing that matches
  the wall rejoins; on a panorama columns wrap around (column W-1 touches
  column 0), so a person standing on the seam is one blob;
* given the changed pixels before the clean-up that made ``fg`` (``links``),
  a region above another in the same columns joins it when those pixels
  bridge the rows between them with no gap over ``merge_gap_px`` rows: people
  stand upright, and the clean-up erases the thin, sparse parts (a neck, the
  outline of a shirt of the wall's grey) that join a person's head to their
  body; their head alone would be one blob and the rest, wider, another;
* a blob is kept if it has at least ``min_blob_px`` changed pixels, is at
  least ``min_blob_height_px`` tall, and at least ``min_changed_frac`` of its
  bounding box changed.

Blob boxes are in *unwrapped* columns: ``u0`` in [0, W) and ``u0 + w`` may pass
W; :func:`roi` cuts any image of the panorama's size the same way.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
import numpy.typing as npt

from common.arrays import IntArray, Mask
from sensor_node.components import packed_components
from sensor_node.config import PipelineSettings

__all__ = ["RawBlob", "find_blobs", "roi"]

"""An 8-bit single-channel image (cv2 results are typed loosely)."""


@dataclass(frozen=True, slots=True, eq=False)
class RawBlob:
    """One validated blob, before annotation."""

    u0: int
    """Left column of the bounding box, in [0, W)."""
    v0: int
    """Top row."""
    w: int
    """Width in columns (u0 + w may exceed W on a panorama: the box wraps)."""
    h: int
    mask: npt.NDArray[np.bool_]
    """(h, w) pixels of the blob inside its box."""
    area_px: int
    changed_frac: float
    """Changed pixels / box area."""


def roi(image: npt.NDArray[np.generic], u0: int, v0: int, w: int, h: int) -> npt.NDArray[np.generic]:
    """The (h, w) box of ``image`` at (u0, v0), wrapping around the right edge if it passes it."""
    width = image.shape[1]
    rows = slice(v0, v0 + h)
    if u0 + w <= width:
        return image[rows, u0 : u0 + w]
    return np.concatenate([image[rows, u0:], image[rows, : u0 + w - width]], axis=1)


def _groups(adj: npt.NDArray[np.bool_]) -> list[list[int]]:
    """Connected components of a small symmetric adjacency matrix (a frame's few regions: plain lists)."""
    n = adj.shape[0]
    # Each region's neighbours in increasing order (a sparse matrix: a region touches a few others).
    neighbours: list[list[int]] = [[] for _ in range(n)]
    for j, k in zip(*(x.tolist() for x in np.nonzero(adj)), strict=True):
        neighbours[j].append(k)
    seen = [False] * n
    out: list[list[int]] = []
    for i in range(n):
        if seen[i]:
            continue
        stack, members = [i], []
        seen[i] = True
        while stack:
            j = stack.pop()
            members.append(j)
            for k in neighbours[j]:
                if not seen[k]:
                    seen[k] = True
                    stack.append(k)
        out.append(members)
    return out


def _circular_start(a0: IntArray, a1: IntArray, width: int) -> int:
    """Start column of the shortest arc covering intervals [a0, a1] (inclusive) on a circle of ``width``."""
    order = np.argsort(a0)
    s, e = a0[order], a1[order]
    # running end of coverage, then the widest uncovered gap (including the one across the seam)
    ends = np.maximum.accumulate(e)
    gaps = np.append(s[1:] - ends[:-1], s[0] + width - ends[-1])
    k = int(np.argmax(gaps))
    return int(s[(k + 1) % len(s)])


def find_blobs(
    fg: Mask,
    settings: PipelineSettings,
    wrap: bool = True,
    *,
    check_frac: bool = True,
    links: Mask | None = None,
) -> list[RawBlob]:
    """Group the foreground pixels of one frame into validated blobs.

    Grouping runs on a ``group_scale``-times reduced mask (a reduced pixel is set
    if any of its pixels is): connected components cost in proportion to the
    pixels scanned, and people are far larger than a reduced pixel. Each
    group's box is then cut from the full-resolution mask and trimmed to it, so
    boxes, masks and heads keep full resolution.

    Args:
        fg: (H, W) 255 = changed against the background.
        settings: grouping and validation knobs.
        wrap: the image is a 360-degree panorama (columns wrap around).
        check_frac: drop blobs with less than ``min_changed_frac`` of their box changed. False: the
            caller checks that after splitting (a person beside a ghost makes a wide, sparse box
            whose parts pass it; dropping the whole would also leave the person unprotected from
            the background update).
        links: (H, W) the changed pixels before the clean-up that made ``fg`` (a superset of its
            evidence): regions one above the other join through them (the module docstring). None: no
            such joins.
    """
    height, width = fg.shape
    k = settings.group_scale
    small = fg if k == 1 else cv2.resize(fg, (width // k, height // k), interpolation=cv2.INTER_AREA)
    n, stats = packed_components(small)
    if n <= 1:
        return []
    width_s = small.shape[1]
    st = stats[1:].astype(np.int64)
    st = st[st[:, cv2.CC_STAT_AREA] * k * k >= settings.min_component_px]
    if st.shape[0] == 0:
        return []
    a0 = st[:, cv2.CC_STAT_LEFT]
    a1 = a0 + st[:, cv2.CC_STAT_WIDTH] - 1
    b0 = st[:, cv2.CC_STAT_TOP]
    b1 = b0 + st[:, cv2.CC_STAT_HEIGHT] - 1
    gx, gy = (-(-g // k) for g in settings.merge_gap_px)
    # Pairwise box gaps (<= 0: overlapping or touching), columns also across the seam.
    gap_x = np.maximum(a0[:, None], a0[None, :]) - np.minimum(a1[:, None], a1[None, :]) - 1
    if wrap:
        for shift in (width_s, -width_s):
            g = np.maximum(a0[:, None], a0[None, :] + shift) - np.minimum(a1[:, None], a1[None, :] + shift) - 1
            gap_x = np.minimum(gap_x, g)
    gap_y = np.maximum(b0[:, None], b0[None, :]) - np.minimum(b1[:, None], b1[None, :]) - 1
    adj = (gap_x <= gx) & (gap_y <= gy)
    if links is not None:
        adj |= _bridged(links, k, (a0, a1, b0, b1), (gap_x, gap_y), gy)
    out: list[RawBlob] = []
    # A frame's few groups of a few regions each: their boxes from plain ints.
    area, left, right, top, bottom = (x.tolist() for x in (st[:, cv2.CC_STAT_AREA], a0, a1, b0, b1))
    for members in _groups(adj):
        if sum(area[i] for i in members) * k * k < settings.min_blob_px:
            continue
        u0, u1 = min(left[i] for i in members), max(right[i] for i in members)
        if wrap and len(members) > 1 and u1 - u0 >= width_s // 2:
            # Only a group spanning half the panorama or more may be shorter across the seam.
            m = np.asarray(members)
            u0 = _circular_start(a0[m], a1[m], width_s)
            s0 = np.where(a0[m] < u0, a0[m] + width_s, a0[m])
            ws = int((s0 + (a1[m] - a0[m])).max()) - u0 + 1
        else:
            ws = u1 - u0 + 1
        v0 = min(top[i] for i in members)
        box = (u0 * k, v0 * k, min(ws * k, width), (max(bottom[i] for i in members) - v0 + 1) * k)
        blob = _cut(fg, box, wrap)
        if blob is None or blob.area_px < settings.min_blob_px or blob.h < settings.min_blob_height_px:
            continue
        if blob.w < settings.min_blob_width_px:
            continue
        if check_frac and blob.changed_frac < settings.min_changed_frac:
            continue
        out.append(blob)
    return out


def _bridged(
    links: Mask, k: int, boxes: tuple[IntArray, IntArray, IntArray, IntArray], gaps: tuple[IntArray, IntArray], gy: int
) -> npt.NDArray[np.bool_]:
    """Pairs of regions (reduced boxes ``a0, a1, b0, b1``) one above the other whose shared columns hold
    ``links`` pixels on the rows between them, with no run of empty rows longer than ``gy``."""
    gap_x, gap_y = gaps
    n = gap_x.shape[0]
    out = np.zeros((n, n), bool)
    stacked = (gap_x < 0) & (gap_y > gy)
    if not stacked.any():
        return out
    pairs = np.argwhere(stacked)
    pairs = pairs[pairs[:, 0] < pairs[:, 1]]
    a0, a1, b0, b1 = boxes
    height, width = links.shape
    small = links if k == 1 else cv2.resize(links, (width // k, height // k), interpolation=cv2.INTER_AREA)
    width_s = small.shape[1]
    for i, j in pairs.tolist():
        up, lo = (i, j) if b1[i] < b0[j] else (j, i)
        # Shared columns, across the seam if that is where they overlap.
        for shift in (0, width_s, -width_s):
            c0, c1 = max(a0[up], a0[lo] + shift), min(a1[up], a1[lo] + shift)
            if c0 <= c1:
                break
        cols = np.arange(c0, c1 + 1) % width_s
        longest = run = 0
        filled_rows: list[bool] = np.any(small[b1[up] + 1 : b0[lo]][:, cols], axis=1).tolist()
        for filled in filled_rows:
            run = 0 if filled else run + 1
            longest = max(longest, run)
        if longest <= gy:
            out[i, j] = out[j, i] = True
    return out


def _cut(fg: Mask, box: tuple[int, int, int, int], wrap: bool) -> RawBlob | None:
    """The blob in a full-resolution box (u0, v0, w, h): its changed pixels, the box trimmed to them."""
    height, width = fg.shape
    u0, v0, w, h = box
    h = min(h, height - v0)
    if not wrap:
        w = min(w, width - u0)
    sub = np.asarray(roi(fg, u0, v0, w, h))
    c0, r0, w, h = cv2.boundingRect(sub)  # of its set pixels
    if w == 0:
        return None
    sub = sub[r0 : r0 + h, c0 : c0 + w]
    u0, v0 = (u0 + c0) % width, v0 + r0
    area = cv2.countNonZero(sub)
    return RawBlob(u0, v0, w, h, sub > 0, area, area / float(w * h))
