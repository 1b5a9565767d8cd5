"""Stage 2c: cast shadows and highlights are the background, dimmed or brightened; people are not.

A person's shadow on the ground (or a patch of sunlight, a reflection)
changes the pixels as much as the person does in grey levels, and joined to
their feet it makes the blob wider and its bottom lower (``bottom_elev_rad``
then says the person is nearer than they are). In colour it is told apart
(Horprasert et al. 1999; Cucchiara et al. 2003): the surface keeps its hue,
only the light on it changes, so the frame's colour vector is the
background's scaled by a brightness ratio ``a`` (shadow: ``SHADOW_MIN_RATIO``
<= a < 1; highlight: 1 < a <= ``HIGHLIGHT_MAX_RATIO``), with a small
chromatic residual ``|I - a B|``: within the image's own noise
(``CHROMA_SIGMAS`` sigmas of it, measured by the background model) plus
``CHROMA_TOLERANCE`` of the brightness (skylight in a shadow is bluer than
sunlight). A person's clothing differs in hue, or is far darker than any
shadow; cloth that matches the floor's hue (grey trousers on a grey floor)
lacks the floor's texture, which a shadow keeps, dimmed (``TEXTURE_KEPT``).

Runs on the frame's reduced colour image (half resolution: the cheap colour
view every camera type has), on the changed pixels only.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol, cast

import cv2
import numpy as np
import numpy.typing as npt

from common.arrays import Mask
from sensor_node.config import PipelineSettings

__all__ = [
    "CHROMA_SIGMAS",
    "CHROMA_TOLERANCE",
    "HIGHLIGHT_MAX_RATIO",
    "SHADOW_MIN_RATIO",
    "ColourImage",
    "ReducedColour",
    "ShadowCells",
    "local_spread",
    "shadow_cells",
    "spread_at",
]


SHADOW_MIN_RATIO = 0.6
"""Darkest shadow, as a fraction of the lit surface's brightness: the soft cast shadows of diffuse light
(overcast daylight, ceiling lights) take away at most about 40 %. Lower: deep shadows of direct sun go
too, but so do legs in trousers a little darker than the floor (their blobs lose their feet: 0.4 cut the
rendered paper2 site's MOTA from 0.99 to 0.47 through wrong bottoms, benchmarks/NOTES.md)."""

HIGHLIGHT_MAX_RATIO = 1.6
"""Brightest highlight (sunlight patch, reflection) relative to the background."""

CHROMA_SIGMAS = 3.0
"""Chromatic residual allowed, in sigmas of the image's own noise (per channel)."""

CHROMA_TOLERANCE = 0.08
"""Chromatic residual allowed besides noise, as a fraction of the pixel's brightness (the colour of the light
in a shadow differs a little from the direct light's)."""

MIN_BRIGHTNESS_SIGMAS = 4.0
"""Background pixels darker than this many noise sigmas carry no usable hue: never shadow."""


TEXTURE_WINDOW = 5
"""Side of the window (reduced pixels) whose grey-level spread is the local texture."""

TEXTURE_SIGMAS = 2.0
"""A background whose local spread is under this many noise sigmas is flat: no texture to keep or lose."""

TEXTURE_KEPT = 0.5
"""A shadow keeps at least this fraction of the background's texture (spread, scaled by the brightness
ratio); cloth of the floor's colour shows little of it."""


class ReducedColour(Protocol):
    """A frame's reduced colour image, read in parts: a panorama's is sampled from the annular frame, and
    the shadow test reads a few thousand of its pixels (:class:`sensor_node.unwarp.PanoFrame` is one)."""

    @property
    def small_shape(self) -> tuple[int, int]:
        """(rows, columns) of the image."""
        ...

    @property
    def small(self) -> Mask:
        """The whole (rows, columns, 3) BGR image."""
        ...

    def small_at(self, at: npt.NDArray[np.integer]) -> Mask:
        """(N, 3) BGR pixels at the flat indices ``at`` (row * columns + column)."""
        ...

    def small_box(self, c0: int, r0: int, w: int, h: int) -> Mask:
        """The (h, w, 3) box at column ``c0``, row ``r0``."""
        ...


class ColourImage:
    """A reduced colour image already made, as a :class:`ReducedColour`."""

    __slots__ = ("small",)

    def __init__(self, small: Mask) -> None:
        self.small = small

    @property
    def small_shape(self) -> tuple[int, int]:
        return self.small.shape[0], self.small.shape[1]

    def small_at(self, at: npt.NDArray[np.integer]) -> Mask:
        return np.take(self.small.reshape(-1, 3), at, axis=0)

    def small_box(self, c0: int, r0: int, w: int, h: int) -> Mask:
        return np.ascontiguousarray(self.small[r0 : r0 + h, c0 : c0 + w])


def local_spread(bgr: Mask) -> npt.NDArray[np.float32]:
    """Per pixel: grey-level variance over ``TEXTURE_WINDOW`` pixels (the texture a shadow keeps)."""
    g = cv2.cvtColor(bgr, cv2.COLOR_BGR2GRAY).astype(np.float32)
    k = (TEXTURE_WINDOW, TEXTURE_WINDOW)
    m = cv2.blur(g, k)
    return cv2.blur(g * g, k) - m * m


_WINDOW_OFFSETS = np.arange(TEXTURE_WINDOW) - TEXTURE_WINDOW // 2


def spread_at(
    colour: ReducedColour, rows: npt.NDArray[np.integer], cols: npt.NDArray[np.integer]
) -> npt.NDArray[np.float32]:
    """:func:`local_spread` of the reduced colour image at the pixels (``rows``, ``cols``) only, the same values.

    A frame's textured shadow candidates are a few dozen pixels: their windows are gathered (mirrored at
    the image's edges, as the box filter's default border is) rather than the image made and filtered
    around them. The window sums of integer grey levels are exact in float64, so scaling them as the
    box filter does gives its float32 results bit for bit.
    """
    h, w = colour.small_shape
    r = np.abs(rows[:, None] + _WINDOW_OFFSETS)
    r = np.where(r >= h, 2 * (h - 1) - r, r)
    c = np.abs(cols[:, None] + _WINDOW_OFFSETS)
    c = np.where(c >= w, 2 * (w - 1) - c, c)
    # One row of pixels: OpenCV converts row by row, and a column of single pixels costs several times more.
    px = colour.small_at((r[:, :, None] * w + c[:, None, :]).ravel()).reshape(1, -1, 3)
    g = cv2.cvtColor(px, cv2.COLOR_BGR2GRAY).reshape(rows.size, -1).astype(np.float64)
    scale = 1.0 / g.shape[1]
    mean = (g.sum(axis=1) * scale).astype(np.float32)
    mean_sq = ((g * g).sum(axis=1) * scale).astype(np.float32)
    return mean_sq - mean * mean


@dataclass(frozen=True, slots=True)
class ShadowCells:
    """The shadow and highlight pixels of a reduced colour image, and the changed pixels they cover."""

    ys: npt.NDArray[np.intc]
    """Rows of the shadow pixels in the reduced image."""
    xs: npt.NDArray[np.intc]
    """Their columns."""
    small_shape: tuple[int, int]
    """The reduced image's size (rows, columns)."""

    def mask(self, fg: Mask) -> Mask:
        """255 on the changed pixels of ``fg`` (full resolution) that are a shadow or highlight."""
        return _cells_mask(fg, self.ys, self.xs, *self.small_shape)

    def removed_from(self, fg: Mask) -> Mask:
        """``fg`` (full resolution) without its shadow and highlight pixels."""
        sh, sw = self.small_shape
        h, w = fg.shape
        if h % sh == 0 and w % sw == 0:
            # Each shadow pixel's block cleared in a copy: what subtracting the shadow mask gives, without
            # making the mask (two fewer full-size passes).
            out = fg.copy()
            out.reshape(sh, h // sh, sw, w // sw)[self.ys, :, self.xs, :] = 0
            return out
        return cv2.subtract(fg, self.mask(fg))


def shadow_cells(
    small: Mask | ReducedColour,
    colour_bg: npt.NDArray[np.float32],
    fg: Mask,
    noise_sigma: float,
    settings: PipelineSettings,
    *,
    floor: Mask | None = None,
    bg_spread: npt.NDArray[np.float32] | None = None,
) -> ShadowCells | None:
    """The changed pixels of ``fg`` that are a shadow or highlight of the background, in the reduced image;
    None if none (then ``fg`` is all objects).

    Args:
        small: the frame's reduced BGR image (or a view that reads it in parts: only the candidates'
            pixels and the texture windows of the textured ones are read).
        colour_bg: the background in the same reduced BGR (float).
        fg: (H, W) changed pixels (255) at full resolution.
        noise_sigma: the image's noise (grey levels, per channel).
        settings: ``shadows`` (False: no test).
        floor: 255 on the reduced pixels whose ray points below the horizon (where a person's cast
            shadow falls: the floor); None: everywhere. Above it are heads, which dark hair against a
            pale wall of the same hue would otherwise pass for a shadow of.
        bg_spread: :func:`local_spread` of ``colour_bg`` (None: computed here, around the candidates).
    """
    if not settings.shadows:
        return None
    colour = ColourImage(small) if isinstance(small, np.ndarray) else small
    sh, sw = colour.small_shape
    h, w = fg.shape
    # The candidates: changed pixels on the floor, looked for in the floor's box only (on a panorama the
    # rows below the horizon).
    x0, y0, bw, bh = (0, 0, sw, sh) if floor is None or floor.shape != (sh, sw) else cv2.boundingRect(floor)
    if bw == 0:
        return None
    if h % sh == 0 and w % sw == 0:  # what the nearest-neighbour resize picks, without its cost
        ky, kx = h // sh, w // sw
        fg_small = np.ascontiguousarray(fg[y0 * ky : (y0 + bh) * ky : ky, x0 * kx : (x0 + bw) * kx : kx])
    else:
        fg_small = cv2.resize(fg, (sw, sh), interpolation=cv2.INTER_NEAREST)[y0 : y0 + bh, x0 : x0 + bw]
    if floor is not None and floor.shape == (sh, sw):
        fg_small = cv2.bitwise_and(fg_small, floor[y0 : y0 + bh, x0 : x0 + bw])
    points = cv2.findNonZero(fg_small)  # a tenth of np.nonzero's time
    if points is None:
        return None
    xs, ys = cast("npt.NDArray[np.intc]", points).reshape(-1, 2).T
    if x0 or y0:
        xs, ys = xs + x0, ys + y0
    # Pixels gathered by flat index along one axis (a third of the time of indexing by rows and columns).
    at = ys * sw + xs
    frame_px = colour.small_at(at).astype(np.float32)
    bg_px = np.take(colour_bg.reshape(-1, 3), at, axis=0)
    bb = np.einsum("ij,ij->i", bg_px, bg_px)
    ratio = np.einsum("ij,ij->i", frame_px, bg_px) / np.maximum(bb, 1.0)
    chroma = frame_px - ratio[:, None] * bg_px
    resid2 = np.einsum("ij,ij->i", chroma, chroma)
    sigma = max(noise_sigma, 1.0)
    norm_bg = np.sqrt(bb)
    lit = (ratio >= SHADOW_MIN_RATIO) & (ratio <= HIGHLIGHT_MAX_RATIO) & (norm_bg >= MIN_BRIGHTNESS_SIGMAS * sigma)
    tol = CHROMA_SIGMAS * sigma * np.sqrt(3.0) + CHROMA_TOLERANCE * ratio * norm_bg
    is_shadow = lit & (resid2 <= tol * tol)
    if not is_shadow.any():
        return None
    # Texture: a shadow keeps the surface's texture, dimmed with it; cloth of the floor's colour (legs in
    # grey trousers on a tiled floor) shows none of it. Where the background is flat, nothing to tell;
    # the frame's texture is measured at the other candidates only.
    ys, xs, at, ratio = ys[is_shadow], xs[is_shadow], at[is_shadow], ratio[is_shadow]
    if bg_spread is None:
        bg_spread = local_spread(colour_bg)
    vb = np.take(bg_spread, at)
    textured = vb >= (TEXTURE_SIGMAS * sigma) ** 2
    if textured.any():
        ty, tx = ys[textured], xs[textured]
        lost = spread_at(colour, ty, tx) < (TEXTURE_KEPT * ratio[textured]) ** 2 * vb[textured]
        keep = np.ones(ys.size, bool)
        keep[np.flatnonzero(textured)[lost]] = False
        ys, xs = ys[keep], xs[keep]
    if ys.size == 0:
        return None
    return ShadowCells(ys, xs, (sh, sw))


def _cells_mask(fg: Mask, ys: npt.NDArray[np.intc], xs: npt.NDArray[np.intc], sh: int, sw: int) -> Mask:
    """255 on the pixels of ``fg`` in the blocks of the reduced pixels (``ys``, ``xs``) of an (sh, sw) image."""
    h, w = fg.shape
    full = np.zeros((h, w), np.uint8)
    if h % sh == 0 and w % sw == 0:
        # Back to full resolution: each reduced pixel's block, set in place (scaling a mask up costs more).
        full.reshape(sh, h // sh, sw, w // sw)[ys, :, xs, :] = 255
        return cv2.bitwise_and(full, fg)
    # Back to full resolution over the shadow pixels' box only (nearest: each reduced pixel's block).
    r0, r1, c0, c1 = int(ys.min()), int(ys.max()) + 1, int(xs.min()), int(xs.max()) + 1
    box_small = np.zeros((r1 - r0, c1 - c0), np.uint8)
    box_small[ys - r0, xs - c0] = 255
    sy, sx = h / sh, w / sw
    fr0, fr1, fc0, fc1 = round(r0 * sy), round(r1 * sy), round(c0 * sx), round(c1 * sx)
    up = cv2.resize(box_small, (fc1 - fc0, fr1 - fr0), interpolation=cv2.INTER_NEAREST)
    full[fr0:fr1, fc0:fc1] = cv2.bitwise_and(up, fg[fr0:fr1, fc0:fc1])
    return full
