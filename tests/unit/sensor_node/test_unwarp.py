"""Unwarp: a panorama warped into an annular image comes back through the remap."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from common.cameras import design_pal
from common.errors import SourceError
from sensor_node.unwarp import PanoFrame, Unwarper
from tests.unit.sensor_node.sn_synth import backdrop, draw_person


def _annular(pano: np.ndarray, model) -> np.ndarray:  # type: ignore[no-untyped-def]
    map_x, map_y = model.warp_maps()
    padded = np.concatenate([pano, pano[:, :1]], axis=1)
    return cv2.remap(padded, map_x, map_y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT)


def test_round_trip_recovers_panorama() -> None:
    model, _ = design_pal()
    pano = backdrop(3)
    draw_person(pano, 500.0)
    unwarper = Unwarper(model)
    annular = _annular(pano, model)
    back = unwarper.apply(annular)
    assert back.shape == pano.shape
    # The ring is sampled coarser than the panorama near its inner edge: compare the mean error.
    err = np.abs(back.astype(np.int16) - pano.astype(np.int16))
    assert float(err.mean()) < 6.0
    # A vertical edge keeps its column: the person's head column is found where it was drawn.
    g = cv2.cvtColor(back, cv2.COLOR_BGR2GRAY).astype(np.float32)
    g0 = cv2.cvtColor(pano, cv2.COLOR_BGR2GRAY).astype(np.float32)
    assert np.argmax(np.abs(np.diff(g[100, 480:520]))) == np.argmax(np.abs(np.diff(g0[100, 480:520])))
    # The pipeline's frame: grey at full resolution, colour at half, full colour on demand (wrapping).
    pf = unwarper.frame(annular)
    assert pf.grey.shape == (162, 1080) and pf.small.shape == (81, 540, 3)
    assert np.abs(pf.grey.astype(int) - cv2.cvtColor(back, cv2.COLOR_BGR2GRAY).astype(int)).mean() < 2.0
    assert np.abs(pf.small.astype(int) - back[::2, ::2].astype(int)).mean() < 8.0
    box = pf.colour(1070, 20, 20, 30)
    assert box.shape == (30, 20, 3)
    ref = np.concatenate([back[20:50, 1070:], back[20:50, :10]], axis=1)
    assert np.abs(box.astype(int) - ref.astype(int)).mean() < 1.0


def test_wrong_frame_size_is_a_source_error() -> None:
    model, _ = design_pal()
    with pytest.raises(SourceError, match="768x576"):
        Unwarper(model).apply(np.zeros((480, 640, 3), np.uint8))
    with pytest.raises(SourceError):
        Unwarper(model).frame(np.zeros((480, 640, 3), np.uint8))


def test_parts_of_the_reduced_colour_image_are_its_pixels() -> None:
    """The shadow test and the blob boxes read the reduced colour image in parts, before (or without) it
    being made whole: the same pixels as the whole image, for a panorama and for a perspective frame."""
    model, _ = design_pal()
    annular = _annular(backdrop(5), model)
    rng = np.random.default_rng(2)
    for lazy, whole in (
        (Unwarper(model).frame(annular), Unwarper(model).frame(annular)),
        (PanoFrame.from_image(annular), PanoFrame.from_image(annular)),
    ):
        small = whole.small
        assert lazy.small_shape == small.shape[:2]
        rows = rng.integers(0, small.shape[0], 200)
        cols = rng.integers(0, small.shape[1], 200)
        assert np.array_equal(lazy.small_at(rows * small.shape[1] + cols), small[rows, cols])
        assert np.array_equal(lazy.small_box(7, 3, 40, 20), small[3:23, 7:47])
        assert np.array_equal(whole.small_at(rows * small.shape[1] + cols), small[rows, cols])
