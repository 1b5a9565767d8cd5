"""A view's blobs: a perspective camera's field of view and picture; a panorama sees every azimuth."""

from __future__ import annotations

import math

import numpy as np
import pytest

from resource_manager.views.blobs import ImageBounds, ViewBlobs


def _view(fov: tuple[float, float] | None) -> ViewBlobs:
    empty = np.zeros(3)
    return ViewBlobs("c", np.zeros(2), 1.0, 0.003, empty, empty, empty, None, np.zeros(3, np.int64), fov=fov)


@pytest.mark.parametrize(
    ("fov", "azimuth", "seen"),
    [
        (None, 3.0, True),
        ((0.0, 0.5), 0.4, True),
        ((0.0, 0.5), 0.6, False),
        ((math.pi, 0.5), -math.pi + 0.4, True),  # across the +-pi seam
    ],
)
def test_sees(fov: tuple[float, float] | None, azimuth: float, seen: bool) -> None:
    v = _view(fov)
    assert v.sees(azimuth) is seen and v.n == 3


def test_image_bounds_inside_the_picture_and_in_front() -> None:
    # looking along world +x, level: camera x = -world y, camera y = -world z, camera z = world x
    r = np.array([[0.0, -1.0, 0.0], [0.0, 0.0, -1.0], [1.0, 0.0, 0.0]])
    k = np.array([[500.0, 0.0, 320.0], [0.0, 500.0, 240.0], [0.0, 0.0, 1.0]])
    img = ImageBounds(k=k, r=r, t=np.zeros(3), width_px=640, height_px=480)
    pts = np.array([[5.0, 0.0, 0.0], [-5.0, 0.0, 0.0], [5.0, 4.0, 0.0], [5.0, 3.3, 0.0]])
    assert img.inside(pts).tolist() == [True, False, False, False]
    assert img.inside(pts, margin_px=20.0).tolist() == [True, False, False, True]  # u = -10 px
