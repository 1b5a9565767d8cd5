"""Shadows and highlights: the background dimmed or brightened with its hue and texture kept is marked; a
differently coloured patch, flat cloth of the floor's colour, or something far darker is not."""

from __future__ import annotations

from typing import Any

import msgspec
import numpy as np
import pytest

from sensor_node.background.shadows import (
    SHADOW_MIN_RATIO,
    TEXTURE_WINDOW,
    ColourImage,
    local_spread,
    shadow_cells,
    spread_at,
)
from sensor_node.config import PipelineSettings

SMALL_H, SMALL_W = 60, 80
"""The reduced colour image; the changed-pixel mask is at twice the resolution."""
NOISE = 2.0
ON = msgspec.structs.replace(PipelineSettings(), shadows=True)


def shadow_mask(
    frame: np.ndarray, bg: np.ndarray, fg: np.ndarray, noise: float, settings: PipelineSettings, **kw: Any
) -> np.ndarray | None:
    """The shadow cells as a mask at ``fg``'s resolution; None if there are none."""
    cells = shadow_cells(frame, bg, fg, noise, settings, **kw)
    return None if cells is None else cells.mask(fg)


def _background() -> np.ndarray:
    """A tiled, textured floor in a warm grey (BGR), like the rendered rooms'."""
    rng = np.random.default_rng(3)
    texture = rng.normal(0.0, 12.0, (SMALL_H, SMALL_W, 1))
    return np.clip(np.array([110.0, 130.0, 150.0]) + texture, 0, 255).astype(np.float32)


PATCHES = {
    "shadow": (slice(5, 20), slice(5, 25)),
    "highlight": (slice(5, 20), slice(45, 65)),
    "blue_cloth": (slice(35, 50), slice(5, 25)),
    "flat_grey_cloth": (slice(35, 50), slice(30, 50)),
    "black": (slice(35, 50), slice(55, 75)),
}


def _scene() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    bg = _background()
    frame = bg.copy()
    frame[PATCHES["shadow"]] *= 0.7  # the light dimmed: hue and texture kept
    frame[PATCHES["highlight"]] *= 1.3
    frame[PATCHES["blue_cloth"]] = (170.0, 90.0, 60.0)
    frame[PATCHES["flat_grey_cloth"]] = 0.7 * np.array([110.0, 130.0, 150.0])  # the floor's hue, no texture
    frame[PATCHES["black"]] *= 0.25  # far darker than any shadow
    frame = np.clip(frame + np.random.default_rng(4).normal(0.0, NOISE, frame.shape), 0, 255).astype(np.uint8)
    fg = np.zeros((2 * SMALL_H, 2 * SMALL_W), np.uint8)
    for rows, cols in PATCHES.values():
        fg[2 * rows.start : 2 * rows.stop, 2 * cols.start : 2 * cols.stop] = 255
    return frame, bg, fg


def _fraction(mask: np.ndarray | None, patch: str, inset: int = 0) -> float:
    """Fraction of a patch (less ``inset`` reduced pixels at its edges) that ``mask`` marks."""
    if mask is None:
        return 0.0
    rows, cols = PATCHES[patch]
    r0, r1, c0, c1 = rows.start + inset, rows.stop - inset, cols.start + inset, cols.stop - inset
    return float((mask[2 * r0 : 2 * r1, 2 * c0 : 2 * c1] > 0).mean())


@pytest.mark.parametrize("precomputed_spread", [False, True])
def test_a_dimmed_or_brightened_background_is_marked_and_people_are_not(precomputed_spread: bool) -> None:
    frame, bg, fg = _scene()
    spread = local_spread(bg.astype(np.uint8)) if precomputed_spread else None
    mask = shadow_mask(frame, bg, fg, NOISE, ON, bg_spread=spread)
    assert mask is not None and mask.shape == fg.shape
    assert _fraction(mask, "shadow") > 0.9
    assert _fraction(mask, "highlight") > 0.9
    assert _fraction(mask, "blue_cloth") < 0.1
    assert _fraction(mask, "black") < 0.1
    # Flat cloth of the floor's hue: told apart by the texture it lacks, once the texture window no longer
    # reaches the textured floor around it.
    assert _fraction(mask, "flat_grey_cloth", inset=TEXTURE_WINDOW // 2) < 0.1
    assert not (mask & ~fg).any()  # only ever changed pixels


def test_only_on_the_floor_when_a_floor_mask_is_given() -> None:
    frame, bg, fg = _scene()
    floor = np.zeros((SMALL_H, SMALL_W), np.uint8)
    floor[:, :35] = 255  # the shadow patch is on the floor, the highlight patch is not
    mask = shadow_mask(frame, bg, fg, NOISE, ON, floor=floor)
    assert _fraction(mask, "shadow") > 0.9 and _fraction(mask, "highlight") == 0.0


def test_nothing_to_mark_gives_none() -> None:
    frame, bg, fg = _scene()
    assert shadow_mask(frame, bg, fg, NOISE, msgspec.structs.replace(ON, shadows=False)) is None
    assert shadow_mask(frame, bg, np.zeros_like(fg), NOISE, ON) is None
    only_cloth = np.zeros_like(fg)
    rows, cols = PATCHES["blue_cloth"]
    only_cloth[2 * rows.start : 2 * rows.stop, 2 * cols.start : 2 * cols.stop] = 255
    assert shadow_mask(frame, bg, only_cloth, NOISE, ON) is None


@pytest.mark.parametrize("fg_size", [(2 * SMALL_H, 2 * SMALL_W), (2 * SMALL_H + 1, 2 * SMALL_W + 3)])
def test_removing_shadows_clears_exactly_the_marked_pixels(fg_size: tuple[int, int]) -> None:
    """The changed pixels without the shadows are the changed pixels less the shadow mask, whether the
    mask is a whole multiple of the reduced image or not; with no changed pixels, no shadow cells."""
    frame, bg, fg = _scene()
    big = np.zeros(fg_size, np.uint8)
    big[: fg.shape[0], : fg.shape[1]] = fg
    mask = shadow_mask(frame, bg, big, NOISE, ON)
    assert mask is not None
    cells = shadow_cells(frame, bg, big, NOISE, ON)
    assert cells is not None
    kept = cells.removed_from(big)
    assert np.array_equal(kept, np.where(mask > 0, 0, big))
    assert kept.any() and (kept & mask).sum() == 0
    assert shadow_cells(frame, bg, np.zeros_like(big), NOISE, ON) is None


@pytest.mark.parametrize(("ratio", "marked"), [(SHADOW_MIN_RATIO + 0.1, True), (SHADOW_MIN_RATIO - 0.15, False)])
def test_the_darkest_shadow_is_the_configured_fraction_of_the_lit_surface(ratio: float, marked: bool) -> None:
    bg = _background()
    frame = np.clip(bg * ratio, 0, 255).astype(np.uint8)
    fg = np.full((2 * SMALL_H, 2 * SMALL_W), 255, np.uint8)
    mask = shadow_mask(frame, bg, fg, NOISE, ON)
    assert (mask is not None and (mask > 0).mean() > 0.9) == marked


def test_local_spread_is_the_grey_level_variance_of_the_texture() -> None:
    flat = np.full((30, 30, 3), 120, np.uint8)
    stripes = flat.copy()
    stripes[:, ::2] = 100  # +-10 grey levels: variance 100
    assert float(local_spread(flat)[15, 15]) == pytest.approx(0.0, abs=1e-3)
    assert float(local_spread(stripes)[15, 15]) == pytest.approx(100.0, rel=0.1)


def test_the_spread_at_some_pixels_is_the_spread_image_there() -> None:
    """The shadow test reads the frame's texture at its candidates only: the same values as the whole
    image's, bit for bit, at the edges too (mirrored windows)."""
    frame, _, _ = _scene()
    rng = np.random.default_rng(5)
    rows = np.concatenate([[0, 1, SMALL_H - 1, SMALL_H - 2], rng.integers(0, SMALL_H, 300)])
    cols = np.concatenate([[0, SMALL_W - 1, 1, SMALL_W - 2], rng.integers(0, SMALL_W, 300)])
    assert np.array_equal(spread_at(ColourImage(frame), rows, cols), local_spread(frame)[rows, cols])
